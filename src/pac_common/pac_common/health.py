"""A node's ``/diagnostics`` publisher and its end-of-run counters line: the rclpy side.

:class:`NodeHealth` owns one ``diagnostic_msgs/DiagnosticArray`` publisher on ``/diagnostics``
and one timer of :data:`pac_common.diagnostics.PERIOD` seconds.  The timer reads the node's
counters (``health_counters()``: plain attributes the loop increments, nothing computed on
the loop's path), turns them into a status with the node's rule (pure, in
:mod:`pac_common.diagnostics`) and publishes it.  The timer is its own callback in the node's
executor: the 1 kHz callbacks never wait for a report except while one runs (well under a
millisecond, measured with ``make bench``).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from . import diagnostics, messages
from .diagnostics import Counters, Status

#: Reliable and transient local, keep last 1: a monitor (``ros2 topic echo``, rqt_robot_monitor,
#: Foxglove) that starts late sees every node's latest status at once; a volatile or best-effort
#: subscriber (diagnostic_aggregator's default) matches it too.
DIAGNOSTICS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

StatusRule = Callable[[str, Counters, Counters | None], Status]


def to_message(statuses: list[Status], stamp_ns: int) -> DiagnosticArray:
    msg = DiagnosticArray()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    for status in statuses:
        entry = DiagnosticStatus(
            level=bytes([status.level]),
            name=status.name,
            message=status.message,
            hardware_id=diagnostics.HARDWARE_ID,
        )
        entry.values = [KeyValue(key=k, value=v) for k, v in status.values]
        msg.status.append(entry)
    return msg


class NodeHealth:
    """``/diagnostics`` for one node: ``counters()`` -> ``rule`` -> DiagnosticArray, every period."""

    def __init__(
        self,
        node: Node,
        counters: Callable[[], dict[str, Any]],
        rule: StatusRule,
        period: float = diagnostics.PERIOD,
    ) -> None:
        self.node = node
        self.counters = counters
        self.rule = rule
        self.before: Counters | None = None
        self.last: Status | None = None
        self.publisher = node.create_publisher(DiagnosticArray, messages.DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self.timer = node.create_timer(period, self.report)

    def status(self) -> Status:
        now = self.counters()
        status = self.rule(self.node.get_name(), now, self.before)
        self.before = now
        return status

    def report(self) -> None:
        """Publish the node's status now (the timer, and once more when the node stops)."""
        self.last = self.status()
        self.publisher.publish(to_message([self.last], time.time_ns()))

    def final_report(self) -> None:
        """The last status, before the node's publishers are waited for; never raises (a context
        shut down by a signal has nobody left to tell)."""
        try:
            self.report()
        except Exception:  # noqa: BLE001 - shutting down: the counters line below still reports
            pass

    def print_stats(self) -> None:
        """The node's counters as one ``pac-stats {json}`` line on stderr (tests parse it)."""
        print(diagnostics.stats_line(self.node.get_name(), self.counters()), file=sys.stderr, flush=True)
