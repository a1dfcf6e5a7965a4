"""The QoS profiles of every pac topic: one place, so publishers and subscribers always match."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from .qos_settings import PUBLISH

#: Loop subscribers (observer <- measurement, controller <- estimate, plant <- command): best
#: effort, keep last 1. Only the newest sample matters in real time, a late sample is worse than
#: a lost one, and a node that falls behind skips to the newest sample (the observer bridges the
#: gap exactly) instead of working through a backlog; with depth 10 the command age reached
#: 20-44 ticks under load (docs/design.md).
LOOP_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
#: Every pac publisher (``qos_settings.PUBLISH``): reliable and transient-local with the last 1000
#: samples. The best-effort
#: loop subscribers are unaffected (no acknowledgements, no retransmission to them); a reliable
#: reader (the recorder) gets every sample, including those sent before its side of the match
#: completed, which best effort loses (seen: tick 0 missing from a lock-step bag).
PUBLISH_QOS = QoSProfile(
    history=HistoryPolicy[PUBLISH.history.upper()],
    depth=PUBLISH.depth,
    reliability=ReliabilityPolicy[PUBLISH.reliability.upper()],
    durability=DurabilityPolicy[PUBLISH.durability.upper()],
)
#: The plant's run_status: reliable and transient local, so a node that starts late (or a
#: recorder) learns at once whether the run has ended.
RUN_STATUS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
#: The recorder's subscription when the topic's publishers offer PUBLISH_QOS ...
RECORD_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=2000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
#: ... and when any of them is best effort or volatile (e.g. a user's node): match everyone.
RECORD_QOS_COMPATIBLE = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=2000, reliability=ReliabilityPolicy.BEST_EFFORT
)
