"""Force and uplift over a tension section with its overlap: the passive pantograph, and passive
against line_adaptive, on a line of tension sections.

``ros2 run pac_experiments realistic_overlap_figure --out DIR [--seed N] [--speed KMH]
[--scenario NAME]`` runs the scenario (default ``realistic_electromechanical``) on
``realistic_3km_sections`` with line seed N through the offline closed loop, with law ``passive``
(the EN 50367 target at the speed) and with law ``line_adaptive``, and draws from the run-in (span
8) to two spans past the first overlap: the 20 Hz contact force of both laws, the raw force and the
contact-wire uplift of the passive run, the supports and the overlap marked. Writes
``DIR/fig_overlap.png``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from pac_common.contact_statistics import target_mean_force
from pac_experiments.realistic.figure import force_series
from pac_plant.catenary.catenary_file import load_catenary

CATENARY = "realistic_3km_sections"
#: Spans of run-in before the stretch drawn (the campaigns' statistics start at span 10).
FROM_SPAN = 8.0


def first_overlap(seed: int) -> tuple[float, float, float]:
    """(start of the line's first overlap, its end [m from the line's start], mean span [m])."""
    drawn = load_catenary(CATENARY)
    masts = drawn.design_supports(seed)
    assert masts is not None  # a whole line: its layout rule draws the masts
    start, end = drawn.design_overlaps(seed)[0]
    return float(start), float(end), float(np.mean(np.diff(masts)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="realistic_overlap_figure", description=__doc__)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--speed", type=float, default=300.0)
    parser.add_argument("--scenario", default="realistic_electromechanical")
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    target = round(target_mean_force(args.speed), 3)
    common = {
        "scenario": args.scenario,
        "catenary": CATENARY,
        "line_seed": args.seed,
        "speed_kmh": args.speed,
        "force_amplitude": target,
    }
    o_from, o_to, span = first_overlap(args.seed)
    runs = {
        law: force_series({**common, "law": law}, (FROM_SPAN, (o_to + 2 * span) / span))
        for law in ("passive", "line_adaptive")
    }
    passive = runs["passive"]
    o_from, o_to = o_from - float(passive["start"]), o_to - float(passive["start"])
    fig, axes = plt.subplots(2, 1, figsize=(12, 7.5), sharex=True)
    ax = axes[0]
    ax.plot(passive["x"], passive["raw"], lw=0.4, color="0.75", label="passive, raw")
    ax.plot(passive["x"], passive["filtered"], lw=1.0, color="C0", label="passive, 20 Hz low-pass")
    ax.set_title(
        f"passive: contact force and contact-wire uplift ({args.scenario}, {CATENARY}, seed {args.seed})",
        fontsize=10,
    )
    twin = ax.twinx()
    twin.plot(passive["x"], passive["uplift_mm"], lw=0.8, color="C2")
    twin.set_ylabel("uplift at the contact point [mm]", color="C2")
    ax2 = axes[1]
    for law, color in (("passive", "0.5"), ("line_adaptive", "C1")):
        ax2.plot(runs[law]["x"], runs[law]["filtered"], lw=1.0, color=color, label=f"{law}, 20 Hz low-pass")
    ax2.set_title("passive against line_adaptive", fontsize=10)
    for a in axes:
        for xs in passive["supports"]:
            a.axvline(xs, color="C3", lw=0.4, alpha=0.5)
        a.axvspan(o_from, o_to, color="C4", alpha=0.12, label="overlap (two contact wires)")
        a.axhline(target, color="k", lw=0.6, ls="--", label="EN 50367 target")
        a.set_ylabel("contact force [N]")
        a.legend(loc="upper left", fontsize=7)
    axes[-1].set_xlabel("distance from the run's start [m] (red: supports)")
    fig.suptitle(f"a tension section and its overlap at {args.speed:g} km/h", fontsize=11)
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "fig_overlap.png"
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
