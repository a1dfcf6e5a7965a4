"""Managed (lifecycle) start-up of pac nodes, and the client side a lifecycle manager uses.

With ``-p lifecycle:=true`` a loop node (plant, observer, controller) or the recorder starts
as a ROS 2 managed node (rclpy's lifecycle API, the ``lifecycle_msgs`` services
``<node>/get_state``, ``<node>/change_state``, ...): *unconfigured*, with its parameters
declared and checked and its ``/diagnostics`` reporting, nothing else.  *configure* builds
it (core, publishers, subscriptions, timers; the recorder creates its bag): *inactive*.
*activate* opens it: the plant starts its run once the loop is matched, as without
lifecycle (``wait_for_recorder`` and ``run_status`` keep working), the observer and
controller answer, the recorder subscribes and records.  *deactivate* closes the gate (the
plant stops taking ticks, the others stop answering, the recorder drops what arrives);
*cleanup* destroys what *configure* built (the recorder closes its bag): *unconfigured*
again; *shutdown* stops the process (exit 0).  A manager can configure all four nodes,
then activate them together: the plant waits for the others, so the order does not matter.

Without the parameter (the default) the node configures and activates itself at once,
with no lifecycle services: the plain node, unchanged.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetAvailableTransitions, GetState
from rclpy.lifecycle import LifecycleNodeMixin, LifecycleState, TransitionCallbackReturn

from .parameters import ParameterError, ParameterSet, parameter

if TYPE_CHECKING:  # what ManagedNode is mixed into (pac_common.pac_node.PacNode)
    from rclpy.node import Node as _Node
else:
    _Node = object


@dataclass(frozen=True)
class LifecycleOptions(ParameterSet):
    lifecycle: bool = parameter(
        False,
        "start as a managed node (unconfigured until a lifecycle manager configures and activates "
        "it: ros2 lifecycle set <node> configure|activate); false: configured and active at once",
    )


#: ``ros2 lifecycle set`` labels -> transition ids (as ros2cli accepts them).
TRANSITIONS = {
    "configure": Transition.TRANSITION_CONFIGURE,
    "cleanup": Transition.TRANSITION_CLEANUP,
    "activate": Transition.TRANSITION_ACTIVATE,
    "deactivate": Transition.TRANSITION_DEACTIVATE,
    "shutdown": Transition.TRANSITION_UNCONFIGURED_SHUTDOWN,
    "unconfigured_shutdown": Transition.TRANSITION_UNCONFIGURED_SHUTDOWN,
    "inactive_shutdown": Transition.TRANSITION_INACTIVE_SHUTDOWN,
    "active_shutdown": Transition.TRANSITION_ACTIVE_SHUTDOWN,
}


class ManagedNode(LifecycleNodeMixin, _Node):
    """The lifecycle half of :class:`pac_common.node.PacNode` (mixed in before ``rclpy.node.Node``).

    The node's body is its ``configure()`` method; ``active`` is the gate its loop callbacks
    check; ``configured`` says whether ``configure()`` ran (and ``close()`` has anything to do).
    """

    configured = False
    active = False
    managed = False

    def start_lifecycle(self, managed: bool) -> None:
        """Managed: wait, unconfigured, for a manager.  Plain: configure and activate now (a
        ParameterError propagates: the process exits 2 as before)."""
        self.managed = managed
        if managed:
            LifecycleNodeMixin.__init__(self, enable_communication_interface=True)
            self.get_logger().info("managed node: unconfigured (ros2 lifecycle set ... configure)")
        else:
            self._build()
            self.active = True

    @property
    def lifecycle_state(self) -> str:
        if self.managed:
            return str(self._state_machine.current_state[1])
        return "active" if self.active else "inactive" if self.configured else "unconfigured"

    def configure(self) -> None:
        """Hook: build the node (its body): core, publishers, subscriptions, timers."""

    def unconfigure(self) -> None:
        """Hook: undo what ``configure`` did beyond ROS entities (the recorder closes its bag)."""

    def _entities(self) -> set[Any]:
        return {*self.publishers, *self.subscriptions, *self.timers, *self.clients}

    def _build(self) -> None:
        before = self._entities()
        self.configure()
        self._built = self._entities() - before
        self.configured = True

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self._build()
        except ParameterError as exc:
            self.get_logger().error(f"configure failed: {exc}")
            return TransitionCallbackReturn.FAILURE
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = True
        self.on_active_changed()
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self.on_active_changed()
        return TransitionCallbackReturn.SUCCESS

    def on_active_changed(self) -> None:
        """Hook: the gate opened or closed (the plant re-bases its real-time schedule)."""

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.unconfigure()
        for entity in getattr(self, "_built", ()):
            self._destroy(entity)
        self._built = set()
        self.configured = False
        return TransitionCallbackReturn.SUCCESS

    def _destroy(self, entity: Any) -> None:
        for kind in ("publisher", "subscription", "timer", "client"):
            if entity in getattr(self, f"{kind}s"):
                getattr(self, f"destroy_{kind}")(entity)
                return

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        self.finished = True  # run_node's loop ends: close() makes the results final
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.active = False
        return TransitionCallbackReturn.SUCCESS


# -- the manager's side (``ros2 lifecycle``, tests, a user's own manager) ---------------------------


class LifecycleError(RuntimeError):
    """A lifecycle request that could not be made or was refused; the message is one line."""


def _call(node: Any, executor: Any, srv_type: Any, name: str, request: Any, timeout: float) -> Any:
    client = node.create_client(srv_type, name)
    try:
        deadline = time.monotonic() + timeout
        while not client.service_is_ready():
            if time.monotonic() > deadline:
                raise LifecycleError(f"{name}: no such service (not a managed node, or not running)")
            executor.spin_once(timeout_sec=0.05)
        future = client.call_async(request)
        while not future.done():
            if time.monotonic() > deadline:
                raise LifecycleError(f"{name}: no answer within {timeout:g} s")
            executor.spin_once(timeout_sec=0.05)
        return future.result()
    finally:
        node.destroy_client(client)


def _service(target: str, name: str) -> str:
    return "/" + target.strip("/") + "/" + name


def get_state(node: Any, executor: Any, target: str, timeout: float = 5.0) -> str:
    """The current state label of the managed node ``target`` (e.g. ``unconfigured``)."""
    response = _call(node, executor, GetState, _service(target, "get_state"), GetState.Request(), timeout)
    return str(response.current_state.label)


def available_transitions(
    node: Any, executor: Any, target: str, timeout: float = 5.0
) -> list[tuple[str, int, str, str]]:
    """(label, id, start state, goal state) of every transition ``target`` can take now."""
    response = _call(
        node,
        executor,
        GetAvailableTransitions,
        _service(target, "get_available_transitions"),
        GetAvailableTransitions.Request(),
        timeout,
    )
    return [
        (t.transition.label, int(t.transition.id), t.start_state.label, t.goal_state.label)
        for t in response.available_transitions
    ]


def change_state(node: Any, executor: Any, target: str, transition: str, timeout: float = 10.0) -> str:
    """Trigger ``transition`` (a label of :data:`TRANSITIONS`) on ``target``; its new state label.

    ``shutdown`` picks the shutdown transition of the node's current state."""
    if transition not in TRANSITIONS:
        raise LifecycleError(f"unknown transition '{transition}': allowed {', '.join(TRANSITIONS)}")
    if transition == "shutdown":
        current = get_state(node, executor, target, timeout)
        transition = f"{current}_shutdown" if f"{current}_shutdown" in TRANSITIONS else transition
    request = ChangeState.Request()
    request.transition.id = TRANSITIONS[transition]
    response = _call(node, executor, ChangeState, _service(target, "change_state"), request, timeout)
    if not response.success:
        raise LifecycleError(f"{target}: transition '{transition}' refused or failed")
    try:
        return get_state(node, executor, target, timeout)
    except LifecycleError:
        return "finalized"  # a shut-down node is gone before it can be asked


def managed_nodes(node: Any) -> list[str]:
    """Fully qualified names of the nodes in the graph that offer lifecycle services."""
    names = []
    for name, namespace in node.get_node_names_and_namespaces():
        full = (namespace.rstrip("/") + "/" + name) if namespace != "/" else "/" + name
        if any(
            s == full + "/get_state" for s, _ in node.get_service_names_and_types_by_node(name, namespace)
        ):
            names.append(full)
    return sorted(names)


def bring_up(node: Any, executor: Any, targets: Iterable[str], timeout: float = 30.0) -> None:
    """What a lifecycle manager does: configure every target, then activate every target."""
    targets = list(targets)
    for transition in ("configure", "activate"):
        for target in targets:
            change_state(node, executor, target, transition, timeout)
