"""Core outputs -> pac_interfaces message fields, one definition for every front.

The plant, observer and controller nodes (rclpy message classes) and the offline
simulator (rosbags message classes) build their messages from these field
dictionaries, so a lock-step run over DDS and an offline run write the same
values.  A *factory* turns a field dictionary into a message object of one
library; nested dictionaries become nested messages.
"""

from __future__ import annotations

import importlib
import math
import struct
from collections.abc import Mapping
from typing import Any

import numpy as np

FRAME_MEASUREMENT = "pac_interfaces/msg/FrameMeasurement"
PLANT_TRUTH = "pac_interfaces/msg/PlantTruth"
OBSERVER_ESTIMATE = "pac_interfaces/msg/ObserverEstimate"
ACTUATOR_COMMAND = "pac_interfaces/msg/ActuatorCommand"
RUN_STATUS = "pac_interfaces/msg/RunStatus"
PANTOGRAPH_TRUTH = "pac_interfaces/msg/PantographTruth"

#: The loop's topics, one message per tick each: relative names (a namespace moves the whole rig).
LOOP_TOPICS: dict[str, str] = {
    "measurement": FRAME_MEASUREMENT,
    "plant_truth": PLANT_TRUTH,
    "estimate": OBSERVER_ESTIMATE,
    "command": ACTUATOR_COMMAND,
}
#: Every pac topic: the loop's, and the plant's run start and end.
TOPICS: dict[str, str] = {**LOOP_TOPICS, "run_status": RUN_STATUS}
#: ROS's health topic, where every pac node publishes its status (pac_common.diagnostics):
#: absolute, one for the whole system whatever a node's namespace, as ROS tools expect.
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
DIAGNOSTICS_TOPIC = "/diagnostics"
#: What the recorder records (``-a``) and the live view serves, by the name it has in a bag:
#: the pac topics and ``diagnostics``; :data:`GRAPH_NAMES` gives each one's name on the graph.
#: ``pantograph_truth`` (every pantograph of an FE line with several) is published (and written by
#: the offline simulator) only then.
WATCHED_TOPICS: dict[str, str] = {
    **TOPICS,
    "pantograph_truth": PANTOGRAPH_TRUTH,
    "diagnostics": DIAGNOSTIC_ARRAY,
}
GRAPH_NAMES: dict[str, str] = {
    **{t: t for t in TOPICS},
    "pantograph_truth": "pantograph_truth",
    "diagnostics": DIAGNOSTICS_TOPIC,
}

# The .msg files' constants (tests/test_messages.py checks each against its .msg file, and every
# field dictionary below against the message's fields).
MODES = {"active": 0, "passive": 1, "fallback": 2}
COMMAND_FRESH, COMMAND_HELD, COMMAND_PASSIVE = 0, 1, 2
RUN_RUNNING, RUN_ENDED = 0, 1
STATUS_OK, STATUS_DIVERGED, STATUS_REINITIALISED, STATUS_MEASUREMENT_REJECTED = 0, 1, 2, 3


def tick_stamp_ns(tick: int, rate_hz: float) -> int:
    """Simulated time of a tick in integer nanoseconds (exact for integer-ns periods)."""
    return tick * int(round(1e9 / rate_hz))


def header(stamp_ns: int) -> dict[str, Any]:
    return {"stamp": time_fields(stamp_ns), "frame_id": ""}


