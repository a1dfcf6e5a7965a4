"""The passive law: a constant uplift, no feedback.

    u_k = F_r(t_k)

With the constant reference this is the static uplift of a passive pantograph (the
paper's comparison case; F_r filtered from 0 so the loop starts at rest).  The
estimate is not used, so a non-finite one does not force the fallback.
"""

from __future__ import annotations

import numpy as np

from .controller import Errors


class PassiveLaw:
    mode = "passive"
    uses_estimate = False

    def restart(self, u_applied: float | None) -> None:
        """Nothing to forget: the law is stateless."""

    def output(
        self, tick: int, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, Errors]:
        return float(f_r[0]), (0.0, 0.0, 0.0)

    def commit(self, tick: int, u_applied: float) -> None:
        """Nothing to update: the law is stateless."""
