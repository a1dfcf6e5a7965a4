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
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, ClassVar, TypeVar

from . import diagnostics, messages
from .parameters import (
    NodeOptions,
    ParameterError,
    ParameterSet,
    ParameterSpec,
    RunEndOptions,
    SchedulingOptions,
    UnknownParameterError,
)


def configure_environment() -> None:
    """Loopback-only DDS discovery, before rclpy is imported or initialised (project rule)."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"


configure_environment()

import rclpy  # noqa: E402
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult  # noqa: E402
from rclpy.duration import Duration  # noqa: E402
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor  # noqa: E402
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402

from .health import NodeHealth, StatusRule  # noqa: E402
from .lifecycle import LifecycleOptions, ManagedNode  # noqa: E402

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


S = TypeVar("S", bound=ParameterSet)


def _descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    unit = f" [{spec.unit}]" if spec.unit else ""
    when = "may be changed at run time" if spec.runtime else "fixed for a run"
    # Ranges are checked by pac's own validation (one message format for start and runtime);
    # dynamic typing lets `-p m1:=8` (an integer) set a float parameter.
    return ParameterDescriptor(
        description=f"{spec.description}{unit}",
        additional_constraints=f"allowed: {spec.allowed()}; {when}",
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


def given_parameter_names(node: Node) -> list[str]:
    """Names set for this node by ``--ros-args -p`` or ``--params-file``.

    rclpy has no public accessor for the overrides it parsed; ``_parameter_overrides`` is the
    dict it fills in ``Node.__init__`` (tests/test_suite.py checks a typo is still caught).
    """
    return list(getattr(node, "_parameter_overrides", {}))


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


def parameter_names(sets: Iterable[type[ParameterSet]]) -> list[str]:
    return [spec.name for cls in sets for spec in cls.specs()]


class PacNode(ManagedNode, Node):
    """Base of every pac node: the contract :func:`run_node` relies on, and the shared start-up.

    A subclass lists its ``PARAMETER_SETS``; the base declares them (description, range and
    whether it may change at run time in each descriptor), refuses unknown names given on the
    command line or in a params file, validates run-time changes with the start-up rules (a
    refused change leaves the node as it was) and applies ``NodeOptions`` (real-time priority).

    Contract with :func:`run_node`: ``finished`` ends the spin loop, ``close()`` makes the
    node's results final (bag closed, counters printed), ``exit_status`` is the process status.

    A subclass builds itself in ``configure()`` (pac_common.lifecycle): at once, or, with
    ``lifecycle:=true`` (``LifecycleOptions`` in its sets), when a lifecycle manager says so;
    its loop callbacks check ``active``.  Every node reports ``health_counters()`` on
    ``/diagnostics`` with its ``HEALTH_RULE`` (pac_common.diagnostics).
    """

    PARAMETER_SETS: ClassVar[Sequence[type[ParameterSet]]] = ()
    #: Why a parameter declared without ``runtime=True`` is refused at run time.
    FROZEN_REASON: ClassVar[str] = "fixed for a run: restart the node to change it"
    #: The node's rule from counters to its ``/diagnostics`` status (pac_common.diagnostics).
    HEALTH_RULE: ClassVar[StatusRule] = staticmethod(diagnostics.relay_status)

    def __init__(self, name: str) -> None:
        # Undeclared names reach our callback, which refuses them by name (rclpy's own refusal
        # reads "Invalid access to undeclared parameter(s): []" in these wheels).
        Node.__init__(self, name, allow_undeclared_parameters=True)
        self.finished = False
        self.exit_status = 0
        sets = declare_parameter_sets(self, self.PARAMETER_SETS)
        self._sets: dict[type[ParameterSet], ParameterSet] = dict(zip(self.PARAMETER_SETS, sets, strict=True))
        known = set(parameter_names(self.PARAMETER_SETS)) | {"use_sim_time"}
        unknown = [n for n in given_parameter_names(self) if n not in known]
        if unknown:
            raise UnknownParameterError(unknown[0], self._parameter_overrides[unknown[0]].value, name)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.factory = messages.RclpyFactory()
        options = self._sets.get(NodeOptions)
        self.node_options: NodeOptions | None = options  # type: ignore[assignment]
        scheduling = [p for p in self._sets.values() if isinstance(p, SchedulingOptions)]
        if scheduling:
            set_realtime_priority(self, scheduling[0].realtime_priority)
        self.health = NodeHealth(self, self._health_counters, self.HEALTH_RULE)
        lifecycle = self._sets.get(LifecycleOptions)
        self.start_lifecycle(bool(lifecycle is not None and lifecycle.lifecycle))  # type: ignore[attr-defined]

    def _health_counters(self) -> dict[str, Any]:
        if not self.configured:
            return {"state": self.lifecycle_state}
        counters = self.health_counters()
        if self.managed:
            counters["lifecycle_state"] = self.lifecycle_state
            if not self.active:
                counters["state"] = self.lifecycle_state
        return counters

    def health_counters(self) -> dict[str, Any]:
        """Hook: the node's counters and state, read (never computed) from what the loop keeps;
        its ``/diagnostics`` key-values every second and its ``pac-stats`` line at the end."""
        return {}

    def _unknown_hint(self) -> str:
        return f"a parameter of {self.get_name()} (`ros2 run <pkg> {self.get_name()} --help` lists them)"

    def parameters(self, cls: type[S]) -> S:
        """The current, validated values of one of the node's parameter sets."""
        return self._sets[cls]  # type: ignore[return-value]

    def apply_parameters(self, changed: Mapping[type[ParameterSet], ParameterSet]) -> None:
        """Hook: run-time changes, validated, about to take effect (``changed``: the new sets)."""

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        runtime = {s.name for cls in self.PARAMETER_SETS for s in cls.specs() if s.runtime}
        known = set(parameter_names(self.PARAMETER_SETS)) | {"use_sim_time"}
        for p in params:
            if p.name not in known:
                return SetParametersResult(
                    successful=False, reason=f"{p.name}: no such parameter; allowed {self._unknown_hint()}"
                )
        frozen = [p.name for p in params if p.name not in runtime and p.name != "use_sim_time"]
        if frozen:
            return SetParametersResult(successful=False, reason=f"{', '.join(frozen)}: {self.FROZEN_REASON}")
        live = [cls for cls in self.PARAMETER_SETS if cls.has_runtime()]
        current = [self._sets[cls] for cls in live]
        updated, error = validate_changes(current, params)
        if error:
            return SetParametersResult(successful=False, reason=error)
        changed = {cls: new for cls, old, new in zip(live, current, updated, strict=True) if new != old}
        if changed:
            if self.configured:
                self.apply_parameters(changed)
            self._sets.update(changed)
        return SetParametersResult(successful=True)

    # -- the plant's run: start and end ------------------------------------------------------------
    #: After the end was announced, how long a follower waits for the last tick before it stops
    #: (a lost last sample must not keep a stop_after_run node alive).
    RUN_END_GRACE = 2.0

    def follow_run(self) -> None:
        """Subscribe ``run_status``: :attr:`run_last_tick` is the ended run's last tick, else None."""
        self.run_last_tick: int | None = None
        self._run_ended_wall = 0.0
        self._last_handled_tick = -1
        self.create_subscription(
            self.factory.cls(messages.RUN_STATUS), "run_status", self._on_run_status, RUN_STATUS_QOS
        )
        if self._sets.get(RunEndOptions) is not None and self.parameters(RunEndOptions).stop_after_run:
            self.create_timer(0.1, self._check_run_end_grace)

    @property
    def run_ended(self) -> bool:
        return self.run_last_tick is not None

    def _on_run_status(self, msg: Any) -> None:
        if msg.state == messages.RUN_ENDED:
            self.run_last_tick, self._run_ended_wall = int(msg.tick), time.monotonic()
            self.get_logger().info(f"the plant's run ended at tick {msg.tick}: idle until a new run")
            self.on_run_end()
            self.handled_tick(self._last_handled_tick)  # the last tick may have come first
        elif self.run_last_tick is not None:
            self.run_new()

    def run_new(self) -> None:
        """A new run started (a RUNNING status, or ticks back at 0): leave the idle state."""
        self.run_last_tick = None
        self._last_handled_tick = -1

    def loop_state(self, last_tick: int) -> str:
        """``waiting`` (no tick handled yet), ``running`` or ``ended``: the state a status reports."""
        if self.run_ended:
            return "ended"
        return "waiting" if last_tick < 0 else "running"

    def on_run_end(self) -> None:
        """Hook: the plant announced the end of its run (``run_last_tick`` is set)."""

    def handled_tick(self, tick: int) -> None:
        """Subclasses call this after handling ``tick``: the end of a run may stop the node."""
        self._last_handled_tick = max(self._last_handled_tick, tick)
        if self.run_last_tick is not None and tick >= self.run_last_tick:
            self._stop_after_run()

    def _stop_after_run(self) -> None:
        if self.parameters(RunEndOptions).stop_after_run and not self.finished:
            self.get_logger().info("run over and its last tick handled: stopping (stop_after_run)")
            self.finished = True

    def _check_run_end_grace(self) -> None:
        if self.run_ended and time.monotonic() - self._run_ended_wall > self.RUN_END_GRACE:
            if not self.finished:
                self.get_logger().warning(
                    f"tick {self.run_last_tick} never reached this node within {self.RUN_END_GRACE:g} s "
                    "of the run's end: stopping anyway"
                )
            self._stop_after_run()

    def wait_for_acknowledgements(self, timeout: float = 2.0) -> None:
        """Before exit: wait (bounded) until reliable readers (the recorder) have every sample.

        Without it the last ticks of a run were lost when the recorder was slower than the
        plant's exit (issue #10, under load).
        """
        deadline = time.monotonic() + timeout
        for pub in list(self.publishers):
            left = deadline - time.monotonic()
            if left <= 0.0:
                break
            try:
                pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))
            except Exception:  # noqa: BLE001 - a context already shut down: nothing to wait for
                return

    def close(self) -> None:
        """Make the node's results final; the base reports the last status and waits for
        acknowledgements of what it sent."""
        self.health.final_report()
        self.wait_for_acknowledgements()


