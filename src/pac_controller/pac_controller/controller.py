"""The law-agnostic controller: reference, estimate checks, fallback, actuator limits, tick bookkeeping.

A control law (a :class:`Law`: adaptive or known-theta backstepping, PID, LQR,
passive; the registry is :mod:`pac_controller.laws`) only proposes the force
u_law for a tick.  Everything else is the same for every law:

* F_r and its derivatives are a pure function of time (reference.py);
* an estimate with a non-finite value never reaches a law that uses it: the
  fallback command answers it;
* every command passes the slew limit (from the last command, at least one
  period) and then the saturation [u_min, u_max];
* the law is told the force actually commanded (``commit``), so a law with state
  (an integrator) can stop winding up against the limits, and it is restarted
  bumplessly from the actuator's force (``restart``) whenever the previous command
  was not its own (start, fallback, a new run).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numba import njit

from pac_model import model
from pac_model.parameters import positive_period

from .parameters import ControllerParameters, ReferenceParameters
from .reference import ForceReference

Errors = tuple[float, float, float]


@dataclass(frozen=True)
class Command:
    """The controller's output at one tick."""

    tick: int
    time: float
    u: float  # applied (saturated) actuator force [N]
    u_unsaturated: float  # what the law asked for [N]
    force_reference: float  # F_r [N]
    tracking_error: Errors  # law-specific; backstepping: (e1, e2, e3), eqs. (24), (29), (36)
    saturated: bool
    mode: str  # "active", "passive" or "fallback"


class Law(Protocol):
    """What a control-law core provides to :class:`Controller`."""

    @property
    def mode(self) -> str:
        """Command.mode of its commands: "active" (feedback) or "passive" (a law may change it:
        line_adaptive's guard falls back to passive)."""

    #: False: the law ignores the estimate (then a non-finite one does not force the fallback).
    uses_estimate: bool

    def restart(self, u_applied: float | None) -> None:
        """Forget the law's state; the next output continues from ``u_applied`` (None: at rest)."""

    def output(
        self,
        tick: int,
        t: float,
        f_r: np.ndarray,
        z_hat: np.ndarray,
        theta_hat: np.ndarray,
        contact_force_hat: float = math.nan,
    ) -> tuple[float, Errors]:
        """The unlimited force u_law for ``tick`` and three law-specific errors; no state change.
        ``contact_force_hat`` (F̂) is passed only to laws with ``uses_contact_force``."""

    def commit(self, tick: int, u_applied: float) -> None:
        """The limited force actually commanded for ``tick``: update the law's state."""


#: A law with ``uses_contact_force = True`` gets the estimate's F_hat as a sixth argument of
#: ``output`` (a non-finite one forces the fallback); the others are called with five.


def contact_force_estimate(t: float, omega: float, z_hat: np.ndarray, theta_hat: np.ndarray) -> float:
    """F_hat = k_hat z_hat_1, k_hat = v(t)^T theta_hat (eqs. (6), (8))."""
    return model.contact_force(model.stiffness(t, omega, theta_hat), float(z_hat[0]), unilateral=False)


@njit(cache=True)
def limit_command(
    u: float,
    last_u: float,
    has_last: bool,
    ticks_since: int,
    slew_rate_max: float,
    sample_period: float,
    u_min: float,
    u_max: float,
) -> float:
    """The actuator limits: slew rate from the last command (over at least one period), then saturation."""
    applied = u
    if has_last:
        # At least one period: a command whose tick is not after the last one (a fallback
        # tick extrapolated ahead of a returning estimate) is still rate limited.
        step = slew_rate_max * sample_period * max(1, ticks_since)
        applied = min(max(applied, last_u - step), last_u + step)
    return min(max(applied, u_min), u_max)


class Controller:
    """One law inside the shared safety chain.

    Explicit state: the last commanded force and its tick (slew limit), and the tick of
    the law's last own command (None: the law must restart before its next output).
    """

    def __init__(
        self,
        law: Law,
        params: ControllerParameters,
        reference: ReferenceParameters,
        sample_period: float,
        name: str = "",
    ) -> None:
        positive_period(sample_period)
        self.law = law
        self.name = name
        self.params = params
        self.reference = ForceReference(reference)
        self.sample_period = sample_period
        self.last_u: float | None = None  # None: no command yet (no rate limit on the first)
        self.last_tick = -1
        self.law_tick: int | None = None

    def compute(
        self, tick: int, z_hat: np.ndarray, theta_hat: np.ndarray, contact_force_hat: float = math.nan
    ) -> Command:
        """The command for ``tick`` from the estimate of that tick (F_hat: its contact_force_hat)."""
        t = tick * self.sample_period
        f_r = self.reference.at(t)
        z_hat, theta_hat = np.asarray(z_hat, dtype=float), np.asarray(theta_hat, dtype=float)
        if self.law.uses_estimate and not (np.isfinite(z_hat).all() and np.isfinite(theta_hat).all()):
            return self.fallback(tick)
        uses_force = getattr(self.law, "uses_contact_force", False)
        if uses_force and not math.isfinite(contact_force_hat):
            return self.fallback(tick)
        if self.law_tick is None or tick <= self.law_tick:
            self.law.restart(self.last_u)
        if uses_force:
            u_law, errors = self.law.output(tick, t, f_r, z_hat, theta_hat, float(contact_force_hat))
        else:
            u_law, errors = self.law.output(tick, t, f_r, z_hat, theta_hat)
        if not math.isfinite(u_law):
            return self.fallback(tick)
        cmd = self._limited(tick, t, u_law, f_r[0], errors, self.law.mode)
        self.law.commit(tick, cmd.u)
        self.law_tick = tick
        return cmd

    def warm_up(self) -> None:
        """Commands on a copy (the law, then the fallback): numba loads the compiled code now, not at
        the loop's first tick."""
        twin = copy.deepcopy(self)
        twin.compute(0, np.zeros(4), np.array([4000.0, 0.0, 0.0]), 100.0)  # F_hat for laws that read it
        twin.compute(1, np.full(4, np.nan), np.array([4000.0, 0.0, 0.0]))

    def fallback(self, tick: int) -> Command:
        """The safe command: the static uplift ``fallback_force``, reached within the slew limit."""
        t = tick * self.sample_period
        force = self.params.fallback_force
        self.law_tick = None  # the law did not command this: it restarts from here
        return self._limited(tick, t, force, self.reference.at(t)[0], (0.0, 0.0, 0.0), "fallback")

    def _limited(
        self, tick: int, t: float, u: float, force_reference: float, errors: Errors, mode: str
    ) -> Command:
        """Slew-rate limit from the last command, then saturation; updates the actuator state."""
        p = self.params
        has_last = self.last_u is not None
        applied = limit_command(
            float(u),
            float(self.last_u) if self.last_u is not None else 0.0,
            has_last,
            tick - self.last_tick,
            float(p.slew_rate_max),
            self.sample_period,
            float(p.u_min),
            float(p.u_max),
        )
        self.last_u, self.last_tick = applied, tick
        return Command(
            tick=tick,
            time=t,
            u=applied,
            u_unsaturated=u,
            force_reference=force_reference,
            tracking_error=errors,
            saturated=applied != u,
            mode=mode,
        )
