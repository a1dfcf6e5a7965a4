"""The settings of pac's QoS profiles as plain values, without rclpy: what ``qos`` builds its
QoSProfiles from, and what a bag written offline records its publishers as offering (importing
rclpy for them cost an offline ``simulate`` ~0.1 s)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class QosSettings:
    """A profile's settings by rclpy's policy names, lower case (as rosbag2 records them)."""

    history: str
    depth: int
    reliability: str
    durability: str


#: Every pac publisher (``qos.PUBLISH_QOS``): reliable and transient-local with the last 1000 samples.
PUBLISH = QosSettings(history="keep_last", depth=1000, reliability="reliable", durability="transient_local")
