"""The source of ``actuator_dispatch``: the actuator's step chosen by its record, written from the registry.

The plant's step (the compiled loop's and ``Plant.advance``) calls the actuator's compiled step in
one branch per step on the record's code (``ACTUATOR_PARAMS.kind``; ``pac_common.dispatch_source``
says why branches). The branches, the imports and the codes are written from
``actuators.ACTUATOR_STEPS``; none of it is kept by hand. After a change there::

    python -m pac_plant.hardware.actuator_dispatch_source --write

(``tests/test_actuator.py`` fails while ``actuator_dispatch.py`` is not what the registry gives).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping

from pac_common.dispatch_source import Dispatched, dispatch_source
from pac_common.dispatch_source import main as dispatch_main

#: The one function of a step (``<step>_apply``; actuator_steps). An unknown code gives a NaN force.
FUNCTIONS = (
    Dispatched(
        "apply",
        "p, s, u",
        True,
        "The mean force over this tick for the command ``u`` held over it; advances ``s``.",
        "    return math.nan\n",
    ),
)

DOCSTRING = """The actuator steps' dispatch: generated from ``pac_plant.hardware.actuators.ACTUATOR_STEPS``
by ``python -m pac_plant.hardware.actuator_dispatch_source --write``. Do not edit.

One branch per step on the record's code (``ACTUATOR_PARAMS.kind``), calling its module's
``<step>_apply`` (actuator_steps). An unknown code gives a NaN force.
"""


def actuator_dispatch_source(steps: Mapping[str, str]) -> str:
    """The text of ``actuator_dispatch.py`` for the steps ``steps`` (name -> module)."""
    return dispatch_source(
        kind="actuator step",
        docstring=DOCSTRING,
        variants=steps,
        code="p.kind",
        codes_name="ACTUATOR_STEP_CODES",
        prefix="actuator",
        functions=FUNCTIONS,
        stdlib=["math"],
    )


def _registry() -> Mapping[str, str]:
    from .actuators import ACTUATOR_STEPS  # here: the registry imports the dispatch it is read for

    return ACTUATOR_STEPS


def main(argv: list[str] | None = None) -> int:
    return dispatch_main(
        "pac_plant.hardware.actuator_dispatch_source",
        __file__,
        "actuator_dispatch.py",
        lambda: actuator_dispatch_source(_registry()),
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
