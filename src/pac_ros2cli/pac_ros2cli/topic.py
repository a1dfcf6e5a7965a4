"""``ros2 topic list | echo | hz | info``."""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from typing import Any

from .common import fail, flat, message_class, parser, plain, to_yaml, topic_name
from .graph import SPIN_TIME, Graph


def topic_list(args: list[str]) -> int:
    p = parser("topic list")
    p.add_argument("-t", "--show-types", action="store_true", help="show each topic's type")
    p.add_argument("-c", "--count-topics", action="store_true", help="only print the number of topics")
    p.add_argument("--spin-time", type=float, default=SPIN_TIME, help="max wait for discovery [s]")
    a = p.parse_args(args)
    with Graph() as graph:
        topics = graph.settled(lambda: sorted(graph.topics().items()), a.spin_time)
    if a.count_topics:
        print(len(topics))
    for name, types in topics:
        print(f"{name} [{', '.join(types)}]" if a.show_types else name)
    return 0


def qos_matching_publishers(graph: Graph, topic: str, depth: int) -> Any:
    """Reliable / transient local only when every publisher offers it (ros2cli's choice for echo)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    infos = graph.node.get_publishers_info_by_topic(topic)
    reliable = bool(infos) and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    local = bool(infos) and all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if local else DurabilityPolicy.VOLATILE,
    )


def select_field(data: Any, field: str | None) -> tuple[Any, bool]:
    """``data`` narrowed to a dotted ``field`` path; (None, False) when the path is not there."""
    for key in field.split(".") if field else ():
        if not isinstance(data, dict) or key not in data:
            return None, False
        data = data[key]
    return data, True


def echo_text(data: Any, csv: bool) -> str:
    """One message as ros2cli prints it: YAML then ``---``, or one comma-separated line."""
    if csv:
        return ",".join(str(v) for v in flat(data)) + "\n"
    text = to_yaml(data) if isinstance(data, dict | list) else f"{data}\n"
    return text + "---\n"


def topic_echo(args: list[str]) -> int:
    p = parser("topic echo")
    p.add_argument("topic_name")
    p.add_argument(
        "message_type", nargs="?", help="e.g. pac_interfaces/msg/ObserverEstimate (default: from the graph)"
    )
    p.add_argument("--once", action="store_true", help="print the first message received, then exit")
    p.add_argument("--times", "-n", type=int, default=0, help="exit after this many messages (0: never)")
    p.add_argument("--csv", action="store_true", help="one line of comma-separated values per message")
    p.add_argument("--field", help="print only this field (dotted path, e.g. header.stamp)")
    p.add_argument("--qos-depth", type=int, default=10)
    p.add_argument("--timeout", type=float, default=0.0, help="give up after this long [s] (0: never)")
    a = p.parse_args(args)
    topic = topic_name(a.topic_name)
    with Graph() as graph:
        typename = a.message_type or graph.topic_type(topic)
        if typename is None:
            fail(
                f"could not determine the type of '{topic}': not published (same ROS_DOMAIN_ID?); "
                "give the type as a second argument to wait for it"
            )
        cls = message_class(typename)
        qos = qos_matching_publishers(graph, topic, a.qos_depth)
        wanted = 1 if a.once else a.times
        state = {"n": 0, "bad_field": False}

        def callback(msg: Any) -> None:
            if (wanted and state["n"] >= wanted) or state["bad_field"]:
                return
            data, ok = select_field(plain(msg), a.field)
            if not ok:
                state["bad_field"] = True
                return
            sys.stdout.write(echo_text(data, a.csv))
            sys.stdout.flush()
            state["n"] += 1

        graph.node.create_subscription(cls, topic, callback, qos)
        graph.spin(
            lambda: bool(state["bad_field"]) or (bool(wanted) and state["n"] >= wanted), a.timeout or None
        )
    if state["bad_field"]:
        fail(f"field '{a.field}' is not in {typename}", 2)
    if wanted and state["n"] < wanted:
        fail(f"{state['n']} of {wanted} message(s) on '{topic}' within {a.timeout:g} s")
    return 0


def rate_text(stamps: list[float]) -> str:
    """ros2cli's `topic hz` block for receive times ``stamps`` (at least two)."""
    d = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    mean = sum(d) / len(d)
    std = math.sqrt(sum((x - mean) ** 2 for x in d) / len(d))
    rate = 1.0 / mean if mean > 0 else 0.0
    spread = f"min: {min(d):.3f}s max: {max(d):.3f}s std dev: {std:.5f}s window: {len(d)}"
    return f"average rate: {rate:.3f}\n\t{spread}"


