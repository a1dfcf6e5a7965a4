"""The lqr law compiled (its equations and design: ``lqr.py``'s module docstring).

The four functions are those ``kernel_common`` describes.
"""

from __future__ import annotations

from numba import njit

from pac_common.smallmat import fma

from .kernel_common import ACTIVE, fed_back_force, restart_memory


@njit(cache=True, error_model="numpy")
def lqr_restart(p, s, table, memory, has_u: bool, u_applied: float) -> None:
    """Bumpless: the pending commands are the actuator's force (0 at rest)."""
    restart_memory(s, has_u, u_applied)
    s.head = 0
    for j in range(p.delay):
        s.commands[j] = u_applied if has_u else 0.0


@njit(cache=True, error_model="numpy")
def lqr_output(
    p, s, table, memory, tick: int, t: float, f_r, z_hat, theta_hat, f_hat: float, force_measured: float
) -> tuple[float, float, float, float]:
    """(u, -(F_hat - F_r), q, 0) of tick ``tick``:
    u = u_ss - K_x (z_hat - x_ss) - K_d (pending - u_ss) - K_q q."""
    u_ss = f_r[0]
    z1_ss = u_ss / p.design_stiffness  # model.static_equilibrium at the design stiffness
    x_ss = (z1_ss, z1_ss + u_ss / p.k1, 0.0, 0.0)
    feedback = 0.0  # K_x (z_hat - x_ss), summed as numpy's dot sums it (smallmat.fma)
    for i in range(4):
        feedback = fma(p.gain[i], z_hat[i] - x_ss[i], feedback)
    if p.delay:
        pending = 0.0
        for j in range(p.delay):
            pending = fma(p.gain[4 + j], s.commands[(s.head + j) % p.delay] - u_ss, pending)
        feedback += pending
    k_q = p.gain[4 + p.delay]
    if s.started:
        integral = s.integral + (tick - s.law_last_tick) * p.dt * s.rate
    elif s.has_bumpless:
        integral = -(s.bumpless_from - u_ss + feedback) / k_q  # u = the actuator's force
    else:
        integral = 0.0
    u = u_ss - feedback - k_q * integral
    error = fed_back_force(p, t, z_hat, theta_hat, f_hat) - u_ss
    s.pending_error, s.pending_integral, s.pending_u = error, integral, u
    return u, -error, integral, 0.0


@njit(cache=True, error_model="numpy")
def lqr_mode(p, s) -> int:
    return ACTIVE


@njit(cache=True, error_model="numpy")
def lqr_commit(p, s, table, memory, tick: int, u_applied: float) -> None:
    k_q = p.gain[4 + p.delay]
    s.rate = s.pending_error + (s.pending_u - u_applied) / (k_q * p.tracking_time)
    s.integral, s.law_last_tick, s.started = s.pending_integral, tick, True
    if p.delay:
        s.commands[s.head] = u_applied  # replaces the oldest
        s.head = (s.head + 1) % p.delay
