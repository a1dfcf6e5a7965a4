"""Backstepping contact-force controller of Chater et al. (2015), eqs. (23)-(43).

Output feedback with certainty equivalence: the law runs on the observer's z_hat
and theta_hat.  Choices the paper leaves open (docs/design.md):

* z1r = +F_r / k_hat (eq. (23) with its sign fixed, docs/paper_errata.md #2),
  k_hat = v(t)^T theta_hat clamped below at ``stiffness_hat_min``.
* The output injection terms g_ij * (y - C z_hat) of eq. (21) contain the unknown
  estimation error; they are dropped from alpha_1' and alpha_2' (they vanish as the
  observer converges). z1 in psi(y) is replaced by z_hat_1, so the law needs the
  estimate only.
* alpha_1' and alpha_2' are exact time derivatives along the observer model without
  injection, with theta_hat frozen (it varies slowly): k_hat' = v'(t)^T theta_hat, etc.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

from . import kernels
from .controller import Command, Errors  # noqa: F401 - Command re-exported (it lived here)
from .kernels import KernelLaw
from .parameters import ControllerParameters, ReferenceParameters
from .reference import ForceReference


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


class BacksteppingController(KernelLaw):
    """The adaptive_backstepping law core: u = m2 (-c3 e3 + alpha_2' - f2(z_hat) - (b1/m1) e2), eq. (43).

    Stateless (F_r is a pure function of time); the actuator limits, fallback and tick
    bookkeeping are the law-agnostic :class:`pac_controller.controller.Controller`'s.  Its
    numbers are fields of ``kernels.CONTROLLER_PARAMS``; ``output`` is ``kernels.law_output``.
    """

    NAME = "adaptive_backstepping"

    def __init__(
        self,
        pantograph: PantographParameters,
        track: TrackParameters,
        params: ControllerParameters,
        reference: ReferenceParameters,
        sample_period: float,
    ) -> None:
        if not (math.isfinite(sample_period) and sample_period > 0.0):
            raise ValueError(f"sample_period must be positive, got {sample_period!r}")
        super().__init__(self.NAME, sample_period)
        self.pantograph = pantograph
        self.omega = track.omega
        self.params_set = params
        self.reference = ForceReference(reference)
        self.sample_period = sample_period
        p = self.params[0]
        p["omega"], p["m1"], p["b1"], p["k1"] = self.omega, pantograph.m1, pantograph.b1, pantograph.k1
        p["m2"], p["b2"] = pantograph.m2, pantograph.b2
        p["c1"], p["c2"], p["c3"] = params.c1, params.c2, params.c3
        p["stiffness_hat_min"] = params.stiffness_hat_min

    def stiffness_hat_derivatives(self, t: float, theta_hat: np.ndarray) -> np.ndarray:
        """k_hat and its derivatives 1..3 with theta_hat frozen, clamped at stiffness_hat_min."""
        theta_hat = np.array(theta_hat, dtype=np.float64)
        k_min = float(self.params_set.stiffness_hat_min)
        return stiffness_hat_derivatives(float(t), self.omega, theta_hat, k_min)

    def law(
        self, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, tuple[float, float, float]]:
        """Eqs. (23)-(43): the unsaturated u and (e1, e2, e3) (:func:`backstepping_law4` via ``kernels``)."""
        return self.output(0, t, f_r, z_hat, theta_hat)


class KnownThetaBackstepping(BacksteppingController):
    """The backstepping_known law core: eq. (43) on z_hat with the true theta of eq. (9).

    An oracle: the same law as adaptive_backstepping, told the catenary parameters
    (k0, alpha, beta) instead of the observer's theta_hat, i.e. the best the adaptive
    law can hope for once theta_hat has converged.  z_hat still comes from the observer.
    """

    NAME = "backstepping_known"

    def __init__(self, backstepping: BacksteppingController, catenary: CatenaryParameters) -> None:
        b = backstepping
        super().__init__(b.pantograph, TrackParameters(), b.params_set, b.reference.params, b.sample_period)
        self.params[0] = b.params[0]
        self.params[0]["law"] = kernels.LAW_CODES[self.NAME]
        self.backstepping = backstepping
        self.theta = catenary.theta
        self.params[0]["theta"] = self.theta
        self.omega = b.omega
