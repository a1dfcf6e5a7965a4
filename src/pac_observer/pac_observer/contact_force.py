"""Contact-force observer: a Kalman filter on the nominal 2-DOF pantograph with F as a state.

``observer:=contact_force``.  Unlike the paper's observer (eq. (17)) it does not assume
F = k(t) z1 (eq. (6)): the contact force is an unknown input, estimated from what it
does to the pantograph.  Model (eqs. (3)-(4) with the contact force F on the head, the
actuator force u on the frame, Table 1's nominal parameters), augmented with F as a
random walk::

    x = (z1, z2, z1', z2', F)
    x' = A_a x + B_a u + (0, 0, 0, 0, 1) w,        y = (z1, z2) + v
    A_a = [[A, -e3 / m1], [0, 0]],  B_a = (0, 0, 0, 1/m2, 0)
    E[w w] = q_F^2 (N^2/s, ``force_process_noise``),  E[v v^T] = r^2 I (``position_noise``)

Sampled exactly with the actuator force held over the period (ZOH: Phi = exp(A_a dt),
Gamma = int_0^dt exp(A_a s) B_a ds; Q_d by Van Loan's method), and run as the
steady-state (predictor-corrector) Kalman filter::

    x_k^- = Phi x_{k-1} + Gamma u_{k-1}          (u_{k-1}: the force applied over (t_{k-1}, t_k])
    x_k   = x_k^- + K (y_k - C x_k^-)            K = P C^T (C P C^T + R)^-1, P from the DARE

q_F sets the bandwidth of F_hat: large enough to follow the line's dropper and span
harmonics (up to ~20 Hz, what the EN 50318 statistics keep), small enough that the
position noise twice differentiated does not swamp it (docs/laws.md, measured accuracy).
The state lives in an OBSERVER_STATE record (``cf_`` fields) and the bank's arrays (:data:`BANK_ARGS`);
:func:`contact_force_advance` is compiled and shared with the compiled closed loop (``pac_rig.loop``).

A bank over the frame mass m2 (multiple-model estimation): one such filter per m2 in
(1 +- ``frame_mass_range``) m2_nominal, ``frame_mass_step`` apart; each keeps a running
innovation energy J_i <- lam J_i + |nu_i|^2 / r^2 (lam = exp(-dt / ``frame_mass_window``)),
and the estimate is the filter with the smallest J (switching only when it is below
``BANK_HYSTERESIS`` times the current one's).  Why m2: the frame equation
m2 z2'' = k1 (z1 - z2) + b1 (z1' - z2') - b2 z2' + u has no unknown input, so a wrong m2
cannot be absorbed by F and shows in z2's innovation at once (on the FE line at 250 km/h with
both masses x1.2: 276 um RMS on the nominal m2, 0.16 um on the right one), and it corrupts
F_hat most (error 21.3 N RMS at 20 Hz against 1.4 N); the head mass m1 is not identifiable
without F (z1's innovation is flattest away from it) and costs only Delta m1 z1'' (F_hat error
1.4-4.3 N for m1 x1.0-1.3 with the right m2).  ``frame_mass_range`` = 0 is the single filter.
This observer estimates no theta: ``theta_hat`` and ``stiffness_hat`` are published as
zeros, so the law built on F = k_hat z1 (adaptive backstepping) needs the adaptive
observer; ``line_adaptive``, ``passive``, and ``pid`` and ``lqr`` on its F_hat
(``force_estimate`` contact_force_hat) run on this one.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np
from numba import njit

from pac_common import divergence
from pac_common.divergence import CONTACT_FORCE_NOT_FINITE
from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters, positive_period

from .choice import observer_builder
from .observer import (
    OBSERVER_CONSTS,
    OBSERVER_STATE,
    AdaptiveObserver,
    Estimate,
    ObserverDivergedError,
    force_estimate,
)
from .observers import OBSERVER_CODES
from .parameters import ObserverParameters

#: State size: (z1, z2, z1', z2', F).
STATE_SIZE = 5
_FORCE = 4
#: The bank's arrays, the compiled functions' ``bank`` argument: per filter Phi, Gamma, K (constants),
#: its state x and innovation energy J, and its last innovation (scratch).
BANK_ARGS = ("phis", "gammas", "gains", "xs", "energy", "innovations")
#: The bank switches to a filter whose innovation energy is below this times the current one's.
BANK_HYSTERESIS = 0.9


def frame_mass_scales(params: ObserverParameters) -> np.ndarray:
    """m2 / m2_nominal of each filter of the bank: 1 +- k step up to +- range (1 alone for range 0)."""
    half = math.floor(params.frame_mass_range / params.frame_mass_step + 1e-9)
    return 1.0 + params.frame_mass_step * np.arange(-half, half + 1)


def contact_force_model(pantograph: PantographParameters) -> tuple[np.ndarray, np.ndarray]:
    """(A_a, B_a): the nominal pantograph with the contact force F as a fifth (constant) state."""
    a_aug = np.zeros((STATE_SIZE, STATE_SIZE))
    a_aug[:4, :4] = model.state_matrix(pantograph)
    a_aug[2, _FORCE] = -1.0 / pantograph.m1  # F pushes the head down (eq. (3))
    b_aug = np.zeros(STATE_SIZE)
    b_aug[3] = model.actuator_acceleration(1.0, pantograph.m2)
    return a_aug, b_aug


@functools.lru_cache(maxsize=256)  # pure; a bank's 25 designs are most of an FE run's set-up (campaigns)
def kalman_design(
    pantograph: PantographParameters, force_process_noise: float, position_noise: float, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, Gamma, K) of the sampled model and its steady-state Kalman gain (module docstring);
    cached and shared, hence read only."""
    import scipy.linalg  # here, not at import: a node starts without loading scipy

    a_aug, b_aug = contact_force_model(pantograph)
    n = STATE_SIZE
    zoh = np.zeros((n + 1, n + 1))
    zoh[:n, :n], zoh[:n, n] = a_aug, b_aug
    sampled = scipy.linalg.expm(zoh * dt)
    phi, gamma = sampled[:n, :n], sampled[:n, n]
    q_c = np.zeros((n, n))
    q_c[_FORCE, _FORCE] = force_process_noise**2
    van_loan = np.zeros((2 * n, 2 * n))
    van_loan[:n, :n], van_loan[:n, n:], van_loan[n:, n:] = -a_aug, q_c, a_aug.T
    e = scipy.linalg.expm(van_loan * dt)
    q_d = e[n:, n:].T @ e[:n, n:]
    q_d = 0.5 * (q_d + q_d.T)
    c = np.zeros((2, n))
    c[0, 0] = c[1, 1] = 1.0
    r = position_noise**2 * np.eye(2)
    p = scipy.linalg.solve_discrete_are(phi.T, c.T, q_d, r)
    gain = p @ c.T @ np.linalg.inv(c @ p @ c.T + r)
    for shared in (phi, gamma, gain):
        shared.setflags(write=False)
    return phi, gamma, gain


