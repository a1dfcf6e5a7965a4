"""The source of ``law_dispatch``: the compiled laws' dispatch, written from the law registry.

numba reaches a compiled function by its name, not through a table of values it could cache, so
the controller's step calls each of pac's compiled laws in one branch per law on the record's
code (``CONTROLLER_PARAMS.law``). Those branches, the imports and the codes (the registry's
order) are written from ``laws.LAWS`` by :func:`dispatch_source`; none of it is kept by hand.
A kernel law joins with its module of four functions (``kernel_common``) and one registry line
naming it (``LawEntry.kernel``); then::

    python -m pac_controller.law_dispatch_source --write

(``tests/test_law_dispatch.py`` fails while ``law_dispatch.py`` is not what the registry gives).
A law of the file protocol (``user_law``) needs none of this: its chain is a closure.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

#: The four functions of a kernel law (``<law>_<function>``) and their arguments, in the chain's order.
FUNCTIONS = {
    "restart": "p, s, table, memory, has_u, u_applied",
    "output": "p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured",
    "mode": "p, s",
    "commit": "p, s, table, memory, tick, u_applied",
}
#: What a branch of each function does with the law's call, and what an unknown code gives: the
#: output NaN (the safety chain answers it with the fallback), the others nothing / active.
_RETURNS = {"restart": False, "output": True, "mode": True, "commit": False}
_UNKNOWN = {"output": "    return math.nan, 0.0, 0.0, 0.0\n", "mode": "    return ACTIVE\n"}
_DOCS = {
    "restart": "Forget the law's state; its next output continues from ``u_applied`` (has_u False: at rest).",
    "output": "The unlimited force u_law of ``tick`` and three law-specific errors (remembered for commit).",
    "mode": "The mode code of the law's command (kernel_common.ACTIVE or PASSIVE).",
    "commit": "The limited force actually commanded for ``tick``: the law's state follows it.",
}
LINE_LENGTH = 110  # ruff.toml's: the written file is formatted as ruff would format it

HEADER = '''"""The compiled laws' dispatch: generated from ``pac_controller.laws.LAWS`` by
``python -m pac_controller.law_dispatch_source --write``. Do not edit.

One branch per kernel law on the record's code (``CONTROLLER_PARAMS.law``), calling the four
functions of its module (``kernel_common``). An unknown code gives a NaN output, which the safety
chain answers with the fallback.
"""

from __future__ import annotations

import math

from numba import njit

'''


def kernel_laws(laws: Mapping[str, Any]) -> dict[str, str]:
    """Law name -> its kernel module, for the registry's kernel laws in its order (their codes)."""
    return {name: entry.kernel for name, entry in laws.items() if getattr(entry, "kernel", None)}


def check_kernel(name: str, module: str) -> None:
    """ValueError in one line unless ``module`` imports and has the law's four functions."""
    try:
        found = importlib.import_module(module)
    except ImportError as exc:
        raise ValueError(f"law {name!r}: its kernel module {module!r} does not import ({exc})") from exc
    missing = [f"{name}_{fn}" for fn in FUNCTIONS if not callable(getattr(found, f"{name}_{fn}", None))]
    if missing:
        raise ValueError(f"law {name!r}: its kernel module {module!r} lacks {', '.join(missing)}")


def _call(indent: str, head: str, args: str) -> str:
    """``head(args)`` at ``indent``, on one line if it fits, else as ruff splits a call."""
    line = f"{indent}{head}({args})"
    if len(line) <= LINE_LENGTH:
        return line + "\n"
    return f"{indent}{head}(\n{indent}    {args}\n{indent})\n"


def _import(package: str, names: list[str]) -> str:
    """``from package import names``, on one line if it fits, else one name per line (ruff's)."""
    line = f"from {package} import {', '.join(names)}"
    if len(line) <= LINE_LENGTH:
        return line + "\n"
    return f"from {package} import (\n" + "".join(f"    {name},\n" for name in names) + ")\n"


def dispatch_source(laws: Mapping[str, Any]) -> str:
    """The text of ``law_dispatch.py`` for the registry ``laws``."""
    kernels = kernel_laws(laws)
    for name, module in kernels.items():
        check_kernel(name, module)
    imports: dict[str, set[str]] = {"pac_controller.kernel_common": {"ACTIVE"}}
    for module in kernels.values():
        package, _, leaf = module.rpartition(".")
        imports.setdefault(package, set()).add(leaf)
    out = [HEADER]
    for package in sorted(imports):
        out.append(_import(package, sorted(imports[package])))
    out.append("\n#: Law name -> the code the compiled functions dispatch on (the registry's order).\n")
    out.append("LAW_CODES = {\n")
    out.extend(f'    "{name}": {code},\n' for code, name in enumerate(kernels))
    out.append("}\n")
    for fn, args in FUNCTIONS.items():
        out.append('\n\n@njit(cache=True, error_model="numpy")\n')
        out.append(_call("", f"def law_{fn}", args)[:-1] + ":\n")
        out.append(f'    """{_DOCS[fn]}"""\n')
        out.append("    law = p.law\n")
        for code, (name, module) in enumerate(kernels.items()):
            out.append(f"    {'if' if code == 0 else 'elif'} law == {code}:\n")
            head = f"{'return ' if _RETURNS[fn] else ''}{module.rpartition('.')[2]}.{name}_{fn}"
            out.append(_call("        ", head, args))
        out.append(_UNKNOWN.get(fn, ""))
    return "".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m pac_controller.law_dispatch_source",
        description="Write (or check) law_dispatch.py from the law registry.",
    )
    parser.add_argument("--write", action="store_true", help="write the file beside this module")
    args = parser.parse_args(argv)
    from pac_controller import laws  # here: the registry imports the dispatch it is read for

    text = dispatch_source(laws.LAWS)
    target = Path(__file__).with_name("law_dispatch.py")
    if args.write:
        target.write_text(text)
        print(f"wrote {target}")
        return 0
    if target.read_text() != text:
        print(f"{target} is not what the registry gives: run with --write", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
