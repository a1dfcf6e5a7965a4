"""The passive law compiled: u = F_r, no memory, its commands in mode passive.

The four functions are those ``kernel_common`` describes.
"""

from __future__ import annotations

from numba import njit

from .kernel_common import PASSIVE, restart_memory


@njit(cache=True, error_model="numpy")
def passive_restart(p, s, table, memory, has_u: bool, u_applied: float) -> None:
    restart_memory(s, has_u, u_applied)


@njit(cache=True, error_model="numpy")
def passive_output(
    p, s, table, memory, tick: int, t: float, f_r, z_hat, theta_hat, f_hat: float, force_measured: float
) -> tuple[float, float, float, float]:
    return f_r[0], 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy")
def passive_mode(p, s) -> int:
    return PASSIVE


@njit(cache=True, error_model="numpy")
def passive_commit(p, s, table, memory, tick: int, u_applied: float) -> None:
    pass
