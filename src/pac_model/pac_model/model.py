"""The 2-DOF pantograph-catenary model, eqs. (2)-(15) of Chater et al. (2015).

State z = (z1, z2, z1', z2') (eq. 4): head and frame positions [m] and velocities
[m/s], positive upwards, measured from the unloaded rest position; z1 > 0 presses
the head into the wire.  Every formula of the model lives here once; the plant,
the observer and the controller all import it.

The formulas the cores evaluate at every tick are compiled (numba, ``njit``) and take
plain numbers and arrays, so the compiled plant, observer and controller call them
directly; the functions taking a :class:`PantographParameters` are thin wrappers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .parameters import PantographParameters

#: C of eq. (13): the two frame positions are measured.
OUTPUT_MATRIX = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


@njit(cache=True)
def stiffness_regressor_derivatives(t: float, omega: float, order: int) -> np.ndarray:
    """Rows d^n v / dt^n for n = 0..order, v of eq. (9)."""
    c, s = math.cos(omega * t), math.sin(omega * t)
    # Each derivative of (cos, sin) rotates the pair by 90 degrees and scales it by omega.
    cos_cycle, sin_cycle = (c, -s, -c, s), (s, c, -s, -c)
    out = np.zeros((order + 1, 3))
    out[0, 0] = 1.0
    for n in range(order + 1):
        out[n, 1] = omega**n * cos_cycle[n % 4]
        out[n, 2] = omega**n * sin_cycle[n % 4]
    return out


@njit(cache=True)
def stiffness(t: float, omega: float, theta: np.ndarray) -> float:
    """k(t) = v(t)^T theta, eq. (8) (equal to eq. (7) for theta of eq. (9)) [N/m]."""
    wt = omega * t
    return float(theta[0] + theta[1] * math.cos(wt) + theta[2] * math.sin(wt))


def state_matrix(p: PantographParameters) -> np.ndarray:
    """A of eq. (12): the pantograph without the catenary spring."""
    return np.array(
        [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-p.k1 / p.m1, p.k1 / p.m1, -p.b1 / p.m1, p.b1 / p.m1],
            [p.k1 / p.m2, -p.k1 / p.m2, p.b1 / p.m2, -(p.b1 + p.b2) / p.m2],
        ]
    )


def input_vector(u: float, p: PantographParameters) -> np.ndarray:
    """phi(u) of eq. (14): the actuator force acts on the lower frame."""
    return actuator_input(float(u), p.m2)


@njit(cache=True)
def actuator_input(u: float, m2: float) -> np.ndarray:
    """phi(u) of eq. (14) (m2 as a number)."""
    return np.array([0.0, 0.0, 0.0, actuator_acceleration(u, m2)])


@njit(cache=True)
def actuator_acceleration(u: float, m2: float) -> float:
    """u / m2, the only non-zero entry of phi(u), eq. (14)."""
    return u / m2


def output_regressor_row(y1: float, t: float, omega: float, p: PantographParameters) -> np.ndarray:
    """The only non-zero row of psi(y), eq. (15): -(y1 / m1) v(t)^T."""
    return regressor_row(y1, t, omega, p.m1)


@njit(cache=True)
def regressor_row(y1: float, t: float, omega: float, m1: float) -> np.ndarray:
    """The only non-zero row of psi(y), eq. (15): -(y1 / m1) v(t)^T (m1 as a number)."""
    r0, r1, r2 = regressor_row3(y1, t, omega, m1)
    return np.array([r0, r1, r2])


@njit(cache=True)
def regressor_row3(y1: float, t: float, omega: float, m1: float) -> tuple[float, float, float]:
    """:func:`regressor_row` as three numbers."""
    wt = omega * t
    c = -y1 / m1
    return c, c * math.cos(wt), c * math.sin(wt)


@njit(cache=True)
def contact_force(k: float, z1: float, unilateral: bool) -> float:
    """F = k z1, eq. (6); with ``unilateral`` the wire can only push (F >= 0)."""
    f = k * z1
    return max(f, 0.0) if unilateral else f


def dynamics(z: np.ndarray, u: float, force: float, a: np.ndarray, p: PantographParameters) -> np.ndarray:
    """z' of eqs. (3)/(5) written as A z + phi(u) - F e3 / m1.

    With F = k z1 this is exactly eq. (5) and eq. (11): A z + phi(u) + psi(y) theta.
    """
    return pantograph_rhs(np.asarray(z, dtype=np.float64), float(u), float(force), a, p.m1, p.m2)


@njit(cache=True)
def pantograph_rhs(z: np.ndarray, u: float, force: float, a: np.ndarray, m1: float, m2: float) -> np.ndarray:
    """:func:`dynamics` on numbers: A z + phi(u) - F e3 / m1, eqs. (3)/(5)/(14)."""
    d0, d1, d2, d3 = pantograph_rhs4(z[0], z[1], z[2], z[3], u, force, a, m1, m2)
    return np.array([d0, d1, d2, d3])


@njit(cache=True)
def pantograph_rhs4(
    z0: float, z1: float, z2: float, z3: float, u: float, force: float, a: np.ndarray, m1: float, m2: float
) -> tuple[float, float, float, float]:
    """:func:`pantograph_rhs` on four numbers, returned as four numbers (no array: the compiled loop's)."""
    d0 = a[0, 0] * z0 + a[0, 1] * z1 + a[0, 2] * z2 + a[0, 3] * z3
    d1 = a[1, 0] * z0 + a[1, 1] * z1 + a[1, 2] * z2 + a[1, 3] * z3
    d2 = a[2, 0] * z0 + a[2, 1] * z1 + a[2, 2] * z2 + a[2, 3] * z3
    d3 = a[3, 0] * z0 + a[3, 1] * z1 + a[3, 2] * z2 + a[3, 3] * z3
    return d0, d1, d2 - force / m1, d3 + actuator_acceleration(u, m2)


def static_equilibrium(u: float, k: float, p: PantographParameters) -> np.ndarray:
    """Rest state under a constant uplift u and constant stiffness k.

    From eq. (3) with all derivatives zero: F = k z1 = u and k1 (z2 - z1) = u.
    """
    z1 = u / k
    return np.array([z1, z1 + u / p.k1, 0.0, 0.0])