def time_fields(stamp_ns: int) -> dict[str, int]:
    return {"sec": stamp_ns // 1_000_000_000, "nanosec": stamp_ns % 1_000_000_000}


def measurement_fields(m: Any, stamp_ns: int) -> dict[str, Any]:
    """FrameMeasurement from pac_plant.plant.Measurement."""
    return {
        "header": header(stamp_ns),
        "tick": m.tick,
        "z1": m.z1,
        "z2": m.z2,
        "actuator_force": m.actuator_force,
        "head_acceleration": float(getattr(m, "head_acceleration", math.nan)),
        "frame_acceleration": float(getattr(m, "frame_acceleration", math.nan)),
        "head_force": float(getattr(m, "head_force", math.nan)),
        "from_roof": bool(getattr(m, "from_roof", False)),
    }


def truth_fields(
    t: Any,
    stamp_ns: int,
    *,
    applied_command_tick: int,
    command_source: int = COMMAND_FRESH,
    command_timeouts: int = 0,
    round_trip_latency: float = math.nan,
    wall_stamp_ns: int = 0,
) -> dict[str, Any]:
    """PlantTruth from pac_plant.plant.Truth and the plant's command bookkeeping."""
    return {
        "header": header(stamp_ns),
        "tick": t.tick,
        "z": np.array(t.z, dtype=np.float64),
        "stiffness": t.stiffness,
        "contact_force": t.contact_force,
        "in_contact": bool(t.in_contact),
        "u_applied": t.u_applied,
        "applied_command_tick": applied_command_tick,
        "command_age_ticks": max(0, t.tick - applied_command_tick) if applied_command_tick >= 0 else 0,
        "command_source": command_source,
        "command_timeouts": command_timeouts,
        "round_trip_latency": round_trip_latency,
        "wall_stamp": time_fields(wall_stamp_ns),
        "contact_uplift": float(getattr(t, "contact_uplift", math.nan)),
        "support_uplift": float(getattr(t, "support_uplift", math.nan)),
        "contact_position": float(getattr(t, "contact_position", math.nan)),
        "roof_height": float(getattr(t, "roof_height", 0.0)),
    }


def pantograph_truth_fields(truths: Any, spacing: Any, tick: int, stamp_ns: int) -> dict[str, Any]:
    """PantographTruth from pac_plant.fe_plant.PantographTruth, one per pantograph, in the order of
    the plant's ``pantographs`` (``spacing``)."""

    def column(name: str) -> np.ndarray:
        return np.array([getattr(t, name) for t in truths], dtype=np.float64)

    return {
        "header": header(stamp_ns),
        "tick": tick,
        "controlled": next(k for k, t in enumerate(truths) if t.controlled),
        "spacing": np.array(spacing, dtype=np.float64),
        "contact_force": column("contact_force"),
        "contact_position": column("contact_position"),
        "contact_uplift": column("contact_uplift"),
        "support_uplift": column("support_uplift"),
    }


def estimate_fields(
    e: Any,
    stamp_ns: int,
    *,
    status: int = STATUS_OK,
    rejected: int = 0,
    reinitialisations: int = 0,
    actuator_force: float = math.nan,
) -> dict[str, Any]:
    """ObserverEstimate from pac_observer.observer.Estimate (``actuator_force``: the measurement's)."""
    return {
        "header": header(stamp_ns),
        "tick": e.tick,
        "z_hat": np.array(e.z_hat, dtype=np.float64),
        "theta_hat": np.array(e.theta_hat, dtype=np.float64),
        "stiffness_hat": e.stiffness_hat,
        "contact_force_hat": e.contact_force_hat,
        "innovation": np.array(e.innovation, dtype=np.float64),
        "status": status,
        "rejected_measurements": rejected,
        "reinitialisations": reinitialisations,
        "actuator_force": float(actuator_force),
    }


def command_fields(c: Any, stamp_ns: int, *, estimate_age_ticks: int = 0) -> dict[str, Any]:
    """ActuatorCommand from pac_controller.backstepping.Command."""
    return {
        "header": header(stamp_ns),
        "tick": c.tick,
        "u": c.u,
        "u_unsaturated": c.u_unsaturated,
        "force_reference": c.force_reference,
        "tracking_error": np.array(c.tracking_error, dtype=np.float64),
        "saturated": bool(c.saturated),
        "mode": MODES[c.mode],
        "estimate_age_ticks": estimate_age_ticks,
    }


def run_status_fields(
    tick: int, state: int, duration: float, stamp_ns: int, catenary_model: str = "", span_length: float = 0.0
) -> dict[str, Any]:
    """RunStatus: the plant's run started (tick 0) or ended (its last tick), and its line."""
    return {
        "header": header(stamp_ns),
        "tick": tick,
        "state": state,
        "duration": duration,
        "catenary_model": catenary_model,
        "span_length": span_length,
    }


def cdr_tick(data: bytes | memoryview) -> int:
    """The ``tick`` of a serialised pac message without deserialising it.

    Every pac message starts with std_msgs/Header (int32 sec, uint32 nanosec,
    string frame_id) followed by uint64 tick, 8-aligned from the start of the CDR
    body (after the 4-byte encapsulation header).
    """
    little = data[1] == 1
    (length,) = struct.unpack_from("<I" if little else ">I", data, 4 + 8)
    offset = (8 + 4 + length + 7) & ~7
    return struct.unpack_from("<Q" if little else ">Q", data, 4 + offset)[0]


class RclpyFactory:
    """Fills rclpy message objects (needs the sourced workspace).

    ``make`` fills and returns one cached instance per type, which costs a sixth
    of constructing a message (this matters at 1 kHz): publish it, or copy it,
    before the next ``make`` of the same type.
    """

    def __init__(self) -> None:
        self._classes: dict[str, type] = {}
        self._instances: dict[str, Any] = {}

    def cls(self, typename: str) -> type:
        if typename not in self._classes:
            pkg, _, name = typename.split("/")
            self._classes[typename] = getattr(importlib.import_module(f"{pkg}.msg"), name)
        return self._classes[typename]

    def make(self, typename: str, fields: Mapping[str, Any]) -> Any:
        msg = self._instances.get(typename)
        if msg is None:
            msg = self._instances[typename] = self.cls(typename)()
        _fill(msg, fields)
        return msg


def _fill(msg: Any, fields: Mapping[str, Any]) -> None:
    for key, value in fields.items():
        if isinstance(value, Mapping):
            _fill(getattr(msg, key), value)
        else:
            setattr(msg, key, value)


class RosbagsFactory:
    """Builds rosbags message objects from a typestore that knows pac_interfaces."""

    def __init__(self, typestore: Any) -> None:
        self.typestore = typestore

    def make(self, typename: str, fields: Mapping[str, Any]) -> Any:
        cls = self.typestore.types[typename]
        kwargs = {}
        for name, ftype in self.typestore.fielddefs[typename][1]:
            value = fields[name]
            if isinstance(value, Mapping):
                value = self.make(ftype[1], value)
            kwargs[name] = value
        return cls(**kwargs)


def _header_columns(stamps_ns: np.ndarray) -> dict[str, Any]:
    return {
        "header.stamp.sec": stamps_ns // 1_000_000_000,
        "header.stamp.nanosec": stamps_ns % 1_000_000_000,
        "header.frame_id": "",
    }


def tick_columns(block: Any, rate_hz: float, command_delay_ticks: int) -> dict[str, dict[str, Any]]:
    """The four loop topics of many offline ticks as columns for ``BagWriter.write_many``.

    ``block`` is an array of ``pac_rig.loop.TICK`` records: the same values, field by field, as
    :func:`measurement_fields`, :func:`truth_fields` (applied_command_tick as the offline
    simulator gives it), :func:`estimate_fields` and :func:`command_fields` of each tick's records,
    without building them (``tests/test_offline.py`` compares the two bags).
    """
    ticks = block["tick"].astype(np.int64)
    head = _header_columns(ticks * int(round(1e9 / rate_hz)))
    applied = np.maximum(-1, ticks - 1 - command_delay_ticks)
    nan = np.full(ticks.size, math.nan)
    return {
        "measurement": {
            **head,
            "tick": ticks,
            "z1": block["y"][:, 0],
            "z2": block["y"][:, 1],
            "actuator_force": block["actuator_force"],
            "head_acceleration": block["head_acceleration"],  # NaN where the suite has none
            "frame_acceleration": block["frame_acceleration"],
            "head_force": block["head_force"],
            "from_roof": block["from_roof"],
        },
        "plant_truth": {
            **head,
            "tick": ticks,
            "z": block["z"],
            "stiffness": block["stiffness"],
            "contact_force": block["contact_force"],
            "in_contact": block["in_contact"],
            "u_applied": block["u_applied"],
            "applied_command_tick": applied,
            "command_age_ticks": np.where(applied >= 0, np.maximum(0, ticks - applied), 0),
            "command_source": COMMAND_FRESH,
            "command_timeouts": 0,
            "round_trip_latency": nan,
            "wall_stamp.sec": 0,
            "wall_stamp.nanosec": 0,
            "contact_uplift": block["contact_uplift"],  # NaN on the lumped line
            "support_uplift": block["support_uplift"],
            "contact_position": block["contact_position"],
            "roof_height": block["roof_height"],
        },
        "estimate": {
            **head,
            "tick": ticks,
            "z_hat": block["z_hat"],
            "theta_hat": block["theta_hat"],
            "stiffness_hat": block["stiffness_hat"],
            "contact_force_hat": block["contact_force_hat"],
            "innovation": block["innovation"],
            "status": STATUS_OK,
            "rejected_measurements": 0,
            "reinitialisations": 0,
            "actuator_force": block["actuator_force"],
        },
        "command": {
            **head,
            "tick": ticks,
            "u": block["u"],
            "u_unsaturated": block["u_unsaturated"],
            "force_reference": block["force_reference"],
            "tracking_error": block["tracking_error"],
            "saturated": block["saturated"],
            "mode": block["mode"],  # pac_controller.kernels.MODES is in the order of MODES here
            "estimate_age_ticks": 0,
        },
    }
