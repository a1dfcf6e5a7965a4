"""Loopback-only DDS discovery (a project rule): set by whoever initialises rclpy, not on import."""

from __future__ import annotations

import os


def loopback_only() -> None:
    """ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST for this process and its children.

    rcl reads it when a context is initialised, so call this before ``rclpy.init``.
    """
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
