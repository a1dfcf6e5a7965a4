"""Command-line parameter overrides shared by every offline tool: ``-p name:=value`` and ``--params-file``.

The syntax is the one ``ros2 run ... --ros-args -p name:=value`` uses; a params file may be
flat (``name: value``) or a ROS 2 parameter file (``/**: {ros__parameters: {...}}``), so the
node defaults shipped in ``share/<pkg>/config/`` work here too.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import yaml

from pac_common.command_line import ROS_OWN_PARAMETERS


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
            raise OverrideError(f"override '{item}' is not name:=value")
        try:
            out[name.strip()] = yaml.safe_load(value)
        except yaml.YAMLError as exc:
            raise OverrideError(f"override '{item}': value is not YAML ({_first_line(exc)})") from None
    return out


def load_params_file(path: Path) -> dict[str, Any]:
    """Flat ``name: value`` pairs from a YAML file (a ROS 2 parameter file is flattened)."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise OverrideError(f"cannot read params file {path}: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise OverrideError(f"params file {path} is not valid YAML ({_first_line(exc)})") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise OverrideError(f"params file {path} must be a mapping of name: value")
    out: dict[str, Any] = {}
    for key, value in data.items():
        if isinstance(value, dict) and isinstance(value.get("ros__parameters"), dict):
            out.update(value["ros__parameters"])  # /**: or /node_name: sections, in file order
        else:
            out[key] = value
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


def _first_line(exc: Exception) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
