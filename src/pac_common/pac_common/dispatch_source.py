"""The text of a generated dispatch module: one branch per variant on a record's code.

numba reaches a compiled function by its name, not through a table of values it could cache, so
a compiled step that serves every variant of a kind (a law, an observer) calls each one in a
branch on the code its record carries. Those branches, their imports and the codes (the
registry's order) are written from the registry by :func:`dispatch_source`, never by hand: each
kind has a small module that gives its registry and protocol and writes or checks its file
(``pac_controller.law_dispatch_source``, ``pac_observer.observer_dispatch_source``).

A variant ``name`` provides, in its module, one compiled function ``<name>_<suffix>`` for each
:class:`Dispatched` function of its kind; :func:`check_variant` refuses a module without them.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

LINE_LENGTH = 110  # ruff.toml's: the written file is formatted as ruff would format it


@dataclass(frozen=True)
class Dispatched:
    """One function of the generated module: ``<prefix>_<suffix>(args)`` calls the code's
    ``<variant>_<suffix>(args)``; ``unknown``: the statement for a code no variant has."""

    suffix: str
    args: str
    returns: bool
    doc: str
    unknown: str = ""


def check_variant(kind: str, name: str, module: str, suffixes: Sequence[str]) -> None:
    """ValueError in one line unless ``module`` imports and has ``<name>_<suffix>`` for each suffix."""
    try:
        found = importlib.import_module(module)
    except ImportError as exc:
        raise ValueError(f"{kind} {name!r}: its kernel module {module!r} does not import ({exc})") from exc
    missing = [f"{name}_{s}" for s in suffixes if not callable(getattr(found, f"{name}_{s}", None))]
    if missing:
        raise ValueError(f"{kind} {name!r}: its kernel module {module!r} lacks {', '.join(missing)}")


def _call(indent: str, head: str, args: str) -> str:
    """``head(args)`` at ``indent``, on one line if it fits, else as ruff splits a call."""
    line = f"{indent}{head}({args})"
    if len(line) <= LINE_LENGTH:
        return line + "\n"
    return f"{indent}{head}(\n{indent}    {args}\n{indent})\n"


def _import(package: str, names: Sequence[str]) -> str:
    """``from package import names``, on one line if it fits, else one name per line (ruff's)."""
    line = f"from {package} import {', '.join(names)}"
    if len(line) <= LINE_LENGTH:
        return line + "\n"
    return f"from {package} import (\n" + "".join(f"    {name},\n" for name in names) + ")\n"


def dispatch_source(
    *,
    kind: str,
    docstring: str,
    variants: Mapping[str, str],
    code: str,
    codes_name: str,
    prefix: str,
    functions: Sequence[Dispatched],
    imports: Mapping[str, Sequence[str]] | None = None,
    stdlib: Sequence[str] = (),
) -> str:
    """The module: ``docstring``, imports, ``codes_name`` (variant -> code, in ``variants``' order)
    and one njit function ``<prefix>_<suffix>`` per :class:`Dispatched`, branching on ``code``
    (the record's field, e.g. ``p.law``) over ``variants`` (name -> kernel module)."""
    for name, module in variants.items():
        check_variant(kind, name, module, [f.suffix for f in functions])
    wanted: dict[str, set[str]] = {package: set(names) for package, names in (imports or {}).items()}
    for module in variants.values():
        package, _, leaf = module.rpartition(".")
        wanted.setdefault(package, set()).add(leaf)
    out = [f'"""{docstring}"""\n\nfrom __future__ import annotations\n\n']
    out.extend(f"import {name}\n" for name in sorted(stdlib))
    out.append("\n" if stdlib else "")
    out.append("from numba import njit\n\n")
    out.extend(_import(package, sorted(wanted[package])) for package in sorted(wanted))
    what = f"{kind.capitalize()} name -> the code the compiled functions dispatch on"
    out.append(f"\n#: {what} (the registry's order).\n")
    out.append(f"{codes_name} = {{\n")
    out.extend(f'    "{name}": {number},\n' for number, name in enumerate(variants))
    out.append("}\n")
    field = code.rpartition(".")[2]
    for f in functions:
        out.append('\n\n@njit(cache=True, error_model="numpy")\n')
        out.append(_call("", f"def {prefix}_{f.suffix}", f.args)[:-1] + ":\n")
        out.append(f'    """{f.doc}"""\n')
        out.append(f"    {field} = {code}\n")
        for number, (name, module) in enumerate(variants.items()):
            out.append(f"    {'if' if number == 0 else 'elif'} {field} == {number}:\n")
            head = f"{'return ' if f.returns else ''}{module.rpartition('.')[2]}.{name}_{f.suffix}"
            out.append(_call("        ", head, f.args))
        out.append(f.unknown)
    return "".join(out)


def main(
    module: str, source_file: str, target_name: str, text: Callable[[], str], argv: list[str] | None
) -> int:
    """The command line of a kind's source module ``module`` (``python -m module [--write]``):
    write ``target_name`` beside ``source_file`` from ``text()``, or check it (exit 1 and one line
    when it is not what the registry gives)."""
    prog = f"python -m {module}"
    parser = argparse.ArgumentParser(
        prog=prog, description=f"Write (or check) {target_name} from its registry."
    )
    parser.add_argument("--write", action="store_true", help="write the file beside this module")
    args = parser.parse_args(argv)
    target = Path(source_file).with_name(target_name)
    written = text()
    if args.write:
        target.write_text(written)
        print(f"wrote {target}")
        return 0
    if target.read_text() != written:
        print(f"{target} is not what the registry gives: run {prog} --write", file=sys.stderr)
        return 1
    return 0
