"""PacNode: the base of every pac node (parameters, start-up) and the run's start/end protocol.

A subclass lists its ``PARAMETER_SETS``; the base declares them as typed ROS parameters
(:mod:`pac_common.ros_parameters`), refuses unknown names given on the command line or in
its own params-file section, validates run-time changes with the start-up rules (a refused
change leaves the node as it was, and pac's one line is the reason) and applies
``NodeOptions`` (real-time priority). The run-end protocol: the plant announces the start and
end of its run on ``run_status``; a follower answers up to the last tick, then idles or stops.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any, ClassVar, TypeVar

from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter

from . import diagnostics, messages
from .command_line import ROS_OWN_PARAMETERS, pac_parameter_names, process_arguments
from .health import NodeHealth
from .lifecycle import LifecycleOptions, ManagedNode
from .parameters import (
    NodeOptions,
    ParameterError,
    ParameterSet,
    RunEndOptions,
    SchedulingOptions,
    UnknownParameterError,
)
from .qos import RUN_STATUS_QOS
from .ros_parameters import (
    declare_parameter_sets,
    given_parameter_names,
    parameter_names,
    ros_value,
    validate_changes,
)
from .scheduling import set_realtime_priority

S = TypeVar("S", bound=ParameterSet)


def unacknowledged(publishers: Iterable[Any], timeout: float) -> list[Any]:
    """The publishers whose reliable readers had not acknowledged every sample sent when
    ``timeout`` seconds (one deadline for all) ran out; a process that destroys its node at once
    loses what is still in flight. A context already shut down has nobody left to wait for."""
    deadline = time.monotonic() + timeout
    late = []
    for pub in publishers:
        left = max(0.0, deadline - time.monotonic())
        try:
            if not pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))):
                late.append(pub)
        except Exception:  # noqa: BLE001 - a context already shut down: nothing to wait for
            break
    return late


class PacNode(ManagedNode, Node):
    """Base of every pac node: the contract :func:`~pac_common.process.run_nodes` relies on.

    Contract: ``finished`` ends the spin loop, ``close()`` makes the node's results final (bag
    closed, counters printed), ``exit_status`` is the process status.

    A subclass builds itself in ``configure()`` (:mod:`pac_common.lifecycle`): at once, or, with
    ``lifecycle:=true`` (``LifecycleOptions`` in its sets), when a lifecycle manager says so; its
    loop callbacks check ``active``. Every node reports ``health_counters()`` on ``/diagnostics``
    with the rule its ``HEALTH`` names (:mod:`pac_common.diagnostics`).
    """

    PARAMETER_SETS: ClassVar[Sequence[type[ParameterSet]]] = ()
    #: Why a parameter declared without ``runtime=True`` is refused at run time.
    FROZEN_REASON: ClassVar[str] = "fixed for a run: restart the node to change it"
    #: The node's rule from counters to its ``/diagnostics`` status (``pac_common.diagnostics.RULES``).
    HEALTH: ClassVar[str] = "node"

    def __init__(self, name: str) -> None:
        # Undeclared names reach our checks, which refuse them by name (rclpy's own refusal
        # reads "Invalid access to undeclared parameter(s): []" in these wheels).
        Node.__init__(self, name, allow_undeclared_parameters=True)
        self.finished = False
        self.exit_status = 0
        sets = declare_parameter_sets(self, self.PARAMETER_SETS)
        self._sets: dict[type[ParameterSet], ParameterSet] = dict(zip(self.PARAMETER_SETS, sets, strict=True))
        self._known = set(parameter_names(self.PARAMETER_SETS)) | ROS_OWN_PARAMETERS
        self._runtime = {s.name for cls in self.PARAMETER_SETS for s in cls.specs() if s.runtime}
        self._check_given_names()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.factory = messages.RclpyFactory()
        options = self._sets.get(NodeOptions)
        self.node_options = options if isinstance(options, NodeOptions) else None
        scheduling = [p for p in self._sets.values() if isinstance(p, SchedulingOptions)]
        if scheduling:
            set_realtime_priority(self, scheduling[0].realtime_priority)
        self.health = NodeHealth(self, self._health_counters, diagnostics.RULES[self.HEALTH])
        lifecycle = self._sets.get(LifecycleOptions)
        self.start_lifecycle(isinstance(lifecycle, LifecycleOptions) and lifecycle.lifecycle)

    # SIGINT / SIGTERM shut the context down from rclpy's signal handling while the executor may
    # be inside one of our callbacks; a publish there fails with "publisher's context is
    # invalid", which the EventsExecutor printed as a FATAL traceback although the stop was
    # clean (seen on plant_node). Our callbacks drop an error raised once the context is down;
    # an error while it runs is raised as ever.
    def create_timer(self, timer_period_sec: float, callback: Callable, *args: Any, **kwargs: Any) -> Any:
        return super().create_timer(timer_period_sec, self._until_shutdown(callback), *args, **kwargs)

    def create_subscription(
        self, msg_type: Any, topic: str, callback: Callable, qos_profile: Any, *args: Any, **kwargs: Any
    ) -> Any:
        return super().create_subscription(
            msg_type, topic, self._until_shutdown(callback), qos_profile, *args, **kwargs
        )

    def _until_shutdown(self, callback: Callable) -> Callable:
        context = self.context

        def guarded(*args: Any) -> Any:
            try:
                return callback(*args)
            except Exception:
                if context.ok():
                    raise
                return None

        return guarded

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

    def _check_given_names(self) -> None:
        """ROS's params-file rules, with pac's typo check.

        A node takes ``-p`` values, its own section and the shared ``/**``. An unknown name from
        ``-p`` or its own section is a typo (refused). From ``/**`` it is refused only when no pac
        node has it; otherwise it is meant for another node and ignored. A params file that gives
        this node nothing is said in one warning line.
        """
        arguments = process_arguments()
        me = self.get_fully_qualified_name()
        own_keys = set(arguments.parameters)
        shared_keys: set[str] = set()
        empty = []
        for params_file in arguments.params_files:
            shared, own = params_file.for_node(me)
            own_keys |= own.keys()
            shared_keys |= shared.keys()
            if not (shared.keys() | own.keys()) & self._known:
                empty.append(params_file)
        unknown = [n for n in given_parameter_names(self) if n not in self._known]
        everyone: set[str] | None = None
        for name in unknown:
            if name not in own_keys and name in shared_keys:
                everyone = pac_parameter_names() if everyone is None else everyone
                if name in everyone or not everyone:
                    continue  # another node's key in a shared section: ROS ignores it too
            raise UnknownParameterError(name, self._parameter_overrides[name].value, self.get_name())
        for params_file in empty:
            sections = ", ".join(f"'{s}'" for s in params_file.sections) or "none"
            self.get_logger().warning(
                f"params file {params_file.path} gives {me} nothing (its sections: {sections}; "
                f"a node takes '/**:' and its own, '{self.get_name()}:')"
            )

    def _unknown_hint(self) -> str:
        return f"a parameter of {self.get_name()} (`ros2 run <pkg> {self.get_name()} --help` lists them)"

    def parameters(self, cls: type[S]) -> S:
        """The current, validated values of one of the node's parameter sets."""
        values = self._sets[cls]
        if not isinstance(values, cls):  # the sets are keyed by their class: cannot happen
            raise TypeError(f"{cls.__name__}'s values are a {type(values).__name__}")
        return values

    def apply_parameters(self, changed: Mapping[type[ParameterSet], ParameterSet]) -> None:
        """Hook: run-time changes, validated, about to take effect (``changed``: the new sets)."""

    @staticmethod
    def changed_or(changed: Mapping[type[ParameterSet], ParameterSet], cls: type[S], current: S) -> S:
        """In :meth:`apply_parameters`: the new values of ``cls`` if ``changed`` has them, else
        ``current`` (typed, where ``changed.get(cls)`` is only a ParameterSet)."""
        new = changed.get(cls, current)
        if not isinstance(new, cls):
            raise TypeError(f"the change of {cls.__name__} is a {type(new).__name__}")
        return new

    # -- run-time changes: pac's checks first, then rclpy's descriptors ------------------------------
    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """pac's refusal (unknown, fixed for a run, out of range) before rclpy's own wording.

        The parameter services call this. An integer for a double parameter is converted
        (`ros2 param set controller_node c1 30` keeps c1 a double).
        """
        checked, refusal = self._pac_check(parameter_list)
        return refusal or super().set_parameters_atomically(checked)

    def set_parameters(self, parameter_list: list[Parameter]) -> list[SetParametersResult]:
        return [self.set_parameters_atomically([p]) for p in parameter_list]

    def _pac_check(self, params: list[Parameter]) -> tuple[list[Parameter], SetParametersResult | None]:
        for p in params:
            if p.name not in self._known:
                return params, SetParametersResult(
                    successful=False, reason=f"{p.name}: no such parameter; allowed {self._unknown_hint()}"
                )
        frozen = [p.name for p in params if p.name not in self._runtime and p.name not in ROS_OWN_PARAMETERS]
        if frozen:
            return params, SetParametersResult(
                successful=False, reason=f"{', '.join(frozen)}: {self.FROZEN_REASON}"
            )
        live = [cls for cls in self.PARAMETER_SETS if cls.has_runtime()]
        current = [self._sets[cls] for cls in live]
        _, error = validate_changes(current, params)
        if error:
            return params, SetParametersResult(successful=False, reason=error)
        specs = {s.name: s for cls in live for s in cls.specs()}
        return [
            Parameter(p.name, value=ros_value(specs[p.name], p.value)) if p.name in specs else p
            for p in params
        ], None

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Apply a change that passed :meth:`_pac_check` and rclpy's descriptors."""
        _, refusal = self._pac_check(params)
        if refusal is not None:
            return refusal
        live = [cls for cls in self.PARAMETER_SETS if cls.has_runtime()]
        current = [self._sets[cls] for cls in live]
        updated, error = validate_changes(current, params)
        if error:
            return SetParametersResult(successful=False, reason=error)
        changed = {cls: new for cls, old, new in zip(live, current, updated, strict=True) if new != old}
        if changed:
            if self.configured:
                try:
                    self.apply_parameters(changed)
                except ParameterError as exc:  # valid values the node cannot apply (a law file edited since)
                    return SetParametersResult(successful=False, reason=str(exc))
            self._sets.update(changed)
        return SetParametersResult(successful=True)

    # -- start-up: say what the node waits for, give up after start_timeout -------------------------
    #: Seconds between two "still waiting for ..." lines.
    WAIT_REPORT_PERIOD = 5.0

    @property
    def waits_for_recorder(self) -> bool:
        """``wait_for_recorder`` (NodeOptions; False for a node without them): the loop starts only
        once a recorder is subscribed to this node's outputs too."""
        return self.node_options is not None and self.node_options.wait_for_recorder

    def readers_missing(self, publisher: Any, topic: str, peer: str) -> list[str]:
        """What ``publisher`` still waits for: its ``peer`` reader and, with wait_for_recorder, a
        recorder; one line naming them (empty: both there)."""
        recorder = int(self.waits_for_recorder)
        readers = publisher.get_subscription_count()
        if readers >= 1 + recorder:
            return []
        who = f"{peer} and a recorder (wait_for_recorder)" if recorder else peer
        return [f"{who} subscribed to {topic} ({readers} of {1 + recorder})"]

    def watch_start(self, missing: Callable[[], list[str]]) -> None:
        """Until ``missing()`` is empty: say what is missing every WAIT_REPORT_PERIOD s, and after
        ``start_timeout`` s (NodeOptions; 0: never) stop with exit status 1 and one error line.

        ``missing()`` names each absent peer, e.g. "a recorder subscribed to measurement".
        """
        state = {"reported": time.monotonic(), "started": time.monotonic()}

        def check() -> None:
            now = time.monotonic()
            if not self.active:  # a managed node waits for its activation, not for its peers
                state["started"] = state["reported"] = now
                return
            absent = missing()
            if not absent:
                self.destroy_timer(timer)
                return
            limit = self.node_options.start_timeout if self.node_options is not None else 0.0
            waited = now - state["started"]
            if limit > 0 and waited >= limit:
                self.get_logger().error(
                    f"gave up after {waited:.0f} s waiting for {'; '.join(absent)} "
                    f"(start_timeout {limit:g} s; is it running, in ROS_DOMAIN_ID "
                    f"{os.environ.get('ROS_DOMAIN_ID', '0')}?)"
                )
                self.exit_status, self.finished = 1, True
                self.destroy_timer(timer)
            elif now - state["reported"] >= self.WAIT_REPORT_PERIOD:
                state["reported"] = now
                self.get_logger().info(f"waiting {waited:.0f} s for {'; '.join(absent)}")

        timer = self.create_timer(0.25, check)

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

    def past_run_end(self, tick: int) -> bool:
        """``tick`` comes after the ended run's last tick: nothing to answer (idle until a new run,
        which starts again at tick 0)."""
        return self.run_last_tick is not None and tick > self.run_last_tick

    def _on_run_status(self, msg: Any) -> None:
        self._check_line(msg)
        if msg.state == messages.RUN_ENDED:
            self.run_last_tick, self._run_ended_wall = int(msg.tick), time.monotonic()
            self.get_logger().info(f"the plant's run ended at tick {msg.tick}: idle until a new run")
            self.on_run_end()
            self.handled_tick(self._last_handled_tick)  # the last tick may have come first
        elif self.run_last_tick is not None:
            self.run_new()

    def _check_line(self, msg: Any) -> None:
        """Warn (once per line) when the plant's span length is not the one this node assumes."""
        span = float(getattr(msg, "span_length", 0.0))
        mine = [p.span_length for p in self._sets.values() if hasattr(p, "span_length")]
        line = (str(getattr(msg, "catenary_model", "")), span)
        if span <= 0.0 or not mine or line == getattr(self, "_line_checked", None):
            return
        self._line_checked = line
        if abs(mine[0] - span) > 1e-9 * span:
            self.get_logger().warning(
                f"the plant runs the {line[0]} line with {span:g} m spans but this node assumes "
                f"span_length {mine[0]:g} m: its model of k(t) is off (set -p span_length:={span:g})"
            )

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
        plant's exit (seen under load).
        """
        unacknowledged(list(self.publishers), timeout)

    def close(self) -> None:
        """Make the node's results final; the base reports the last status and waits for
        acknowledgements of what it sent."""
        self.health.final_report()
        self.wait_for_acknowledgements()
