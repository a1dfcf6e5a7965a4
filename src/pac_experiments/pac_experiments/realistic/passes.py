"""A learned map over passes of the same train: ``line_adaptive`` on a map learned on an earlier pass,
against its first pass, on the realistic line (``make realistic-passes``).

Per line seed, speed and scenario, five runs, each with the realistic experiment's window and
statistics (``config/campaigns/realistic_laws.yaml``: EN 50318 over spans 10-30, F_r the EN 50367
target):

- pass A (the train's first pass; the scenario's seeds, line map error +0.5 m): ``line_adaptive`` as
  in the realistic experiment (its row there, with passive's, is pass A's result), which writes a
  map (``LineAdaptiveLaw.next_map``);
- pass B (the same train later: another draw of the track under the car body, of the turbulent
  uplift and of the sensors' noise, :data:`PASS_B`): passive; ``line_adaptive`` on a first pass again
  (no map); on the map of pass A with the line map's error of the other sign (-0.5 m: the map and
  the train's position 1 m apart, the worst the +-0.5 m bound allows); and on the map with the same
  error as pass A (+0.5 m: a train localised by the same balises, the best case).

Each run of pass B is compared with pass B's passive run on the same line. Writes
``reports/realistic/passes/`` (passes.md, results.csv). ``--spec`` and ``--catenary`` run the same on
another SPEC's window and line (``make realistic-passes-sections``: realistic_3km_sections, the
window of ``config/campaigns/realistic_sections_laws.yaml``, into ``reports/realistic/passes_sections/``).
The map's law: docs/laws.md, "A map learned over passes".
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from pac_common import markdown
from pac_experiments.campaign.summary import Interval, percent_change
from pac_experiments.realistic import (
    REPORT_LINES,
    add_settings_option,
    draw,
    settings_or_none,
    settings_text,
    write_results,
)

SCENARIOS = ("realistic_electromechanical", "realistic_pneumatic")
SPEEDS = (250.0, 300.0, 320.0, 350.0)
SEEDS = REPORT_LINES
SPEC = Path("config/campaigns/realistic_laws.yaml")
OUT = Path("reports/realistic/passes")
#: Pass A's line map error (the scenario files') and pass B's draws of what changes between passes.
POSITION_ERROR = 0.5
PASS_B = draw(1)
#: The runs of one line: (name, pass, law, map, position error); "map" runs read pass A's map.
RUNS = (
    ("first pass A", "A", "line_adaptive", False, POSITION_ERROR),
    ("passive B", "B", "passive", False, -POSITION_ERROR),
    ("first pass B", "B", "line_adaptive", False, -POSITION_ERROR),
    ("map, position 1 m off", "B", "line_adaptive", True, -POSITION_ERROR),
    ("map, position as pass A", "B", "line_adaptive", True, POSITION_ERROR),
)
#: What the report compares, each with the passive run of its pass.
COMPARED = ("first pass B", "map, position 1 m off", "map, position as pass A")


def run_line(
    scenario: str,
    speed: float,
    seed: int,
    maps: str,
    spec_path: Path = SPEC,
    catenary: str | None = None,
    settings: dict[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """The five runs of one line (module docstring), in order; pass A's map goes to ``maps``. ``spec_path``:
    the campaign SPEC whose window and statistics the runs take; ``catenary``: the line (default: the
    scenario's); ``settings``: parameters of the law for each line_adaptive run."""
    from pac_controller.line_adaptive import TRIP_REASONS, LineAdaptiveLaw
    from pac_controller.line_map import write_line_map
    from pac_experiments.campaign.run import en50318_measures
    from pac_experiments.campaign.spec import load_spec, resolve
    from pac_rig.closed_loop import build_cores, run_blocks
    from pac_rig.loop import compile_loop

    spec = load_spec(spec_path)
    map_path = Path(maps) / f"{scenario}_{speed:g}_{seed}.json"
    rows = []
    for name, pass_, law, use_map, position_error in RUNS:
        values: dict[str, Any] = {
            "scenario": scenario, "observer": "head_balance", "law": law, "line_seed": seed,
            "speed_kmh": speed, "line_position_error": position_error,
            **({"catenary": catenary} if catenary else {}),
            **(PASS_B if pass_ == "B" else {}), **({"line_map": str(map_path)} if use_map else {}),
            **(settings or {} if law == "line_adaptive" else {}),
        }  # fmt: skip
        s, _, window = resolve(spec, values)
        plant, observer, controller = build_cores(s)
        loop = compile_loop(plant, observer, controller, s.loop.command_delay_ticks)
        assert loop is not None  # every part here has its compiled form
        ticks = np.concatenate(list(run_blocks(s, plant, loop)))
        dt = s.loop.sample_period
        m = en50318_measures(
            np.arange(ticks.size) * dt, ticks["contact_force"], ticks["u"], ticks["contact_force_hat"],
            ticks["contact_uplift"], window, dt,
        )  # fmt: skip
        row: dict[str, Any] = {
            "scenario": scenario, "speed_kmh": speed, "line_seed": seed, "run": name,
            "sigma": m["en50318_contact_force_std"], "mean": m["en50318_contact_force_mean"],
            "loss_percent": m["en50318_contact_loss_percent"],
            "u_max_abs": float(np.max(np.abs(ticks["u"] - ticks["force_reference"]))), "trip": "",
            "map_scale": "",
        }  # fmt: skip
        law_object = controller.law
        if isinstance(law_object, LineAdaptiveLaw):
            state = loop.controller_state[0]
            row["trip"] = TRIP_REASONS[int(state["line_trip_reason"])]
            row["map_scale"] = float(state["line_map_scale"]) if use_map else ""
            if name == "first pass A":
                write_line_map(law_object.next_map(loop.memory, loop.controller_state), map_path)
        rows.append(row)
    return rows


def _run(args: tuple[str, float, int, str, Path, str | None, dict[str, Any]]) -> list[dict[str, Any]]:
    return run_line(*args)


def _changes(rows: list[dict[str, Any]], run: str, passive: str) -> dict[int, float]:
    """sigma change [%] of ``run`` against ``passive`` on each line (by seed)."""
    base = {r["line_seed"]: r for r in rows if r["run"] == passive}
    return {
        r["line_seed"]: percent_change(r["sigma"], base[r["line_seed"]]["sigma"])
        for r in rows
        if r["run"] == run and r["line_seed"] in base
    }


def read_results(path: Path) -> list[dict[str, Any]]:
    """The rows of a results.csv that :func:`write_report` wrote, with their numbers as numbers."""
    with path.open(newline="") as f:
        rows: list[dict[str, Any]] = list(csv.DictReader(f))
    for row in rows:
        row["line_seed"] = int(row["line_seed"])
        for key in ("speed_kmh", "sigma", "mean", "loss_percent", "u_max_abs"):
            row[key] = float(row[key])
        row["map_scale"] = float(row["map_scale"]) if row["map_scale"] else ""
    return rows


def write_report(
    rows: list[dict[str, Any]],
    out: Path,
    spec_path: Path = SPEC,
    catenary: str | None = None,
    settings: dict[str, Any] | None = None,
) -> str:
    """passes.md: per scenario, speed and run, the sigma change against the passive run of its pass
    (mean [95 % interval], worst line), lines with more contact loss than that passive run, and the
    map pass's change against the first pass under the same conditions (pass B), line by line."""
    write_results(rows, out)
    table = []
    for scenario in dict.fromkeys(r["scenario"] for r in rows):
        for speed in sorted({r["speed_kmh"] for r in rows if r["scenario"] == scenario}):
            group = [r for r in rows if r["scenario"] == scenario and r["speed_kmh"] == speed]
            first_b = {r["line_seed"]: r for r in group if r["run"] == "first pass B"}
            for run in COMPARED:
                passive = "passive B"
                change = _changes(group, run, passive)
                if not change:
                    continue
                iv = Interval.of(list(change.values()))
                members = {r["line_seed"]: r for r in group if r["run"] == run}
                base = {r["line_seed"]: r for r in group if r["run"] == passive}
                more = sum(members[k]["loss_percent"] > base[k]["loss_percent"] for k in members if k in base)
                worse = sum(v > 0.0 for v in change.values())
                tripped = sum(bool(members[k]["trip"]) for k in members)
                versus = ""
                if run.startswith("map"):
                    d = Interval.of(
                        [
                            percent_change(members[k]["sigma"], first_b[k]["sigma"])
                            for k in members
                            if k in first_b
                        ]
                    )
                    versus = f"{d.mean:+.1f} [{d.low:+.1f}, {d.high:+.1f}]"
                table.append(
                    [
                        scenario, f"{speed:g}", run, str(len(change)),
                        f"{iv.mean:+.1f} [{iv.low:+.1f}, {iv.high:+.1f}]", f"{iv.largest:+.1f}",
                        str(worse), str(more), str(tripped), versus,
                    ]
                )  # fmt: skip
    header = [
        "scenario", "speed [km/h]", "run", "lines", "sigma vs passive [%]", "worst line [%]",
        "lines worse than passive", "lines with more loss than passive", "guard fell back",
        "map vs first pass B [%]",
    ]  # fmt: skip
    from pac_experiments.campaign.spec import load_spec

    seeds = sorted({r["line_seed"] for r in rows})
    spans = load_spec(spec_path).window_spans or (10, 30)
    line = f" on {catenary}" if catenary else ""
    text = (
        "# A learned map over passes of the same train\n\n"
        f"Generated by `make {'realistic-passes-sections' if catenary else 'realistic-passes'}` "
        "(src/pac_experiments/pac_experiments/realistic/passes.py): "
        f"line seeds {seeds[0]}-{seeds[-1]}{line}, the window and statistics of {spec_path} (EN 50318 "
        f"over spans {spans[0]:g}-{spans[1]:g}, F_r the EN 50367 target). Pass A: the scenario's seeds, "
        "line map error +0.5 m; "
        + (
            f"`line_adaptive` with {settings_text(settings)} (every run of it) there writes the map. "
            if settings
            else "`line_adaptive` there writes the map (pass A's own result is the realistic "
            "experiment's row). "
        )
        + "Pass B: other draws of the track under the car body, the "
        "turbulent uplift and the sensors' noise (roof_seed, aero_turbulence_seed, noise_seed 1). Each "
        "run of pass B against pass B's passive run on the same line: mean [95 % interval] over "
        "the lines; the map runs also against the first pass B on the same line.\n\n"
        + markdown.table(header, table)
        + "\n"
    )
    (out / "passes.md").write_text(text)
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="realistic_passes", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=OUT, help="report folder (default: %(default)s)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--seeds", type=int, nargs="*", default=list(SEEDS), help="line seeds")
    parser.add_argument("--speeds", type=float, nargs="*", default=list(SPEEDS), help="speeds [km/h]")
    parser.add_argument("--scenarios", nargs="*", default=list(SCENARIOS), help="scenarios")
    parser.add_argument(
        "--spec", type=Path, default=SPEC, help="campaign SPEC: window, statistics (default: %(default)s)"
    )
    parser.add_argument("--catenary", help="the line (default: the scenario's)")
    parser.add_argument(
        "--add-to",
        type=Path,
        metavar="CSV",
        help="an earlier run's results.csv: its rows are kept and these runs added (one report of both)",
    )
    add_settings_option(parser, "each of its runs")
    args = parser.parse_args(argv)
    settings = settings_or_none(args.param, "realistic_passes")
    if settings is None:
        return 2
    try:
        earlier = read_results(args.add_to) if args.add_to else []
    except (OSError, KeyError, ValueError) as error:
        print(f"realistic_passes: cannot read {args.add_to}: {error}", file=sys.stderr)
        return 2
    again = {(r["scenario"], r["speed_kmh"], r["line_seed"]) for r in earlier} & {
        (sc, sp, seed) for sc in args.scenarios for sp in args.speeds for seed in args.seeds
    }
    if again:
        sc, sp, seed = min(again)
        print(f"realistic_passes: {args.add_to} has {sc} line {seed} at {sp:g} km/h already", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="pac_maps_") as maps:
        jobs = [
            (sc, sp, seed, maps, args.spec, args.catenary, settings)
            for sc in args.scenarios
            for sp in args.speeds
            for seed in args.seeds
        ]
        with ProcessPoolExecutor(args.workers) as pool:
            rows = earlier + [row for line in pool.map(_run, jobs) for row in line]
    print(write_report(rows, args.out, args.spec, args.catenary, settings))
    return 0


if __name__ == "__main__":
    sys.exit(main())
