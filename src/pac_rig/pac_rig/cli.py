"""Command-line parameter overrides shared by every offline tool: ``-p name:=value`` and ``--params-file``.

The syntax is the one ``ros2 run ... --ros-args -p name:=value`` uses; a params file may be
flat (``name: value``) or a ROS 2 parameter file (``/**: {ros__parameters: {...}}``), so the
node defaults shipped in ``share/<pkg>/config/`` work here too. A ROS 2 parameter file is read
as the rig's nodes read it: the ``/**`` sections and those naming one of the rig's nodes
(``/plant_node``, ...), nothing else. Files and values go through the suite's reading
discipline (``pac_common.files``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from pac_common.command_line import ROS_OWN_PARAMETERS, ParamsFile, UsageError
from pac_common.files import FileInputError, excerpt, load_yaml, read_yaml

from .nodes import LOOP_NODES, NODES

#: The nodes an offline tool stands for: a params-file section for any other node is not its.
RIG_NODE_NAMES = tuple(f"/{NODES[role].executable}" for role in ("recorder", *LOOP_NODES))


class OverrideError(ValueError):
    """An override or a params file that cannot be read; the message is one line."""


def add_override_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "-p", "--param", action="append", default=[], metavar="NAME:=VALUE", help="parameter override"
    )
    parser.add_argument(
        "--params-file",
        type=Path,
        action="append",
        default=[],
        help="YAML of name: value pairs (flat, or a ROS 2 parameter file such as a `ros2 param dump`); "
        "may be repeated, later files win",
    )


def without_ros_args(argv: list[str]) -> list[str]:
    """``--ros-args -p a:=1 --params-file f --`` as a node takes it -> the same options here.

    ``--param`` is ``-p``; the ``--ros-args`` and ``--`` markers themselves carry nothing offline.
    """
    return [a for a in argv if a not in ("--ros-args", "--")]


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``name:=value`` (as ros2 -p) or ``name=value``; values parsed as YAML."""
    out = {}
    for item in items:
        name, sep, value = item.partition(":=") if ":=" in item else item.partition("=")
        if not sep or not name.strip():
            raise OverrideError(f"override {excerpt(item)} is not name:=value")
        try:
            out[name.strip()] = load_yaml(value, f"override {excerpt(item)}")
        except FileInputError as exc:
            raise OverrideError(str(exc)) from None
    return out


def load_params_file(path: Path) -> dict[str, Any]:
    """Flat ``name: value`` pairs from a YAML file; of a ROS 2 parameter file, what the rig's
    nodes take (its ``/**`` sections and their own)."""
    try:
        data = read_yaml(path, "params")
    except FileInputError as exc:
        raise OverrideError(str(exc)) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise OverrideError(f"params file {excerpt(str(path))} must be a mapping of name: value")
    sections = {k: v for k, v in data.items() if isinstance(v, dict) and "ros__parameters" in v}
    try:
        ros = ParamsFile.parse(str(path), sections).for_nodes(RIG_NODE_NAMES) if sections else {}
    except UsageError as exc:
        raise OverrideError(str(exc)) from None
    out = {k: v for k, v in data.items() if k not in sections}
    out.update(ros)
    for name in ROS_OWN_PARAMETERS:  # in every `ros2 param dump`; nothing to do offline
        out.pop(name, None)
    return out


def overrides_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """The params file (if any), then the ``-p`` overrides on top."""
    values: dict[str, Any] = {}
    for path in args.params_file:
        values.update(load_params_file(path))
    values.update(parse_overrides(args.param))
    return values
