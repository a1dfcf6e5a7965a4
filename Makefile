# Workspace entry points. `make setup` is idempotent and a quick no-op when nothing changed.
SHELL := /bin/bash
.DEFAULT_GOAL := setup

# Extra arguments for the tools, e.g. `make demo ARGS="--duration 5"`.
ARGS ?=
# Bag directory for `make report BAG=bags/<run>`.
BAG ?=
# $(BAG) as one shell word, whatever it holds (spaces, quotes, `;`, `$`): single-quoted, with each
# single quote closed, escaped and reopened.
QUOTED_BAG = '$(subst ','\'',$(value BAG))'
# SPECs of config/campaigns/ that `make campaigns` runs.
CAMPAIGNS ?= laws_speeds robustness lines_speeds

# Test kinds: pytest.ini (unit, offline, live; slow marks the costly ones); `make test-fast` = unit +
# offline without slow: no DDS, no tool started as a process. `make test` runs all.
FAST_TESTS := (unit or offline) and not live and not slow
# The kinds that start nothing over DDS run on TEST_WORKERS processes (pytest-xdist; each test file on
# one, so a module's fixtures are built once; 0: in pytest's own process). The live ones run after
# them with the machine to themselves: their nodes keep real time.
TEST_WORKERS ?= 2
PARALLEL = --numprocesses=$(TEST_WORKERS) --dist=loadfile

.PHONY: setup test test-fast test-portable mutation lint typecheck clean demo reproduce catenary two-pantographs fe-experiment realistic-passive realistic-experiment realistic-goals realistic-held-out realistic-guard-estimate realistic-support-zone realistic-draws realistic-pair realistic-pair-sections realistic-pair-bound realistic-pair-draw realistic-deviation realistic-sections realistic-passes realistic-passes-sections line-response fe-live bench soak report info replay re-estimate recover sweep campaigns

setup:
	bash scripts/setup.sh

# Style first (ruff, the project's packages first-party), types (mypy), then the tests: CI runs exactly this.
test: setup
	scripts/with_env.sh ruff check src tests scripts examples
	scripts/with_env.sh ruff format --check src tests scripts examples
	scripts/with_env.sh mypy
	bash scripts/run_tests.sh -m "not live" $(PARALLEL)
	bash scripts/run_tests.sh -m live

# The fast kinds only (cores, offline tools in process), not the slow ones: no node process, no DDS.
test-fast: setup
	bash scripts/run_tests.sh -m "$(FAST_TESTS)" $(PARALLEL)

# The fast tests on another CPU's arithmetic (docs/numerics.md, "Tests that pass on any machine"):
# numpy's SIMD loops narrowed to its x86-64-v2 baseline (AVX-512 and AVX2/FMA off), OpenBLAS on
# another core type's kernels than the one it chose here (scripts/other_openblas_core.py), then numba
# compiling for a generic x86-64 (no FMA, no AVX; its machine code goes beside the host's in the cache).
PORTABLE_NUMPY := X86_V4 AVX512_ICL AVX512_SPR X86_V3
test-portable: setup
	NPY_DISABLE_CPU_FEATURES="$(PORTABLE_NUMPY)" bash scripts/run_tests.sh -m "$(FAST_TESTS)" $(PARALLEL)
	core="$$(scripts/with_env.sh python scripts/other_openblas_core.py)"; echo "OpenBLAS core type: $${core:-unchanged}"; \
	  OPENBLAS_CORETYPE="$$core" bash scripts/run_tests.sh -m "$(FAST_TESTS)" $(PARALLEL)
	NUMBA_CPU_NAME=generic scripts/with_env.sh python -m pac_rig.warm
	NUMBA_CPU_NAME=generic bash scripts/run_tests.sh -m "$(FAST_TESTS)" $(PARALLEL)

# Mutation testing (scripts/mutation.py): defects planted one at a time in the safety chain, the
# guard, the observers, the line law, the line's assembly, the FE step and the MCAP writer; each
# scope's fast tests run on each; the report in reports/mutation/. Not part of `make test` (tens of minutes per scope).
# ARGS="--modules kernels guard" narrows it, ARGS="--list" lists the mutants, ARGS="--slow" runs
# the survivors again with the slow tests too.
mutation: setup
	scripts/with_env.sh python scripts/mutation.py $(ARGS)

lint: setup
	scripts/with_env.sh ruff check src tests scripts examples

# mypy on src/ as configured in mypy.ini (the code as annotated; not strict).
typecheck: setup
	scripts/with_env.sh mypy

clean:
	rm -rf build install log

demo: setup
	scripts/with_env.sh ros2 run pac_experiments demo $(ARGS)

reproduce: setup
	scripts/with_env.sh ros2 run pac_experiments reproduce $(ARGS)

# The FE line's checks (reports/catenary/metrics.md), then the laws on it and the live run.
catenary: setup
	scripts/with_env.sh ros2 run pac_experiments catenary $(ARGS)
	$(MAKE) fe-experiment ARGS=
	$(MAKE) fe-live ARGS=

