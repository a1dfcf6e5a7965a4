"""The lqr law: an LQ servo with integral action, fixed gains from the model at design_stiffness.

Design model (pac_controller.linear): the contact model at k_d = design_stiffness,
sampled (ZOH) at dt, with the d = design_delay_ticks commands already sent as
states, and the force-error integral:

    xi_k = (x_k - x_ss,  u_{k-d} - u_ss, ..., u_{k-1} - u_ss,  q_k)
    x_{k+1} = Ad x_k + Bd u_{k-d},        q_{k+1} = q_k + dt (C_F x_k - F_r)

where (x_ss, u_ss) is the static equilibrium at F_r (eq. (3): z1 = F_r / k_d,
z2 = z1 + F_r / k1, u_ss = F_r).  K minimises sum xi^T Q xi + r (u - u_ss)^2
(``scipy.linalg.solve_discrete_are``), weights by Bryson's rule:

    Q = C_F^T C_F / dF^2 + (e3 e3^T + e4 e4^T) / v^2 + e_q e_q^T / (dF T_I)^2,   r = 1 / du^2

(dF = lqr_force_scale, v = lqr_velocity_scale, T_I = lqr_integral_time,
du = lqr_input_scale; pending commands unweighted).  The law, on the observer's z_hat:

    u_k = u_ss - K xi_k,    q_{k+1} = q_k + h (F_hat_k - F_r,k),   F_hat = k_hat z_hat_1 (eqs. (6), (8))

The integral uses the observer's force estimate, so at rest F_hat = F_r whatever the
true mean stiffness (zero steady-state error on a constant reference at constant
stiffness); the gains stay those of k_d (fixed, non-adaptive).  Anti-windup by
back-calculation, as the pid law: q_{k+1} = q_k + h (F_hat_k - F_r,k + (u_k - u_applied,k) / (K_q T_I))
(K_q the gain on q, tracking time T_I), so while the actuator is at a limit q is pulled
to where u_law sits at that limit instead of growing.  A (re)start is bumpless (q set
so that u equals the actuator's present force; the pending commands are that force).
"""

from __future__ import annotations

import functools
from collections import deque
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from pac_common.parameters import ParameterError
from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters

from .controller import Errors, contact_force_estimate
from .linear import contact_model, discretise, spectral_radius, with_delay
from .parameters import LawParameters


@dataclass(frozen=True)
class LqrGains:
    """u = u_ss - K xi; xi as in the module docstring."""

    k: np.ndarray  # (4 + d + 1,)
    delay: int
    design_stiffness: float
    spectral_radius: float  # of the sampled closed loop at design_stiffness (< 1: stable)
    poles: np.ndarray  # closed-loop poles as continuous-time equivalents ln(z) / dt [1/s]

    @property
    def state_gain(self) -> np.ndarray:
        return self.k[:4]

    @property
    def pending_gain(self) -> np.ndarray:
        return self.k[4 : 4 + self.delay]

    @property
    def integral_gain(self) -> float:
        return float(self.k[-1])