def topic_hz(args: list[str]) -> int:
    p = parser("topic hz")
    p.add_argument("topic_name")
    p.add_argument("--window", "-w", type=int, default=10000, help="intervals in the statistics")
    p.add_argument("--duration", type=float, default=0.0, help="stop after this long [s] (0: at Ctrl-C)")
    a = p.parse_args(args)
    if a.window < 1:
        fail(f"invalid --window {a.window}: allowed an integer >= 1", 2)
    topic = topic_name(a.topic_name)
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    with Graph() as graph:
        typename = graph.topic_type(topic)
        if typename is None:
            print(f"WARNING: topic [{topic}] does not appear to be published yet", file=sys.stderr)
            if not graph.wait(lambda: graph.topic_type(topic, wait=False), a.duration or math.inf):
                return 1
            typename = graph.topic_type(topic)
        stamps: deque[float] = deque(maxlen=a.window + 1)
        state = {"printed": time.monotonic(), "seen": 0, "last_seen": 0}

        def callback(_data: bytes, info: Any) -> None:
            # The middleware's receive time: exact arrival even when this process runs late.
            stamps.append(info["received_timestamp"] * 1e-9)
            state["seen"] += 1

        def report() -> None:
            now = time.monotonic()
            if now - state["printed"] < 1.0:
                return
            state["printed"] = now
            if state["seen"] == state["last_seen"] or len(stamps) < 2:
                return
            state["last_seen"] = state["seen"]
            print(rate_text(list(stamps)), flush=True)

        # Raw (no deserialisation) and best effort, as ros2cli's hz: cheap for a 1 kHz publisher. A
        # deeper queue than sensor data's 5, so a burst is counted rather than dropped by a busy CLI.
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
        assert typename is not None  # the wait above returned only once the topic was seen
        # rclpy passes the message info to a callback that takes two arguments (its annotation
        # names only the one-argument form).
        graph.node.create_subscription(message_class(typename), topic, callback, qos, raw=True)  # type: ignore[arg-type]
        graph.spin(lambda: False, a.duration or None, report)
    return 0


def endpoint_text(info: Any) -> str:
    q = info.qos_profile
    return (
        f"Node name: {info.node_name}\nNode namespace: {info.node_namespace}\n"
        f"Topic type: {info.topic_type}\nEndpoint type: {info.endpoint_type.name}\n"
        f"QoS profile:\n  Reliability: {q.reliability.name}\n"
        f"  History (Depth): {q.history.name}{f' ({q.depth})' if q.depth else ''}\n"
        f"  Durability: {q.durability.name}\n"
    )


def topic_info(args: list[str]) -> int:
    p = parser("topic info")
    p.add_argument("topic_name")
    p.add_argument("-v", "--verbose", action="store_true", help="every endpoint with its QoS")
    a = p.parse_args(args)
    topic = topic_name(a.topic_name)
    with Graph() as graph:
        if graph.topic_type(topic) is None:
            fail(f"unknown topic '{topic}' (same ROS_DOMAIN_ID? ros2 topic list shows them)")
        pubs, subs = graph.settled(lambda: graph.endpoints(topic))
        print(f"Type: {', '.join(graph.topics().get(topic, []))}")
        for label, infos in (("Publisher", pubs), ("Subscription", subs)):
            print(f"{label} count: {len(infos)}")
            if a.verbose:
                print()
                for info in infos:
                    print(endpoint_text(info))
    return 0
