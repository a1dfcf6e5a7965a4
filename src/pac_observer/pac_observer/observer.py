"""Kalman-like adaptive observer of Chater et al. (2015), eq. (17), in a well-conditioned discrete form.

Continuous equations (eq. (17), with the bold matrix read as Lambda, see
docs/paper_errata.md)::

    z_hat'   = A z_hat + phi(u) + psi(y) theta_hat
               + (Lambda S_theta^-1 Lambda^T C^T + S_z^-1 C^T) Sigma (y - C z_hat)
    theta_hat' = S_theta^-1 Lambda^T C^T Sigma (y - C z_hat)
    Lambda'  = (A - S_z^-1 C^T Sigma C) Lambda + psi(y)
    S_z'     = -rho_z S_z - A^T S_z - S_z A + C^T Sigma C
    S_theta' = -rho_theta S_theta + Lambda^T C^T Sigma C Lambda

Implementation (derivation in docs/numerics.md).  With xi := z_hat - Lambda theta_hat
the theta_hat' terms cancel and eq. (17) is exactly

    xi'      = A xi + phi(u) + S_z^-1 C^T Sigma (y - C xi)         (a linear observer)
    theta_hat' = S_theta^-1 Phi^T Sigma (y - C xi - Phi theta_hat),  Phi := C Lambda
    (continuous recursive least squares with forgetting), z_hat = xi + Lambda theta_hat.

Per sample period [t_{k-1}, t_k] the observer

1. advances S_z exactly (a constant-coefficient Lyapunov ODE, independent of the data),
2. advances X = [xi | Lambda] with one RK4 step, y interpolated linearly between the
   samples y_{k-1}, y_k (both known at tick k) and u held (the force applied over the period),
3. updates S_theta and theta_hat by the implicit-Euler step of the RLS equations, which is
   the exact discrete RLS with forgetting factor exp(-rho_theta dt): the parameter error
   contracts in the S_theta norm at every step however small S_theta has become, which is
   what a naive explicit step fails to do (PAPER_NOTES item 5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from pac_common.integrate import rk4_step
from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters

from .parameters import ObserverParameters


class ObserverDivergedError(RuntimeError):
    """The update produced non-finite values or lost positive definiteness; state is unchanged."""

    def __init__(self, tick: int, reason: str) -> None:
        self.tick = tick
        self.reason = reason
        super().__init__(f"observer diverged at tick {tick}: {reason}")


@dataclass(frozen=True)
class Estimate:
    """The observer's output at one tick."""

    tick: int
    time: float
    z_hat: np.ndarray  # (z1, z2, z1', z2') [m, m/s]
    theta_hat: np.ndarray  # [N/m]
    stiffness_hat: float  # k_hat = v(t)^T theta_hat, eq. (8) [N/m]
    contact_force_hat: float  # F_hat = k_hat y1, eq. (6) [N]
    innovation: np.ndarray  # y - C z_hat before the update [m]


