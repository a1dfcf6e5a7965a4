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
   what a naive explicit step fails to do (docs/paper_errata.md #5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numba import njit

from pac_common.integrate import rk4_step
from pac_common.smallmat import matmul, matvec
from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters

from .parameters import ObserverParameters

# Status codes of the compiled step (0: fine); the text is the ObserverDivergedError reason.
_DIVERGED_REASONS = {
    1: "xi or Lambda is not finite",
    2: "S_theta not positive definite (Cholesky failed)",
    3: "theta_hat is not finite",
}


@njit(cache=True, error_model="numpy")
def cholesky_solve(a: np.ndarray, b: np.ndarray) -> tuple[bool, np.ndarray]:
    """x = a^-1 b for a symmetric positive definite a (n x n), b (n x m); False if a is not.

    The Cholesky factor doubles as the positive-definiteness check (a pivot <= 0 or NaN fails,
    as LAPACK's potrf does).
    """
    n = a.shape[0]
    lo = np.zeros((n, n))
    for j in range(n):
        d = a[j, j]
        for k in range(j):
            d -= lo[j, k] * lo[j, k]
        if not d > 0.0:
            return False, np.zeros_like(b)
        lo[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= lo[i, k] * lo[j, k]
            lo[i, j] = s / lo[j, j]
    x = b.copy()
    for c in range(b.shape[1]):  # L w = b, then L^T x = w
        for i in range(n):
            s = x[i, c]
            for k in range(i):
                s -= lo[i, k] * x[k, c]
            x[i, c] = s / lo[i, i]
        for i in range(n - 1, -1, -1):
            s = x[i, c]
            for k in range(i + 1, n):
                s -= lo[k, i] * x[k, c]
            x[i, c] = s / lo[i, i]
    return True, x


@njit(cache=True, error_model="numpy")
def _half_step_s_z(s_z: np.ndarray, half_map: np.ndarray, half_input: np.ndarray) -> np.ndarray:
    """S_z half a period later, exactly: E^T S_z E + Q_h (docs/numerics.md, observer step 1)."""
    return matmul(matmul(half_map.T, s_z), half_map) + half_input


@njit(cache=True, error_model="numpy")
def _observer_rhs(
    t: float,
    x: np.ndarray,
    t0: float,
    dt: float,
    gains: np.ndarray,
    a: np.ndarray,
    y0: np.ndarray,
    dy: np.ndarray,
    u: float,
    omega: float,
    m1: float,
    m2: float,
) -> np.ndarray:
    """X' = (A - L C) X + [phi(u) + L y, psi(y)] for X = [xi | Lambda], eq. (17) in xi form.

    L is known exactly at the RK4 stage times (start, middle, end of the period:
    ``gains[0..2]``); y is interpolated linearly between the samples.
    """
    frac = (t - t0) / dt
    gain = gains[round(2.0 * frac)]
    y1_s, y2_s = y0[0] + frac * dy[0], y0[1] + frac * dy[1]  # y at t (scalars: no allocation)
    closed = a.copy()  # A - L C
    closed[:, :2] -= gain
    out = matmul(closed, x)
    for i in range(4):
        out[i, 0] += gain[i, 0] * y1_s + gain[i, 1] * y2_s  # + L y
    out[3, 0] += model.actuator_acceleration(u, m2)  # + phi(u), eq. (14)
    out[2, 1:] += model.regressor_row(y1_s, t, omega, m1)  # + psi(y), eq. (15)
    return out


# The observer's state and constants travel through the compiled functions as tuples:
#   state  = (xi, Lambda, S_z, S_z settled, L, S_theta, theta_hat, y_prev)
#   consts = (dt, A, C^T Sigma, Sigma, E, Q_h, exp(-rho_theta dt), (1 - exp(-rho_theta dt)) s_floor,
#             omega, m1, m2)


@njit(cache=True, error_model="numpy")
def observer_initial_state(xi0: np.ndarray, theta_hat0: np.ndarray, s_z0: float, s_theta0: float, consts):
    """The state at the initial conditions: Lambda(0) = 0 (z_hat(0) carries no theta information)."""
    s_z = s_z0 * np.eye(4)
    ok, gain = cholesky_solve(s_z, consts[2])  # L = S_z^-1 C^T Sigma
    if not ok:
        gain[:] = np.nan
    s_theta = s_theta0 * np.eye(3)
    return (xi0.copy(), np.zeros((4, 3)), s_z, False, gain, s_theta, theta_hat0.copy(), np.zeros(2))


@njit(cache=True, error_model="numpy")
def observer_output(state) -> np.ndarray:
    """z_hat = xi + Lambda theta_hat (docs/numerics.md)."""
    xi, lam, theta_hat = state[0], state[1], state[6]
    return xi + matvec(lam, theta_hat)


@njit(cache=True, error_model="numpy")
def observer_step(t0: float, state, y_now: np.ndarray, u: float, consts):
    """One sample period of the observer from t0 to t0 + dt (docs/numerics.md, steps 1-3).

    Pure: the inputs are not modified.  Returns (status, state, innovation); status 0 is
    fine, otherwise a key of ``_DIVERGED_REASONS`` and the returned state is the input state.
    """
    xi, lam, s_z, s_z_settled, gain_now, s_theta, theta_hat, y_prev = state
    dt, a, c_t_sigma, sigma, sz_half_map, sz_half_input, forgetting, floor_input, omega, m1, m2 = consts
    # 1. S_z exactly at the start, middle and end of the period (until it has settled).
    gains = np.empty((3, 4, 2))
    gains[0] = gain_now
    if s_z_settled:
        s_z_end = s_z
        gains[1] = gain_now
        gains[2] = gain_now
    else:
        s_z_mid = _half_step_s_z(s_z, sz_half_map, sz_half_input)
        s_z_end = _half_step_s_z(s_z_mid, sz_half_map, sz_half_input)
        _, gains[1] = cholesky_solve(s_z_mid, c_t_sigma)  # L = S_z^-1 C^T Sigma
        _, gains[2] = cholesky_solve(s_z_end, c_t_sigma)

    # 2. X = [xi | Lambda], one RK4 step.
    x = np.empty((4, 4))
    x[:, 0] = xi
    x[:, 1:] = lam
    x = rk4_step(_observer_rhs, t0, x, dt, (t0, dt, gains, a, y_prev, y_now - y_prev, u, omega, m1, m2))
    innovation = np.zeros(2)
    if not np.isfinite(x).all():
        return 1, state, innovation
    xi_new = x[:, 0].copy()
    lam_new = x[:, 1:].copy()

    # 3. RLS: implicit Euler of the theta_hat / S_theta equations.
    phi_reg = lam_new[:2, :].copy()  # Phi = C Lambda (2x3)
    weighted = matmul(phi_reg.T, sigma)  # Phi^T Sigma (3x2)
    s_theta_new = forgetting * s_theta + dt * matmul(weighted, phi_reg) + floor_input * np.eye(3)
    innovation = y_now - xi_new[:2] - matvec(phi_reg, theta_hat)  # a priori, y - C z_hat
    rhs = (dt * matvec(weighted, innovation)).reshape((3, 1))
    ok, step = cholesky_solve(s_theta_new, rhs)
    if not ok:
        return 2, state, innovation
    theta_new = theta_hat + step[:, 0]
    if not np.isfinite(theta_new).all():
        return 3, state, innovation

    settled = s_z_settled
    if not s_z_settled:
        settled = np.max(np.abs(s_z_end - s_z)) <= 1e-13 * np.max(np.abs(s_z_end))
    new = (xi_new, lam_new, s_z_end, settled, gains[2].copy(), s_theta_new, theta_new, y_now.copy())
    return 0, new, innovation


@njit(cache=True, error_model="numpy")
def observer_advance(tick: int, state, y_now: np.ndarray, gap: int, u: float, consts):
    """From ``tick`` to ``tick + gap``: ``gap`` periods, y interpolated linearly from y_prev, u held.

    Returns (status, tick reached or failed at, state, a priori innovation of the last period);
    on failure the returned state is the input state.
    """
    dt = consts[0]
    y_start = state[7]
    new = state
    innovation = np.zeros(2)
    for j in range(1, gap + 1):
        y_j = y_start + (j / gap) * (y_now - y_start)
        status, new, innovation = observer_step((tick + j - 1) * dt, new, y_j, u, consts)
        if status:
            return status, tick + j, state, innovation
    return 0, tick + gap, new, innovation


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
        self._floor_input = (1.0 - self._theta_forgetting) * params.s_theta_floor
        #: What the compiled functions take as ``consts``.
        # C-contiguous float64 everywhere: one compiled specialisation, the one the cache holds.
        c_arr = np.ascontiguousarray
        self.consts = (
            float(dt),
            c_arr(a, dtype=np.float64),
            c_arr(self._c_t_sigma, dtype=np.float64),
            c_arr(sigma, dtype=np.float64),
            c_arr(self._sz_half_map, dtype=np.float64),
            c_arr(self._sz_half_input, dtype=np.float64),
            float(self._theta_forgetting),
            float(self._floor_input),
            float(self.omega),
            float(pantograph.m1),
            float(pantograph.m2),
        )
        self.reset()

    # -- state -----------------------------------------------------------------
    def reset(self) -> None:
        """Back to the initial conditions of :class:`ObserverParameters` (tick 0)."""
        p = self.params
        self.tick = -1  # no sample processed yet
        self._set_state(
            observer_initial_state(
                np.array(p.z_hat0, dtype=float),
                np.array(p.theta_hat0, dtype=float),
                float(p.s_z0),
                float(p.s_theta0),
                self.consts,
            )
        )

    @property
    def z_hat(self) -> np.ndarray:
        return observer_output(self._state())

    def _state(self) -> tuple:
        return (
            self.xi,
            self.lam,
            self.s_z,
            self._s_z_settled,
            self._gain_now,
            self.s_theta,
            self.theta_hat,
            self._y_prev,
        )

    def _set_state(self, state: tuple) -> None:
        (
            self.xi,
            self.lam,
            self.s_z,
            self._s_z_settled,
            self._gain_now,
            self.s_theta,
            self.theta_hat,
            self._y_prev,
        ) = state

    # -- one tick ----------------------------------------------------------------
    def update(self, tick: int, y: tuple[float, float], actuator_force: float) -> Estimate:
        """Process the sample y_k = (z1, z2) of ``tick`` and the force applied over (t_{k-1}, t_k].

        The first call initialises and returns the initial estimate.  Ticks must
        increase; a gap (lost samples) is bridged period by period with y
        interpolated linearly across it and the force held (compiled
        :func:`observer_advance`).  Raises :class:`ObserverDivergedError` and leaves
        the state untouched if the update is not finite or S_theta is not positive definite.
        """
        y_now = np.array(y, dtype=float)
        if self.tick < 0:
            self.tick = tick
            self._y_prev = y_now
            return self._estimate(y_now, y_now - self.z_hat[:2])
        gap = tick - self.tick
        if gap < 1:
            raise ValueError(f"observer expects a tick after {self.tick}, got {tick}")
        status, reached, state, innovation = observer_advance(
            self.tick, self._state(), y_now, gap, float(actuator_force), self.consts
        )
        if status:
            raise ObserverDivergedError(reached, _DIVERGED_REASONS[status])
        self._set_state(state)
        self.tick = reached
        return self._estimate(y_now, innovation)

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
