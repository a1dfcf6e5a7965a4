"""A passive pantograph over a whole drawn line against the ideal periodic line: cost and statistics.

``python -m pac_experiments.realistic.line`` builds ``FEPlant`` on a line with a layout rule and a
deviation model (default ``realistic_3km``) and on the ideal line (``benchmark_55m``, the endless
10-span window), runs the passive 3-mass pantograph (its file's uplift at the speed, no actuator
force) over the same distance on both and prints, per line: set-up CPU time and resident memory it
added, CPU time per plant tick, and the EN 50318 statistics (20 Hz low-pass) over every span after a
run-in of ``RUN_IN_SPANS`` spans, contact loss on the unfiltered force, the largest uplift at the
support nearest the contact point. Measured, never tuned: the line is as its file states it.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import time

import numpy as np

from pac_common import markdown
from pac_common.contact_statistics import contact_statistics
from pac_model.parameters import PantographParameters, TrackParameters
from pac_plant.fe_plant import FEPlant
from pac_plant.parameters import PlantOptions

RUN_IN_SPANS = 10
DT = 1e-3


def rss_mb() -> float:
    """Peak resident memory of this process so far [MB]."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def build(catenary: str, speed_kmh: float, seed: int) -> tuple[FEPlant, float, float]:
    """(plant, set-up CPU seconds, peak memory it added [MB])."""
    before, start = rss_mb(), time.process_time()
    options = PlantOptions(catenary_model="fe", catenary=catenary, pantograph="three_mass", line_seed=seed)
    plant = FEPlant(PantographParameters(), TrackParameters(speed_kmh=speed_kmh), None, options, DT)
    return plant, time.process_time() - start, rss_mb() - before


def passive_run(plant: FEPlant, ticks: int) -> dict[str, float]:
    """Run ``ticks`` ticks; the statistics over the spans after the run-in; CPU per tick."""
    line, sim = plant.line, plant.sim
    supports = line.layout.support_x
    force, position, uplift = np.empty(ticks), np.empty(ticks), np.empty(ticks)
    cpu: list[float] = []
    for k in range(ticks):
        t0 = time.process_time()
        plant.advance(0.0)
        truth = plant.truth()
        cpu.append(time.process_time() - t0)
        force[k], position[k] = truth.contact_force, truth.contact_position
        # The support nearest the contact point, on the line's own supports (window coordinates).
        x = sim.x
        xs = supports[int(np.argmin(np.abs(supports - x)))]
        uplift[k] = line.contact_height(sim.d, float(xs))
    start = position[0]
    span = float(np.mean(np.diff(supports)))
    x_from, x_to = start + RUN_IN_SPANS * span, position[-1] - span
    s = contact_statistics(force, position, DT, x_from, x_to)
    window = (position >= x_from) & (position <= x_to)
    batches = [statistics.mean(cpu[i : i + 500]) for i in range(0, len(cpu) - 499, 500)]
    return {
        "tick_us": 1e6 * statistics.median(batches),
        "x_from": x_from,
        "x_to": x_to,
        "Fm": s.contact_force_mean,
        "sigma": s.contact_force_std,
        "Fm_minus_3sigma": s.statistical_min,
        "max": s.contact_force_max,
        "min": s.contact_force_min,
        "loss_percent": s.contact_loss_percent,
        "support_uplift_mm": 1e3 * float(np.max(uplift[window])),
        "slack_at_rest": float(len(line.rest_slack)),
        "n_dof": float(line.n_dof),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="realistic_line", description=__doc__.splitlines()[0])
    parser.add_argument("--catenary", default="realistic_3km", help="the drawn line (default realistic_3km)")
    parser.add_argument("--ideal", default="benchmark_55m", help="the ideal line (default benchmark_55m)")
    parser.add_argument("--speed", type=float, default=300.0, help="km/h (default 300)")
    parser.add_argument("--seed", type=int, default=-1, help="line_seed (default -1: the file's)")
    args = parser.parse_args(argv)
    rows = []
    real, real_setup, real_mb = build(args.catenary, args.speed, args.seed)
    supports = real.line.layout.support_x
    # From the start support to one span before the far anchor.
    ticks = int((supports[-2] - real.sim.x) / (args.speed / 3.6) / DT)
    ideal, ideal_setup, ideal_mb = build(args.ideal, args.speed, -1)
    for name, plant, setup, mb in (
        (args.ideal, ideal, ideal_setup, ideal_mb),
        (args.catenary, real, real_setup, real_mb),
    ):
        r = passive_run(plant, ticks)
        rows.append(
            [
                name,
                f"{r['n_dof']:.0f}",
                f"{setup:.1f}",
                f"{mb:.0f}",
                f"{r['tick_us']:.0f}",
                f"{r['Fm']:.1f}",
                f"{r['sigma']:.1f}",
                f"{r['Fm_minus_3sigma']:.1f}",
                f"{r['max']:.1f}",
                f"{r['min']:.1f}",
                f"{r['loss_percent']:.2f}",
                f"{r['support_uplift_mm']:.1f}",
                f"{r['slack_at_rest']:.0f}",
            ]
        )
    print(f"passive three_mass at {args.speed:g} km/h, {ticks} ticks ({ticks * DT:.1f} s), statistics after")
    print(f"{RUN_IN_SPANS} spans of run-in; load average {os.getloadavg()[0]:.1f}")
    header = [
        "line",
        "DOFs",
        "set-up CPU [s]",
        "memory added [MB]",
        "CPU per tick [us]",
        "Fm [N]",
        "sigma [N]",
        "Fm - 3 sigma [N]",
        "max [N]",
        "min [N]",
        "loss [%]",
        "support uplift [mm]",
        "droppers slack at rest",
    ]
    print(markdown.table(header, rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
