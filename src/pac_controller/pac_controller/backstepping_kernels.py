"""The backstepping laws compiled: eq. (43) on the adaptive observer's theta_hat, or on the true theta.

The equations are ``backstepping_equations`` (shared with the Python reference); the classes are
``backstepping.py``. The four functions of each law are those ``kernel_common`` describes.
"""

from __future__ import annotations

from numba import njit

from . import backstepping_equations
from .kernel_common import ACTIVE, restart_memory


@njit(cache=True, error_model="numpy")
def _law(p, t: float, f_r, z_hat, th0: float, th1: float, th2: float) -> tuple[float, float, float, float]:
    """Eq. (43) at the catenary parameters (th0, th1, th2): (u, e1, e2, e3)."""
    return backstepping_equations.backstepping_law4(
        t, f_r, z_hat, th0, th1, th2, p.omega, p.m1, p.b1, p.k1, p.m2, p.b2,
        p.c1, p.c2, p.c3, p.stiffness_hat_min,
    )  # fmt: skip


@njit(cache=True, error_model="numpy")
def adaptive_backstepping_restart(p, s, table, memory, has_u: bool, u_applied: float) -> None:
    restart_memory(s, has_u, u_applied)


@njit(cache=True, error_model="numpy")
def adaptive_backstepping_output(
    p, s, table, memory, tick: int, t: float, f_r, z_hat, theta_hat, f_hat: float, force_measured: float
) -> tuple[float, float, float, float]:
    """Eq. (43) on the observer's theta_hat (eq. (17))."""
    return _law(p, t, f_r, z_hat, theta_hat[0], theta_hat[1], theta_hat[2])


@njit(cache=True, error_model="numpy")
def adaptive_backstepping_mode(p, s) -> int:
    return ACTIVE


@njit(cache=True, error_model="numpy")
def adaptive_backstepping_commit(p, s, table, memory, tick: int, u_applied: float) -> None:
    pass


@njit(cache=True, error_model="numpy")
def backstepping_known_restart(p, s, table, memory, has_u: bool, u_applied: float) -> None:
    restart_memory(s, has_u, u_applied)


@njit(cache=True, error_model="numpy")
def backstepping_known_output(
    p, s, table, memory, tick: int, t: float, f_r, z_hat, theta_hat, f_hat: float, force_measured: float
) -> tuple[float, float, float, float]:
    """Eq. (43) told the catenary's true theta (the oracle)."""
    return _law(p, t, f_r, z_hat, p.theta[0], p.theta[1], p.theta[2])


@njit(cache=True, error_model="numpy")
def backstepping_known_mode(p, s) -> int:
    return ACTIVE


@njit(cache=True, error_model="numpy")
def backstepping_known_commit(p, s, table, memory, tick: int, u_applied: float) -> None:
    pass