@njit(cache=True, error_model="numpy")
def contact_force_bank_step(st, c, bank, y1: float, y2: float, u: float) -> None:
    """Every filter of the bank one period on, in place (x_k from x_{k-1}, y_k and the force u held
    over it; J_i <- lam J_i + |nu_i|^2 / r^2); the selection with hysteresis; ``st.innovation``
    the selected filter's y_k - C x_k^- (module docstring)."""
    phis, gammas, gains, xs, energy, innovations = bank
    pred = st.cf_pred
    best = 0
    for f in range(xs.shape[0]):
        x = xs[f]
        for i in range(STATE_SIZE):
            s = gammas[f, i] * u
            for j in range(STATE_SIZE):
                s += phis[f, i, j] * x[j]
            pred[i] = s
        nu0, nu1 = y1 - pred[0], y2 - pred[1]
        for i in range(STATE_SIZE):
            x[i] = pred[i] + gains[f, i, 0] * nu0 + gains[f, i, 1] * nu1
        innovations[f, 0], innovations[f, 1] = nu0, nu1
        energy[f] = c.cf_forget * energy[f] + (nu0**2 + nu1**2) * c.cf_inv_r2
        if energy[f] < energy[best]:
            best = f
    if energy[best] < BANK_HYSTERESIS * energy[st.cf_selected]:
        st.cf_selected = best
    st.innovation[0], st.innovation[1] = innovations[st.cf_selected, 0], innovations[st.cf_selected, 1]


