"""The backstepping law's equations, eqs. (23)-(43) of Chater et al. (2015), compiled.

Pure functions of numbers; the laws that call them (``backstepping.py``) and the compiled
dispatcher (``kernels.py``) both import them from here, so neither imports the other's
module to reach them.  The choices the paper leaves open are listed in backstepping.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def reciprocal_derivatives(k: np.ndarray) -> np.ndarray:
    """Derivatives 0..3 of g = 1 / k from those of k (Faa di Bruno)."""
    g0, g1, g2, g3 = reciprocal_derivatives4(k[0], k[1], k[2], k[3])
    return np.array([g0, g1, g2, g3])


@njit(cache=True, error_model="numpy")
def reciprocal_derivatives4(k0: float, k1: float, k2: float, k3: float) -> tuple[float, float, float, float]:
    """:func:`reciprocal_derivatives` on four numbers."""
    g0 = 1.0 / k0
    g1 = -k1 * g0**2
    g2 = -k2 * g0**2 + 2.0 * k1**2 * g0**3
    g3 = -k3 * g0**2 + 6.0 * k1 * k2 * g0**3 - 6.0 * k1**3 * g0**4
    return g0, g1, g2, g3


@njit(cache=True)
def product_derivatives(f: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Derivatives 0..3 of f g (Leibniz)."""
    p0, p1, p2, p3 = product_derivatives4((f[0], f[1], f[2], f[3]), (g[0], g[1], g[2], g[3]))
    return np.array([p0, p1, p2, p3])


@njit(cache=True)
def product_derivatives4(f, g) -> tuple[float, float, float, float]:
    """:func:`product_derivatives` on two 4-tuples."""
    return (
        f[0] * g[0],
        f[1] * g[0] + f[0] * g[1],
        f[2] * g[0] + 2.0 * f[1] * g[1] + f[0] * g[2],
        f[3] * g[0] + 3.0 * f[2] * g[1] + 3.0 * f[1] * g[2] + f[0] * g[3],
    )


@njit(cache=True)
def stiffness_hat_derivatives(t: float, omega: float, theta_hat: np.ndarray, k_min: float) -> np.ndarray:
    """k_hat = v(t)^T theta_hat (eq. (8)) and its derivatives 1..3 with theta_hat frozen, clamped at k_min."""
    k0, k1, k2, k3 = stiffness_hat_derivatives4(t, omega, theta_hat[0], theta_hat[1], theta_hat[2], k_min)
    return np.array([k0, k1, k2, k3])


@njit(cache=True)
def _regressor_dot(n: int, omega: float, c: float, s: float, th0: float, th1: float, th2: float) -> float:
    """Row n of ``model.stiffness_regressor_derivatives`` times theta_hat (its sum, in its order)."""
    cos_cycle, sin_cycle = (c, -s, -c, s), (s, c, -s, -c)
    v0 = 1.0 if n == 0 else 0.0
    v1 = omega**n * cos_cycle[n % 4]
    v2 = omega**n * sin_cycle[n % 4]
    acc = 0.0
    acc += v0 * th0
    acc += v1 * th1
    acc += v2 * th2
    return acc


@njit(cache=True)
def stiffness_hat_derivatives4(
    t: float, omega: float, th0: float, th1: float, th2: float, k_min: float
) -> tuple[float, float, float, float]:
    """:func:`stiffness_hat_derivatives` as four numbers (nothing allocated)."""
    c, s = math.cos(omega * t), math.sin(omega * t)
    k0 = _regressor_dot(0, omega, c, s, th0, th1, th2)
    if k0 < k_min:
        return k_min, 0.0, 0.0, 0.0
    k1 = _regressor_dot(1, omega, c, s, th0, th1, th2)
    k2 = _regressor_dot(2, omega, c, s, th0, th1, th2)
    k3 = _regressor_dot(3, omega, c, s, th0, th1, th2)
    return k0, k1, k2, k3


@njit(cache=True, error_model="numpy")
def backstepping_law4(
    t: float,
    f_r,
    z_hat: np.ndarray,
    th0: float,
    th1: float,
    th2: float,
    omega: float,
    m1: float,
    b1: float,
    k1: float,
    m2: float,
    b2: float,
    c1: float,
    c2: float,
    c3: float,
    k_min: float,
) -> tuple[float, float, float, float]:
    """Eqs. (23)-(43): (u, e1, e2, e3), u unsaturated; F_r and its derivatives a 4-tuple, theta_hat
    three numbers (nothing allocated: the compiled loop's form)."""
    z1, z2, z3, z4 = z_hat[0], z_hat[1], z_hat[2], z_hat[3]
    k = stiffness_hat_derivatives4(t, omega, th0, th1, th2, k_min)
    r = product_derivatives4(
        f_r, reciprocal_derivatives4(k[0], k[1], k[2], k[3])
    )  # z1r and derivatives, eq. (23)

    # Observer model (21) without injection; z1 in psi replaced by z_hat_1.
    f1 = -(k1 / m1) * z1 + (k1 / m1) * z2 - (b1 / m1) * z3  # eq. (22)
    f2 = (k1 / m2) * (z1 - z2) + (b1 / m2) * z3 - ((b1 + b2) / m2) * z4  # eq. (22)
    force_term = z1 * k[0] / m1  # (z1/m1) v^T theta_hat
    dz1, dz2 = z3, z4
    dz3 = f1 + (b1 / m1) * z4 - force_term

    e1 = z1 - r[0]  # eq. (24)
    alpha1 = r[1] - c1 * e1  # eq. (28)
    de1 = dz1 - r[1]
    dalpha1 = r[2] - c1 * de1
    e2 = z3 - alpha1  # eq. (29)
    alpha2 = (m1 / b1) * (-c2 * e2 - e1 - f1 + force_term + dalpha1)  # eq. (35)
    e3 = z4 - alpha2  # eq. (36)

    # alpha_2' along the model: needs e2', f1', (z1 k_hat)' and alpha_1''.
    de2 = dz3 - dalpha1
    df1 = -(k1 / m1) * dz1 + (k1 / m1) * dz2 - (b1 / m1) * dz3
    dforce_term = (dz1 * k[0] + z1 * k[1]) / m1
    ddalpha1 = r[3] - c1 * (dz3 - r[2])
    dalpha2 = (m1 / b1) * (-c2 * de2 - de1 - df1 + dforce_term + ddalpha1)

    u = m2 * (-c3 * e3 + dalpha2 - f2 - (b1 / m1) * e2)  # eq. (43)
    return u, e1, e2, e3