def augmented_model(
    pantograph: PantographParameters, k: float, dt: float, delay: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C_F) of xi (module docstring); C_F picks the force of x."""
    a, b, c_f = contact_model(pantograph, k)
    ap, bp = with_delay(*discretise(a, b, dt), delay)
    n = ap.shape[0]
    aa = np.zeros((n + 1, n + 1))
    aa[:n, :n] = ap
    aa[n, :4] = dt * c_f
    aa[n, n] = 1.0
    ba = np.append(bp, 0.0)
    return aa, ba, c_f


@functools.lru_cache(maxsize=16)  # pure; a retune of other parameters must not redesign in the loop
def design_lqr(pantograph: PantographParameters, laws: LawParameters, dt: float) -> LqrGains:
    """K from the discrete algebraic Riccati equation with Bryson weights (module docstring)."""
    d = laws.design_delay_ticks
    aa, ba, c_f = augmented_model(pantograph, laws.design_stiffness, dt, d)
    q = np.zeros_like(aa)
    q[:4, :4] = np.outer(c_f, c_f) / laws.lqr_force_scale**2
    q[2, 2] += 1.0 / laws.lqr_velocity_scale**2
    q[3, 3] += 1.0 / laws.lqr_velocity_scale**2
    q[-1, -1] = 1.0 / (laws.lqr_force_scale * laws.lqr_integral_time) ** 2
    r = np.array([[1.0 / laws.lqr_input_scale**2]])
    try:
        p = scipy.linalg.solve_discrete_are(aa, ba[:, None], q, r)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ParameterError(
            "lqr_force_scale",
            laws.lqr_force_scale,
            f"weights for which the Riccati equation is solvable ({exc})",
        ) from None
    k = np.linalg.solve(r + ba[None, :] @ p @ ba[:, None], ba[None, :] @ p @ aa)[0]
    closed = aa - np.outer(ba, k)
    rho = spectral_radius(closed)
    if not rho < 1.0:
        raise ParameterError(
            "lqr_force_scale", laws.lqr_force_scale, f"weights giving a stable loop (rho {rho:.4f})"
        )
    poles = np.log(np.linalg.eigvals(closed).astype(complex)) / dt
    for shared in (k, poles):  # the result is cached and shared by every law built from it
        shared.setflags(write=False)
    return LqrGains(k=k, delay=d, design_stiffness=laws.design_stiffness, spectral_radius=rho, poles=poles)


class LqrLaw:
    """The lqr law core (module docstring). State: q, the pending commands, the last tick."""

    mode = "active"
    uses_estimate = True

    def __init__(
        self,
        gains: LqrGains,
        pantograph: PantographParameters,
        track: TrackParameters,
        sample_period: float,
        tracking_time: float,
    ) -> None:
        self.gains = gains
        self.pantograph = pantograph
        self.omega = track.omega
        self.sample_period = sample_period
        self.tracking_time = tracking_time
        self.restart(None)

    def restart(self, u_applied: float | None) -> None:
        self.bumpless_from = u_applied
        self.started = False
        self.integral = 0.0
        self.integral_step = 0.0  # q' of the last tick: F_hat - F_r, plus the back-calculation term
        self.pending_commands: deque[float] = deque(
            [0.0 if u_applied is None else u_applied] * self.gains.delay, maxlen=max(self.gains.delay, 1)
        )
        self.last_tick = 0
        self.pending: tuple[float, float, float] | None = None

    def output(
        self, tick: int, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, Errors]:
        g = self.gains
        u_ss = float(f_r[0])
        x_ss = model.static_equilibrium(u_ss, g.design_stiffness, self.pantograph)
        feedback = g.state_gain @ (z_hat - x_ss)
        if g.delay:
            feedback += g.pending_gain @ (np.array(self.pending_commands) - u_ss)
        if self.started:
            integral = self.integral + (tick - self.last_tick) * self.sample_period * self.integral_step
        elif self.bumpless_from is not None:
            integral = -(self.bumpless_from - u_ss + feedback) / g.integral_gain  # u = the actuator's force
        else:
            integral = 0.0
        u = u_ss - feedback - g.integral_gain * integral
        error = contact_force_estimate(t, self.omega, z_hat, theta_hat) - u_ss
        self.pending = (error, integral, u)
        return u, (-error, integral, 0.0)

    def commit(self, tick: int, u_applied: float) -> None:
        assert self.pending is not None, "commit without output"
        error, integral, u = self.pending
        # Back-calculation: while the command is limited, q moves u back towards the limit.
        self.integral_step = error + (u - u_applied) / (self.gains.integral_gain * self.tracking_time)
        self.integral, self.last_tick, self.started = integral, tick, True
        if self.gains.delay:
            self.pending_commands.append(u_applied)
        self.pending = None


def describe(gains: LqrGains) -> str:
    """One line for logs and docs."""
    slowest = float(np.max(gains.poles.real))
    k = np.array2string(gains.k, precision=4)
    return f"K = {k}, slowest pole {slowest:.1f} 1/s, rho {gains.spectral_radius:.5f}"
