"""``ros2 run pac_experiments sweep``: gains x command delay, offline, as a markdown table.

The evidence behind the shipped gains (docs/design.md): contact-force standard
deviation over [3, T] s with a constant 100 N reference and an ideal actuator
(no limits), or the tick at which the loop diverged.
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from pac_rig.closed_loop import DivergenceError, run
from pac_rig.progress import progress
from pac_rig.simulate import scenario_from_flat

GAINS = [(400, 400, 50), (350, 350, 50), (150, 150, 50), (80, 80, 50), (40, 40, 50), (20, 20, 20)]
DELAYS = [0, 1, 2, 3, 5, 10]


def cell(job: tuple[tuple[float, float, float], int, float]) -> str:
    (c1, c2, c3), delay, duration = job
    scenario = scenario_from_flat(
        {
            "c1": c1,
            "c2": c2,
            "c3": c3,
            "u_min": -1e7,
            "u_max": 1e7,
            "command_delay_ticks": delay,
            "duration": duration,
        }
    )
    errors = []
    try:
        for rec in run(scenario):
            if rec.truth.time >= 3.0:
                errors.append(rec.truth.contact_force - rec.command.force_reference)
    except DivergenceError as exc:
        return f"diverged at {exc.tick / 1000:.2f} s"
    return f"{np.std(errors):.3g}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="sweep", description=__doc__)
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    jobs = [(g, d, args.duration) for g in GAINS for d in DELAYS]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        cells = list(progress(pool.map(cell, jobs), len(jobs), "sweep", "cell"))
    print(f"Contact-force std [N] over [3, {args.duration:g}] s, constant 100 N, ideal actuator\n")
    print("| c1, c2, c3 | " + " | ".join(f"delay {d}" for d in DELAYS) + " |")
    print("|---|" + "---:|" * len(DELAYS))
    for i, g in enumerate(GAINS):
        row = cells[i * len(DELAYS) : (i + 1) * len(DELAYS)]
        print(f"| {g[0]:g}, {g[1]:g}, {g[2]:g} | " + " | ".join(row) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
