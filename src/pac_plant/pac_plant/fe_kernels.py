"""The FE line (``pac_plant.fe_plant.FEPlant``) in the compiled loop: its three functions
(``plant_kernels``' protocol), on the packed buffers of its ``ContactSimulation``."""

from __future__ import annotations

import numpy as np
from numba import njit

from pac_common.divergence import OFF_LINE

from .catenary import step
from .catenary.packing import unpack
from .fe_plant import several_pantographs
from .hardware.car_body import roof_force
from .plant_kernels import no_pantographs


@njit(cache=True, error_model="numpy")
def _pantographs_output(pp, ps, c, st, flexibility, out) -> None:
    """Every pantograph's contact on the FE line into ``out``: what ``FEPlant.pantograph_truths``
    reports, by the same kernels (``pantograph_contact``, ``readings_at`` its contact point)."""
    r = ps.readings
    for j in range(pp.pantographs):
        k = pp.contact_of[j]
        force, position = step.pantograph_contact(c, st, k)
        out.pantograph_contact_force[j], out.pantograph_contact_position[j] = force, position
        step.readings_at(c, st, flexibility, st.scalars[step.X] - c.p_lag[k], r)
        out.pantograph_contact_uplift[j] = r[step.CONTACT_UPLIFT]
        out.pantograph_support_uplift[j] = r[step.SUPPORT_UPLIFT]
    no_pantographs(out, pp.pantographs)


@njit(cache=True, error_model="numpy")
def fe_output(k, t, pp, ps, fe_args, out) -> tuple[float, float, float, float]:
    """The pantograph's positions against the datum (fixed, or the static wire under the contact
    point), the static stiffness there, the penalty contact force, the line's fields; the
    accelerations the Newmark state's (``FEPlant._accelerations``)."""
    z = ps.z
    cf, ci, cl, sf, si, sl, flexibility, readings = fe_args
    c, st = unpack(cf, ci, cl, sf, si, sl)
    if pp.static_wire:  # the datum moves with the contact point along the pre-sagged wire
        datum, rate = readings[step.STATIC_HEIGHT], c.numbers[1] * readings[step.STATIC_SLOPE]
    else:
        datum, rate = pp.datum, 0.0
    z[0], z[1], z[2], z[3] = st.p[0] - datum, st.p[1] - datum, st.vp[0] - rate, st.vp[1] - rate
    stiff = readings[step.STATIC_STIFFNESS]
    force = c.numbers[4] * st.scalars[step.DELTA] if st.counters[step.IN_CONTACT] else 0.0
    out.contact_uplift, out.support_uplift = readings[step.CONTACT_UPLIFT], readings[step.SUPPORT_UPLIFT]
    out.contact_position = st.scalars[step.X] + st.scalars[step.OFFSET] - c.p_lag[c.indices[5]]
    _pantographs_output(pp, ps, c, st, flexibility, out)
    return stiff, force, st.ap[0], st.ap[1]


@njit(cache=True, error_model="numpy")
def fe_advance(k, pp, ps, fe_args, force) -> int:
    """One period of the FE line (``fe_substeps`` Newmark steps); OFF_LINE past the line's end."""
    cf, ci, cl, sf, si, sl, flexibility, readings = fe_args
    c, st = unpack(cf, ci, cl, sf, si, sl)
    t0 = k * pp.dt
    for j in range(pp.passive_roofs):  # each passive pantograph's roof force (FEPlant.advance)
        st.base_force[pp.passive_roof_contact[j]] = roof_force(
            pp.roof_amplitude,
            pp.roof_frequency,
            pp.passive_roof_phase[j],
            pp.passive_roof_k[j],
            pp.passive_roof_c[j],
            t0,
            (k + 1) * pp.dt,
        )
    if step.fe_advance(c, st, force, pp.substeps, flexibility, readings) != step.STEP_OK:
        return OFF_LINE
    return 0


def fe_pack(plant, record) -> tuple:
    """The FE options' fields (substeps, datum, the pantographs reported) and the line's buffers:
    copies of the simulation's state (the core is not changed by the loop)."""
    record["substeps"] = plant.options.fe_substeps
    record["static_wire"], record["datum"] = plant.options.fe_datum == "static_wire", plant.datum
    contacts = plant.contact_of if several_pantographs(plant) else []  # pantograph_truth's
    record["pantographs"], record["contact_of"][: len(contacts)] = len(contacts), contacts
    roofs = plant.passive_roofs
    record["passive_roofs"] = len(roofs)
    for j, roof in enumerate(roofs):
        # One track under one kind of car: the controlled roof's cosines but for their phases.
        assert plant.roof is not None and np.array_equal(roof.motion.frequency, plant.roof.frequency)
        assert np.array_equal(roof.motion.amplitude, plant.roof.amplitude)
        record["passive_roof_contact"][j], record["passive_roof_phase"][j] = roof.contact, roof.motion.phase
        record["passive_roof_k"][j], record["passive_roof_c"][j] = roof.stiffness, roof.damping
    cf, ci, cl, sf, si, sl = plant.sim.packed
    flexibility = np.ascontiguousarray(plant.flexibility, dtype=np.float64)
    return (cf, ci, cl, sf.copy(), si.copy(), sl, flexibility, plant.readings)
