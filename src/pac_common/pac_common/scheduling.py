"""SCHED_FIFO for a node's process: every thread of it, all or nothing."""

from __future__ import annotations

import os
from typing import Any


def process_threads() -> list[int]:
    """Thread ids of this process (Linux); ``[0]`` (the calling thread) where /proc is missing."""
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


def set_realtime_priority(node: Any, priority: int) -> bool:
    """SCHED_FIFO at ``priority`` for every thread of this process; one warning line if refused.

    Every thread, not only the caller: the node is created first, so Fast DDS's receive and
    event threads already exist, and a sample reaches the executor through them (threads
    started later, e.g. the recorder's writer, inherit the policy). ``node`` gives the logger.
    """
    if priority <= 0:
        return False
    try:
        for tid in process_threads():
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError) as exc:
        for tid in process_threads():  # all or nothing: no half real-time process
            try:
                os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
            except OSError:
                pass
        node.get_logger().warning(f"realtime_priority {priority} refused ({exc}): normal scheduling")
        return False
    node.get_logger().info(f"running with SCHED_FIFO priority {priority} ({len(process_threads())} threads)")
    return True


def normal_scheduling() -> None:
    """Every thread of this process back to SCHED_OTHER (best effort), for the teardown: a
    real-time thread spinning while rclpy shuts down must not starve the thread that guards it."""
    for tid in process_threads():
        try:
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
        except OSError:
            pass