def process_threads() -> list[int]:
    """Thread ids of this process (Linux); ``[0]`` (the calling thread) where /proc is missing."""
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


def set_realtime_priority(node: Node, priority: int) -> bool:
    """SCHED_FIFO at ``priority`` for every thread of this process; one warning line if refused.

    Every thread, not only the caller: the node is created first, so Fast DDS's receive and
    event threads already exist, and a sample reaches the executor through them (threads
    started later, e.g. the recorder's writer, inherit the policy).
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


def make_executor() -> Any:
    """EventsExecutor (about 4x less CPU for a 1 kHz node here) unless PAC_EXECUTOR=single."""
    if os.environ.get("PAC_EXECUTOR", "events") == "single":
        return SingleThreadedExecutor()
    from rclpy.experimental import EventsExecutor

    return EventsExecutor()


#: Fast DDS maps a domain id to UDP ports 7400 + 250 * id + ...: above 232 they pass 65535.
MAX_DOMAIN_ID = 232


class UsageError(ValueError):
    """A command line or environment the node cannot start with; the message is one line."""


def check_domain_id(environ: Mapping[str, str] = os.environ) -> None:
    """ROS_DOMAIN_ID must be an integer in [0, 232] (else every node dies in Fast DDS)."""
    text = environ.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_DOMAIN_ID:
        raise UsageError(
            f"ROS_DOMAIN_ID={text!r} is out of range: allowed an integer in [0, {MAX_DOMAIN_ID}]"
        )


def check_ros_arguments(argv: Sequence[str]) -> None:
    """Reject what rcl would refuse with a traceback, with one line naming the problem.

    ``argv`` is the program's arguments without the program name.  Outside ``--ros-args``
    nothing is accepted (``-p c1:=3`` there would otherwise be ignored silently).
    """
    in_ros = False
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg == "--ros-args":
            in_ros = True
        elif arg == "--":
            in_ros = False
        elif not in_ros:
            raise UsageError(
                f"unexpected argument {arg!r}: parameters go after --ros-args "
                "(e.g. --ros-args -p name:=value); --help lists them"
            )
        elif arg in ("-p", "--param", "--params-file"):
            if i + 1 >= len(argv):
                raise UsageError(f"{arg} needs a value")
            value = argv[i + 1]
            if arg == "--params-file":
                _check_params_file(value)
            else:
                name, sep, text = value.partition(":=")
                if not sep or not name or not text:
                    raise UsageError(f"{arg} {value!r}: expected name:=value (e.g. -p c1:=30.0)")
            i += 1
        i += 1


def _check_params_file(path: str) -> None:
    import yaml

    try:
        with open(path, encoding="utf-8") as handle:
            data = yaml.safe_load(handle)
    except OSError as exc:
        raise UsageError(f"cannot read params file {path}: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "invalid YAML"
        raise UsageError(f"params file {path} is not valid YAML ({first})") from None
    sections = data.values() if isinstance(data, dict) else []
    if not isinstance(data, dict) or not all(
        isinstance(v, dict) and isinstance(v.get("ros__parameters"), dict) for v in sections
    ):
        raise UsageError(
            f"params file {path} is not a ROS 2 parameter file "
            "(expected '/**:' or '<node>:' sections with 'ros__parameters:')"
        )


def node_help(program: str, node_class: type[PacNode]) -> str:
    """``--help``: usage, what the node does, and every parameter with its range and default."""
    import inspect

    module = inspect.getmodule(node_class)
    summary = (module.__doc__ or "").strip() if module is not None else ""
    lines = [
        f"usage: {program} [--help] [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] [-r ...]]",
        "",
        summary,
        "",
        "parameters (* may be changed at run time with `ros2 param set`):",
    ]
    for cls in node_class.PARAMETER_SETS:
        for spec in cls.specs():
            unit = f" [{spec.unit}]" if spec.unit else ""
            mark = "*" if spec.runtime else " "
            default = list(spec.default) if isinstance(spec.default, tuple) else spec.default
            lines.append(f"  {mark}{spec.name} (default {default!r}; {spec.allowed()}){unit}")
            lines.append(f"      {spec.description}")
    return "\n".join(lines)


def run_node(program: str, node_class: type[PacNode], args: list[str] | None = None) -> int:
    """Initialise rclpy, build the node, spin until shutdown; the exit status of the program.

    ``--help`` prints the usage and parameters (exit 0); a bad command line, params file,
    parameter value or ``ROS_DOMAIN_ID`` is one line on stderr and exit status 2.
    ``EventsExecutor.spin()`` busy-loops in these rclpy wheels; a ``spin_once`` loop does not.
    """
    return run_nodes(program, [node_class], args)


def run_nodes(program: str, node_classes: Sequence[type[PacNode]], args: list[str] | None = None) -> int:
    """:func:`run_node` for several nodes in one process and one executor (a component container).

    The process runs until every node is ``finished`` (or a signal); each node is then closed
    in order; the status is the first non-zero one.  Parameters reach each node by name
    (``--params-file`` with one section per node): a global ``-p`` would reach all of them,
    and each refuses the names it does not declare.
    """
    argv = list(sys.argv if args is None else args)[1:]
    outside = argv[: argv.index("--ros-args")] if "--ros-args" in argv else argv
    if "--help" in outside or "-h" in outside:
        print("\n\n".join(node_help(program, cls) for cls in node_classes))
        return 0
    try:
        check_domain_id()
        check_ros_arguments(argv)
    except UsageError as exc:
        print(f"{program}: {exc}", file=sys.stderr)
        return 2
    try:
        rclpy.init(args=args)
    except _rclpy.RCLError as exc:  # anything check_ros_arguments did not foresee
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"{program}: cannot start: {first}", file=sys.stderr)
        return 2
    nodes: list[PacNode] = []
    executor = None
    status = 0
    try:
        try:
            for cls in node_classes:
                nodes.append(cls())
        except ParameterError as exc:
            print(f"{program}: {exc}", file=sys.stderr)
            status = 2
            return 2
        executor = make_executor()
        for node in nodes:
            executor.add_node(node)
        while rclpy.ok() and not all(node.finished for node in nodes):
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
        if nodes and status != 2:
            for node in nodes:
                if node.configured:
                    node.close()  # the node's own results (bag, counters) are final from here on
                else:
                    node.health.final_report()
                node.health.print_stats()
                status = status or node.exit_status
            # Tearing down rclpy (EventsExecutor) in these wheels was seen to hang once in ~50
            # stops; everything that matters is done, so a stuck teardown ends the process.
            final = status
            guard = threading.Timer(5.0, lambda: os._exit(final))
            guard.daemon = True
            guard.start()
            if executor is not None:
                executor.shutdown(timeout_sec=1.0)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
    return status
