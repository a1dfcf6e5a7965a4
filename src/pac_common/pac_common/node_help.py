"""``--help`` of a node executable: usage, what it does, every parameter with range and default."""

from __future__ import annotations

import inspect
from typing import Any


def node_help(program: str, node_class: Any) -> str:
    """The text ``<node> --help`` prints (``node_class``: a PacNode subclass)."""
    module = inspect.getmodule(node_class)
    summary = (module.__doc__ or "").strip() if module is not None else ""
    lines = [
        f"usage: {program} [--help] [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] [-r ...]]",
        "",
        summary,
        "",
        "parameters (* may be changed at run time with `ros2 param set`; the others are read only):",
    ]
    for cls in node_class.PARAMETER_SETS:
        for spec in cls.specs():
            unit = f" [{spec.unit}]" if spec.unit else ""
            mark = "*" if spec.runtime else " "
            default = list(spec.default) if isinstance(spec.default, tuple) else spec.default
            lines.append(f"  {mark}{spec.name} (default {default!r}; {spec.allowed()}){unit}")
            lines.append(f"      {spec.description}")
    lines += [
        "",
        "params files (--params-file) follow ROS: this node takes the '/**:' section and its own",
        "('<node name>:'); keys for other nodes are ignored, a key no pac node has is refused.",
    ]
    return "\n".join(lines)


def print_help(text: str) -> None:
    """Print ``text``; a reader that stops early (``--help | head``) is not an error."""
    import os
    import sys

    try:
        print(text, flush=True)
    except BrokenPipeError:
        # Python would report the broken pipe again when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
