"""``law:=skyhook``: the reference force plus a damper from the frame to a fixed point in the sky.

A law module of the file protocol (:mod:`pac_controller.user_law`; docs/laws.md, "Your own law"),
registered by one line in :data:`pac_controller.laws.LAWS`: the example of how a law joins the rig.

The skyhook damper (Karnopp, Crosby and Harwood 1974, "Vibration control using semi-active force
generators", J. Eng. Ind. 96(2)) pushes against the absolute velocity of the mass it acts on.
Here the actuator acts on the frame m2 (eq. (3)), whose velocity is the estimate's z2' (eq. (4)):

    u = F_r - c z2'_hat,     c = 2 zeta sqrt(k_d (m1 + m2))

with k_d the law parameters' ``design_stiffness`` (the fixed-gain laws' linear contact) and zeta
= DAMPING_RATIO: critical damping of the whole pantograph on that spring. No integrator, so no
memory, no restart and no anti-windup: the safety chain's limits apply to u as they are.

Judgement, not a design: zeta was picked from three 6 s runs of the default scenario (the paper's
line at 360 km/h, Table 1), zeta = 0.25, 0.5, 1: RMS(F - F_r) over the last 3 s was 35.4, 29.1
and 26.7 N against the passive pantograph's 54.8 N.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

if TYPE_CHECKING:
    from .user_law import LawSetup

#: The law reads the estimated state only (either observer gives it).
NEEDS = ("z_hat",)

#: zeta of the damper on the whole pantograph at design_stiffness (module docstring).
DAMPING_RATIO = 1.0

#: Index of z2' (the frame's velocity) in the state z = (z1, z2, z1', z2'), eq. (4).
FRAME_VELOCITY = 3


def design(setup: LawSetup) -> np.ndarray:
    """The damper's coefficient c [N s/m] from the nominal pantograph and the design stiffness."""
    p = setup.pantograph
    return np.array([2.0 * DAMPING_RATIO * math.sqrt(setup.laws.design_stiffness * (p.m1 + p.m2))])


@njit(cache=True)
def output(
    consts: np.ndarray,
    state: np.ndarray,
    t: float,
    f_r: np.ndarray,
    z_hat: np.ndarray,
    theta_hat: np.ndarray,
    f_hat: float,
) -> float:
    """u = F_r - c z2'_hat (the module docstring)."""
    return f_r[0] - consts[0] * z_hat[FRAME_VELOCITY]
