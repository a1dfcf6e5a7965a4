"""A node process's command line and environment, checked before rclpy sees them.

rcl refuses a bad command line with a traceback, and ignores what it does not understand:
these checks turn both into one line naming the problem (exit status 2 in the caller).
Params files follow ROS's rules (:class:`ParamsFile`): a node takes the ``/**`` section and
its own; sections for other nodes are not errors.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

#: Fast DDS maps a domain id to UDP ports 7400 + 250 * id + ...: above 232 they pass 65535.
MAX_DOMAIN_ID = 232
#: Parameters rclpy declares on every node (a `ros2 param dump` holds them): always accepted.
ROS_OWN_PARAMETERS = frozenset({"use_sim_time", "start_type_description_service"})


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


@dataclass(frozen=True)
class ParamsFile:
    """A ROS 2 parameter file: node-name patterns -> flat parameter names -> values."""

    path: str
    sections: dict[str, dict[str, Any]]

    @classmethod
    def read(cls, path: str) -> ParamsFile:
        """Parse ``path`` by the suite's reading discipline (``pac_common.files``): a regular file
        of at most 256 KiB, UTF-8, YAML without aliases or keys given twice; :class:`UsageError`
        (one line) when it is missing or not a params file."""
        from .files import FileInputError, read_yaml

        try:
            data = read_yaml(path, "params")
        except FileInputError as exc:
            raise UsageError(str(exc)) from None
        return cls.parse(path, data)

    @classmethod
    def parse(cls, path: str, data: Any) -> ParamsFile:
        """The params file ``path`` from its parsed YAML ``data``."""
        sections = data.values() if isinstance(data, dict) else []
        if not isinstance(data, dict) or not all(
            isinstance(v, dict) and isinstance(v.get("ros__parameters"), dict) for v in sections
        ):
            raise UsageError(
                f"params file {path} is not a ROS 2 parameter file "
                "(expected '/**:' or '<node>:' sections with 'ros__parameters:')"
            )
        return cls(path, {str(k): _flatten(v["ros__parameters"]) for k, v in data.items()})

    def for_nodes(self, nodes: Sequence[str]) -> dict[str, Any]:
        """What the nodes ``nodes`` (fully qualified names) take together: the shared sections'
        keys, then each node's own; sections for other nodes are left out, as ROS does."""
        shared: dict[str, Any] = {}
        own: dict[str, Any] = {}
        for node in nodes:
            node_shared, node_own = self.for_node(node)
            shared.update(node_shared)
            own.update(node_own)
        return {**shared, **own}

    def for_node(self, node: str) -> tuple[dict[str, Any], dict[str, Any]]:
        """(keys from wildcard sections such as ``/**``, keys from sections naming ``node``).

        ``node`` is the node's fully qualified name (``/controller_node``); a later section
        wins, as in rcl.
        """
        shared: dict[str, Any] = {}
        own: dict[str, Any] = {}
        for pattern, values in self.sections.items():
            if section_matches(pattern, node):
                # "/**" and "/ns/*" are shared; "/**/controller_node" names this node.
                (shared if "*" in pattern.rsplit("/", 1)[-1] else own).update(values)
        return shared, own


def _flatten(values: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested keys are dotted parameter names, as rcl reads them."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, f"{name}."))
        else:
            out[name] = value
    return out


def section_matches(pattern: str, node: str) -> bool:
    """Whether a params-file section applies to the node ``node`` (fully qualified).

    rcl's rules: a leading ``/`` is optional, ``*`` stands for one name token, ``**`` for any
    number of namespace levels (``/**`` is every node).
    """
    text = pattern if pattern.startswith("/") else "/" + pattern
    regex = ""
    for part in re.split(r"(\*\*|\*)", text):
        regex += "(/[^/]+)*" if part == "**" else "[^/]*" if part == "*" else re.escape(part)
    regex = regex.replace("/(/[^/]+)*", "(/[^/]+)*")  # "/**" also matches no extra level
    return re.fullmatch(regex, node) is not None


@dataclass
class RosArguments:
    """What ``--ros-args`` gives: ``-p`` values (every node in the process) and params files."""

    parameters: dict[str, str] = field(default_factory=dict)
    params_files: list[ParamsFile] = field(default_factory=list)


def check_ros_arguments(argv: Sequence[str]) -> RosArguments:
    """Reject what rcl would refuse with a traceback, with one line naming the problem.

    ``argv`` is the program's arguments without the program name.  Outside ``--ros-args``
    nothing is accepted (``-p c1:=3`` there would otherwise be ignored silently).
    """
    out = RosArguments()
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
                out.params_files.append(ParamsFile.read(value))
            else:
                name, sep, text = value.partition(":=")
                if not sep or not name or not text:
                    raise UsageError(f"{arg} {value!r}: expected name:=value (e.g. -p c1:=30.0)")
                out.parameters[name] = text
            i += 1
        i += 1
    return out


#: The process's own ``--ros-args`` as :func:`run_nodes` checked them (nodes consult it to tell a
#: typo from a key meant for another node); parsed from ``sys.argv`` when nobody set it.
_process_arguments: RosArguments | None = None


def set_process_arguments(arguments: RosArguments) -> None:
    global _process_arguments
    _process_arguments = arguments


def process_arguments() -> RosArguments:
    if _process_arguments is None:
        import sys

        try:
            return check_ros_arguments(sys.argv[1:])
        except UsageError:
            return RosArguments()
    return _process_arguments


def pac_parameter_names() -> set[str]:
    """Every parameter name of every installed pac node (the generated share/pac_*/config files).

    Used to tell a typo in a shared ``/**`` section (no pac node has it: refused) from a key
    meant for another node (ignored, as ROS does). Empty when the index cannot be read.
    """
    import glob

    import yaml

    try:
        from ament_index_python.packages import get_packages_with_prefixes
    except ImportError:
        return set()
    names: set[str] = set()
    for package, prefix in get_packages_with_prefixes().items():
        if not package.startswith("pac_"):
            continue
        for path in glob.glob(os.path.join(prefix, "share", package, "config", "*.yaml")):
            # Files that make setup generated, of which only the keys are wanted: libyaml's loader
            # reads them in ~1/10 of the time of the checked one that a user's files get
            # (files.read_yaml).
            try:
                with open(path, encoding="utf-8") as stream:
                    data = yaml.load(stream, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader)) or {}
            except (OSError, UnicodeDecodeError, yaml.YAMLError):
                continue
            for section in data.values() if isinstance(data, dict) else ():
                if isinstance(section, dict) and isinstance(section.get("ros__parameters"), dict):
                    names |= set(section["ros__parameters"])
    return names
