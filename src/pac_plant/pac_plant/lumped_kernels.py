"""The lumped line (``pac_plant.plant.Plant``) in the compiled loop: its three functions
(``plant_kernels``' protocol), eqs. (5), (6), (9) with k(t) the catenary's."""

from __future__ import annotations

import numpy as np
from numba import njit

from pac_model import model

from .hardware.car_body import roof_at
from .plant import plant_advance_inplace, plant_rhs4
from .plant_kernels import NO_FE, no_pantographs


@njit(cache=True, error_model="numpy")
def _accelerations(t, pp, ps) -> tuple[float, float]:
    """(z1'', z2'') at tick time t (``Plant._accelerations``): eq. (5) with the forces of the
    period that ends here, the roof's spring and damper force (``ps.roof``: the roof at t) and the
    turbulent uplift at that instant."""
    force = ps.u_applied
    if pp.roof:
        force += pp.roof_k * ps.roof[0] + pp.roof_c * ps.roof[1]
    if pp.gusts:
        roof_at(pp.gust_amplitude, pp.gust_frequency, pp.gust_phase, t, ps.gust)
        force += ps.gust[0]
    z = ps.z
    args = (pp.a, pp.theta, pp.omega, pp.m1, pp.m2, pp.unilateral)
    _, _, a1, a2 = plant_rhs4(t, z[0], z[1], z[2], z[3], force + pp.uplift, *args)  # the wind with u
    return a1, a2


@njit(cache=True, error_model="numpy")
def lumped_output(k, t, pp, ps, fe_args, out) -> tuple[float, float, float, float]:
    """k(t) and F = k z1 (eqs. (6), (9)); no line fields; the accelerations only for a suite."""
    stiff = model.stiffness(t, pp.omega, pp.theta)
    force = model.contact_force(stiff, ps.z[0], pp.unilateral)
    out.contact_uplift, out.support_uplift, out.contact_position = np.nan, np.nan, np.nan
    no_pantographs(out, 0)
    if pp.suite:
        a1, a2 = _accelerations(t, pp, ps)
    else:
        a1 = a2 = 0.0
    return stiff, force, a1, a2


@njit(cache=True, error_model="numpy")
def lumped_advance(k, pp, ps, fe_args, force) -> int:
    """Eq. (5) over the period, ``substeps`` RK4 steps with ``force`` held (zero-order hold)."""
    plant_advance_inplace(
        ps.z, k * pp.dt, pp.dt, pp.substeps, force, pp.a, pp.theta, pp.omega, pp.m1, pp.m2, pp.unilateral
    )
    return 0


def lumped_pack(plant, record) -> tuple:
    """The line's numbers (span frequency, contact law, A and theta of eqs. (9), (12)); no arrays."""
    record["omega"], record["unilateral"] = plant.span_frequency, plant.unilateral
    record["a"], record["theta"] = plant.state_matrix, plant.catenary_theta
    return NO_FE
