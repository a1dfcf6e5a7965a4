"""``ros2 param list | get | set | dump | describe`` through a node's parameter services."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from .common import fail, join_name, plain
from .graph import Graph

USAGE = "expected param list|dump <node>, get|describe <node> <name>... or set <node> <name> <value>"
#: rcl_interfaces/ParameterType -> the word ros2cli prints.
TYPE_NAMES = {
    0: "not set",
    1: "boolean",
    2: "integer",
    3: "double",
    4: "string",
    5: "byte array",
    6: "boolean array",
    7: "integer array",
    8: "double array",
    9: "string array",
}


class _Client:
    """A parameter client of one node, answering synchronously (bounded)."""

    def __init__(self, graph: Graph, node_name: str) -> None:
        from rclpy.parameter_client import AsyncParameterClient

        name, ns = graph.find_node(node_name)
        self.graph = graph
        self.full = join_name(ns, name)
        self.client = AsyncParameterClient(graph.node, self.full)
        if not self.client.wait_for_services(timeout_sec=5.0):
            fail(f"node '{self.full}' offers no parameter services")

    def call(self, future: Any) -> Any:
        import rclpy

        rclpy.spin_until_future_complete(self.graph.node, future, timeout_sec=10.0)
        if not future.done():
            fail("no answer from the node within 10 s")
        return future.result()

    def names(self) -> list[str]:
        return sorted(self.call(self.client.list_parameters()).result.names)


@contextmanager
def _client(node_name: str) -> Iterator[_Client]:
    with Graph() as graph:
        yield _Client(graph, node_name)


def _args(args: list[str], count: int | None) -> tuple[str, list[str]]:
    """(node, rest); ``count`` is how many arguments follow the node (None: one or more)."""
    if not args or (count is not None and len(args) != 1 + count) or (count is None and len(args) < 2):
        fail(USAGE, 2)
    return args[0], args[1:]


def param_list(args: list[str]) -> int:
    node, _ = _args(args, 0)
    with _client(node) as c:
        for n in c.names():
            print(f"  {n}")
    return 0


def dump_document(full_name: str, values: dict[str, Any]) -> dict:
    """The params-file layout of a node's values (dotted names nest), loadable with --params-file."""
    params: dict = {}
    for n, v in values.items():
        *groups, leaf = n.split(".")
        d = params
        for g in groups:
            d = d.setdefault(g, {})
        d[leaf] = v
    return {full_name: {"ros__parameters": params}}


def param_dump(args: list[str]) -> int:
    import yaml
    from rclpy.parameter import parameter_value_to_python

    node, _ = _args(args, 0)
    with _client(node) as c:
        names = c.names()
        values = c.call(c.client.get_parameters(names)).values
        document = dump_document(
            c.full, {n: plain(parameter_value_to_python(v)) for n, v in zip(names, values, strict=True)}
        )
    print(yaml.dump(document, default_flow_style=False, width=sys.maxsize), end="")
    return 0


def param_get(args: list[str]) -> int:
    from rclpy.parameter import parameter_value_to_python

    node, (name,) = _args(args, 1)
    with _client(node) as c:
        values = c.call(c.client.get_parameters([name])).values
        if not values or values[0].type == 0:
            fail(f"parameter '{name}' not set on '{c.full}'")
    print(parameter_value_to_python(values[0]))
    return 0


def param_set(args: list[str]) -> int:
    """The value is YAML, as in ros2cli; the node converts an integer for a double parameter."""
    from rclpy.parameter import Parameter

    from pac_common.files import FileInputError, load_yaml

    node, (name, text) = _args(args, 2)
    try:  # the one YAML loader: no aliases (an alias bomb is refused, not expanded)
        value = load_yaml(text, f"the value of {name}")
    except FileInputError as exc:
        fail(str(exc), 2)
    with _client(node) as c:
        result = c.call(c.client.set_parameters([Parameter(name, value=value)])).results[0]
    if not result.successful:
        fail(f"setting parameter failed: {result.reason}")
    print("Set parameter successful")
    return 0


def describe_text(descriptor: Any) -> str:
    """ros2cli's `param describe` block for one ``rcl_interfaces/ParameterDescriptor``."""
    kind = TYPE_NAMES.get(descriptor.type, descriptor.type)
    lines = [f"Parameter name: {descriptor.name}", f"  Type: {kind}"]
    if descriptor.description:
        lines.append(f"  Description: {descriptor.description}")
    if (
        descriptor.additional_constraints
        or descriptor.read_only
        or descriptor.floating_point_range
        or descriptor.integer_range
        or descriptor.dynamic_typing
    ):
        lines.append("  Constraints:")
        if descriptor.read_only:
            lines.append("    Read only: true")
        if descriptor.dynamic_typing:
            lines.append("    Dynamic typing: true")
        for rng in [*descriptor.floating_point_range, *descriptor.integer_range]:
            lines.append(f"    Min value: {rng.from_value}")
            lines.append(f"    Max value: {rng.to_value}")
            if rng.step:
                lines.append(f"    Step: {rng.step}")
        if descriptor.additional_constraints:
            lines.append(f"    Additional constraints: {descriptor.additional_constraints}")
    return "\n".join(lines)


def param_describe(args: list[str]) -> int:
    node, names = _args(args, None)
    with _client(node) as c:
        known = set(c.names())
        missing = [n for n in names if n not in known]
        if missing:
            fail(f"parameter '{missing[0]}' not declared on '{c.full}' (ros2 param list {c.full} shows them)")
        descriptors = c.call(c.client.describe_parameters(names)).descriptors
    print("\n".join(describe_text(d) for d in descriptors))
    return 0
