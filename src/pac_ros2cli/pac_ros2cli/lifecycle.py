"""``ros2 lifecycle nodes | get [<node>] | list <node> | set <node> <transition>`` (as ros2cli).

Over the lifecycle services of managed nodes (pac nodes started with ``-p lifecycle:=true``);
the requests themselves are :mod:`pac_common.lifecycle`'s, which a user's manager can call too.
"""

from __future__ import annotations

from typing import Any

from .common import fail, parser
from .graph import FIND_TIME, SPIN_TIME, Graph


def _executor(graph: Graph) -> Any:
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor()
    executor.add_node(graph.node)
    return executor


def _managed(graph: Graph, target: str | None) -> list[str]:
    """The managed nodes once discovery settled (a named one: as soon as it shows up)."""
    from pac_common.lifecycle import managed_nodes

    if target is None:
        return graph.settled(lambda: managed_nodes(graph.node), SPIN_TIME)
    graph.wait(lambda: target in managed_nodes(graph.node), FIND_TIME)
    names = managed_nodes(graph.node)
    if target not in names:
        fail(f"node '{target}' is not a managed node here (ros2 lifecycle nodes lists them)")
    return names


def _call(action: Any) -> Any:
    from pac_common.lifecycle import LifecycleError

    try:
        return action()
    except LifecycleError as exc:
        fail(str(exc))


def lifecycle_nodes(args: list[str]) -> int:
    parser("lifecycle nodes").parse_args(args)
    with Graph() as graph:
        names = _managed(graph, None)
    if names:
        print("\n".join(names))
    return 0


def lifecycle_get(args: list[str]) -> int:
    from pac_common.lifecycle import get_state

    p = parser("lifecycle get")
    p.add_argument("node_name", nargs="?", help="default: every managed node")
    a = p.parse_args(args)
    target = "/" + a.node_name.strip("/") if a.node_name else None
    with Graph() as graph:
        names = _managed(graph, target)
        executor = _executor(graph)
        for name in [target] if target else names:
            state = _call(lambda n=name: get_state(graph.node, executor, n))
            print(state if target else f"{name}: {state}")
        executor.shutdown(timeout_sec=1.0)
    return 0


def lifecycle_list(args: list[str]) -> int:
    from pac_common.lifecycle import available_transitions

    p = parser("lifecycle list")
    p.add_argument("node_name")
    a = p.parse_args(args)
    target = "/" + a.node_name.strip("/")
    with Graph() as graph:
        _managed(graph, target)
        executor = _executor(graph)
        transitions = _call(lambda: available_transitions(graph.node, executor, target))
        executor.shutdown(timeout_sec=1.0)
    for label, ident, start, goal in transitions:
        print(f"- {label} [{ident}]\n\tStart: {start}\n\tGoal: {goal}")
    return 0


def lifecycle_set(args: list[str]) -> int:
    from pac_common.lifecycle import TRANSITIONS, change_state

    p = parser("lifecycle set")
    p.add_argument("node_name")
    p.add_argument("transition", help="one of " + ", ".join(TRANSITIONS))
    a = p.parse_args(args)
    target = "/" + a.node_name.strip("/")
    with Graph() as graph:
        _managed(graph, target)
        executor = _executor(graph)
        _call(lambda: change_state(graph.node, executor, target, a.transition))
        executor.shutdown(timeout_sec=1.0)
    print("Transitioning successful")
    return 0
