"""The law-agnostic controller: reference, estimate checks, fallback, actuator limits, tick bookkeeping.

The safety chain is compiled once (``kernels.controller_step`` and its parts); the node's
controller and the compiled closed loop run that same code on the same records, so they cannot
drift.  A control law (a :class:`Law`: adaptive or known-theta backstepping, PID, LQR,
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

from pac_model import model
from pac_model.parameters import positive_period

from .kernels import (
    CONTROLLER_PARAMS,
    CONTROLLER_STATE,
    MODES,
    KernelLaw,
    fallback_one,
    fill_safety_chain,
    law_command_one,
    must_restart_one,
    new_state,
    refused_one,
    step_one,
)
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


def watchdog_fallback_tick(
    elapsed: float, sample_period: float, watchdog_ticks: int, last_estimate_tick: int, last_command_tick: int
) -> tuple[int, int | None]:
    """The watchdog's decision ``elapsed`` seconds after the last fresh estimate arrived: (its age in
    whole ticks, the tick of the fallback command to send now, or None while the estimate is younger
    than ``watchdog_ticks`` ticks or the watchdog is off, 0)."""
    age = int(elapsed / sample_period)
    if watchdog_ticks == 0 or age < watchdog_ticks:
        return age, None
    # The tick the loop would be at, extrapolated by the wall clock; never one already commanded.
    return age, max(last_estimate_tick + age, last_command_tick + 1)


class Controller:
    """One law inside the shared safety chain.

    Explicit state, in a ``kernels.CONTROLLER_STATE`` record: the last commanded force and its
    tick (slew limit), and the tick of the law's last own command (none: the law must restart
    before its next output).  A law with a compiled form (:class:`kernels.KernelLaw`: every law
    pac ships) shares its records with the controller and each command is one call of
    ``kernels.controller_step``, the compiled loop's; any other :class:`Law` is called from
    Python between the same compiled parts of the chain.
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
        if isinstance(law, KernelLaw):  # the law's own records: its design and memory are fields
            self.record, self.state = law.params, law.state
        else:
            self.record, self.state = np.zeros(1, CONTROLLER_PARAMS), np.zeros(1, CONTROLLER_STATE)
            self.record[0]["uses_estimate"] = law.uses_estimate
            self.record[0]["uses_contact_force"] = getattr(law, "uses_contact_force", False)
        fill_safety_chain(self.record[0], params, self.reference.args, sample_period)
        new_state(self.state)

    @property
    def last_u(self) -> float | None:
        """The last commanded force (None: no command yet, no rate limit on the first)."""
        s = self.state[0]
        return float(s["last_u"]) if s["has_last"] else None

    @last_u.setter
    def last_u(self, value: float | None) -> None:
        s = self.state[0]
        s["has_last"], s["last_u"] = value is not None, 0.0 if value is None else float(value)

    @property
    def last_tick(self) -> int:
        """The tick of the last command (-1: none)."""
        return int(self.state[0]["last_tick"])

    @last_tick.setter
    def last_tick(self, tick: int) -> None:
        self.state[0]["last_tick"] = tick

    @property
    def law_tick(self) -> int | None:
        """The tick of the law's last own command (None: it restarts before its next output)."""
        s = self.state[0]
        return int(s["law_tick"]) if s["has_law_tick"] else None

    def compute(
        self,
        tick: int,
        z_hat: np.ndarray,
        theta_hat: np.ndarray,
        contact_force_hat: float = math.nan,
        actuator_force: float = math.nan,
    ) -> Command:
        """The command for ``tick`` from the estimate of that tick (F_hat: its contact_force_hat) and
        the actuator force measured with it (``ObserverEstimate.actuator_force``; NaN: not told,
        line_adaptive then weighs its own commands instead)."""
        z_hat = np.ascontiguousarray(z_hat, dtype=np.float64)
        theta_hat = np.ascontiguousarray(theta_hat, dtype=np.float64)
        f_hat, measured, law = float(contact_force_hat), float(actuator_force), self.law
        if isinstance(law, KernelLaw):
            arrays = (law.table, law.memory)
            return self._command(
                tick, step_one(self.record, self.state, *arrays, int(tick), z_hat, theta_hat, f_hat, measured)
            )
        # A user's law compiled into the chain (user_law.UserLaw.chain_step): one compiled step too.
        compiled = getattr(law, "chain_step", None)
        out = compiled(self.record, self.state, int(tick), z_hat, theta_hat, f_hat) if compiled else None
        if out is not None:
            return self._command(tick, out)
        if refused_one(self.record, z_hat, theta_hat, f_hat):
            return self.fallback(tick)
        if must_restart_one(self.state, int(tick)):
            law.restart(self.last_u)
        t = tick * self.sample_period
        f_r = self.reference.at(t)
        if self.record[0]["uses_contact_force"]:
            u_law, errors = law.output(tick, t, f_r, z_hat, theta_hat, f_hat)
        else:
            u_law, errors = law.output(tick, t, f_r, z_hat, theta_hat)
        if not math.isfinite(u_law):
            return self.fallback(tick)
        mode = law.mode  # before commit: line_adaptive's guard trips there, from the next command on
        u = law_command_one(self.record, self.state, int(tick), float(u_law))
        law.commit(tick, u)
        return Command(tick, t, u, u_law, float(f_r[0]), errors, u != u_law, mode)

    def warm_up(self) -> None:
        """Commands on a copy (the law, then the fallback): numba loads the compiled code now, not at
        the loop's first tick."""
        twin = copy.deepcopy(self)
        twin.compute(0, np.zeros(4), np.array([4000.0, 0.0, 0.0]), 100.0)  # F_hat for laws that read it
        twin.compute(1, np.full(4, np.nan), np.array([4000.0, 0.0, 0.0]))

    def fallback(self, tick: int) -> Command:
        """The safe command: the static uplift ``fallback_force``, reached within the slew limit."""
        return self._command(tick, fallback_one(self.record, self.state, int(tick)))

    def _command(self, tick: int, out: tuple[float, float, float, float, float, float, int]) -> Command:
        """The Command of the compiled chain's output (u, u_law, F_r, e1, e2, e3, mode code)."""
        u, u_law, f_r, e1, e2, e3, mode = out
        return Command(
            tick=tick,
            time=tick * self.sample_period,
            u=u,
            u_unsaturated=u_law,
            force_reference=f_r,
            tracking_error=(e1, e2, e3),
            saturated=u != u_law,
            mode=MODES[mode],
        )
