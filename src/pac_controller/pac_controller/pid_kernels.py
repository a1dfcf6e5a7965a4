"""The pid law compiled (its equations and design: ``pid.py``'s module docstring).

The four functions are those ``kernel_common`` describes.
"""

from __future__ import annotations

from numba import njit

from .kernel_common import ACTIVE, fed_back_force, restart_memory


@njit(cache=True, error_model="numpy")
def pid_restart(p, s, table, memory, has_u: bool, u_applied: float) -> None:
    restart_memory(s, has_u, u_applied)


@njit(cache=True, error_model="numpy")
def pid_output(
    p, s, table, memory, tick: int, t: float, f_r, z_hat, theta_hat, f_hat: float, force_measured: float
) -> tuple[float, float, float, float]:
    """(u, e, I, D) of tick ``tick``; P, I, D and the bumpless start as ``pid.py`` writes them."""
    e = f_r[0] - fed_back_force(p, t, z_hat, theta_hat, f_hat)
    if s.started:
        h = (tick - s.law_last_tick) * p.dt
        integral = s.integral + h * s.rate
        derivative = (p.tf * s.derivative + p.kd * (e - s.last_error)) / (p.tf + h)
    else:
        integral, derivative = 0.0, 0.0
    u = f_r[0] + p.kp * e + derivative
    if not s.started and s.has_bumpless:
        integral = s.bumpless_from - u  # continue from the actuator's force
    u += integral
    s.pending_error, s.pending_integral, s.pending_derivative, s.pending_u = e, integral, derivative, u
    return u, e, integral, derivative


@njit(cache=True, error_model="numpy")
def pid_mode(p, s) -> int:
    return ACTIVE


@njit(cache=True, error_model="numpy")
def pid_commit(p, s, table, memory, tick: int, u_applied: float) -> None:
    s.integral, s.derivative, s.last_error = s.pending_integral, s.pending_derivative, s.pending_error
    s.law_last_tick = tick
    s.rate = p.ki * s.pending_error + (u_applied - s.pending_u) / p.tt  # back-calculation
    s.started = True
