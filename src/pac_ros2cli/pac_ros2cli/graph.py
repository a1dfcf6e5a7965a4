"""The ROS graph as a CLI sees it: one hidden node, bounded waits for discovery.

Discovery here: participants show up over ~0.1-0.9 s (a busy one answers at its next
re-announcement, every 0.5 s per config/fastdds_profile.xml). A node's name arrives after its
endpoints (on the middleware's own discovery-info topic): until then its endpoints carry the
name UNKNOWN_NODE. A listing is taken once no endpoint is nameless, the graph has been still for
SETTLE_TIME (two re-announcement periods: one lost announcement is covered) and MIN_DISCOVERY
has passed, at most SPIN_TIME after joining; a lookup of one named thing returns as soon as it
is there, or says it is not after FIND_TIME.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from typing import Any

from .common import fail, join_name

MIN_DISCOVERY = 1.1
SETTLE_TIME = 1.0
SPIN_TIME = 3.0
FIND_TIME = 1.5
# rmw_dds_common's name for an endpoint whose participant's node names have not arrived yet.
UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"


class Graph:
    """An rclpy context with one hidden node (a leading '_': `node list` skips it) for graph queries."""

    def __init__(self) -> None:
        try:
            import rclpy

            from pac_common.command_line import UsageError, check_domain_id
            from pac_common.discovery import loopback_only
        except ImportError:
            fail("rclpy or pac_common not importable: source env.sh (repo root) first")
        try:
            check_domain_id()  # else Fast DDS prints a coloured error and rclpy a traceback
        except UsageError as exc:
            fail(str(exc), 2)
        if not os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE"):
            loopback_only()
        self.rclpy = rclpy
        rclpy.init()
        self.node = rclpy.create_node(
            f"_ros2cli_{os.getpid()}", start_parameter_services=False, enable_rosout=False
        )
        self.started = time.monotonic()

    def __enter__(self) -> Graph:
        return self

    def __exit__(self, *exc: object) -> None:
        self.node.destroy_node()
        self.rclpy.try_shutdown()

    def wait(self, found: Callable[[], Any], timeout: float = FIND_TIME) -> bool:
        """Poll ``found()`` until it is true (True) or ``timeout`` s have passed (False).

        The graph cache is filled by the middleware's own discovery thread: no spinning needed.
        """
        deadline = time.monotonic() + timeout
        while not found():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
        return True

    def settled(self, snapshot: Callable[[], Any], timeout: float = SPIN_TIME) -> Any:
        """``snapshot()`` once discovery has had MIN_DISCOVERY s, no endpoint waits for its node's
        name, and the result has not changed for SETTLE_TIME s; at the latest ``timeout`` s after
        this process joined the graph. An empty result is not settled before ``timeout``: on a
        loaded machine the first participants can take longer than MIN_DISCOVERY to show up, and
        "nothing yet" is not "nothing"."""
        deadline = self.started + max(timeout, MIN_DISCOVERY)
        last, since = snapshot(), time.monotonic()
        while time.monotonic() < deadline:
            now = time.monotonic()
            still = now - since >= SETTLE_TIME and now - self.started >= MIN_DISCOVERY
            if last and still and not self.has_nameless_endpoint():
                break
            time.sleep(0.02)
            current = snapshot()
            if current != last:
                last, since = current, time.monotonic()
        return last

    def endpoints(self, topic: str) -> tuple[list[Any], list[Any]]:
        """(publishers, subscriptions) of ``topic`` as rclpy's TopicEndpointInfo lists."""
        return self.node.get_publishers_info_by_topic(topic), self.node.get_subscriptions_info_by_topic(topic)

    def has_nameless_endpoint(self) -> bool:
        """Whether an endpoint is seen whose node's name has not arrived: a participant half discovered."""
        return any(
            info.node_name == UNKNOWN_NODE
            for topic in self.topics()
            for infos in self.endpoints(topic)
            for info in infos
        )

    def node_names(self, hidden: bool = False) -> list[str]:
        return sorted(
            join_name(ns, name)
            for name, ns in self.node.get_node_names_and_namespaces()
            if hidden or not name.startswith("_")
        )

    def topics(self) -> dict[str, list[str]]:
        return dict(self.node.get_topic_names_and_types())

    def find_node(self, name: str) -> tuple[str, str]:
        """(name, namespace) of a running node, or exit 1 with one line after a bounded wait."""
        full = "/" + name.lstrip("/")
        if not self.wait(lambda: full in self.node_names(hidden=True)):
            fail(f"node '{full}' not found (same ROS_DOMAIN_ID? ros2 node list shows them)")
        ns, _, base = full.rpartition("/")
        return base, ns or "/"

    def topic_type(self, topic: str, wait: bool = True) -> str | None:
        """The type of a topic seen in the graph (waits up to FIND_TIME when ``wait``)."""

        def found() -> bool:
            return bool(self.topics().get(topic))

        if wait:
            self.wait(found)
        types = self.topics().get(topic)
        return types[0] if types else None

    def spin(
        self, done: Callable[[], bool], duration: float | None, tick: Callable[[], None] | None = None
    ) -> int:
        """Spin until ``done()``, ``duration`` s, or SIGINT/SIGTERM (exit 0, as ros2cli); ``tick`` each loop.

        SingleThreadedExecutor, as ros2cli uses: the well-trodden path for a CLI.
        """
        from rclpy.executors import SingleThreadedExecutor

        executor = SingleThreadedExecutor()
        executor.add_node(self.node)
        end = time.monotonic() + duration if duration else math.inf
        try:
            while not done() and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
                if tick is not None:
                    tick()
        except KeyboardInterrupt:
            pass
        finally:
            executor.shutdown(timeout_sec=1.0)
        return 0
