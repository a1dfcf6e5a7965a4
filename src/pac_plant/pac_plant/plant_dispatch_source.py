"""The source of ``plant_dispatch``: the compiled loop's plant dispatch, written from the registry.

The compiled loop calls each plant's output and advance in one branch per plant on the record's
code (``PLANT_PARAMS.kind``; ``pac_common.dispatch_source`` says why branches). The branches, the
imports and the codes are written from ``plants.PLANTS``; none of it is kept by hand. A plant
joins with its modules (its class; its compiled parts, ``plant_kernels``' protocol) and one
registry line; then::

    python -m pac_plant.plant_dispatch_source --write

(``tests/test_plant_dispatch.py`` fails while ``plant_dispatch.py`` is not what the registry gives).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping

from pac_common.dispatch_source import Dispatched, check_variant, dispatch_source
from pac_common.dispatch_source import main as dispatch_main

from .plants import PLANTS, PlantKind

#: The compiled functions of a plant (``<name>_<suffix>``; plant_kernels). An unknown code gives a
#: NaN truth and a divergence of its own (pac_common.divergence.UNKNOWN_PLANT) when it advances.
FUNCTIONS = (
    Dispatched(
        "output",
        "k, t, pp, ps, fe_args, out",
        True,
        "The truth of tick k: (stiffness, contact force, a1, a2); the line's fields into out.",
        "    return math.nan, math.nan, 0.0, 0.0\n",
    ),
    Dispatched(
        "advance",
        "k, pp, ps, fe_args, force",
        True,
        "The plant over [t_k, t_k+1] under ``force`` held: 0 or a divergence code.",
        "    return UNKNOWN_PLANT\n",
    ),
)
#: What the loop's set-up calls in Python (``loop.compile_loop``): checked, not dispatched.
PYTHON_FUNCTIONS = ("pack",)

DOCSTRING = """The compiled plants' dispatch: generated from ``pac_plant.plants.PLANTS`` by
``python -m pac_plant.plant_dispatch_source --write``. Do not edit.

One branch per compiled plant on the record's code (``PLANT_PARAMS.kind``), calling its kernel
module's functions (``plant_kernels``). An unknown code is a divergence of its own.
"""


def compiled_plants(plants: Mapping[str, PlantKind]) -> dict[str, str]:
    """Plant name -> its kernel module, for the registry's compiled plants in its order."""
    return {name: kind.kernel for name, kind in plants.items() if kind.kernel}


def plant_dispatch_source(plants: Mapping[str, PlantKind]) -> str:
    """The text of ``plant_dispatch.py`` for the registry ``plants``."""
    variants = compiled_plants(plants)
    for name, module in variants.items():
        check_variant("plant", name, module, PYTHON_FUNCTIONS)
    return dispatch_source(
        kind="plant",
        docstring=DOCSTRING,
        variants=variants,
        code="pp.kind",
        codes_name="PLANT_CODES",
        prefix="plant",
        functions=FUNCTIONS,
        imports={"pac_common.divergence": ["UNKNOWN_PLANT"]},
        stdlib=["math"],
    )


def main(argv: list[str] | None = None) -> int:
    return dispatch_main(
        "pac_plant.plant_dispatch_source",
        __file__,
        "plant_dispatch.py",
        lambda: plant_dispatch_source(PLANTS),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
