"""Force and contact-wire uplift along the line: the passive pantograph on the realistic scenario
beside the ideal rig, one figure.

``ros2 run pac_experiments realistic_figure --out DIR [--seed N] [--speed KMH] [--spans A B]``
runs law ``passive`` (the EN 50367 target at the speed) twice through the offline closed loop:
on the ideal rig's FE line (the paper's 2-DOF, the endless benchmark window) and on the scenario
``realistic_electromechanical`` with line seed N (its sensors replaced by the fixed datum, which
the passive law does not read), and draws, over spans A..B of each run, the contact force (raw
and EN 50318's 20 Hz low-pass) and the contact wire's uplift at the contact point against the
distance from the run's start, the supports of each line marked. Writes
``DIR/fig_force_uplift.png``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from pac_common.contact_statistics import lowpass, target_mean_force
from pac_rig.closed_loop import build_cores, run
from pac_rig.composition import derive
from pac_rig.simulate import scenario_from_flat

DT = 1e-3


def force_series(values: dict, spans: tuple[float, float]) -> dict[str, np.ndarray]:
    """Position from the start [m], raw and filtered force [N], uplift [mm] over spans a..b, and
    the supports there [m from the start]."""
    derived, _ = derive(values)
    scenario = scenario_from_flat(derived)
    span = scenario.track.span_length
    duration = (spans[1] + 0.5) * span / (scenario.track.speed_kmh / 3.6)
    scenario = scenario_from_flat({**derived, "duration": round(duration, 3)})
    force, position, uplift = [], [], []
    for rec in run(scenario):
        force.append(rec.truth.contact_force)
        position.append(rec.truth.contact_position)
        uplift.append(rec.truth.contact_uplift)
    x = np.asarray(position)
    start = x[0]
    window = (x >= start + spans[0] * span) & (x <= start + spans[1] * span)
    filtered = lowpass(np.asarray(force), DT)
    # Every run starts at a support: a whole line's are its layout's; the endless window's repeat
    # every span (its layout holds window coordinates).
    plant = build_cores(scenario)[0]
    data = plant.data  # type: ignore[attr-defined]
    if data.whole_line:
        supports = np.asarray(plant.line.layout.support_x)  # type: ignore[attr-defined]
    else:
        supports = start + span * np.arange(int(spans[1]) + 2)
    seen = supports[(supports >= x[window][0]) & (supports <= x[window][-1])]
    return {
        "x": x[window] - start,
        "raw": np.asarray(force)[window],
        "filtered": filtered[window],
        "uplift_mm": 1e3 * np.asarray(uplift)[window],
        "supports": seen - start,
        "start": np.asarray(start),  # the run's first contact position [m from the line's start]
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="realistic_figure", description=__doc__)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--speed", type=float, default=300.0)
    parser.add_argument("--spans", type=float, nargs=2, default=(10.0, 35.0))
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    common = {"law": "passive", "speed_kmh": args.speed, "force_amplitude": target_mean_force(args.speed)}
    runs = {
        "ideal rig (paper's 2-DOF, endless benchmark window)": {**common, "catenary_model": "fe"},
        f"realistic_electromechanical, line seed {args.seed}": {
            **common,
            "scenario": "realistic_electromechanical",
            "line_seed": args.seed,
            "sensors": "ground",
        },
    }
    fig, axes = plt.subplots(len(runs), 1, figsize=(12, 7), sharex=True)
    for ax, (title, values) in zip(axes, runs.items(), strict=True):
        s = force_series(values, tuple(args.spans))
        ax.plot(s["x"], s["raw"], lw=0.4, color="0.7", label="contact force, raw")
        ax.plot(s["x"], s["filtered"], lw=1.0, color="C0", label="contact force, 20 Hz low-pass")
        ax.axhline(common["force_amplitude"], color="k", lw=0.6, ls="--", label="EN 50367 target")
        for xs in s["supports"]:
            ax.axvline(xs, color="C3", lw=0.4, alpha=0.5)
        ax.set_ylabel("force [N]")
        ax.set_title(title, fontsize=10)
        twin = ax.twinx()
        twin.plot(s["x"], s["uplift_mm"], lw=0.8, color="C2", label="uplift at the contact point")
        twin.set_ylabel("uplift [mm]", color="C2")
        ax.legend(loc="upper left", fontsize=7)
    axes[-1].set_xlabel("distance from the run's start [m] (red: supports)")
    fig.suptitle(f"passive pantograph at {args.speed:g} km/h, spans {args.spans[0]:g}-{args.spans[1]:g}")
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "fig_force_uplift.png"
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
