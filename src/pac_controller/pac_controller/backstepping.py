"""Backstepping contact-force controller of Chater et al. (2015), eqs. (23)-(43).

Output feedback with certainty equivalence: the law runs on the observer's z_hat
and theta_hat.  Choices the paper leaves open (docs/design.md):

* z1r = +F_r / k_hat (eq. (23) with its sign fixed, docs/paper_errata.md #2),
  k_hat = v(t)^T theta_hat clamped below at ``stiffness_hat_min``.
* The output injection terms g_ij * (y - C z_hat) of eq. (21) contain the unknown
  estimation error; they are dropped from alpha_1' and alpha_2' (they vanish as the
  observer converges). z1 in psi(y) is replaced by z_hat_1, so the law needs the
  estimate only.
* alpha_1' and alpha_2' are exact time derivatives along the observer model without
  injection, with theta_hat frozen (it varies slowly): k_hat' = v'(t)^T theta_hat, etc.
"""

from __future__ import annotations

import numpy as np

from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters, positive_period

from . import kernels
from .backstepping_equations import (  # noqa: F401 - the equations, re-exported where they lived
    backstepping_law4,
    product_derivatives,
    product_derivatives4,
    reciprocal_derivatives,
    reciprocal_derivatives4,
    stiffness_hat_derivatives,
    stiffness_hat_derivatives4,
)
from .controller import Command, Errors  # noqa: F401 - Command re-exported (it lived here)
from .kernels import KernelLaw
from .parameters import ControllerParameters, ReferenceParameters
from .reference import ForceReference


class BacksteppingController(KernelLaw):
    """The adaptive_backstepping law core: u = m2 (-c3 e3 + alpha_2' - f2(z_hat) - (b1/m1) e2), eq. (43).

    Stateless (F_r is a pure function of time); the actuator limits, fallback and tick
    bookkeeping are the law-agnostic :class:`pac_controller.controller.Controller`'s.  Its
    numbers are fields of ``kernels.CONTROLLER_PARAMS``; its arithmetic is ``backstepping_kernels``'.
    """

    NAME = "adaptive_backstepping"

    def __init__(
        self,
        pantograph: PantographParameters,
        track: TrackParameters,
        params: ControllerParameters,
        reference: ReferenceParameters,
        sample_period: float,
    ) -> None:
        positive_period(sample_period)
        super().__init__(self.NAME, sample_period)
        self.pantograph = pantograph
        self.omega = track.omega
        self.params_set = params
        self.reference = ForceReference(reference)
        self.sample_period = sample_period
        p = self.params[0]
        p["omega"], p["m1"], p["b1"], p["k1"] = self.omega, pantograph.m1, pantograph.b1, pantograph.k1
        p["m2"], p["b2"] = pantograph.m2, pantograph.b2
        p["c1"], p["c2"], p["c3"] = params.c1, params.c2, params.c3
        p["stiffness_hat_min"] = params.stiffness_hat_min

    def stiffness_hat_derivatives(self, t: float, theta_hat: np.ndarray) -> np.ndarray:
        """k_hat and its derivatives 1..3 with theta_hat frozen, clamped at stiffness_hat_min."""
        theta_hat = np.array(theta_hat, dtype=np.float64)
        k_min = float(self.params_set.stiffness_hat_min)
        return stiffness_hat_derivatives(float(t), self.omega, theta_hat, k_min)

    def law(
        self, t: float, f_r: np.ndarray, z_hat: np.ndarray, theta_hat: np.ndarray
    ) -> tuple[float, tuple[float, float, float]]:
        """Eqs. (23)-(43): the unsaturated u and (e1, e2, e3) (:func:`backstepping_law4` via ``kernels``)."""
        return self.output(0, t, f_r, z_hat, theta_hat)


class KnownThetaBackstepping(BacksteppingController):
    """The backstepping_known law core: eq. (43) on z_hat with the true theta of eq. (9).

    An oracle: the same law as adaptive_backstepping, told the catenary parameters
    (k0, alpha, beta) instead of the observer's theta_hat, i.e. the best the adaptive
    law can hope for once theta_hat has converged.  z_hat still comes from the observer.
    """

    NAME = "backstepping_known"

    def __init__(self, backstepping: BacksteppingController, catenary: CatenaryParameters) -> None:
        b = backstepping
        super().__init__(b.pantograph, TrackParameters(), b.params_set, b.reference.params, b.sample_period)
        self.params[0] = b.params[0]
        self.params[0]["law"] = kernels.LAW_CODES[self.NAME]
        self.backstepping = backstepping
        self.theta = catenary.theta
        self.params[0]["theta"] = self.theta
        self.omega = b.omega
