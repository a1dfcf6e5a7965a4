"""The source of ``law_dispatch``: the compiled laws' dispatch, written from the law registry.

The controller's step calls each of pac's compiled laws in one branch per law on the record's
code (``CONTROLLER_PARAMS.law``; ``pac_common.dispatch_source`` says why branches). The branches,
the imports and the codes (the registry's order) are written from ``laws.LAWS``; none of it is
kept by hand. A kernel law joins with its module of four functions (``kernel_common``) and one
registry line naming it (``LawEntry.kernel``); then::

    python -m pac_controller.law_dispatch_source --write

(``tests/test_law_dispatch.py`` fails while ``law_dispatch.py`` is not what the registry gives).
A law of the file protocol (``user_law``) needs none of this: its chain is a closure.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Any

from pac_common.dispatch_source import Dispatched, dispatch_source
from pac_common.dispatch_source import main as dispatch_main

#: The four functions of a kernel law (``<law>_<suffix>``), in the chain's order. An unknown code
#: gives a NaN output (the safety chain answers it with the fallback) and an active mode.
FUNCTIONS = (
    Dispatched(
        "restart",
        "p, s, table, memory, has_u, u_applied",
        False,
        "Forget the law's state; its next output continues from ``u_applied`` (has_u False: at rest).",
    ),
    Dispatched(
        "output",
        "p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured",
        True,
        "The unlimited force u_law of ``tick`` and three law-specific errors (remembered for commit).",
        "    return math.nan, 0.0, 0.0, 0.0\n",
    ),
    Dispatched(
        "mode",
        "p, s",
        True,
        "The mode code of the law's command (kernel_common.ACTIVE or PASSIVE).",
        "    return ACTIVE\n",
    ),
    Dispatched(
        "commit",
        "p, s, table, memory, tick, u_applied",
        False,
        "The limited force actually commanded for ``tick``: the law's state follows it.",
    ),
)

DOCSTRING = """The compiled laws' dispatch: generated from ``pac_controller.laws.LAWS`` by
``python -m pac_controller.law_dispatch_source --write``. Do not edit.

One branch per kernel law on the record's code (``CONTROLLER_PARAMS.law``), calling the four
functions of its module (``kernel_common``). An unknown code gives a NaN output, which the safety
chain answers with the fallback.
"""


def kernel_laws(laws: Mapping[str, Any]) -> dict[str, str]:
    """Law name -> its kernel module, for the registry's kernel laws in its order (their codes)."""
    return {name: entry.kernel for name, entry in laws.items() if getattr(entry, "kernel", None)}


def law_dispatch_source(laws: Mapping[str, Any]) -> str:
    """The text of ``law_dispatch.py`` for the registry ``laws``."""
    return dispatch_source(
        kind="law",
        docstring=DOCSTRING,
        variants=kernel_laws(laws),
        code="p.law",
        codes_name="LAW_CODES",
        prefix="law",
        functions=FUNCTIONS,
        imports={"pac_controller.kernel_common": ["ACTIVE"]},
        stdlib=["math"],
    )


def _registry() -> Mapping[str, Any]:
    from pac_controller import laws  # here: the registry imports the dispatch it is read for

    return laws.LAWS


def main(argv: list[str] | None = None) -> int:
    return dispatch_main(
        "pac_controller.law_dispatch_source",
        __file__,
        "law_dispatch.py",
        lambda: law_dispatch_source(_registry()),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