# Two pantographs 200 m apart on the FE line at 250-320 km/h (reports/catenary/two_pantographs/).
two-pantographs: setup
	scripts/with_env.sh ros2 run pac_experiments two_pantographs $(ARGS)

# The control laws on the FE line: the campaign config/campaigns/fe_laws.yaml from fresh (Dask),
# then its goals and figures (reports/catenary/laws/laws.md); ARGS="--report-only" rewrites them.
fe-experiment: setup
	@if [[ " $(ARGS) " != *" --report-only "* ]]; then rm -f reports/catenary/laws/runs.jsonl; fi
	scripts/with_env.sh ros2 run pac_experiments fe_experiment $(ARGS)

# The FE line's response to a span-periodic command: its coupling of harmonics and what a law
# that knew it could reach (reports/catenary/laws/response/response.md).
line-response: setup
	scripts/with_env.sh ros2 run pac_experiments line_response $(ARGS)

# The four-process rig in real time on the FE line, line_adaptive at 300 km/h, against the
# campaign's offline row (reports/catenary/live/live.md).
fe-live: setup
	scripts/with_env.sh ros2 run pac_experiments fe_live $(ARGS)

bench: setup
	scripts/with_env.sh ros2 run pac_experiments bench $(ARGS)

# The real-time rig for 10 min (ARGS="--minutes 3" shortens it): RSS, CPU, every tick, sigma per minute.
soak: setup
	scripts/with_env.sh ros2 run pac_experiments soak $(ARGS)

report: setup
	@if [ -z $(QUOTED_BAG) ]; then echo "usage: make report BAG=<bag directory>" >&2; exit 2; fi
	scripts/with_env.sh ros2 run pac_analysis report $(QUOTED_BAG) $(ARGS)

info re-estimate recover: setup
	@if [ -z $(QUOTED_BAG) ]; then echo "usage: make $@ BAG=<bag directory> [ARGS=...]" >&2; exit 2; fi
	scripts/with_env.sh ros2 run pac_analysis $(subst -,_,$@) $(QUOTED_BAG) $(ARGS)

replay: setup
	@if [ -z $(QUOTED_BAG) ]; then echo "usage: make $@ BAG=<bag directory> [ARGS=...]" >&2; exit 2; fi
	scripts/with_env.sh ros2 run pac_rig replay $(QUOTED_BAG) $(ARGS)

sweep: setup
	scripts/with_env.sh ros2 run pac_experiments sweep $(ARGS)

# Fresh runs (runs.jsonl removed: its rows are keyed by parameters, not by code version);
# the campaign CLI itself resumes when called again on the same --out.
# The passive pantograph on the realistic scenario beside the ideal rig: 20 drawn lines per speed
# (config/campaigns/realistic_passive.yaml -> reports/realistic/passive/; docs/realistic_scenario.md).
# Resumable: an interrupted run goes on where it stopped (ARGS="--workers N").
realistic-passive: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_passive.yaml --out reports/realistic/passive $(ARGS)

# The laws on the realistic scenario: passive, pid, lqr and line_adaptive on 20 drawn lines per speed,
# both actuators (config/campaigns/realistic_laws.yaml -> reports/realistic/laws/; then each law
# against passive run by run, against.md; docs/realistic_scenario.md). Resumable (ARGS="--workers N").
realistic-experiment: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_laws.yaml --out reports/realistic/laws $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/laws --against passive
	scripts/with_env.sh ros2 run pac_experiments realistic_laws_figures reports/realistic/laws

# The realistic scenario's goals, each met or not met with its numbers, read from the committed reports
# (realistic/laws, held_out, pair; catenary/laws) into reports/realistic/goals.md: no run, seconds.
realistic-goals: setup
	scripts/with_env.sh ros2 run pac_experiments realistic_goals $(ARGS)

# line_adaptive against passive on lines held out of design and report (seeds 120-159; 120-139 with
# the pneumatic actuator), the laws campaign's speeds and window (config/campaigns/realistic_held_out.yaml
# -> reports/realistic/held_out/; docs/realistic_scenario.md). 480 runs, about 35 min on 2 workers.
realistic-held-out: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_held_out.yaml --out reports/realistic/held_out $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/held_out --against passive
	scripts/with_env.sh ros2 run pac_experiments realistic_laws_figures reports/realistic/held_out --sigma-only

# line_adaptive with the guard's bar estimated span by span against passive on the same report lines,
# speeds and window (config/campaigns/realistic_guard_estimate.yaml -> reports/realistic/guard_estimate/;
# docs/laws.md, "The guard's bar"). 320 runs, about 16 min on 2 workers. Resumable (ARGS="--workers N").
realistic-guard-estimate: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_guard_estimate.yaml --out reports/realistic/guard_estimate $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/guard_estimate --against passive

