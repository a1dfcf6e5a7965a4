"""The passive law: a constant uplift, no feedback.

    u_k = F_r(t_k)

With the constant reference this is the static uplift of a passive pantograph (the
paper's comparison case; F_r filtered from 0 so the loop starts at rest).  The
estimate is not used, so a non-finite one does not force the fallback.
"""

from __future__ import annotations

from .kernels import KernelLaw


class PassiveLaw(KernelLaw):
    """u = F_r (``passive_kernels``); stateless, the estimate unused."""

    mode = "passive"
    uses_estimate = False

    def __init__(self) -> None:
        super().__init__("passive", 1.0)
