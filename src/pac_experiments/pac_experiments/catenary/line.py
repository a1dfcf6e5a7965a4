"""``make catenary``: the FE catenary's line checks (writes ``reports/catenary/``).

1. statics: achieved vs target pre-sag, dropper lengths, static stiffness along a span;
2. reference runs: the benchmark-like 3-mass pantograph, passive, at 250 and 300 km/h on
   the 10-span section of every shipped catenary preset (config/catenaries/), EN 50318
   statistics over the middle two spans, beside the EN 50318:2002 bands (a *different*
   reference model) with the distance to each band;
3. numerics: mesh/time-step convergence, penalty stiffness, damping, cost per step;
4. the diagnosis of the paper's law on the FE line (passive vs adaptive backstepping, two
   measurement datums, the best fit of the paper's contact model).

Runs: ``fe_line_runs``; write-up: ``fe_line_report``. The laws-against-speeds experiment
on the FE line is the campaign config/campaigns/fe_laws.yaml (``fe_experiment``).
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from pac_common import jsonio
from pac_experiments.catenary.line_report import write_report
from pac_experiments.catenary.line_runs import (
    EXPERIMENT_RUNS,
    EXPERIMENT_SPEEDS,
    NUMERICS_VARIANTS,
    REFERENCE_SPEEDS,
    closed_loop_run,
    cost_breakdown,
    passive_reference,
    reference_lines,
    statics_summary,
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="catenary", description=__doc__)
    parser.add_argument("--reports", type=Path, default=Path("reports/catenary"))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--skip-numerics", action="store_true", help="no convergence/penalty/damping runs")
    parser.add_argument(
        "--cost-only", action="store_true", help="CPU cost per step only (to <reports>/cost.json), then stop"
    )
    args = parser.parse_args(argv)
    if args.cost_only:
        args.reports.mkdir(parents=True, exist_ok=True)
        cost = cost_breakdown()
        jsonio.write(args.reports / "cost.json", cost)
        print(jsonio.dumps(cost, indent=2))
        return 0
    out = args.reports
    out.mkdir(parents=True, exist_ok=True)
    statics, _ = statics_summary()
    print(
        f"statics: pre-sag error {statics['presag_max_error_mm_all_droppers']:.2e} mm, "
        f"k {statics['stiffness_min_N_per_m']:.0f}..{statics['stiffness_max_N_per_m']:.0f} N/m"
    )

    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        exp_jobs = [(v, m, d) for v in EXPERIMENT_SPEEDS for m, d in EXPERIMENT_RUNS]
        exp_futures = [pool.submit(closed_loop_run, j) for j in exp_jobs]
        ref_futures = {
            (name, v): pool.submit(passive_reference, v, catenary=name)
            for name in reference_lines()
            for v in REFERENCE_SPEEDS
        }
        num_jobs: dict[str, Any] = {}
        if not args.skip_numerics:
            for label, kw in NUMERICS_VARIANTS.items():
                num_jobs[label] = pool.submit(passive_reference, 300, **kw)
        refs_by_line: dict[str, dict[int, dict[str, Any]]] = {}
        for (name, v), f in ref_futures.items():
            refs_by_line.setdefault(name, {})[v] = f.result()
        numerics = {k: f.result() for k, f in num_jobs.items()}
        exp = [f.result() for f in exp_futures]
    cost = cost_breakdown()

    print(write_report(out, statics, refs_by_line, numerics, cost, exp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
