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

from pac_common.smallmat import matvec
from pac_model import model
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

from .controller import Command, Errors  # noqa: F401 - Command re-exported (it lived here)
from .parameters import ControllerParameters, ReferenceParameters
from .reference import ForceReference


@njit(cache=True, error_model="numpy")
def reciprocal_derivatives(k: np.ndarray) -> np.ndarray:
    """Derivatives 0..3 of g = 1 / k from those of k (Faa di Bruno)."""
    k0, k1, k2, k3 = k[0], k[1], k[2], k[3]
    g0 = 1.0 / k0
    g1 = -k1 * g0**2
    g2 = -k2 * g0**2 + 2.0 * k1**2 * g0**3
    g3 = -k3 * g0**2 + 6.0 * k1 * k2 * g0**3 - 6.0 * k1**3 * g0**4
    return np.array([g0, g1, g2, g3])


@njit(cache=True)
def product_derivatives(f: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Derivatives 0..3 of f g (Leibniz)."""
    return np.array(
        [
            f[0] * g[0],
            f[1] * g[0] + f[0] * g[1],
            f[2] * g[0] + 2.0 * f[1] * g[1] + f[0] * g[2],
            f[3] * g[0] + 3.0 * f[2] * g[1] + 3.0 * f[1] * g[2] + f[0] * g[3],
        ]
    )


@njit(cache=True)
def stiffness_hat_derivatives(t: float, omega: float, theta_hat: np.ndarray, k_min: float) -> np.ndarray:
    """k_hat = v(t)^T theta_hat (eq. (8)) and its derivatives 1..3 with theta_hat frozen, clamped at k_min."""
    k = matvec(model.stiffness_regressor_derivatives(t, omega, 3), theta_hat)
    if k[0] < k_min:
        return np.array([k_min, 0.0, 0.0, 0.0])
    return k


@njit(cache=True, error_model="numpy")
def backstepping_law(
    t: float,
    f_r: np.ndarray,
    z_hat: np.ndarray,
    theta_hat: np.ndarray,
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
    """Eqs. (23)-(43) on numbers: (u, e1, e2, e3), u unsaturated."""
    z1, z2, z3, z4 = z_hat[0], z_hat[1], z_hat[2], z_hat[3]
    k = stiffness_hat_derivatives(t, omega, theta_hat, k_min)
    r = product_derivatives(f_r, reciprocal_derivatives(k))  # z1r and derivatives, eq. (23)

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


class BacksteppingController:
    """The adaptive_backstepping law core: u = m2 (-c3 e3 + alpha_2' - f2(z_hat) - (b1/m1) e2), eq. (43).

    Stateless (F_r is a pure function of time); the actuator limits, fallback and tick
    bookkeeping are the law-agnostic :class:`pac_controller.controller.Controller`'s.
    """

    mode = "active"
    uses_estimate = True

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
        self.pantograph = pantograph
        self.omega = track.omega
        self.params = params
        self.reference = ForceReference(reference)
        self.sample_period = sample_period

    def stiffness_hat_derivatives(self, t: float, theta_hat: np.ndarray) -> np.ndarray:
        """k_hat and its derivatives 1..3 with theta_hat frozen, clamped at stiffness_hat_min."""
        theta_hat = np.array(theta_hat, dtype=np.float64)
        k_min = float(self.params.stiffness_hat_min)
        return stiffness_hat_derivatives(float(t), self.omega, theta_hat, k_min)

    def restart(self, u_applied: float | None) -> None:
        """Nothing to forget: the law is stateless."""

    def output(
        self, tick: int, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, Errors]:
        return self.law(t, f_r, z_hat, theta_hat)

    def commit(self, tick: int, u_applied: float) -> None:
        """Nothing to update: the law is stateless."""

    def law(
        self, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, tuple[float, float, float]]:
        """Eqs. (23)-(43): the unsaturated u and (e1, e2, e3) (compiled :func:`backstepping_law`)."""
        p, c = self.pantograph, self.params
        u, e1, e2, e3 = backstepping_law(
            float(t),
            np.array(f_r, dtype=np.float64),
            np.array(z_hat, dtype=np.float64),
            np.array(theta_hat, dtype=np.float64),
            self.omega,
            p.m1,
            p.b1,
            p.k1,
            p.m2,
            p.b2,
            float(c.c1),
            float(c.c2),
            float(c.c3),
            float(c.stiffness_hat_min),
        )
        return u, (e1, e2, e3)


class KnownThetaBackstepping:
    """The backstepping_known law core: eq. (43) on z_hat with the true theta of eq. (9).

    An oracle: the same law as adaptive_backstepping, told the catenary parameters
    (k0, alpha, beta) instead of the observer's theta_hat, i.e. the best the adaptive
    law can hope for once theta_hat has converged.  z_hat still comes from the observer.
    """

    mode = "active"
    uses_estimate = True

    def __init__(self, backstepping: BacksteppingController, catenary: CatenaryParameters) -> None:
        self.backstepping = backstepping
        self.theta = catenary.theta

    def restart(self, u_applied: float | None) -> None:
        """Nothing to forget: the law is stateless."""

    def output(
        self, tick: int, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, Errors]:
        return self.backstepping.law(t, f_r, z_hat, self.theta)

    def commit(self, tick: int, u_applied: float) -> None:
        """Nothing to update: the law is stateless."""
