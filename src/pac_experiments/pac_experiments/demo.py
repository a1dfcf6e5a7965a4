"""``make demo``: the rig as four processes in real time, then its report.

Starts plant (realtime, 1 kHz), observer, controller and recorder with ``ros2 run``
in a free ROS domain (loopback discovery only), runs 10 s of a constant 100 N
reference (filtered from 0) at 360 km/h with Table 1's pantograph and the shipped
gains, stops every process cleanly and prints the EN 50367-style contact-force
table and the loop timing, both read back from the recorded bag, and ends with the
Fig. 3-5 style figure of the run (reports/<bag name>/<bag name>.png).
"""

from __future__ import annotations

import argparse
import os
import sys
from datetime import datetime
from pathlib import Path

from pac_analysis.metrics import compute_metrics, loop_timing, markdown_table, timing_table
from pac_analysis.plots import run_figure
from pac_bag.reader import read_bag
from pac_common.command_line import UsageError
from pac_rig.launcher import Rig


def free_domain():
    """An exported ROS_DOMAIN_ID is used as it is (the user's choice, e.g. to watch the demo with
    `ros2 topic echo`); else a free one is reserved, so that two demos never hear each other."""
    import contextlib
    import os

    import domain_coordinator

    from pac_common.command_line import check_domain_id

    if os.environ.get("ROS_DOMAIN_ID", "").strip():
        check_domain_id()
        return contextlib.nullcontext(int(os.environ["ROS_DOMAIN_ID"]))
    return domain_coordinator.domain_id()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="demo", description=__doc__)
    parser.add_argument("--duration", type=float, default=10.0, help="simulated seconds (default 10)")
    parser.add_argument("--bag", type=Path, default=None, help="bag directory (default bags/demo_<time>)")
    parser.add_argument("--timing-mode", choices=("realtime", "lockstep"), default="realtime")
    parser.add_argument(
        "--realtime-priority",
        type=int,
        default=None,
        help="SCHED_FIFO priority for plant, observer and controller, recorder at normal (0: all normal; "
        "default: the launcher's, loop 60 above recorder 50; needs root or CAP_SYS_NICE, else a warning)",
    )
    parser.add_argument(
        "--composed",
        action="store_true",
        help="plant, observer and controller in one process (ros2 run pac_rig composed)",
    )
    args = parser.parse_args(argv)
    bag_path = args.bag or Path("bags") / f"demo_{datetime.now():%Y%m%d_%H%M%S}"
    try:
        domain = free_domain()
    except UsageError as exc:
        print(f"demo: {exc}", file=sys.stderr)
        return 2
    chosen = "yours (exported)" if os.environ.get("ROS_DOMAIN_ID", "").strip() else "a free one"
    with domain as domain_id:
        print(
            f"demo: ROS_DOMAIN_ID={domain_id} ({chosen}), loopback discovery; starting recorder, observer, "
            f"controller, plant ({args.timing_mode}, {args.duration:g} s)",
            flush=True,
        )
        rig = Rig(
            bag_path,
            duration=args.duration,
            timing_mode=args.timing_mode,
            domain_id=domain_id,
            composed=args.composed,
            params={}
            if args.realtime_priority is None
            else {"all": {"realtime_priority": args.realtime_priority}},
        )
        try:
            rig.start()
            rig.wait_finished(timeout=60.0 + 5.0 * args.duration)
        finally:
            codes = rig.stop()
    print(f"demo: exit codes {codes}; logs in {rig.log_dir}")
    print(
        "demo: CPU per process: "
        + ", ".join(
            f"{name} {100 * p.cpu_seconds / p.wall_seconds:.0f} %"
            for name, p in rig.processes.items()
            if p.cpu_seconds is not None and p.wall_seconds
        )
    )
    bag = read_bag(bag_path)
    print(f"\n## Contact force, {bag_path.name}\n")
    # The window skips the 3 s start transient; a shorter demo (--duration 2) uses its second half.
    print(markdown_table({bag_path.name: compute_metrics(bag, min(3.0, args.duration / 2))}))
    print("## Loop timing (from the bag)\n")
    print(timing_table({bag_path.name: loop_timing(bag)}))
    # Same place and name as `make report BAG=...` uses for this bag's figure.
    figure = run_figure(bag, bag_path.name, Path("reports") / bag_path.name / f"{bag_path.name}.png")
    print(f"bag: {bag_path}   full report: make report BAG={bag_path}")
    print(f"figure (contact force, u, k and k_hat; cf. the paper's Figs. 3-5): {figure}")
    return 0 if all(code == 0 for code in codes.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
