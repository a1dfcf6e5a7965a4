"""The actuator steps' dispatch: generated from ``pac_plant.hardware.actuators.ACTUATOR_STEPS``
by ``python -m pac_plant.hardware.actuator_dispatch_source --write``. Do not edit.

One branch per step on the record's code (``ACTUATOR_PARAMS.kind``), calling its module's
``<step>_apply`` (actuator_steps). An unknown code gives a NaN force.
"""

from __future__ import annotations

import math

from numba import njit

from pac_plant.hardware import actuator_steps

#: Actuator step name -> the code the compiled functions dispatch on (the registry's order).
ACTUATOR_STEP_CODES = {
    "ideal": 0,
    "lag": 1,
}


@njit(cache=True, error_model="numpy")
def actuator_apply(p, s, u):
    """The mean force over this tick for the command ``u`` held over it; advances ``s``."""
    kind = p.kind
    if kind == 0:
        return actuator_steps.ideal_apply(p, s, u)
    elif kind == 1:
        return actuator_steps.lag_apply(p, s, u)
    return math.nan
