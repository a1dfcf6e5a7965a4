"""``make reproduce``: the paper's Section 6 scenarios as bags, figures and a metrics table.

Writes ``bags/reproduce/{paper_square,constant_adaptive,constant_passive,paper_gains}/`` and
``reports/reproduce/`` (PNG figures, metrics.md, metrics.json).  All runs: Table 1,
360 km/h, 1 kHz, one-step command delay, theta_hat(0) = (3000, 0, 0) N/m.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from pac_analysis.metrics import compute_metrics, markdown_table
from pac_analysis.plots import overlay_figure, run_figure
from pac_bag.reader import read_bag
from pac_common import jsonio
from pac_rig.progress import progress
from pac_rig.simulate import RunResult, scenario_from_flat, simulate_to_bag

#: Section 6's gains, run with an actuator without limits as in the paper's continuous simulation.
PAPER_GAINS = {"c1": 400.0, "c2": 400.0, "c3": 50.0, "u_min": -1e7, "u_max": 1e7, "slew_rate_max": 1e12}

RUNS: dict[str, dict[str, Any]] = {
    "paper_square": {"shape": "square"},
    "constant_adaptive": {"shape": "constant"},
    "constant_passive": {"shape": "constant", "law": "passive"},
    "paper_gains": {"shape": "constant", **PAPER_GAINS},
}
COMMON = {"duration": 10.0, "command_delay_ticks": 1, "theta_hat0": (3000.0, 0.0, 0.0)}
WINDOW = (3.0, 10.0)


def _run(job: tuple[str, dict[str, Any], Path]) -> RunResult:
    name, values, bag_dir = job
    if bag_dir.exists():
        shutil.rmtree(bag_dir)
    return simulate_to_bag(scenario_from_flat({**COMMON, **values}), bag_dir, label=name)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="reproduce", description=__doc__)
    parser.add_argument("--bags", type=Path, default=Path("bags/reproduce"))
    parser.add_argument("--reports", type=Path, default=Path("reports/reproduce"))
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    jobs = [(name, values, args.bags / name) for name, values in RUNS.items()]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        results = dict(zip(RUNS, progress(pool.map(_run, jobs), len(jobs), "reproduce", "run"), strict=True))
    args.reports.mkdir(parents=True, exist_ok=True)
    bags, metrics, notes = {}, {}, []
    for name, result in results.items():
        bag = read_bag(result.bag_path)
        bags[name] = bag
        speed = result.simulated_seconds / result.wall_seconds
        if result.diverged:
            notes.append(
                f"- **{name}**: {result.diverged} (t = {result.ticks / 1000:.3f} s); "
                "the run stopped there and its bag holds every tick up to it."
            )
        else:
            metrics[name] = compute_metrics(bag, *WINDOW)
        print(
            f"{name:18s} {result.ticks:6d} ticks, {speed:5.1f}x real time (incl. bag writing)"
            + (f"  DIVERGED: {result.diverged}" if result.diverged else "")
        )
        run_figure(bag, name, args.reports / f"{name}.png")
    overlay_figure(
        {"passive (u = F_r)": bags["constant_passive"], "adaptive backstepping": bags["constant_adaptive"]},
        "Passive vs active pantograph, 360 km/h, F_r = 100 N",
        args.reports / "passive_vs_adaptive.png",
        window=(0.0, 4.0),
    )
    table = markdown_table(metrics)
    notes.insert(
        0,
        "- **paper_square**: the reference itself is a 0/100 N square wave, so Fm and sigma "
        "describe the wave; tracking RMS (F - F_r) is the measure of the controller.",
    )
    text = "# make reproduce: metrics\n\n" + table + "\n" + "\n".join(notes) + "\n"
    (args.reports / "metrics.md").write_text(text)
    payload: dict[str, dict[str, Any]] = {name: m.as_dict() for name, m in metrics.items()}
    payload.update(
        {name: {"diverged": r.diverged, "ticks": r.ticks} for name, r in results.items() if r.diverged}
    )
    jsonio.write(args.reports / "metrics.json", payload)
    print(text)
    print(f"bags: {args.bags}/  figures and tables: {args.reports}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
