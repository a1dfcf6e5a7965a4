"""``ros2 run pac_rig replay <bag> --topics measurement [command ...] [--rate R | --lockstep]``.

Republishes chosen topics of a bag into the running graph (this process's
ROS_DOMAIN_ID, loopback discovery) with the original timing of their log times
scaled by ``--rate`` (2 = twice as fast; 0 = as fast as possible), the serialised
messages untouched.  Typical use: replay ``measurement`` into a live
``observer_node`` (your own, or ours with other parameters) and record its new
``estimate`` with ``ros2 run pac_rig recorder``.

A node's loop input keeps the last sample only, so a timed replay loses samples
whenever two arrive within one spin of the node (a few % on a loaded machine).
``--lockstep`` makes the replay exact on any machine: each tick's sample is
published once the node has answered the previous one (its ``estimate`` for a
``measurement``, its ``command`` for an ``estimate``), and re-sent when no answer
comes within ``--resend-timeout``, as the plant does in lock step.

Every message is decoded before the replay starts: one that does not decode, or is of
another type than its topic's, is counted (one line per topic) and not published, and the
replay exits 1 after replaying the rest, as for any damage the bag readers report.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from pac_bag.reader import BagError, bag_files
from pac_bag.recovery import iter_records
from pac_common import messages
from pac_common.node import PUBLISH_QOS, loopback_only
from pac_common.pac_node import unacknowledged

#: The topic a loop node answers each replayed topic's sample on, with the same tick.
ANSWERS = {"measurement": "estimate", "estimate": "command"}


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
    parser.add_argument(
        "--timeout",
        type=float,
        default=30.0,
        help="how long to wait for the subscribers, and (--lockstep) for one tick's answer [s]",
    )
    parser.add_argument(
        "--lockstep",
        action="store_true",
        help="publish each tick once the node answered the previous one (one topic: measurement or "
        "estimate); every sample is processed whatever the load, --rate is ignored",
    )
    parser.add_argument(
        "--resend-timeout",
        type=float,
        default=0.5,
        help="--lockstep: re-send a sample that got no answer within this time [s] (default 0.5)",
    )
    args = parser.parse_args(argv)
    if args.rate < 0:
        print(f"replay: invalid --rate {args.rate}: allowed >= 0", file=sys.stderr)
        return 2
    for name in ("timeout", "resend_timeout"):
        value = getattr(args, name)
        if not value > 0:
            print(f"replay: invalid --{name.replace('_', '-')} {value}: allowed > 0", file=sys.stderr)
            return 2
    if args.lockstep and (len(args.topics) != 1 or args.topics[0] not in ANSWERS):
        print(
            f"replay: --lockstep replays one topic that a loop node answers "
            f"({' or '.join(ANSWERS)}), not {' '.join(args.topics)}",
            file=sys.stderr,
        )
        return 2
    warnings: list[str] = []
    try:
        records = replayable(args.bag, args.topics, warnings)
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
        start = time.monotonic()
        if args.lockstep:
            (topic,) = args.topics
            replayed = lockstep(node, factory, topic, pubs[topic], records, args)
            if replayed is None:
                return 1
            records = replayed
        else:
            timed(pubs, records, args.rate)
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
    return 1 if warnings else 0  # a damaged bag: replayed as far as it was readable


@dataclass(frozen=True)
class Replayed:
    """One message to replay: its topic, log time [ns], tick and serialised (CDR) bytes."""

    topic: str
    log_time: int
    tick: int
    data: bytes


def replayable(bag: Path, topics: list[str], warnings: list[str]) -> list[Replayed]:
    """The messages of ``topics`` in ``bag`` that their subscribers can take, in log-time order.

    Each one is decoded first (with the bag's type store: a damaged record must not reach a
    node, where rclpy would drop it uncounted, nor stop the replay with an rmw error): records
    of another type than the topic's, and undecodable ones, are counted on ``warnings``."""
    from pac_bag.typestore import typestore

    bag_files(bag)  # not a bag: the one line every tool gives
    store = typestore()
    out: list[Replayed] = []
    refused: dict[str, list] = {}
    for topic, typename, log_time, data in iter_records(bag, warnings):
        if topic not in topics:
            continue
        try:
            if typename != messages.TOPICS[topic]:
                raise ValueError(f"a {typename}, not a {messages.TOPICS[topic]}")
            msg = store.deserialize_cdr(data, typename)
        except Exception as exc:  # noqa: BLE001 - rosbags raises several types on damaged CDR
            refused.setdefault(topic, [0, f"first at {log_time} ns: {exc}"])[0] += 1
            continue
        out.append(Replayed(topic, log_time, int(getattr(msg, "tick", -1)), data))
    for topic, (count, first) in refused.items():
        warnings.append(f"topic '{topic}': {count} messages not replayed, undecodable ({first})")
    return sorted(out, key=lambda r: r.log_time)


def timed(pubs: dict, records: list[Replayed], rate: float) -> None:
    """Publish ``records`` at their log times scaled by ``rate`` (0: as fast as possible)."""
    first, start = records[0].log_time, time.monotonic()
    for record in records:
        if rate > 0:
            delay = start + (record.log_time - first) * 1e-9 / rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        pubs[record.topic].publish(record.data)


def lockstep(
    node, factory, topic: str, pub, records: list[Replayed], args: argparse.Namespace
) -> list[Replayed] | None:
    """Publish each tick of ``records`` once the node answered the one before (on
    :data:`ANSWERS`), re-sending it after ``--resend-timeout``: the records published, one per
    tick, or None when an answer did not come within ``--timeout`` (said on stderr)."""
    import rclpy

    answer = ANSWERS[topic]
    answered = [-1]  # the highest tick answered

    def on_answer(msg) -> None:
        answered[0] = max(answered[0], int(msg.tick))

    node.create_subscription(factory.cls(messages.TOPICS[answer]), answer, on_answer, PUBLISH_QOS)
    # One sample per tick, in tick order: a bag of a live run holds re-sent samples more than once.
    by_tick: dict[int, Replayed] = {}
    for record in records:
        by_tick.setdefault(record.tick, record)
    for tick in sorted(by_tick):
        data = by_tick[tick].data
        pub.publish(data)
        first = sent = time.monotonic()
        while answered[0] < tick:
            rclpy.spin_once(node, timeout_sec=args.resend_timeout / 10)
            now = time.monotonic()
            if answered[0] >= tick:
                break
            if now - first > args.timeout:
                print(
                    f"replay: --lockstep: no {answer} for tick {tick} within {args.timeout:g} s",
                    file=sys.stderr,
                )
                return None
            if now - sent > args.resend_timeout:
                pub.publish(data)
                sent = now
    return [by_tick[tick] for tick in sorted(by_tick)]


if __name__ == "__main__":
    sys.exit(main())
