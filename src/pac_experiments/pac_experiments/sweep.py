"""``ros2 run pac_experiments sweep``: gains x command delay, offline, as a markdown table.

The evidence behind the shipped gains (docs/design.md): contact-force standard
deviation over [3, T] s with a constant 100 N reference and an ideal actuator
(no limits), or the tick at which the loop diverged.  All cells run in one process with the
compiled batch closed loop (``pac_rig.batch``), scenarios in parallel threads.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from pac_common import markdown
from pac_rig.batch import BatchResult, run_batch
from pac_rig.closed_loop import Scenario
from pac_rig.simulate import scenario_from_flat

GAINS = [(400, 400, 50), (350, 350, 50), (150, 150, 50), (80, 80, 50), (40, 40, 50), (20, 20, 20)]
DELAYS = [0, 1, 2, 3, 5, 10]


def scenario(gains: tuple[float, float, float], delay: int, duration: float) -> Scenario:
    c1, c2, c3 = gains
    return scenario_from_flat(
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


def cell(result: BatchResult, i: int, window_from: float = 3.0) -> str:
    """std of F - F_r over t >= window_from for run i, or when it diverged."""
    n = int(result.ticks[i])
    dt = float(result.sample_period[i])
    if result.diverged[i] is not None:
        return f"diverged at {n * dt:.2f} s"
    t = np.arange(n) * dt
    error = result.traces["contact_force"][i, :n] - result.traces["force_reference"][i, :n]
    return f"{np.std(error[t >= window_from]):.3g}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="sweep", description=__doc__)
    parser.add_argument("--duration", type=float, default=6.0)
    parser.add_argument("--jobs", type=int, default=2, help="threads")
    args = parser.parse_args(argv)
    if not 3.0 < args.duration <= 3600.0:
        print(f"sweep: invalid --duration {args.duration!r}: allowed (3, 3600] s", file=sys.stderr)
        return 2
    if not 1 <= args.jobs <= 64:
        print(f"sweep: invalid --jobs {args.jobs!r}: allowed 1..64", file=sys.stderr)
        return 2
    result = run_batch([scenario(g, d, args.duration) for g in GAINS for d in DELAYS], threads=args.jobs)
    cells = [cell(result, i) for i in range(len(GAINS) * len(DELAYS))]
    print(f"Contact-force std [N] over [3, {args.duration:g}] s, constant 100 N, ideal actuator\n")
    rows = [
        [f"{g[0]:g}, {g[1]:g}, {g[2]:g}", *cells[i * len(DELAYS) : (i + 1) * len(DELAYS)]]
        for i, g in enumerate(GAINS)
    ]
    header = ["c1, c2, c3", *(f"delay {d}" for d in DELAYS)]
    print(markdown.table(header, rows, ["l"] + ["r"] * len(DELAYS)))
    print(
        f"\n{len(cells)} runs, {result.simulated_seconds:.0f} scenario-s in {result.wall_seconds:.2f} s "
        f"({result.simulated_seconds / result.wall_seconds:.0f} scenario-s per wall-s, {args.jobs} threads)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
