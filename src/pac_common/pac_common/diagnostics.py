"""Node health as ROS tools read it (``diagnostic_msgs/DiagnosticStatus``): the pure part.

Every pac node reports, about once a second, one status on ``/diagnostics``: a level (OK,
WARN, ERROR), a one-line message and key-value pairs (its counters and its loop timing).
This module turns a node's counters into that status; it imports no ROS, so it is tested
like any core, and the same counters are printed as the node's end-of-run ``pac-stats``
line (:func:`stats_line`).  The rclpy side (publisher, timer) is :mod:`pac_common.health`.

A status compares the counters with those of the previous report: an event (a refused
measurement, a re-initialisation, a schedule slip) makes one report WARN and the next one
OK again if nothing else happened; a condition (fallback active, command timed out, input
stale, disk full) stays WARN / ERROR for as long as it lasts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import jsonio

#: diagnostic_msgs/DiagnosticStatus levels (its byte constants OK, WARN, ERROR, STALE).
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = ("OK", "WARN", "ERROR", "STALE")
#: DiagnosticStatus.hardware_id of every pac status.
HARDWARE_ID = "pac"
#: Seconds between two reports (ROS's diagnostic_updater default is 1 s too).
PERIOD = 1.0
#: An input older than this (while a run is going on) makes the status WARN.
STALE_INPUT = 0.5
#: The prefix of the end-of-run counters line on stderr (one JSON object follows).
STATS_PREFIX = "pac-stats "

Counters = Mapping[str, Any]


@dataclass(frozen=True)
class Status:
    """One ``DiagnosticStatus``: ``name`` is ``<node>: <what>`` as diagnostic_updater names it."""

    name: str
    level: int
    message: str
    values: tuple[tuple[str, str], ...] = ()

    @property
    def level_name(self) -> str:
        return LEVEL_NAMES[self.level]


def level_name(level: int) -> str:
    return LEVEL_NAMES[level] if 0 <= level < len(LEVEL_NAMES) else str(level)


class LoopTiming:
    """The last ``size`` loop events: their wall time and a latency, for percentiles off the loop.

    ``record`` is what the 1 kHz path pays: two list stores and an increment, no arithmetic
    over the window; :meth:`summary` (the 1 Hz report) sorts the window.
    """

    def __init__(self, size: int = 1024) -> None:
        self.size = size
        self.starts_ns = [0] * size
        self.latencies = [math.nan] * size
        self.count = 0

    def record(self, start_ns: int, latency: float) -> None:
        i = self.count % self.size
        self.starts_ns[i] = start_ns
        self.latencies[i] = latency
        self.count += 1

    @property
    def last_ns(self) -> int | None:
        return self.starts_ns[(self.count - 1) % self.size] if self.count else None

    def window(self) -> tuple[np.ndarray, np.ndarray]:
        """The recorded events, oldest first."""
        n = min(self.count, self.size)
        first = (self.count - n) % self.size
        order = (first + np.arange(n)) % self.size
        return np.asarray(self.starts_ns, dtype=np.int64)[order], np.asarray(self.latencies)[order]

    def summary(self) -> dict[str, float]:
        """Percentiles [ms] of the period between events and of the latency over the window
        (numpy: about a tenth of a millisecond for a full window, once a second)."""
        starts, latencies = self.window()
        periods = np.diff(starts) * 1e-6
        finite = latencies[np.isfinite(latencies)] * 1e3
        out: dict[str, float] = {}
        for label, values in (("period", periods), ("latency", finite)):
            if values.size:
                p50, p99 = np.percentile(values, [50.0, 99.0])
                out[f"{label}_p50_ms"], out[f"{label}_p99_ms"] = float(p50), float(p99)
                out[f"{label}_max_ms"] = float(values.max())
            else:
                out[f"{label}_p50_ms"] = out[f"{label}_p99_ms"] = out[f"{label}_max_ms"] = math.nan
        return out


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.6g}"
    return str(value)


def key_values(counters: Counters) -> tuple[tuple[str, str], ...]:
    """Every counter as a (key, text) pair, in the order the node gave them."""
    return tuple((str(k), _text(v)) for k, v in counters.items())


def _grew(now: Counters, before: Counters | None, key: str) -> int:
    """How much a cumulative counter grew since the previous report (all of it on the first)."""
    return int(now.get(key, 0)) - int((before or {}).get(key, 0))


def _state_message(node: str, now: Counters) -> str:
    state = now.get("state", "")
    if state == "waiting":
        return f"waiting for the loop ({now.get('waiting_for', 'its peers')})"
    if state == "ended":
        return f"run over at tick {now.get('last_tick', '?')}"
    if state == "idle":
        return "idle: no run yet"
    if state in ("unconfigured", "inactive"):
        return f"lifecycle state {state}"
    return f"running, tick {now['last_tick']}" if "last_tick" in now else "running"


def _status(node: str, what: str, level: int, problems: list[str], now: Counters) -> Status:
    message = "; ".join(problems) if problems else _state_message(node, now)
    return Status(f"{node}: {what}", level, message, key_values(now))


def plant_status(node: str, now: Counters, before: Counters | None) -> Status:
    """The plant: WARN while the last command has timed out (passive uplift) or when the real-time
    schedule slipped since the last report."""
    problems = []
    if now.get("command_timed_out"):
        problems.append(f"no command for {now.get('command_age_ticks', '?')} ticks: passive uplift applied")
    slips = _grew(now, before, "schedule_slips")
    if slips:
        problems.append(f"loop fell behind: schedule slipped {slips} time(s)")
    return _status(node, "loop", WARN if problems else OK, problems, now)


def observer_status(node: str, now: Counters, before: Counters | None) -> Status:
    """The observer: WARN when measurements were refused or the observer re-initialised since the
    last report, or when measurements stopped while the run goes on."""
    problems = []
    refused = _grew(now, before, "refused")
    if refused:
        problems.append(f"{refused} measurement(s) refused")
    reinit = _grew(now, before, "reinitialisations")
    if reinit:
        problems.append(f"observer re-initialised {reinit} time(s)")
    if _stale(now):
        problems.append(f"no measurement for {now['input_age_s']:.1f} s")
    return _status(node, "estimation", WARN if problems else OK, problems, now)


def controller_status(node: str, now: Counters, before: Counters | None) -> Status:
    """The controller: WARN while the fallback command is active (no fresh estimate), and when
    estimates were refused since the last report."""
    problems = []
    if now.get("fallback_active"):
        problems.append(
            f"fallback active: no fresh estimate for {now.get('estimate_age_ticks', '?')} ticks, "
            f"static uplift {_text(now.get('fallback_force', math.nan))} N"
        )
    refused = _grew(now, before, "refused")
    if refused:
        problems.append(f"{refused} non-finite or implausible estimate(s) refused")
    if not now.get("fallback_active") and _stale(now):
        problems.append(f"no estimate for {now['input_age_s']:.1f} s")
    return _status(node, "control", WARN if problems else OK, problems, now)


def recorder_status(node: str, now: Counters, before: Counters | None) -> Status:
    """The recorder: ERROR once a write failed, once DDS reported messages lost to it, or when the
    free disk is below ``min_free_disk_mb``;
    WARN when messages wait in its queue for more than a second's worth of writes."""
    errors, warnings = [], []
    if now.get("failed"):
        errors.append(f"recording stopped: {now.get('failure', 'write failed')}")
    free, floor = float(now.get("free_disk_mb", math.inf)), float(now.get("min_free_disk_mb", 0.0))
    if free < floor:
        errors.append(f"free disk {free:.1f} MB below min_free_disk_mb {floor:g} MB")
    lost = {k[5:]: int(n) for k, n in now.items() if k.startswith("lost_") and k != "lost_messages" and n}
    if lost:  # a condition: the bag lacks them for good
        errors.append(
            f"{sum(lost.values())} messages lost before they reached the recorder ("
            + ", ".join(f"{t} {n}" for t, n in sorted(lost.items()))
            + ")"
        )
    if int(now.get("queued", 0)) > 10000:
        warnings.append(f"{now['queued']} messages waiting to be written")
    level = ERROR if errors else WARN if warnings else OK
    problems = errors + warnings
    if not problems and now.get("state") == "recording":
        problems = [f"recording {now.get('messages', 0)} messages, {now.get('bag_bytes', 0)} bytes written"]
    return _status(node, "recording", level, problems, now)


