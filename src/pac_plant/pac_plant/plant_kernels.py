"""What the compiled loop asks of a plant, and what the plants share for it.

A plant of the registry (``plants.PLANTS``) with a ``kernel`` module gives the compiled closed
loop (``pac_rig.loop``) three functions named after it, called through ``plant_dispatch``
(generated from the registry by ``plant_dispatch_source``, never written by hand):

- ``<name>_output(k, t, pp, ps, fe_args, out) -> (stiffness, contact_force, a1, a2)``: the truth
  of tick k (time t) into ``ps.z`` and the line's fields of ``out`` (a ``loop.TICK`` record: the
  uplifts, the contact position, every pantograph's contact); a1, a2 the head's and the frame's
  accelerations, which a train's sensor suite reads (``pp.suite``; the moving roof ``ps.roof`` is
  already that of t);
- ``<name>_advance(k, pp, ps, fe_args, force) -> status``: the plant over [t_k, t_k+1] under
  ``force`` (the actuator's, the wind and the roof's, held); 0 or a divergence code;
- ``<name>_pack(plant, record) -> fe_args`` (Python): the plant's own fields of a
  ``PLANT_PARAMS`` record and its arrays (:data:`NO_FE` where it has none).

``pp`` / ``ps`` are the ``loop.PLANT_PARAMS`` / ``PLANT_STATE`` records, ``fe_args`` the FE line's
buffers (``loop.FE_ARGS``; empty arrays of their types for a plant without them: one compiled
loop for every plant).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .parameters import MAX_PANTOGRAPHS

#: The FE line's buffers of a plant without them: empty arrays of their types.
NO_FE = (
    np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 4), np.int64), np.zeros(0), np.zeros(0, np.int64),
    np.zeros((0, 4), np.int64), np.zeros((0, 4, 4)), np.zeros(0),
)  # fmt: skip


@njit(cache=True, error_model="numpy")
def no_pantographs(out, first) -> None:
    """NaN in the pantograph fields of ``out`` from pantograph ``first`` on (none reported there)."""
    for j in range(first, MAX_PANTOGRAPHS):
        out.pantograph_contact_force[j] = np.nan
        out.pantograph_contact_position[j] = np.nan
        out.pantograph_contact_uplift[j] = np.nan
        out.pantograph_support_uplift[j] = np.nan