# line_adaptive whose harmonics only raise the command about each support, against passive on the
# same report lines, speeds and window (config/campaigns/realistic_support_zone.yaml ->
# reports/realistic/support_zone/; docs/laws.md, "On the realistic line", point 9).
realistic-support-zone: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_support_zone.yaml --out reports/realistic/support_zone $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/support_zone --against passive

# line_adaptive against passive on the 20 report lines with three draws each of the car body's track,
# the turbulence and the noise (config/campaigns/realistic_draws.yaml -> reports/realistic/draws/;
# draw 0 is realistic-experiment's; against.md averages each line's draws before the interval).
realistic-draws: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_draws.yaml --out reports/realistic/draws $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/draws --against passive --draws roof_seed,aero_turbulence_seed,noise_seed

# What the drawn contact-wire deviation does: the passive 3-mass pantograph on the 20 report lines as
# installed (realistic_3km) and as designed (realistic_3km_as_designed), each run against its line
# as designed (config/campaigns/realistic_deviation.yaml -> reports/realistic/deviation/).
realistic-deviation: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_deviation.yaml --out reports/realistic/deviation $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/deviation --against catenary=realistic_3km_as_designed

# Tension sections joined by overlaps: the passive pantograph with and without them, then passive
# against line_adaptive on realistic_electromechanical over them, and the force over the first overlap.
realistic-sections: setup
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_sections.yaml --out reports/realistic/sections $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/sections --against catenary=realistic_3km
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_sections_laws.yaml --out reports/realistic/sections_laws $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/sections_laws --against law=passive
	scripts/with_env.sh ros2 run pac_experiments realistic_overlap_figure --out reports/realistic/sections_laws
	scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/realistic_sections_baselines.yaml --out reports/realistic/sections_baselines $(ARGS)
	scripts/with_env.sh ros2 run pac_experiments campaign_summary reports/realistic/sections_baselines --against law=passive
	scripts/with_env.sh ros2 run pac_experiments realistic_laws_figures reports/realistic/sections_laws \
		--also reports/realistic/sections_baselines --sigma-only

# Two pantographs 200 m apart on the realistic line: active leading, active trailing, both active,
# passive pair, at 250/300/320/350 km/h (reports/realistic/pair/pair.md; src/pac_experiments/pac_experiments/realistic/pair.py;
# ARGS="--speeds 300" for one speed, "--add-to CSV" to add speeds to an earlier run's results).
realistic-pair: setup
	scripts/with_env.sh ros2 run pac_experiments realistic_pair $(ARGS)

# The same over tension sections and their first overlap (realistic_3km_sections, supports 10-40),
# at 300 km/h (reports/realistic/pair_sections/pair.md).
realistic-pair-sections: setup
	scripts/with_env.sh ros2 run pac_experiments realistic_pair --catenary realistic_3km_sections --spans 10 40 \
		--speeds 300 --out reports/realistic/pair_sections $(ARGS)

# A leading pantograph's learned feedforward reshaped (band, stretch, phase) to spare its passive
# follower's sigma, chosen per line from both pantographs' measured responses: what a law learning
# both could reach, not a law (reports/realistic/pair_bound/bound.md; src/pac_experiments/pac_experiments/realistic/pair_bound.py).
realistic-pair-bound: setup
	scripts/with_env.sh ros2 run pac_experiments realistic_pair_bound $(ARGS)

# The pair's runs again on draw 1 (the car bodies' track, turbulence, sensor noise), against the pair
# report's draw 0: what "more loss than the passive pair" resolves (reports/realistic/pair_draw/draw.md).
realistic-pair-draw: setup
	scripts/with_env.sh ros2 run pac_experiments realistic_pair_draw $(ARGS)

# line_adaptive on a map learned on an earlier pass, against its first pass, on the realistic line
# (reports/realistic/passes/passes.md; src/pac_experiments/pac_experiments/realistic/passes.py).
realistic-passes: setup
	scripts/with_env.sh ros2 run pac_experiments realistic_passes $(ARGS)

# The same over tension sections and their overlaps (realistic_3km_sections, the window and statistics
# of realistic_sections_laws.yaml): electromechanical at four speeds, pneumatic at 300 km/h added to
# it (reports/realistic/passes_sections/passes.md).
PASSES_SECTIONS = scripts/with_env.sh ros2 run pac_experiments realistic_passes --out reports/realistic/passes_sections \
	--catenary realistic_3km_sections --spec config/campaigns/realistic_sections_laws.yaml
realistic-passes-sections: setup
	$(PASSES_SECTIONS) --scenarios realistic_electromechanical
	$(PASSES_SECTIONS) --scenarios realistic_pneumatic --speeds 300 --add-to reports/realistic/passes_sections/results.csv

campaigns: setup
	set -e; for c in $(CAMPAIGNS); do \
		rm -f reports/campaigns/$$c/runs.jsonl; \
		scripts/with_env.sh ros2 run pac_experiments campaign config/campaigns/$$c.yaml --out reports/campaigns/$$c $(ARGS); \
	done
