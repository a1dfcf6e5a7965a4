"""The compiled plants' dispatch: generated from ``pac_plant.plants.PLANTS`` by
``python -m pac_plant.plant_dispatch_source --write``. Do not edit.

One branch per compiled plant on the record's code (``PLANT_PARAMS.kind``), calling its kernel
module's functions (``plant_kernels``). An unknown code is a divergence of its own.
"""

from __future__ import annotations

import math

from numba import njit

from pac_common.divergence import UNKNOWN_PLANT
from pac_plant import fe_kernels, lumped_kernels

#: Plant name -> the code the compiled functions dispatch on (the registry's order).
PLANT_CODES = {
    "lumped": 0,
    "fe": 1,
}


@njit(cache=True, error_model="numpy")
def plant_output(k, t, pp, ps, fe_args, out):
    """The truth of tick k: (stiffness, contact force, a1, a2); the line's fields into out."""
    kind = pp.kind
    if kind == 0:
        return lumped_kernels.lumped_output(k, t, pp, ps, fe_args, out)
    elif kind == 1:
        return fe_kernels.fe_output(k, t, pp, ps, fe_args, out)
    return math.nan, math.nan, 0.0, 0.0


@njit(cache=True, error_model="numpy")
def plant_advance(k, pp, ps, fe_args, force):
    """The plant over [t_k, t_k+1] under ``force`` held: 0 or a divergence code."""
    kind = pp.kind
    if kind == 0:
        return lumped_kernels.lumped_advance(k, pp, ps, fe_args, force)
    elif kind == 1:
        return fe_kernels.fe_advance(k, pp, ps, fe_args, force)
    return UNKNOWN_PLANT
