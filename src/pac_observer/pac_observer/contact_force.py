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
The state is the numpy array ``x``; :func:`contact_force_step` is pure and compiled.

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
zeros, so the laws built on F = k_hat z1 (backstepping, pid, lqr) need the adaptive
observer; ``line_adaptive`` and ``passive`` run on this one.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import scipy.linalg
from numba import njit

from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters

from .observer import AdaptiveObserver, Estimate, ObserverDivergedError
from .parameters import ObserverParameters

#: State size: (z1, z2, z1', z2', F).
STATE_SIZE = 5
_FORCE = 4
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


def kalman_design(
    pantograph: PantographParameters, force_process_noise: float, position_noise: float, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, Gamma, K) of the sampled model and its steady-state Kalman gain (module docstring)."""
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
    return phi, gamma, gain


@njit(cache=True, error_model="numpy")
def contact_force_step(
    x: np.ndarray, y: np.ndarray, u: float, phi: np.ndarray, gamma: np.ndarray, gain: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """One period: (x_k, innovation y_k - C x_k^-) from x_{k-1}, y_k and the force u held over it. Pure."""
    n = x.shape[0]
    pred = np.empty(n)
    for i in range(n):
        s = gamma[i] * u
        for j in range(n):
            s += phi[i, j] * x[j]
        pred[i] = s
    innovation = np.empty(2)
    innovation[0] = y[0] - pred[0]
    innovation[1] = y[1] - pred[1]
    new = np.empty(n)
    for i in range(n):
        new[i] = pred[i] + gain[i, 0] * innovation[0] + gain[i, 1] * innovation[1]
    return new, innovation


@njit(cache=True, error_model="numpy")
def contact_force_bank_step(
    xs: np.ndarray,
    energy: np.ndarray,
    selected: int,
    y: np.ndarray,
    u: float,
    phis: np.ndarray,
    gammas: np.ndarray,
    gains: np.ndarray,
    forget: float,
    inv_r2: float,
) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """Every filter of the bank one period on; (states, energies, selected filter, its innovation). Pure."""
    count = xs.shape[0]
    new_xs = np.empty_like(xs)
    new_energy = np.empty(count)
    innovations = np.empty((count, 2))
    best = 0
    for f in range(count):
        x, innovation = contact_force_step(xs[f], y, u, phis[f], gammas[f], gains[f])
        new_xs[f] = x
        innovations[f] = innovation
        new_energy[f] = forget * energy[f] + (innovation[0] ** 2 + innovation[1] ** 2) * inv_r2
        if new_energy[f] < new_energy[best]:
            best = f
    if new_energy[best] < BANK_HYSTERESIS * new_energy[selected]:
        selected = best
    return new_xs, new_energy, selected, innovations[selected].copy()


class ContactForceObserver:
    """The filter with explicit state ``x``; same interface as ``AdaptiveObserver`` (update, reset, tick)."""

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
        self.sample_period = sample_period
        self.frame_mass_scales = frame_mass_scales(params)
        designs = [
            kalman_design(
                replace(pantograph, m2=pantograph.m2 * scale),
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
        self.reset()

    def reset(self) -> None:
        """Back to rest: z_hat from ``z_hat0``, F_hat = 0; the first sample sets the positions."""
        self.tick = -1
        self.xs = np.zeros((len(self.frame_mass_scales), STATE_SIZE))
        self.xs[:, :4] = self.params.z_hat0
        self.energy = np.zeros(len(self.frame_mass_scales))
        self.selected = self.nominal
        self._y_prev = np.zeros(2)

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

    def update(self, tick: int, y: tuple[float, float], actuator_force: float) -> Estimate:
        """Process y_k of ``tick`` and the force applied over (t_{k-1}, t_k]; a gap is predicted through."""
        y_now = np.array(y, dtype=float)
        if self.tick < 0:
            self.tick = tick
            self.xs[:, 0], self.xs[:, 1] = y_now  # the positions are measured: start from them
            self._y_prev = y_now
            return self._estimate(np.zeros(2))
        gap = tick - self.tick
        if gap < 1:
            raise ValueError(f"observer expects a tick after {self.tick}, got {tick}")
        xs, energy, selected = self.xs, self.energy, self.selected
        y_start = self._y_prev
        innovation = np.zeros(2)
        for j in range(1, gap + 1):  # lost samples: y interpolated linearly, u held (as the adaptive one)
            y_j = y_start + (j / gap) * (y_now - y_start)
            xs, energy, selected, innovation = contact_force_bank_step(
                xs, energy, selected, y_j, float(actuator_force), self.phis, self.gammas, self.gains,
                self.forget, self.inv_r2,
            )  # fmt: skip
        if not np.isfinite(xs[selected]).all():
            raise ObserverDivergedError(tick, "the contact-force state is not finite")
        self.xs, self.energy, self.selected, self._y_prev = xs, energy, selected, y_now
        self.tick = tick
        return self._estimate(innovation)

    def _estimate(self, innovation: np.ndarray) -> Estimate:
        return Estimate(
            tick=self.tick,
            time=self.tick * self.sample_period,
            z_hat=self.z_hat,
            theta_hat=np.zeros(3),
            stiffness_hat=0.0,
            contact_force_hat=float(self.x[_FORCE]),
            innovation=innovation,
        )


def make_observer(
    pantograph: PantographParameters, track: TrackParameters, params: ObserverParameters, sample_period: float
):
    """The observer ``params.observer`` names: the paper's (eq. (17)) or the contact-force filter."""
    cls = ContactForceObserver if params.observer == "contact_force" else AdaptiveObserver
    return cls(pantograph, track, params, sample_period)
