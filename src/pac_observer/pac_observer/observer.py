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

import copy
import functools
import math
import warnings
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numba import njit

from pac_common import divergence
from pac_common.divergence import COVARIANCE_NOT_POSITIVE, OBSERVER_GAIN_NOT_FINITE, THETA_NOT_FINITE
from pac_common.parameters import ParameterError
from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters, positive_period

from .observers import OBSERVER_CODES
from .parameters import ObserverParameters

#: The observer's state and its scratch space: one named record (a numpy structured scalar), so that
#: the compiled step allocates nothing.  ``xi`` .. ``y_prev`` are the state (docs/numerics.md), the
#: fields after ``y_prev`` are scratch, meaningless between steps.
OBSERVER_STATE = np.dtype(
    [
        ("xi", "f8", 4),
        ("lam", "f8", (4, 3)),  # Lambda
        ("s_z", "f8", (4, 4)),
        ("settled", "b1"),  # S_z has reached its limit: L is constant from here on
        ("gain", "f8", (4, 2)),  # L = S_z^-1 C^T Sigma at the present S_z
        ("s_theta", "f8", (3, 3)),
        ("theta_hat", "f8", 3),
        ("y_prev", "f8", 2),
        # scratch
        ("gains", "f8", (3, 4, 2)),  # L at the start, middle and end of the period
        ("s_mid", "f8", (4, 4)),
        ("s_end", "f8", (4, 4)),
        ("tmp", "f8", (4, 4)),
        ("lo", "f8", (4, 4)),  # Cholesky factor
        ("x", "f8", (4, 4)),  # X = [xi | Lambda]
        ("stage", "f8", (4, 4)),
        ("k", "f8", (4, 4, 4)),  # the four RK4 slopes
        ("x_new", "f8", (4, 4)),
        ("weighted", "f8", (3, 2)),  # Phi^T Sigma
        ("s_theta_new", "f8", (3, 3)),
        ("rhs", "f8", (3, 1)),
        ("step", "f8", (3, 1)),
        ("innovation", "f8", 2),  # a priori y - C z_hat of the last period
        ("z_hat", "f8", 4),  # z_hat = xi + Lambda theta_hat after the last update
        # observer:=contact_force (pac_observer.contact_force; the filters' states are its bank's
        # arrays): the selected filter, its F_hat, and the prediction x^- (scratch)
        ("cf_selected", "i8"),
        ("cf_force", "f8"),
        ("cf_pred", "f8", 5),
        # observer:=head_balance (pac_observer.head_balance; F_hat in cf_force): C, the mean's offset
        ("hb_offset", "f8"),
        ("hb_samples", "i8"),  # samples the mean has taken so far
    ]
)

#: What the compiled step takes as constants (``AdaptiveObserver.consts``).
OBSERVER_CONSTS = np.dtype(
    [
        ("dt", "f8"),
        ("a", "f8", (4, 4)),  # A of eq. (12), the observer's (nominal) model
        ("c_t_sigma", "f8", (4, 2)),  # C^T Sigma
        ("sigma", "f8", (2, 2)),
        ("half_map", "f8", (4, 4)),  # E: exact half-period map of S_z
        ("half_input", "f8", (4, 4)),  # Q_h
        ("forgetting", "f8"),  # exp(-rho_theta dt)
        ("floor_input", "f8"),  # (1 - exp(-rho_theta dt)) s_theta_floor
        ("omega", "f8"),
        ("m1", "f8"),
        ("m2", "f8"),
        ("kind", "i8"),  # observers.OBSERVER_CODES: which observer the records are
        # observer:=contact_force (the filters' Phi, Gamma, K are its bank's arrays)
        ("cf_forget", "f8"),  # lam = exp(-dt / frame_mass_window)
        ("cf_inv_r2", "f8"),  # 1 / position_noise^2
        # observer:=head_balance (pac_observer.head_balance)
        ("hb_k1", "f8"),
        ("hb_b1", "f8"),
        ("hb_forget", "f8"),  # lam = exp(-dt / head_balance_window)
    ]
)


