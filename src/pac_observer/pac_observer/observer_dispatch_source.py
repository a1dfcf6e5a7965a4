"""The source of ``observer_dispatch``: the compiled loop's observer dispatch, written from the registry.

The compiled loop calls each observer's update in one branch per observer on the record's code
(``OBSERVER_CONSTS.kind``; ``pac_common.dispatch_source`` says why branches). The branches, the
imports and the codes are written from ``observers.OBSERVERS``; none of it is kept by hand. An
observer joins with its module (its core class and its ``<name>_update``, observers.py) and one
registry line; then::

    python -m pac_observer.observer_dispatch_source --write

(``tests/test_observer_dispatch.py`` fails while ``observer_dispatch.py`` is not what the
registry gives).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping

from pac_common.dispatch_source import Dispatched, dispatch_source
from pac_common.dispatch_source import main as dispatch_main

from .observers import OBSERVERS, ObserverEntry

#: The one function of a compiled observer (``<name>_update``; observers.py). An unknown code is
#: a divergence of its own (pac_common.divergence.UNKNOWN_OBSERVER).
FUNCTIONS = (
    Dispatched(
        "update",
        "k, t, oc, os, bank, y1, y2, u_applied, head_acceleration",
        True,
        "The observer of the records at tick k: (status, stiffness_hat, contact_force_hat).",
        "    return UNKNOWN_OBSERVER, 0.0, 0.0\n",
    ),
)

DOCSTRING = """The compiled observers' dispatch: generated from ``pac_observer.observers.OBSERVERS`` by
``python -m pac_observer.observer_dispatch_source --write``. Do not edit.

One branch per compiled observer on the record's code (``OBSERVER_CONSTS.kind``), calling its
module's ``<name>_update`` (observers.py). An unknown code is a divergence of its own.
"""


def compiled_observers(observers: Mapping[str, ObserverEntry]) -> dict[str, str]:
    """Observer name -> its kernel module, for the registry's compiled observers in its order."""
    return {name: entry.kernel for name, entry in observers.items() if entry.kernel}


def observer_dispatch_source(observers: Mapping[str, ObserverEntry]) -> str:
    """The text of ``observer_dispatch.py`` for the registry ``observers``."""
    return dispatch_source(
        kind="observer",
        docstring=DOCSTRING,
        variants=compiled_observers(observers),
        code="oc.kind",
        codes_name="OBSERVER_CODES",
        prefix="observer",
        functions=FUNCTIONS,
        imports={"pac_common.divergence": ["UNKNOWN_OBSERVER"]},
    )


def main(argv: list[str] | None = None) -> int:
    return dispatch_main(
        "pac_observer.observer_dispatch_source",
        __file__,
        "observer_dispatch.py",
        lambda: observer_dispatch_source(OBSERVERS),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