@njit(cache=True, error_model="numpy")
def contact_force_start(st, bank, y1: float, y2: float) -> None:
    """The first sample: the positions are measured, so every filter starts from them."""
    xs = bank[3]
    for f in range(xs.shape[0]):
        xs[f, 0], xs[f, 1] = y1, y2
    st.y_prev[0], st.y_prev[1] = y1, y2
    st.innovation[0], st.innovation[1] = 0.0, 0.0
    _output(st, xs)


@njit(cache=True, error_model="numpy")
def contact_force_advance(st, c, bank, y1: float, y2: float, gap: int, u: float) -> int:
    """``gap`` periods to y_k (lost samples: y interpolated linearly, u held, as the adaptive
    observer); 0, or CONTACT_FORCE_NOT_FINITE if the selected filter's state is not finite."""
    y_start_1, y_start_2 = st.y_prev[0], st.y_prev[1]
    for j in range(1, gap + 1):
        f = j / gap
        contact_force_bank_step(
            st, c, bank, y_start_1 + f * (y1 - y_start_1), y_start_2 + f * (y2 - y_start_2), u
        )
    xs = bank[3]
    for i in range(STATE_SIZE):
        if not math.isfinite(xs[st.cf_selected, i]):
            return CONTACT_FORCE_NOT_FINITE
    st.y_prev[0], st.y_prev[1] = y1, y2
    _output(st, xs)
    return 0


@njit(cache=True, error_model="numpy")
def contact_force_update(
    k, t, oc, os, bank, y1, y2, u_applied, head_acceleration
) -> tuple[int, float, float]:
    """Tick k of the compiled loop (observers.py): the filter bank on y_k (k = 0: its first sample);
    (status, 0, F_hat): no stiffness estimate, F_hat the selected filter's state."""
    if k == 0:
        contact_force_start(os, bank, y1, y2)
    else:
        status = contact_force_advance(os, oc, bank, y1, y2, 1, u_applied)
        if status:
            return status, 0.0, 0.0
    return 0, 0.0, os.cf_force


@njit(cache=True, error_model="numpy")
def _output(st, xs) -> None:
    for i in range(4):
        st.z_hat[i] = xs[st.cf_selected, i]
    st.cf_force = xs[st.cf_selected, _FORCE]


@njit(cache=True, error_model="numpy")
def _start_one(states, bank, y1, y2) -> None:
    contact_force_start(states[0], bank, y1, y2)


@njit(cache=True, error_model="numpy")
def _advance_one(states, consts, bank, y1, y2, gap, u) -> int:
    return contact_force_advance(states[0], consts[0], bank, y1, y2, gap, u)


