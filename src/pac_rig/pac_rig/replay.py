"""``ros2 run pac_rig replay <bag> --topics measurement [command ...] [--rate R]``.

Republishes chosen topics of a bag into the running graph (this process's
ROS_DOMAIN_ID, loopback discovery) with the original timing of their log times
scaled by ``--rate`` (2 = twice as fast; 0 = as fast as possible), the serialised
messages untouched.  Typical use: replay ``measurement`` into a live
``observer_node`` (your own, or ours with other parameters) and record its new
``estimate`` with ``ros2 run pac_rig recorder``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from pac_bag.reader import BagError, bag_files
from pac_bag.recovery import iter_records
from pac_common import messages
from pac_common.node import PUBLISH_QOS, loopback_only
from pac_common.pac_node import unacknowledged


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="replay", description=__doc__)
    parser.add_argument("bag", type=Path)
    parser.add_argument("--topics", nargs="+", default=["measurement"], choices=list(messages.TOPICS))
    parser.add_argument("--rate", type=float, default=1.0, help="time scale (0: as fast as possible)")
    parser.add_argument(
        "--wait-for",
        type=int,
        default=1,
        help="subscribers each replayed topic needs before the replay starts (default 1)",
    )
    parser.add_argument("--timeout", type=float, default=30.0, help="how long to wait for them [s]")
    args = parser.parse_args(argv)
    if args.rate < 0:
        print(f"replay: invalid --rate {args.rate}: allowed >= 0", file=sys.stderr)
        return 2
    warnings: list[str] = []
    try:
        bag_files(args.bag)  # not a bag: the one line every tool gives
        records = sorted(
            (r for r in iter_records(args.bag, warnings) if r[0] in args.topics), key=lambda r: r[2]
        )
    except BagError as exc:
        print(f"replay: {exc}", file=sys.stderr)
        return 1
    for warning in warnings:
        print(f"replay: warning: {warning}", file=sys.stderr)
    if not records:
        print(f"replay: {args.bag}: none of {', '.join(args.topics)} in the bag", file=sys.stderr)
        return 1

    import rclpy
    from rclpy.node import Node

    loopback_only()
    rclpy.init()
    node = Node("replay")
    factory = messages.RclpyFactory()
    pubs = {t: node.create_publisher(factory.cls(messages.TOPICS[t]), t, PUBLISH_QOS) for t in args.topics}
    try:
        deadline = time.monotonic() + args.timeout
        while any(p.get_subscription_count() < args.wait_for for p in pubs.values()):
            if time.monotonic() > deadline:
                print(
                    f"replay: no {args.wait_for} subscriber(s) on {', '.join(args.topics)} "
                    f"within {args.timeout:g} s",
                    file=sys.stderr,
                )
                return 1
            time.sleep(0.01)
        first = records[0][2]
        start = time.monotonic()
        for topic, _, log_time, data in records:
            if args.rate > 0:
                delay = start + (log_time - first) * 1e-9 / args.rate - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            pubs[topic].publish(bytes(data))
        # The last samples are still in flight when the loop ends: destroying the node now lost
        # them (4 of 500 in a loaded CI run). Reliable writers wait for every reader's ack.
        late = unacknowledged(pubs.values(), args.timeout)
        unacked = [t for t, p in pubs.items() if p in late]
        if unacked:
            print(
                f"replay: warning: {', '.join(unacked)}: not every subscriber acknowledged the last "
                f"messages within {args.timeout:g} s",
                file=sys.stderr,
            )
        print(
            f"replay: published {len(records)} messages of {', '.join(args.topics)} "
            f"in {time.monotonic() - start:.2f} s",
            file=sys.stderr,
        )
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
