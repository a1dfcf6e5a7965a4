"""rclpy glue shared by every pac node: parameters, QoS, executor loop, clean start and stop.

Nodes stay thin: they declare their parameter sets here (one ROS parameter per
field, with the field's description and allowed range in the descriptor), get
validated core parameter objects back, and run through :func:`run_node`, which
turns an invalid parameter into a one-line error and exit status 2 and SIGINT /
SIGTERM into a clean shutdown with exit status 0.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any, TypeVar

from .parameters import ParameterError, ParameterSet, ParameterSpec


def configure_environment() -> None:
    """Loopback-only DDS discovery, before rclpy is imported or initialised (project rule)."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"


configure_environment()

import rclpy  # noqa: E402
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult  # noqa: E402
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

#: Loop subscribers (observer <- measurement, controller <- estimate, plant <- command): best
#: effort, keep last 1. Only the newest sample matters in real time, a late sample is worse than
#: a lost one, and a node that falls behind skips to the newest sample (the observer bridges the
#: gap exactly) instead of working through a backlog; with depth 10 the command age reached
#: 20-44 ticks under load (docs/design.md).
LOOP_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
#: Every pac publisher: reliable and transient-local with the last 1000 samples. The best-effort
#: loop subscribers are unaffected (no acknowledgements, no retransmission to them); a reliable
#: reader (the recorder) gets every sample, including those sent before its side of the match
#: completed, which best effort loses (seen: tick 0 missing from a lock-step bag).
PUBLISH_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1000,
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


S = TypeVar("S", bound=ParameterSet)


def _descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    unit = f" [{spec.unit}]" if spec.unit else ""
    # Ranges are checked by pac's own validation (one message format for start and runtime);
    # dynamic typing lets `-p m1:=8` (an integer) set a float parameter.
    return ParameterDescriptor(
        description=f"{spec.description}{unit}",
        additional_constraints=f"allowed: {spec.allowed()}",
        dynamic_typing=True,
    )


def _ros_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def declare_parameter_sets(node: Node, classes: Sequence[type[ParameterSet]]) -> list[ParameterSet]:
    """Declare every field of ``classes`` as a ROS parameter and return validated instances.

    Raises :class:`ParameterError` (name, value, allowed range) for the first invalid value.
    """
    out = []
    for cls in classes:
        values = {}
        for spec in cls.specs():
            if not node.has_parameter(spec.name):
                node.declare_parameter(spec.name, _ros_value(spec.default), _descriptor(spec))
            values[spec.name] = node.get_parameter(spec.name).value
        out.append(cls.from_mapping(values))
    return out


def validate_changes(
    current: Iterable[ParameterSet], changes: Sequence[Parameter]
) -> tuple[list[ParameterSet], str]:
    """Apply parameter changes to copies of ``current``; return the new sets, or an error string."""
    updated = []
    by_name = {p.name: p.value for p in changes}
    try:
        for pset in current:
            names = {s.name for s in pset.specs()}
            mine = {k: v for k, v in by_name.items() if k in names}
            updated.append(dataclasses.replace(pset, **mine) if mine else pset)
    except ParameterError as exc:
        return list(current), str(exc)
    return updated, ""


def handle_parameter_changes(
    node: Node,
    frozen: Iterable[str],
    frozen_reason: str,
    live: Callable[[], list[ParameterSet]] | None = None,
    apply: Callable[[list[ParameterSet]], None] | None = None,
) -> None:
    """Validate ``set_parameters`` with the start-up rules; a refused change leaves the node as it was.

    Names in ``frozen`` are refused with ``frozen_reason``.  Changes to the sets returned by
    ``live()`` are validated together (cross-field checks included) and, when all are valid,
    handed to ``apply`` with the updated sets before they take effect.
    """
    frozen = set(frozen)

    def callback(params: list[Parameter]) -> SetParametersResult:
        hit = [p.name for p in params if p.name in frozen]
        if hit:
            return SetParametersResult(successful=False, reason=f"{', '.join(hit)}: {frozen_reason}")
        if live is not None:
            current = live()
            updated, error = validate_changes(current, params)
            if error:
                return SetParametersResult(successful=False, reason=error)
            if apply is not None and updated != current:
                apply(updated)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(callback)


def parameter_names(sets: Iterable[type[ParameterSet]]) -> list[str]:
    return [spec.name for cls in sets for spec in cls.specs()]


def set_realtime_priority(node: Node, priority: int) -> bool:
    """SCHED_FIFO at ``priority`` for this process; warn and carry on when it is refused."""
    if priority <= 0:
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError) as exc:
        node.get_logger().warning(f"realtime_priority {priority} refused ({exc}): normal scheduling")
        return False
    node.get_logger().info(f"running with SCHED_FIFO priority {priority}")
    return True


def make_executor() -> Any:
    """EventsExecutor (about 4x less CPU for a 1 kHz node here) unless PAC_EXECUTOR=single."""
    if os.environ.get("PAC_EXECUTOR", "events") == "single":
        return SingleThreadedExecutor()
    from rclpy.experimental import EventsExecutor

    return EventsExecutor()


def run_node(program: str, factory: Callable[[], Node], args: list[str] | None = None) -> int:
    """Initialise rclpy, build the node, spin until shutdown; the exit status of the program.

    ``EventsExecutor.spin()`` busy-loops in these rclpy wheels; a ``spin_once`` loop does not.
    """
    rclpy.init(args=args)
    node = None
    executor = None
    status = 0
    try:
        try:
            node = factory()
        except ParameterError as exc:
            print(f"{program}: {exc}", file=sys.stderr)
            return 2
        executor = make_executor()
        executor.add_node(node)
        while rclpy.ok() and not getattr(node, "finished", False):
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:  # noqa: BLE001 - report, then exit non-zero with a clean shutdown
        # SIGINT/SIGTERM shut the context down asynchronously: an error raised by a callback (or by
        # the executor) in that instant is part of a clean stop. Give the shutdown a moment to show.
        deadline = time.monotonic() + 0.5
        while rclpy.ok() and time.monotonic() < deadline:
            time.sleep(0.01)
        if rclpy.ok():
            print(f"{program}: fatal: {exc!r}", file=sys.stderr)
            status = 1
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()  # the node's own results (bag, counters) are final from here on
            status = status or getattr(node, "exit_status", 0)
            # Tearing down rclpy (EventsExecutor) in these wheels was seen to hang once in ~50
            # stops; everything that matters is done, so a stuck teardown ends the process.
            final = status
            guard = threading.Timer(5.0, lambda: os._exit(final))
            guard.daemon = True
            guard.start()
            if executor is not None:
                executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
        rclpy.try_shutdown()
    return status