class ContactForceObserver:
    """The bank with explicit state (``state``: an OBSERVER_STATE record; ``bank``: the filters'
    arrays); same interface as ``AdaptiveObserver`` (update, reset, tick, consts, state)."""

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
        self.sample_period = sample_period
        self.frame_mass_scales = frame_mass_scales(params)
        designs = [
            kalman_design(
                # A member is the nominal 2-DOF with another m2: its numbers are already the file's
                # (check_consistency wrote them in), so it names no file that would re-check m2.
                replace(pantograph, m2=pantograph.m2 * scale, nominal_pantograph=""),
                params.force_process_noise,
                params.position_noise,
                sample_period,
            )
            for scale in self.frame_mass_scales
        ]
        self.phis, self.gammas, self.gains = (
            np.ascontiguousarray(np.stack([d[i] for d in designs]), dtype=np.float64) for i in range(3)
        )
        self.nominal = int(np.argmin(np.abs(self.frame_mass_scales - 1.0)))
        self.forget = math.exp(-sample_period / params.frame_mass_window)
        self.inv_r2 = 1.0 / params.position_noise**2
        #: What the compiled functions take as constants: one OBSERVER_CONSTS record.
        self.consts = np.zeros(1, OBSERVER_CONSTS)
        c = self.consts[0]
        c["kind"], c["dt"], c["cf_forget"], c["cf_inv_r2"] = (
            OBSERVER_CODES["contact_force"],
            sample_period,
            self.forget,
            self.inv_r2,
        )
        count = len(self.frame_mass_scales)
        self.xs = np.zeros((count, STATE_SIZE))
        self.energy = np.zeros(count)
        self._innovations = np.zeros((count, 2))
        self._st = np.zeros(1, OBSERVER_STATE)
        self.reset()

    @property
    def bank(self) -> tuple[np.ndarray, ...]:
        """The bank's arrays in the order of :data:`BANK_ARGS` (the state ones are views: live)."""
        return self.phis, self.gammas, self.gains, self.xs, self.energy, self._innovations

    def reset(self) -> None:
        """Back to rest: z_hat from ``z_hat0``, F_hat = 0; the first sample sets the positions."""
        self.tick = -1
        self.xs[:] = 0.0
        self.xs[:, :4] = self.params.z_hat0
        self.energy[:] = 0.0
        self._st[0] = 0
        st = self._st[0]
        st["cf_selected"] = self.nominal
        st["z_hat"] = self.params.z_hat0

    @property
    def state(self) -> np.ndarray:
        """The OBSERVER_STATE record (a 1-element array): what the compiled loop starts from."""
        return self._st

    @property
    def selected(self) -> int:
        return int(self._st[0]["cf_selected"])

    @property
    def x(self) -> np.ndarray:
        """The state of the selected filter (z1, z2, z1', z2', F)."""
        return self.xs[self.selected]

    @property
    def frame_mass_scale(self) -> float:
        """m2 / m2_nominal of the selected filter."""
        return float(self.frame_mass_scales[self.selected])

    @property
    def z_hat(self) -> np.ndarray:
        return self.x[:4].copy()

    #: Updates on a copy (first sample, a tick, a gap), as the adaptive observer's: the compiled
    #: step loaded before the loop, not at its first tick.
    warm_up = AdaptiveObserver.warm_up

    def update(
        self, tick: int, y: tuple[float, float], actuator_force: float, head_acceleration: float = math.nan
    ) -> Estimate:
        """Process y_k of ``tick`` and the force applied over (t_{k-1}, t_k]; a gap is predicted through
        (``head_acceleration``: not read; the head-balance observer's)."""
        y1, y2 = float(y[0]), float(y[1])
        if self.tick < 0:
            self.tick = tick
            _start_one(self._st, self.bank, y1, y2)
            return self._estimate()
        gap = tick - self.tick
        if gap < 1:
            raise ValueError(f"observer expects a tick after {self.tick}, got {tick}")
        saved = self._st.copy(), self.xs.copy(), self.energy.copy()
        status = _advance_one(self._st, self.consts, self.bank, y1, y2, gap, float(actuator_force))
        if status:
            self._st[:], self.xs[:], self.energy[:] = saved
            raise ObserverDivergedError(tick, divergence.reason(status))
        self.tick = tick
        return self._estimate()

    def _estimate(self) -> Estimate:
        return force_estimate(self.tick, self.sample_period, self._st)


def make_observer(
    pantograph: PantographParameters, track: TrackParameters, params: ObserverParameters, sample_period: float
):
    """The observer ``params.observer`` names (the registry, observers.py): the paper's (eq. (17)),
    the contact-force filter, the head balance, or a user's observer file (user_observer)."""
    return observer_builder(params.observer)(pantograph, track, params, sample_period)
