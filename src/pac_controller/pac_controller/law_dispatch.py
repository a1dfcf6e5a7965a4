"""The compiled laws' dispatch: generated from ``pac_controller.laws.LAWS`` by
``python -m pac_controller.law_dispatch_source --write``. Do not edit.

One branch per kernel law on the record's code (``CONTROLLER_PARAMS.law``), calling the four
functions of its module (``kernel_common``). An unknown code gives a NaN output, which the safety
chain answers with the fallback.
"""

from __future__ import annotations

import math

from numba import njit

from pac_controller import (
    backstepping_kernels,
    line_adaptive_kernels,
    lqr_kernels,
    passive_kernels,
    pid_kernels,
)
from pac_controller.kernel_common import ACTIVE

#: Law name -> the code the compiled functions dispatch on (the registry's order).
LAW_CODES = {
    "adaptive_backstepping": 0,
    "backstepping_known": 1,
    "pid": 2,
    "lqr": 3,
    "passive": 4,
    "line_adaptive": 5,
}


@njit(cache=True, error_model="numpy")
def law_restart(p, s, table, memory, has_u, u_applied):
    """Forget the law's state; its next output continues from ``u_applied`` (has_u False: at rest)."""
    law = p.law
    if law == 0:
        backstepping_kernels.adaptive_backstepping_restart(p, s, table, memory, has_u, u_applied)
    elif law == 1:
        backstepping_kernels.backstepping_known_restart(p, s, table, memory, has_u, u_applied)
    elif law == 2:
        pid_kernels.pid_restart(p, s, table, memory, has_u, u_applied)
    elif law == 3:
        lqr_kernels.lqr_restart(p, s, table, memory, has_u, u_applied)
    elif law == 4:
        passive_kernels.passive_restart(p, s, table, memory, has_u, u_applied)
    elif law == 5:
        line_adaptive_kernels.line_adaptive_restart(p, s, table, memory, has_u, u_applied)


@njit(cache=True, error_model="numpy")
def law_output(p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured):
    """The unlimited force u_law of ``tick`` and three law-specific errors (remembered for commit)."""
    law = p.law
    if law == 0:
        return backstepping_kernels.adaptive_backstepping_output(
            p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured
        )
    elif law == 1:
        return backstepping_kernels.backstepping_known_output(
            p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured
        )
    elif law == 2:
        return pid_kernels.pid_output(
            p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured
        )
    elif law == 3:
        return lqr_kernels.lqr_output(
            p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured
        )
    elif law == 4:
        return passive_kernels.passive_output(
            p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured
        )
    elif law == 5:
        return line_adaptive_kernels.line_adaptive_output(
            p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured
        )
    return math.nan, 0.0, 0.0, 0.0


@njit(cache=True, error_model="numpy")
def law_mode(p, s):
    """The mode code of the law's command (kernel_common.ACTIVE or PASSIVE)."""
    law = p.law
    if law == 0:
        return backstepping_kernels.adaptive_backstepping_mode(p, s)
    elif law == 1:
        return backstepping_kernels.backstepping_known_mode(p, s)
    elif law == 2:
        return pid_kernels.pid_mode(p, s)
    elif law == 3:
        return lqr_kernels.lqr_mode(p, s)
    elif law == 4:
        return passive_kernels.passive_mode(p, s)
    elif law == 5:
        return line_adaptive_kernels.line_adaptive_mode(p, s)
    return ACTIVE


@njit(cache=True, error_model="numpy")
def law_commit(p, s, table, memory, tick, u_applied):
    """The limited force actually commanded for ``tick``: the law's state follows it."""
    law = p.law
    if law == 0:
        backstepping_kernels.adaptive_backstepping_commit(p, s, table, memory, tick, u_applied)
    elif law == 1:
        backstepping_kernels.backstepping_known_commit(p, s, table, memory, tick, u_applied)
    elif law == 2:
        pid_kernels.pid_commit(p, s, table, memory, tick, u_applied)
    elif law == 3:
        lqr_kernels.lqr_commit(p, s, table, memory, tick, u_applied)
    elif law == 4:
        passive_kernels.passive_commit(p, s, table, memory, tick, u_applied)
    elif law == 5:
        line_adaptive_kernels.line_adaptive_commit(p, s, table, memory, tick, u_applied)