def relay_status(node: str, now: Counters, before: Counters | None) -> Status:
    """A node without health rules of its own: OK with its counters."""
    return _status(node, "node", OK, [], now)


def _stale(now: Counters) -> bool:
    age = now.get("input_age_s")
    return now.get("state") == "running" and age is not None and math.isfinite(age) and age > STALE_INPUT


#: Each node's rule, by the name its class gives (``PacNode.HEALTH``).
RULES = {
    "plant": plant_status,
    "observer": observer_status,
    "controller": controller_status,
    "recorder": recorder_status,
    "node": relay_status,
}


def worst(levels: list[int]) -> int:
    """The worst of some levels (STALE counts as worse than ERROR, as rqt_robot_monitor shows it)."""
    return max(levels, default=OK)


def array_fields(statuses: list[Status], stamp_ns: int) -> dict[str, Any]:
    """A DiagnosticArray as plain fields (header stamp, one entry per status), for any factory."""
    return {
        "header": {
            "stamp": {"sec": stamp_ns // 1_000_000_000, "nanosec": stamp_ns % 1_000_000_000},
            "frame_id": "",
        },
        "status": [
            {
                "level": s.level,
                "name": s.name,
                "message": s.message,
                "hardware_id": HARDWARE_ID,
                "values": [{"key": k, "value": v} for k, v in s.values],
            }
            for s in statuses
        ],
    }


def stats_line(node: str, counters: Counters) -> str:
    """The end-of-run counters as one line: ``pac-stats {"node": ..., ...}`` (strict JSON)."""
    return STATS_PREFIX + jsonio.dumps({"node": node, **counters}, sort_keys=False)


def parse_stats(text: str) -> dict[str, dict[str, Any]]:
    """Every ``pac-stats`` line of a log, by node name (the last line of a node wins)."""
    import json

    out: dict[str, dict[str, Any]] = {}
    for line in text.splitlines():
        start = line.find(STATS_PREFIX)
        if start >= 0:
            data = json.loads(line[start + len(STATS_PREFIX) :])
            out[str(data.get("node"))] = data
    return out
