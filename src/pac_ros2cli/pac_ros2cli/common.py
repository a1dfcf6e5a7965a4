"""What every verb shares: one-line errors, the ament index, argument parsing, YAML output."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from typing import Any, NoReturn


class CliError(Exception):
    """A verb cannot do what it was asked: one line on stderr and ``code`` as exit status."""

    def __init__(self, message: str, code: int = 1) -> None:
        super().__init__(message)
        self.code = code


def fail(message: str, code: int = 1) -> NoReturn:
    raise CliError(message, code)


def index() -> Any:
    try:
        import ament_index_python
    except ImportError:
        fail("ament_index_python not importable: source env.sh (repo root) first")
    return ament_index_python


def package_prefix(pkg: str) -> str:
    aip = index()
    try:
        return aip.get_package_prefix(pkg)
    except aip.PackageNotFoundError:
        fail(f"package '{pkg}' not found (is install/ built and env.sh sourced?)")


def executables(pkg: str) -> list[str]:
    libdir = os.path.join(package_prefix(pkg), "lib", pkg)
    if not os.path.isdir(libdir):
        return []
    return sorted(
        name
        for name in os.listdir(libdir)
        if os.path.isfile(os.path.join(libdir, name)) and os.access(os.path.join(libdir, name), os.X_OK)
    )


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, exit 2 (argparse would add the usage first)
        self.exit(2, f"{self.prog}: {message} (-h for usage)\n")


def parser(prog: str) -> argparse.ArgumentParser:
    return _Parser(prog=f"ros2 {prog}")


def join_name(ns: str, name: str) -> str:
    return (ns.rstrip("/") or "") + "/" + name


def topic_name(name: str) -> str:
    """Relative names resolve against the root namespace, as for a node started without one."""
    return name if name.startswith("/") else "/" + name


def split_type(typename: str) -> tuple[str, str, str]:
    """``pkg/msg/Name`` (or ``pkg/Name``) -> (pkg, kind, Name); exit 2 when malformed."""
    parts = typename.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or not all(parts):
        fail(f"invalid type '{typename}': expected <package>/msg/<Name>", 2)
    return parts[0], parts[1], parts[2]


def message_class(typename: str) -> Any:
    """``pkg/msg/Name`` (or ``pkg/Name``) -> the generated Python class."""
    pkg, kind, name = split_type(typename)
    try:
        return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
    except (ImportError, AttributeError):
        fail(f"type '{typename}' not found (is install/ built and env.sh sourced?)")


def plain(value: Any) -> Any:
    """A message as nested dicts/lists of Python scalars, in field order (as ros2cli prints it)."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if hasattr(value, "tolist"):  # numpy arrays and scalars, array.array
        return value.tolist()
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, bytes) and len(value) == 1:  # a `byte` field (DiagnosticStatus.level)
        return value[0]
    if isinstance(value, bytes | bytearray):
        return list(value)
    return value


def flat(value: Any) -> list:
    if isinstance(value, dict):
        return [x for v in value.values() for x in flat(v)]
    if isinstance(value, list):
        return [x for v in value for x in flat(v)]
    return [value]


def to_yaml(data: Any) -> str:
    import yaml

    return yaml.dump(data, allow_unicode=True, width=sys.maxsize, default_flow_style=False, sort_keys=False)
