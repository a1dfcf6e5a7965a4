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

(or the estimate's own F_hat with ``force_estimate`` contact_force_hat: the contact-force observer's).

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
from dataclasses import dataclass

import numpy as np

from pac_common.parameters import ParameterError
from pac_model.parameters import PantographParameters, TrackParameters

from .kernels import MAX_PENDING, KernelLaw
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
    import scipy.linalg  # here, not at import: a node starts without loading scipy

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


class LqrLaw(KernelLaw):
    """The lqr law core (module docstring). State (q, the pending commands, the last tick) and
    arithmetic: ``kernels.CONTROLLER_STATE`` / ``lqr_kernels``, shared with the compiled loop."""

    def __init__(
        self,
        gains: LqrGains,
        pantograph: PantographParameters,
        track: TrackParameters,
        sample_period: float,
        tracking_time: float,
        force_estimate: str = "k_hat_z1",
    ) -> None:
        if gains.delay > MAX_PENDING:
            raise ValueError(f"lqr: at most {MAX_PENDING} pending commands, got {gains.delay}")
        self.gains = gains
        self.pantograph = pantograph
        self.omega = track.omega
        self.sample_period = sample_period
        self.uses_contact_force = force_estimate == "contact_force_hat"  # F_hat: module docstring
        super().__init__("lqr", sample_period)
        p = self.params[0]
        p["omega"], p["k1"], p["delay"], p["design_stiffness"] = (
            track.omega, pantograph.k1, gains.delay, gains.design_stiffness,
        )  # fmt: skip
        p["gain"][: gains.k.size] = gains.k
        p["tracking_time"] = tracking_time
        self.restart(None)

    @property
    def tracking_time(self) -> float:
        """Anti-windup tracking time T_I [s] (module docstring)."""
        return float(self.params[0]["tracking_time"])

    @tracking_time.setter
    def tracking_time(self, value: float) -> None:
        self.params[0]["tracking_time"] = value


def describe(gains: LqrGains) -> str:
    """One line for logs and docs."""
    slowest = float(np.max(gains.poles.real))
    k = np.array2string(gains.k, precision=4)
    return f"K = {k}, slowest pole {slowest:.1f} 1/s, rho {gains.spectral_radius:.5f}"