@njit(cache=True, error_model="numpy")
def cholesky_solve_into(a: np.ndarray, b: np.ndarray, lo: np.ndarray, x: np.ndarray) -> bool:
    """x <- a^-1 b for a symmetric positive definite a (n x n), b (n x m); False (x zero) if a is not.

    The Cholesky factor (into ``lo``) doubles as the positive-definiteness check (a pivot <= 0 or
    NaN fails, as LAPACK's potrf does).
    """
    n = a.shape[0]
    for j in range(n):
        d = a[j, j]
        for k in range(j):
            d -= lo[j, k] * lo[j, k]
        if not d > 0.0:
            x[:] = 0.0
            return False
        lo[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= lo[i, k] * lo[j, k]
            lo[i, j] = s / lo[j, j]
    x[:] = b
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
    return True


@njit(cache=True, error_model="numpy")
def cholesky_solve(a: np.ndarray, b: np.ndarray) -> tuple[bool, np.ndarray]:
    """x = a^-1 b (:func:`cholesky_solve_into` into new arrays); False if a is not positive definite."""
    x = np.empty_like(b)
    ok = cholesky_solve_into(a, b, np.empty_like(a), x)
    return ok, x


@njit(cache=True, error_model="numpy")
def _half_step_s_z(s_z: np.ndarray, half_map: np.ndarray, half_input: np.ndarray, tmp: np.ndarray, out):
    """out <- S_z half a period later, exactly: E^T S_z E + Q_h (docs/numerics.md, observer step 1)."""
    for i in range(4):
        for j in range(4):
            s = 0.0
            for k in range(4):
                s += half_map[k, i] * s_z[k, j]
            tmp[i, j] = s
    for i in range(4):
        for j in range(4):
            s = 0.0
            for k in range(4):
                s += tmp[i, k] * half_map[k, j]
            out[i, j] = s + half_input[i, j]


@njit(cache=True, error_model="numpy")
def _observer_rhs(t, x, t0, dt, gains, a, y0_1, y0_2, dy_1, dy_2, u, omega, m1, m2, out) -> None:
    """out <- X' = (A - L C) X + [phi(u) + L y, psi(y)] for X = [xi | Lambda], eq. (17) in xi form.

    L is known exactly at the RK4 stage times (start, middle, end of the period:
    ``gains[0..2]``); y is interpolated linearly between the samples.
    """
    frac = (t - t0) / dt
    g = round(2.0 * frac)
    y1_s, y2_s = y0_1 + frac * dy_1, y0_2 + frac * dy_2  # y at t
    for i in range(4):
        for j in range(4):
            s = 0.0
            for k in range(4):
                c = a[i, k] - gains[g, i, k] if k < 2 else a[i, k]  # A - L C
                s += c * x[k, j]
            out[i, j] = s
    for i in range(4):
        out[i, 0] += gains[g, i, 0] * y1_s + gains[g, i, 1] * y2_s  # + L y
    out[3, 0] += model.actuator_acceleration(u, m2)  # + phi(u), eq. (14)
    r0, r1, r2 = model.regressor_row3(y1_s, t, omega, m1)  # + psi(y), eq. (15)
    out[2, 1] += r0
    out[2, 2] += r1
    out[2, 3] += r2


@njit(cache=True, error_model="numpy")
def _axpy_into(x: np.ndarray, a: float, k: np.ndarray, out: np.ndarray) -> None:
    """out <- x + a k (4 x 4)."""
    for i in range(4):
        for j in range(4):
            out[i, j] = x[i, j] + a * k[i, j]


@njit(cache=True, error_model="numpy")
def observer_init(st, xi0: np.ndarray, theta_hat0: np.ndarray, s_z0: float, s_theta0: float, c) -> None:
    """st <- the state at the initial conditions: Lambda(0) = 0 (z_hat(0) carries no theta information)."""
    st.xi[:] = xi0
    st.lam[:] = 0.0
    for i in range(4):
        for j in range(4):
            st.s_z[i, j] = s_z0 * (1.0 if i == j else 0.0)
    st.settled = False
    if not cholesky_solve_into(st.s_z, c.c_t_sigma, st.lo, st.gain):  # L = S_z^-1 C^T Sigma
        st.gain[:] = np.nan
    for i in range(3):
        for j in range(3):
            st.s_theta[i, j] = s_theta0 * (1.0 if i == j else 0.0)
    st.theta_hat[:] = theta_hat0
    st.y_prev[:] = 0.0
    st.innovation[:] = 0.0
    observer_output(st)


@njit(cache=True, error_model="numpy")
def observer_output(st) -> None:
    """st.z_hat <- xi + Lambda theta_hat (docs/numerics.md)."""
    for i in range(4):
        s = 0.0
        for k in range(3):
            s += st.lam[i, k] * st.theta_hat[k]
        st.z_hat[i] = st.xi[i] + s


@njit(cache=True, error_model="numpy")
def observer_step(t0: float, st, y1: float, y2: float, u: float, c) -> int:
    """One sample period of the observer from t0 to t0 + dt (docs/numerics.md, steps 1-3), in place.

    Returns the status: 0 fine (the state has moved on and ``st.innovation`` is the a priori
    y - C z_hat), otherwise a code of ``pac_common.divergence`` and the state is untouched.
    """
    dt = c.dt
    gains = st.gains
    # 1. S_z exactly at the start, middle and end of the period (until it has settled).
    gains[0] = st.gain
    if st.settled:
        s_z_end = st.s_z
        gains[1] = st.gain
        gains[2] = st.gain
    else:
        _half_step_s_z(st.s_z, c.half_map, c.half_input, st.tmp, st.s_mid)
        _half_step_s_z(st.s_mid, c.half_map, c.half_input, st.tmp, st.s_end)
        s_z_end = st.s_end
        cholesky_solve_into(st.s_mid, c.c_t_sigma, st.lo, gains[1])  # L = S_z^-1 C^T Sigma
        cholesky_solve_into(st.s_end, c.c_t_sigma, st.lo, gains[2])

    # 2. X = [xi | Lambda], one RK4 step (the arithmetic of pac_common.integrate.rk4_step).
    x, stage, k, x_new = st.x, st.stage, st.k, st.x_new
    x[:, 0] = st.xi
    x[:, 1:] = st.lam
    y0_1, y0_2 = st.y_prev[0], st.y_prev[1]
    dy_1, dy_2 = y1 - y0_1, y2 - y0_2
    args = (t0, dt, gains, c.a, y0_1, y0_2, dy_1, dy_2, u, c.omega, c.m1, c.m2)
    h = dt
    _observer_rhs(t0, x, *args, k[0])
    _axpy_into(x, 0.5 * h, k[0], stage)
    _observer_rhs(t0 + 0.5 * h, stage, *args, k[1])
    _axpy_into(x, 0.5 * h, k[1], stage)
    _observer_rhs(t0 + 0.5 * h, stage, *args, k[2])
    _axpy_into(x, h, k[2], stage)
    _observer_rhs(t0 + h, stage, *args, k[3])
    finite = True
    for i in range(4):
        for j in range(4):
            v = x[i, j] + (h / 6.0) * (k[0, i, j] + 2.0 * (k[1, i, j] + k[2, i, j]) + k[3, i, j])
            x_new[i, j] = v
            finite = finite and math.isfinite(v)
    if not finite:
        st.innovation[:] = 0.0
        return OBSERVER_GAIN_NOT_FINITE

    # 3. RLS: implicit Euler of the theta_hat / S_theta equations; Phi = C Lambda = x_new[:2, 1:].
    w, sigma = st.weighted, c.sigma
    for i in range(3):
        for j in range(2):
            s = 0.0
            for m in range(2):
                s += x_new[m, 1 + i] * sigma[m, j]
            w[i, j] = s  # Phi^T Sigma
    for i in range(3):
        for j in range(3):
            s = 0.0
            for m in range(2):
                s += w[i, m] * x_new[m, 1 + j]
            st.s_theta_new[i, j] = (c.forgetting * st.s_theta[i, j] + dt * s) + c.floor_input * (
                1.0 if i == j else 0.0
            )
    th = st.theta_hat
    for i in range(2):  # a priori, y - C z_hat
        s = 0.0
        for m in range(3):
            s += x_new[i, 1 + m] * th[m]
        st.innovation[i] = ((y1 if i == 0 else y2) - x_new[i, 0]) - s
    for i in range(3):
        s = 0.0
        for m in range(2):
            s += w[i, m] * st.innovation[m]
        st.rhs[i, 0] = dt * s
    if not cholesky_solve_into(st.s_theta_new, st.rhs, st.lo, st.step):
        return COVARIANCE_NOT_POSITIVE
    for i in range(3):
        if not math.isfinite(th[i] + st.step[i, 0]):
            return THETA_NOT_FINITE

    if not st.settled:
        big, diff = 0.0, 0.0
        for i in range(4):
            for j in range(4):
                b, d = abs(s_z_end[i, j]), abs(s_z_end[i, j] - st.s_z[i, j])
                big = b if (b > big or b != b) else big
                diff = d if (d > diff or d != d) else diff
        st.s_z[:] = s_z_end
        st.settled = diff <= 1e-13 * big
    for i in range(3):
        th[i] = th[i] + st.step[i, 0]
    st.xi[:] = x_new[:, 0]
    st.lam[:] = x_new[:, 1:]
    st.gain[:] = gains[2]
    st.s_theta[:] = st.s_theta_new
    st.y_prev[0], st.y_prev[1] = y1, y2
    return 0


@njit(cache=True, error_model="numpy")
def observer_advance(tick: int, st, y1: float, y2: float, gap: int, u: float, c) -> tuple[int, int]:
    """From ``tick`` to ``tick + gap``: ``gap`` periods, y interpolated linearly from y_prev, u held.

    Returns (status, tick reached or failed at); ``st.z_hat`` is then the new estimate and
    ``st.innovation`` the a priori innovation of the last period.  A failure in period j > 1
    leaves the state after period j - 1 (the caller restores a copy if it must).
    """
    dt = c.dt
    y_start_1, y_start_2 = st.y_prev[0], st.y_prev[1]
    for j in range(1, gap + 1):
        f = j / gap
        y_j1 = y_start_1 + f * (y1 - y_start_1)
        y_j2 = y_start_2 + f * (y2 - y_start_2)
        status = observer_step((tick + j - 1) * dt, st, y_j1, y_j2, u, c)
        if status:
            return status, tick + j
    observer_output(st)
    return 0, tick + gap


@njit(cache=True, error_model="numpy")
def observer_start(st, y1: float, y2: float) -> None:
    """The first sample: remembered as y_prev, the innovation against the initial z_hat."""
    st.y_prev[0], st.y_prev[1] = y1, y2
    observer_output(st)
    st.innovation[0] = y1 - st.z_hat[0]
    st.innovation[1] = y2 - st.z_hat[1]


@njit(cache=True, error_model="numpy")
def adaptive_update(k, t, oc, os, bank, y1, y2, u_applied, head_acceleration) -> tuple[int, float, float]:
    """Tick k of the compiled loop (observers.py): eq. (17) on y_k (k = 0: the first sample);
    (status, k_hat, F_hat) with k_hat = v(t)^T theta_hat and F_hat = k_hat y1 (eqs. (6), (8))."""
    if k == 0:
        observer_start(os, y1, y2)
    else:
        status, _ = observer_advance(k - 1, os, y1, y2, 1, u_applied, oc)
        if status:
            return status, 0.0, 0.0
    k_hat = model.stiffness(t, oc.omega, os.theta_hat)
    return 0, k_hat, k_hat * y1


@njit(cache=True, error_model="numpy")
def _init_one(states, xi0, theta_hat0, s_z0, s_theta0, consts) -> None:
    observer_init(states[0], xi0, theta_hat0, s_z0, s_theta0, consts[0])


@njit(cache=True, error_model="numpy")
def _start_one(states, y1, y2) -> None:
    observer_start(states[0], y1, y2)


@njit(cache=True, error_model="numpy")
def _advance_one(states, tick, y1, y2, gap, u, consts) -> tuple[int, int]:
    return observer_advance(tick, states[0], y1, y2, gap, u, consts[0])


def force_estimate(tick: int, sample_period: float, state: np.ndarray) -> Estimate:
    """The Estimate of an observer that gives F_hat and no theta_hat (the contact-force filter, the
    head balance):
    z_hat, F_hat and the innovation of its OBSERVER_STATE record ``state``; theta_hat zeros."""
    st = state[0]
    return Estimate(
        tick=tick,
        time=tick * sample_period,
        z_hat=st["z_hat"].copy(),
        theta_hat=np.zeros(3),
        stiffness_hat=0.0,
        contact_force_hat=float(st["cf_force"]),
        innovation=st["innovation"].copy(),
    )


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


@functools.lru_cache(maxsize=64)  # pure, and scipy's expm dominates building an observer (campaigns)
def _s_z_maps(
    pantograph: PantographParameters, rho_z: float, sigma_diag: tuple[float, ...], dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(E, S_z limit, Q_h): the exact half-step map of
    S_z' = -(A + rho/2 I)^T S_z - S_z (A + rho/2 I) + C^T Sigma C (docs/numerics.md, observer step 1)."""
    import scipy.linalg  # here, not at import: a node starts without loading scipy

    a, c, sigma = model.state_matrix(pantograph), model.OUTPUT_MATRIX, np.diag(sigma_diag)
    shifted = a + 0.5 * rho_z * np.eye(4)
    # A pantograph far stiffer than the sample period resolves (a tiny mass) overflows the
    # exponential: refused in one line, not numpy's warnings followed by a diverged run.
    try:
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)  # scipy's "solution perturbed" too
            half_map = scipy.linalg.expm(-shifted * (0.5 * dt))
            limit = scipy.linalg.solve_continuous_lyapunov(shifted.T, c.T @ sigma @ c)
            half_input = limit - half_map.T @ limit @ half_map
        finite = all(np.isfinite(m).all() for m in (half_map, limit, half_input))
    except (ValueError, RuntimeWarning):  # non-finite input refused (LinAlgError is a ValueError)
        finite = False
    if not finite:
        raise ParameterError(
            "pantograph",
            f"m1={pantograph.m1:g} kg, m2={pantograph.m2:g} kg",
            f"a pantograph whose observer design is finite at a {dt:g} s sample period "
            "(its fastest mode resolved: larger masses or a higher rate_hz)",
        )
    for shared in (half_map, limit, half_input):  # cached and shared by every observer built alike
        shared.setflags(write=False)
    return half_map, limit, half_input


class SampleUpdater(Protocol):
    """What the nodes call on an observer core each sample (AdaptiveObserver, ContactForceObserver)."""

    def update(
        self, tick: int, y: tuple[float, float], actuator_force: float, head_acceleration: float = ...
    ) -> Estimate: ...


class AdaptiveObserver:
    """Eq. (17) with explicit state; call :meth:`update` once per tick, in tick order."""

    def __init__(
        self,
        pantograph: PantographParameters,
        track: TrackParameters,
        params: ObserverParameters,
        sample_period: float,
    ) -> None:
        positive_period(sample_period)
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
        self._sz_half_map, self._sz_limit, self._sz_half_input = _s_z_maps(
            pantograph, float(params.rho_z), tuple(params.sigma), dt
        )
        self._theta_forgetting = math.exp(-params.rho_theta * dt)
        # A constant input (1 - forgetting) * floor * I keeps S_theta >= floor * I once the
        # initial S_theta has been forgotten, so a long run without excitation (z1 = 0, no
        # contact) cannot let S_theta underflow; floor is ~1e6 times below the information
        # a 100 N contact gives (docs/numerics.md).
        self._floor_input = (1.0 - self._theta_forgetting) * params.s_theta_floor
        #: What the compiled functions take as constants: one OBSERVER_CONSTS record.
        self.consts = np.zeros(1, OBSERVER_CONSTS)
        c = self.consts[0]
        c["dt"], c["a"], c["c_t_sigma"], c["sigma"] = dt, a, self._c_t_sigma, sigma
        c["half_map"], c["half_input"] = self._sz_half_map, self._sz_half_input
        c["forgetting"], c["floor_input"] = self._theta_forgetting, self._floor_input
        c["omega"], c["m1"], c["m2"] = self.omega, pantograph.m1, pantograph.m2
        c["kind"] = OBSERVER_CODES["adaptive"]
        self._st = np.zeros(1, OBSERVER_STATE)
        self.reset()

    # -- state -----------------------------------------------------------------
    def reset(self) -> None:
        """Back to the initial conditions of :class:`ObserverParameters` (tick 0)."""
        p = self.params
        self.tick = -1  # no sample processed yet
        _init_one(
            self._st,
            np.array(p.z_hat0, dtype=float),
            np.array(p.theta_hat0, dtype=float),
            float(p.s_z0),
            float(p.s_theta0),
            self.consts,
        )

    @property
    def state(self) -> np.ndarray:
        """The OBSERVER_STATE record (a 1-element array): what the compiled loop starts from."""
        return self._st

    @property
    def z_hat(self) -> np.ndarray:
        """z_hat = xi + Lambda theta_hat (a copy)."""
        return self._st["z_hat"][0].copy()

    xi = property(lambda self: self._st["xi"][0])
    lam = property(lambda self: self._st["lam"][0])
    s_z = property(lambda self: self._st["s_z"][0])
    s_theta = property(lambda self: self._st["s_theta"][0])
    theta_hat = property(lambda self: self._st["theta_hat"][0])

    def warm_up(self: SampleUpdater) -> None:
        """Updates on a copy (first sample, a tick, a gap): numba loads the compiled code now, not at
        the loop's first tick. Any observer with ``update`` may share it (the contact-force one does)."""
        twin = copy.deepcopy(self)
        twin.update(0, (0.0, 0.0), 0.0, 0.0)  # a head acceleration: the head balance reads one
        twin.update(1, (0.0, 0.0), 0.0, 0.0)
        twin.update(3, (0.0, 0.0), 0.0, 0.0)

    # -- one tick ----------------------------------------------------------------
    def update(
        self, tick: int, y: tuple[float, float], actuator_force: float, head_acceleration: float = math.nan
    ) -> Estimate:
        """Process the sample y_k = (z1, z2) of ``tick`` and the force applied over (t_{k-1}, t_k]
        (``head_acceleration``: not read; the head-balance observer's).

        The first call initialises and returns the initial estimate.  Ticks must
        increase; a gap (lost samples) is bridged period by period with y
        interpolated linearly across it and the force held (compiled
        :func:`observer_advance`).  Raises :class:`ObserverDivergedError` and leaves
        the state untouched if the update is not finite or S_theta is not positive definite.
        """
        y1, y2 = float(y[0]), float(y[1])
        if self.tick < 0:
            self.tick = tick
            _start_one(self._st, y1, y2)
            return self._estimate(y1)
        gap = tick - self.tick
        if gap < 1:
            raise ValueError(f"observer expects a tick after {self.tick}, got {tick}")
        saved = self._st.copy() if gap > 1 else None  # a single period leaves the state untouched itself
        status, reached = _advance_one(self._st, self.tick, y1, y2, gap, float(actuator_force), self.consts)
        if status:
            if saved is not None:
                self._st[:] = saved
            raise ObserverDivergedError(reached, divergence.reason(status))
        self.tick = reached
        return self._estimate(y1)

    def _estimate(self, y1: float) -> Estimate:
        t = self.tick * self.sample_period
        st = self._st[0]
        theta_hat = st["theta_hat"].copy()
        k_hat = model.stiffness(t, self.omega, theta_hat)
        return Estimate(
            tick=self.tick,
            time=t,
            z_hat=st["z_hat"].copy(),
            theta_hat=theta_hat,
            stiffness_hat=k_hat,
            contact_force_hat=k_hat * y1,
            innovation=st["innovation"].copy(),
        )
