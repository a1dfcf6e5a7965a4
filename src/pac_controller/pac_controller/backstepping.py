"""Backstepping contact-force controller of Chater et al. (2015), eqs. (23)-(43).

Output feedback with certainty equivalence: the law runs on the observer's z_hat
and theta_hat.  Choices the paper leaves open (docs/design.md):

* z1r = +F_r / k_hat (eq. (23) with its sign fixed, PAPER_NOTES item 2),
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
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common.smallmat import matvec
from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters

from .parameters import ControllerParameters, ReferenceParameters
from .reference import ForceReference


@dataclass(frozen=True)
class Command:
    """The controller's output at one tick."""

    tick: int
    time: float
    u: float  # applied (saturated) actuator force [N]
    u_unsaturated: float  # what the law asked for [N]
    force_reference: float  # F_r [N]
    tracking_error: tuple[float, float, float]  # (e1, e2, e3), eqs. (24), (29), (36)
    saturated: bool
    mode: str  # "active", "passive" or "fallback"


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
    t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray, omega: float, m1: float, b1: float,
    k1: float, m2: float, b2: float, c1: float, c2: float, c3: float, k_min: float,
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


@njit(cache=True)
def limit_command(
    u: float, last_u: float, has_last: bool, ticks_since: int, slew_rate_max: float, sample_period: float,
    u_min: float, u_max: float,
) -> float:
    """The actuator limits: slew rate from the last command (over at least one period), then saturation."""
    applied = u
    if has_last:
        # At least one period: a command whose tick is not after the last one (a fallback
        # tick extrapolated ahead of a returning estimate) is still rate limited.
        step = slew_rate_max * sample_period * max(1, ticks_since)
        applied = min(max(applied, last_u - step), last_u + step)
    return min(max(applied, u_min), u_max)


class BacksteppingController:
    """u = m2 (-c3 e3 + alpha_2' - f2(z_hat) - (b1/m1) e2), eq. (43), then the actuator limits.

    Explicit state: the last commanded force and its tick (for the slew-rate limit).
    The law itself is stateless; F_r is a pure function of time.
    """

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
        self.last_u: float | None = None  # None: no command yet (no rate limit on the first)
        self.last_tick = -1

    def stiffness_hat_derivatives(self, t: float, theta_hat: np.ndarray) -> np.ndarray:
        """k_hat and its derivatives 1..3 with theta_hat frozen, clamped at stiffness_hat_min."""
        theta_hat = np.array(theta_hat, dtype=np.float64)
        k_min = float(self.params.stiffness_hat_min)
        return stiffness_hat_derivatives(float(t), self.omega, theta_hat, k_min)

    def compute(self, tick: int, z_hat: np.ndarray, theta_hat: np.ndarray) -> Command:
        """The command for ``tick`` from the estimate of that tick."""
        t = tick * self.sample_period
        f_r = self.reference.at(t)
        if self.params.mode == "passive":
            return self._limited(tick, t, f_r[0], f_r[0], (0.0, 0.0, 0.0), "passive")
        # Fresh C-contiguous float64 copies: message arrays may be read-only or strided, and the
        # compiled law has one cached specialisation.
        z_hat, theta_hat = np.array(z_hat, dtype=np.float64), np.array(theta_hat, dtype=np.float64)
        if not (np.isfinite(z_hat).all() and np.isfinite(theta_hat).all()):
            return self.fallback(tick)
        u_law, errors = self.law(t, f_r, z_hat, theta_hat)
        if not math.isfinite(u_law):
            return self.fallback(tick)
        return self._limited(tick, t, u_law, f_r[0], errors, "active")

    def fallback(self, tick: int) -> Command:
        """The safe command: the static uplift ``fallback_force``, reached within the slew limit."""
        t = tick * self.sample_period
        force = self.params.fallback_force
        return self._limited(tick, t, force, self.reference.at(t)[0], (0.0, 0.0, 0.0), "fallback")

    def law(
        self, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, tuple[float, float, float]]:
        """Eqs. (23)-(43): the unsaturated u and (e1, e2, e3) (compiled :func:`backstepping_law`)."""
        p, c = self.pantograph, self.params
        u, e1, e2, e3 = backstepping_law(
            float(t), np.array(f_r, dtype=np.float64), np.array(z_hat, dtype=np.float64),
            np.array(theta_hat, dtype=np.float64), self.omega, p.m1, p.b1, p.k1, p.m2, p.b2,
            float(c.c1), float(c.c2), float(c.c3), float(c.stiffness_hat_min),
        )
        return u, (e1, e2, e3)

    def _limited(
        self,
        tick: int,
        t: float,
        u: float,
        force_reference: float,
        errors: tuple[float, float, float],
        mode: str,
    ) -> Command:
        """Slew-rate limit from the last command, then saturation; updates the actuator state."""
        p = self.params
        has_last = self.last_u is not None
        applied = limit_command(
            float(u), self.last_u if has_last else 0.0, has_last, tick - self.last_tick,
            float(p.slew_rate_max), self.sample_period, float(p.u_min), float(p.u_max),
        )
        self.last_u, self.last_tick = applied, tick
        return Command(
            tick=tick,
            time=t,
            u=applied,
            u_unsaturated=u,
            force_reference=force_reference,
            tracking_error=errors,
            saturated=applied != u,
            mode=mode,
        )
