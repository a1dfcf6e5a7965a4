"""End the process with a given status after a delay, even when Python cannot run any more.

A node's results (bag, counters) are final before rclpy is torn down; a teardown that hangs
must not turn a clean stop into a kill. The hang seen in these wheels sits in a C call that
holds the GIL (``Node.destroy_node`` -> ``destroy_when_not_in_use``: a stop of the rig's
controller, its Python traceback from SIGUSR1), so a Python timer thread never gets to run.
POSIX ``timer_create`` with ``SIGEV_THREAD`` lets the C library start a thread of its own
that calls ``_exit(status)``: no Python, no GIL. Where that is not available (not glibc),
a Python timer thread is the fallback.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import threading

CLOCK_MONOTONIC = 1
SIGEV_THREAD = 2


class _SigEvent(ctypes.Structure):
    """``struct sigevent`` (glibc, 64 bytes) with the ``SIGEV_THREAD`` member of its union."""

    _fields_ = [
        ("sigev_value", ctypes.c_void_p),  # union sigval: its int is the low half (little endian)
        ("sigev_signo", ctypes.c_int),
        ("sigev_notify", ctypes.c_int),
        ("sigev_notify_function", ctypes.c_void_p),
        ("sigev_notify_attributes", ctypes.c_void_p),
        ("_pad", ctypes.c_byte * 32),
    ]


class _TimeSpec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _ITimerSpec(ctypes.Structure):
    _fields_ = [("it_interval", _TimeSpec), ("it_value", _TimeSpec)]


def _native(status: int, seconds: float) -> bool:
    """Arm a C-library timer whose own thread calls ``_exit(status)``; False if unavailable."""
    if ctypes.sizeof(ctypes.c_void_p) != 8 or not 0 <= status <= 255:
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        timer_create, timer_settime = libc.timer_create, libc.timer_settime
        exit_now = ctypes.cast(libc._exit, ctypes.c_void_p).value
    except (OSError, AttributeError):
        return False
    event = _SigEvent()
    event.sigev_value = status or None  # sival_int = status (0: a null pointer)
    event.sigev_notify = SIGEV_THREAD
    event.sigev_notify_function = exit_now
    timer = ctypes.c_void_p()
    if timer_create(CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
        return False
    whole = int(seconds)
    when = _ITimerSpec(_TimeSpec(0, 0), _TimeSpec(whole, int((seconds - whole) * 1e9)))
    return timer_settime(timer, 0, ctypes.byref(when), None) == 0


def exit_after(seconds: float, status: int) -> None:
    """``os._exit(status)`` in ``seconds`` unless the process ended before."""
    if _native(status, seconds):
        return
    guard = threading.Timer(seconds, lambda: os._exit(status))
    guard.daemon = True
    guard.start()