class AdaptiveObserver:
    """Eq. (17) with explicit state; call :meth:`update` once per tick, in tick order."""

    def __init__(
        self,
        pantograph: PantographParameters,
        track: TrackParameters,
        params: ObserverParameters,
        sample_period: float,
    ) -> None:
        if not (math.isfinite(sample_period) and sample_period > 0.0):
            raise ValueError(f"sample_period must be positive, got {sample_period!r}")
        self.pantograph = pantograph
        self.params = params
        self.sample_period = dt = sample_period
        self.omega = track.omega
        a = model.state_matrix(pantograph)
        c = model.OUTPUT_MATRIX
        sigma = np.diag(params.sigma)
        self._a = a
        self._c_t_sigma = c.T @ sigma  # C^T Sigma (4x2)
        self._sigma = sigma
        # Exact half-step map of S_z' = -(A + rho/2 I)^T S_z - S_z (A + rho/2 I) + C^T Sigma C.
        shifted = a + 0.5 * params.rho_z * np.eye(4)
        self._sz_half_map = scipy.linalg.expm(-shifted * (0.5 * dt))
        self._sz_limit = scipy.linalg.solve_continuous_lyapunov(shifted.T, c.T @ sigma @ c)
        self._sz_half_input = self._sz_limit - self._sz_half_map.T @ self._sz_limit @ self._sz_half_map
        self._theta_forgetting = math.exp(-params.rho_theta * dt)
        # A constant input (1 - forgetting) * floor * I keeps S_theta >= floor * I once the
        # initial S_theta has been forgotten, so a long run without excitation (z1 = 0, no
        # contact) cannot let S_theta underflow; floor is ~1e6 times below the information
        # a 100 N contact gives (docs/numerics.md).
        self._floor_input = (1.0 - self._theta_forgetting) * params.s_theta_floor * np.eye(3)
        self.reset()

    # -- state -----------------------------------------------------------------
    def reset(self) -> None:
        """Back to the initial conditions of :class:`ObserverParameters` (tick 0)."""
        p = self.params
        self.tick = -1  # no sample processed yet
        self.theta_hat = np.array(p.theta_hat0, dtype=float)
        self.lam = np.zeros((4, 3))  # Lambda(0) = 0: z_hat(0) carries no theta information
        self.xi = np.array(p.z_hat0, dtype=float)
        self.s_z = p.s_z0 * np.eye(4)
        self.s_theta = p.s_theta0 * np.eye(3)
        self._gain_now = self._gain(self.s_z)
        self._closed_now = self._closed(self._gain_now)
        self._s_z_settled = False
        self._y_prev = np.zeros(2)

    @property
    def z_hat(self) -> np.ndarray:
        return self.xi + self.lam @ self.theta_hat

    def _closed(self, gain: np.ndarray) -> np.ndarray:
        """A - L C: the observer's homogeneous dynamics (eq. (17), Lambda' and xi')."""
        out = self._a.copy()
        out[:, :2] -= gain
        return out

    def _gain(self, s_z: np.ndarray) -> np.ndarray:
        """Output injection L = S_z^-1 C^T Sigma (4x2)."""
        return np.linalg.solve(s_z, self._c_t_sigma)

    # -- one tick ----------------------------------------------------------------
    def update(self, tick: int, y: tuple[float, float], actuator_force: float) -> Estimate:
        """Process the sample y_k = (z1, z2) of ``tick`` and the force applied over (t_{k-1}, t_k].

        The first call initialises and returns the initial estimate.  Ticks must
        increase; a gap (lost samples) is bridged period by period with y
        interpolated linearly across it and the force held.  Raises
        :class:`ObserverDivergedError` and leaves the state untouched if the update
        is not finite or S_theta is not positive definite.
        """
        y_now = np.array(y, dtype=float)
        if self.tick < 0:
            self.tick = tick
            self._y_prev = y_now
            return self._estimate(y_now, y_now - self.z_hat[:2])
        gap = tick - self.tick
        if gap < 1:
            raise ValueError(f"observer expects a tick after {self.tick}, got {tick}")
        saved = self._snapshot()
        y_start = self._y_prev
        try:
            with np.errstate(all="ignore"):  # non-finite results are checked and reported
                for j in range(1, gap + 1):
                    innovation = self._step(y_start + (j / gap) * (y_now - y_start), actuator_force)
        except ObserverDivergedError:
            self._restore(saved)
            raise
        return self._estimate(y_now, innovation)

    #: Everything an update changes (each is replaced, never mutated in place, so a snapshot is cheap).
    _STATE = (
        "tick",
        "xi",
        "lam",
        "s_z",
        "s_theta",
        "theta_hat",
        "_gain_now",
        "_closed_now",
        "_s_z_settled",
        "_y_prev",
    )

    def _snapshot(self) -> tuple:
        return tuple(getattr(self, name) for name in self._STATE)

    def _restore(self, saved: tuple) -> None:
        for name, value in zip(self._STATE, saved, strict=True):
            setattr(self, name, value)

    def _step(self, y_now: np.ndarray, actuator_force: float) -> np.ndarray:
        """One sample period to tick + 1; returns the a priori innovation."""
        tick = self.tick + 1
        dt = self.sample_period
        t0 = self.tick * dt

        # 1. S_z, exact, at the start, middle and end of the period (until it has settled).
        if self._s_z_settled:
            s_z_end = self.s_z
            m0 = m_mid = m_end = self._closed_now
            gain0 = gain_mid = gain_end = self._gain_now
        else:
            s_z_mid = self._sz_half_map.T @ self.s_z @ self._sz_half_map + self._sz_half_input
            s_z_end = self._sz_half_map.T @ s_z_mid @ self._sz_half_map + self._sz_half_input
            gain0, gain_mid, gain_end = self._gain_now, self._gain(s_z_mid), self._gain(s_z_end)
            m0, m_mid, m_end = self._closed_now, self._closed(gain_mid), self._closed(gain_end)

        # 2. X = [xi | Lambda], one RK4 step of X' = (A - L C) X + [phi(u) + L y, psi(y)].
        y0 = self._y_prev
        dy = y_now - y0
        phi = model.input_vector(actuator_force, self.pantograph)
        x = np.empty((4, 4))
        x[:, 0] = self.xi
        x[:, 1:] = self.lam
        omega, panto = self.omega, self.pantograph

        # S_z is known exactly at the stage times of RK4 (start, middle, end of the period).
        stage_gains = {0: (m0, gain0), 1: (m_mid, gain_mid), 2: (m_end, gain_end)}

        def f(t: float, xx: np.ndarray) -> np.ndarray:
            frac = (t - t0) / dt
            closed, gain = stage_gains[round(2.0 * frac)]
            y_s = y0 + frac * dy
            out = closed @ xx
            out[:, 0] += phi + gain @ y_s
            out[2, 1:] += model.output_regressor_row(y_s[0], t, omega, panto)
            return out

        x = rk4_step(f, t0, x, dt)
        if not np.isfinite(x).all():
            raise ObserverDivergedError(tick, "xi or Lambda is not finite")
        xi, lam = x[:, 0], x[:, 1:]

        # 3. RLS: implicit Euler of the theta_hat / S_theta equations.
        phi_reg = lam[:2, :]  # Phi = C Lambda (2x3)
        weighted = phi_reg.T @ self._sigma  # Phi^T Sigma (3x2)
        s_theta = self._theta_forgetting * self.s_theta + dt * (weighted @ phi_reg) + self._floor_input
        innovation = y_now - xi[:2] - phi_reg @ self.theta_hat  # a priori, y - C z_hat
        try:
            np.linalg.cholesky(s_theta)  # positive definiteness check (raises otherwise)
            step = np.linalg.solve(s_theta, dt * (weighted @ innovation))
        except np.linalg.LinAlgError as exc:
            raise ObserverDivergedError(tick, f"S_theta not positive definite ({exc})") from None
        theta_hat = self.theta_hat + step
        if not np.isfinite(theta_hat).all():
            raise ObserverDivergedError(tick, "theta_hat is not finite")

        # Commit.
        if not self._s_z_settled:
            settled = np.max(np.abs(s_z_end - self.s_z)) <= 1e-13 * np.max(np.abs(s_z_end))
            self.s_z, self._gain_now, self._closed_now, self._s_z_settled = s_z_end, gain_end, m_end, settled
        self.xi, self.lam, self.s_theta, self.theta_hat = xi, lam, s_theta, theta_hat
        self.tick = tick
        self._y_prev = y_now
        return innovation

    def _estimate(self, y_now: np.ndarray, innovation: np.ndarray) -> Estimate:
        t = self.tick * self.sample_period
        k_hat = model.stiffness(t, self.omega, self.theta_hat)
        return Estimate(
            tick=self.tick,
            time=t,
            z_hat=self.z_hat,
            theta_hat=self.theta_hat.copy(),
            stiffness_hat=k_hat,
            contact_force_hat=k_hat * float(y_now[0]),
            innovation=innovation,
        )
