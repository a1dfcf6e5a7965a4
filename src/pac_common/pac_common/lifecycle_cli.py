"""``ros2 lifecycle nodes | get [<node>] | list <node> | set <node> <transition>`` (as ros2cli).

The ``lifecycle`` verb of the ``ros2`` stand-in (scripts/bin/ros2), over the lifecycle
services of managed nodes (pac nodes started with ``-p lifecycle:=true``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from .lifecycle import (
    TRANSITIONS,
    LifecycleError,
    available_transitions,
    change_state,
    get_state,
    managed_nodes,
)

#: Discovery of the graph's managed nodes: at least this long, as `ros2 node list` waits [s].
DISCOVERY = 1.5


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        self.exit(2, f"{self.prog}: {message} (-h for usage)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="ros2 lifecycle", description=__doc__)
    sub = parser.add_subparsers(dest="verb", required=True)
    sub.add_parser("nodes", help="list the managed nodes")
    get = sub.add_parser("get", help="the current state of a managed node (or of every one)")
    get.add_argument("node_name", nargs="?")
    listing = sub.add_parser("list", help="the transitions a managed node can take now")
    listing.add_argument("node_name")
    setting = sub.add_parser("set", help="trigger a transition")
    setting.add_argument("node_name")
    setting.add_argument("transition", help="one of " + ", ".join(TRANSITIONS))
    return parser


def _discovered(node, executor, wanted: str | None) -> list[str]:
    """Managed nodes after discovery (returns early once ``wanted`` is seen)."""
    deadline = time.monotonic() + DISCOVERY
    names = managed_nodes(node)
    while time.monotonic() < deadline and (wanted is None or wanted not in names):
        executor.spin_once(timeout_sec=0.05)
        names = managed_nodes(node)
    return names


def main(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    rclpy.init()
    node = rclpy.create_node(f"_ros2cli_lifecycle_{os.getpid()}", start_parameter_services=False)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    target = "/" + args.node_name.strip("/") if getattr(args, "node_name", None) else None
    try:
        if args.verb == "nodes":
            for name in _discovered(node, executor, None):
                print(name)
            return 0
        names = _discovered(node, executor, target)
        if target is not None and target not in names:
            print(f"ros2: node '{target}' is not a managed node here (ros2 lifecycle nodes)", file=sys.stderr)
            return 1
        if args.verb == "get":
            for name in [target] if target else names:
                state = get_state(node, executor, name)
                print(f"{name}: {state}" if target is None else state)
        elif args.verb == "list":
            for label, ident, start, goal in available_transitions(node, executor, target):
                print(f"- {label} [{ident}]\n\tStart: {start}\n\tGoal: {goal}")
        else:
            change_state(node, executor, target, args.transition)
            print("Transitioning successful")
        return 0
    except LifecycleError as exc:
        print(f"ros2: {exc}", file=sys.stderr)
        return 1
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
