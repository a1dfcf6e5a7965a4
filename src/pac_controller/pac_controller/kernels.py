"""The controller compiled: every law's arithmetic and the law-agnostic safety chain, on named records.

One record type holds what a controller is given (:data:`CONTROLLER_PARAMS`: the law's code and
design, the actuator limits, the reference) and one what it remembers
(:data:`CONTROLLER_STATE`: the last command and its tick, the law's integrator and pending
commands).  Both are numpy structured scalars, so the compiled closed loop
(``pac_rig.loop``) steps a controller without allocating, and the Python law classes
(:class:`KernelLaw` and its subclasses, which the controller node runs) call the very same
functions: one formula, two fronts.

Each law's arithmetic is its own module (``pid_kernels``, ``lqr_kernels``, ...; the four functions
``kernel_common`` describes); the step reaches them through ``law_dispatch``, generated from the
law registry (``law_dispatch_source``). Adding a compiled law (docs/design.md, "Adding a law"):
its module, its numbers as fields of :data:`CONTROLLER_PARAMS` (filled by its class's ``pack``),
its memory as fields of :data:`CONTROLLER_STATE`, one registry line, and the dispatch written again.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernel_common import FALLBACK, MODES
from .law_dispatch import LAW_CODES, law_commit, law_mode, law_output, law_restart
from .parameters import ControllerParameters
from .reference import reference_at4

assert MODES == ("active", "passive", "fallback")

#: Most pending commands the lqr law keeps (design_delay_ticks is at most 10).
MAX_PENDING = 16

CONTROLLER_PARAMS = np.dtype(
    [
        ("law", "i8"),  # LAW_CODES
        ("dt", "f8"),  # sample period [s]
        # safety chain (controller_step; set by fill_safety_chain)
        ("slew_rate_max", "f8"),
        ("u_min", "f8"),
        ("u_max", "f8"),
        ("fallback_force", "f8"),
        # what the law reads of the estimate: z_hat, theta_hat (a non-finite one forces the
        # fallback) and F_hat (likewise); set from the law's Law.uses_estimate / uses_contact_force
        ("uses_estimate", "b1"),
        ("uses_contact_force", "b1"),
        # F_r (reference.reference_args)
        ("shape", "i8"),
        ("force_amplitude", "f8"),
        ("force_initial", "f8"),
        ("step_time", "f8"),
        ("period", "f8"),
        ("filter_bandwidth", "f8"),
        # backstepping, eqs. (23)-(43)
        ("omega", "f8"),
        ("m1", "f8"),
        ("b1", "f8"),
        ("k1", "f8"),
        ("m2", "f8"),
        ("b2", "f8"),
        ("c1", "f8"),
        ("c2", "f8"),
        ("c3", "f8"),
        ("stiffness_hat_min", "f8"),
        ("theta", "f8", 3),  # backstepping_known: the catenary's true theta
        # pid (pid.PidGains)
        ("kp", "f8"),
        ("ki", "f8"),
        ("kd", "f8"),
        ("tf", "f8"),
        ("tt", "f8"),
        # lqr (lqr.LqrGains): K = (state 4, pending delay, integral 1)
        ("gain", "f8", 4 + MAX_PENDING + 1),
        ("delay", "i8"),
        ("design_stiffness", "f8"),
        ("tracking_time", "f8"),
        # line_adaptive (line_adaptive.LineAdaptiveLaw; its arrays: the law's table and memory)
        ("line_period", "i8"),  # N, ticks per span
        ("line_harmonics", "i8"),  # H
        ("line_delay", "i8"),  # d, design_delay_ticks
        ("line_gain", "f8"),
        ("line_step_max", "f8"),
        ("line_probe_step", "f8"),
        ("line_forgetting", "f8"),
        ("line_prior_weight", "f8"),
        ("line_response_min", "f8"),
        ("line_effort_weight", "f8"),
        ("line_model_below", "f8"),
        ("line_runin_spans", "i8"),
        ("line_guard_ratio", "f8"),
        ("line_guard_after", "i8"),
        ("line_guard_estimate", "b1"),  # line_guard_reference "estimate"
        ("line_guard_bias", "f8"),  # |mean(F_hat - F_applied)| over a span, fraction of mean(F_r)
        ("line_guard_loss", "f8"),  # share of a span's ticks nearly lost above the passive spans'
        ("line_guard_loss_margin", "f8"),  # nearly lost: F_hat <= this times F_r
        ("line_guard_saturation", "f8"),  # share of a span's commands the limits changed
        ("line_guard_strikes", "i8"),  # back-offs before the guard falls back
        ("line_guard_loss_after", "i8"),  # learning spans before the loss check's bar is the run-in's
        ("line_supports", "i8"),  # supports of the design layout in the table (< 2: the period N)
        ("line_support_before", "f8"),  # share of a span before / after each support where the
        ("line_support_after", "f8"),  # harmonics only raise the command (support_lift), starting
        ("line_actuator_lag_ticks", "i8"),  # earlier by the actuator's lag (line_actuator_lag / dt)
        ("line_position_start", "f8"),  # the law's x at tick 0 (with the position error)
        ("line_step_distance", "f8"),  # v dt
        # a map learned on an earlier pass (line_adaptive_kernels: the map's rows of ``memory``)
        ("line_map", "b1"),  # each span starts from its own harmonics; the responses are frozen
        ("line_map_passive_var", "f8"),  # the earlier pass's passive sigma_b^2 (the guard's bar)
        ("line_map_passive_loss", "f8"),  # and its worst passive span's nearly-lost share
        ("line_map_stiffness", "f8"),  # its fitted line impedance k_s, c and whether it is valid
        ("line_map_damping", "f8"),
        ("line_map_model_valid", "b1"),
        ("line_map_u_mean", "f8"),  # its U_0 at the end
    ]
)

CONTROLLER_STATE = np.dtype(
    [
        # safety chain
        ("has_last", "b1"),  # a command was given (the slew limit applies from it)
        ("last_u", "f8"),
        ("last_tick", "i8"),
        ("has_law_tick", "b1"),  # False: the law restarts before its next output
        ("law_tick", "i8"),
        # the law's memory (pid, lqr)
        ("started", "b1"),
        ("has_bumpless", "b1"),
        ("bumpless_from", "f8"),
        ("integral", "f8"),
        ("rate", "f8"),  # pid: Ki e + (u_applied - u) / Tt; lqr: q' of the last tick
        ("derivative", "f8"),
        ("last_error", "f8"),
        ("law_last_tick", "i8"),
        ("pending_error", "f8"),  # output -> commit
        ("pending_integral", "f8"),
        ("pending_derivative", "f8"),
        ("pending_u", "f8"),
        ("commands", "f8", MAX_PENDING),  # lqr: commands sent, not yet applied (a ring)
        ("head", "i8"),  # the oldest of them
        # line_adaptive's scalars (module docstring of line_adaptive)
        ("line_u_mean", "f8"),  # U_0
        ("line_clip_offset", "f8"),  # C
        ("line_a_mean", "f8"),
        ("line_e_mean", "f8"),
        ("line_has_prev", "b1"),
        ("line_start_tick", "i8"),  # -1: the spans have not started
        ("line_passive_var", "f8"),
        ("line_passive_spans", "i8"),
        ("line_recent_var", "f8", 3),  # line_adaptive_kernels.GUARD_SPANS
        ("line_recent_passive_var", "f8", 3),  # the same spans' passive estimates
        ("line_last_sigma_ratio", "f8"),
        ("line_stiffness", "f8"),  # k_s of the fitted line impedance Z = k_s + i c w
        ("line_damping", "f8"),  # c
        ("line_model_valid", "b1"),  # the model has the first harmonic strong: it may stand in for weak ones
        ("line_tripped", "b1"),
        ("line_pending_error", "f8"),
        ("line_pending_reference", "f8"),
        ("line_open_span", "i8"),  # the span whose sums are accumulating (-1: none)
        ("line_last_commit", "i8"),  # the tick of the last commit (-1: none)
        ("line_restart_pending", "b1"),  # restarted after a fallback: resume or, on a new run, forget
        ("line_tainted_span", "i8"),  # a span a fallback episode touched: neither learned nor judged (-1)
        # the guard's sums over the open span (line_adaptive_kernels: _end_of_span)
        ("line_pending_measured", "f8"),  # the actuator force of this tick's measurement (NaN: none)
        ("line_pending_law", "f8"),  # u_law of this tick (the limits changed it: saturated)
        ("line_span_ticks", "i8"),
        ("line_bias_sum", "f8"),  # sum of F_hat - F_applied
        ("line_reference_sum", "f8"),  # sum of F_r
        ("line_loss_ticks", "i8"),  # ticks nearly lost (F_hat less the bias <= the margin's share of F_r)
        ("line_passive_loss_ticks", "i8"),  # the same, of F_hat as it would have been passive (estimate)
        ("line_clip_ticks", "i8"),  # ticks the limits changed u_law
        ("line_passive_loss", "f8"),  # the largest nearly-lost share over the passive spans
        ("line_last_passive_loss", "f8"),  # the last judged span's estimated passive share (estimate)
        ("line_strikes", "i8"),  # back-offs on contact loss so far (the trip counts them)
        ("line_saturation_backoffs", "i8"),  # back-offs on saturation so far
        ("line_last_bias", "f8"),  # mean of F_hat - F_applied over the last judged span
        ("line_trip_reason", "i8"),  # line_adaptive_kernels.TRIP_*: why the guard fell back (0: it did not)
        ("line_fade_from", "i8"),  # the tick the feedforward's fade-out started (the guard's trip)
        ("line_cursor", "i8"),  # the layout's span the last position fell in
        ("line_first_span", "i8"),  # the layout's span of the run's first command (its span 0)
        ("line_backoff_from", "i8"),  # the tick a back-off's ramp started (-1: none)
        ("line_map_scale", "f8"),  # the share of the map's harmonics applied (back-offs halve it)
    ]
)

#: The fields of CONTROLLER_PARAMS that ``reference.reference_args`` gives, in its order.
REFERENCE_FIELDS = ("shape", "force_amplitude", "force_initial", "step_time", "period", "filter_bandwidth")


def fill_safety_chain(
    record: np.ndarray, params: ControllerParameters, reference_args: tuple, sample_period: float
) -> None:
    """The safety chain's fields of a CONTROLLER_PARAMS record: period, actuator limits, fallback
    force and F_r (``reference_args``: ``reference.reference_args``)."""
    record["dt"] = sample_period
    record["slew_rate_max"] = params.slew_rate_max
    record["u_min"], record["u_max"] = params.u_min, params.u_max
    record["fallback_force"] = params.fallback_force
    for name, value in zip(REFERENCE_FIELDS, reference_args, strict=True):
        record[name] = value


#: The law tables of a law without arrays (every law but line_adaptive): one complex zero.
NO_TABLE = np.zeros((1, 1), dtype=np.complex128)


@njit(cache=True)
def new_state(states) -> None:
    """A controller that has commanded nothing yet (``Controller.__init__``)."""
    s = states[0]
    s.has_last, s.last_u, s.last_tick, s.has_law_tick, s.law_tick = False, 0.0, -1, False, 0


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


@njit(cache=True, error_model="numpy")
def estimate_refused(p, z_hat, theta_hat, f_hat: float) -> bool:
    """A law never sees a non-finite value of what it reads (``uses_estimate``: z_hat and
    theta_hat; ``uses_contact_force``: F_hat): such an estimate is answered by the fallback."""
    if p.uses_estimate:
        for i in range(4):
            if not math.isfinite(z_hat[i]):
                return True
        for i in range(3):
            if not math.isfinite(theta_hat[i]):
                return True
    return p.uses_contact_force and not math.isfinite(f_hat)


@njit(cache=True, error_model="numpy")
def law_must_restart(s, tick: int) -> bool:
    """The previous command was not the law's (none yet, a fallback) or ``tick`` is not after its
    last one (a new run): the law restarts, bumplessly from the actuator's force."""
    return not s.has_law_tick or tick <= s.law_tick


@njit(cache=True, error_model="numpy")
def _limited(p, s, tick: int, u: float) -> float:
    """Slew-rate limit from the last command, then saturation; updates the actuator state."""
    applied = limit_command(
        u, s.last_u if s.has_last else 0.0, s.has_last, tick - s.last_tick,
        p.slew_rate_max, p.dt, p.u_min, p.u_max,
    )  # fmt: skip
    s.has_last, s.last_u, s.last_tick = True, applied, tick
    return applied


@njit(cache=True, error_model="numpy")
def controller_fallback(p, s, tick: int) -> tuple[float, float, float, float, float, float, int]:
    """The safe command (``Controller.fallback``): fallback_force within the slew limit."""
    t = tick * p.dt
    f_r = reference_at4(
        t, p.shape, p.force_amplitude, p.force_initial, p.step_time, p.period, p.filter_bandwidth
    )
    s.has_law_tick = False  # the law did not command this: it restarts from here
    u = _limited(p, s, tick, p.fallback_force)
    return u, p.fallback_force, f_r[0], 0.0, 0.0, 0.0, FALLBACK


def safety_chain(restart, output, mode_of, commit):
    """The chain around a law, written once: ``controller_step(p, s, table, memory, tick, z_hat,
    theta_hat, f_hat, force_measured) -> (u, u_unsaturated, F_r, e1, e2, e3, mode code)``
    (``force_measured``: the actuator force reported with this tick's measurement, the force
    applied over the last period; NaN where the controller is not told it) for the law of the four
    compiled functions (signatures of ``law_dispatch``'s law_restart, law_output, law_mode,
    law_commit; ``table`` and ``memory`` are the law's, passed through to them).

    A closure, not a function taking the law as an argument: numba calls the four statically, so
    the functions that call the chain (``step_one``, ``pac_rig.loop``) stay cached on disk (a
    compiled function passed as a value is a run-time pointer numba cannot cache).  pac's laws
    are :data:`controller_step`; a user's compiled law file gets its own (``user_law``)."""

    @njit(error_model="numpy")
    def controller_step(
        p, s, table, memory, tick: int, z_hat, theta_hat, f_hat: float, force_measured: float
    ) -> tuple[float, float, float, float, float, float, int]:
        t = tick * p.dt
        f_r = reference_at4(
            t, p.shape, p.force_amplitude, p.force_initial, p.step_time, p.period, p.filter_bandwidth
        )
        if estimate_refused(p, z_hat, theta_hat, f_hat):
            return controller_fallback(p, s, tick)
        if law_must_restart(s, tick):
            restart(p, s, table, memory, s.has_last, s.last_u)
        u_law, e1, e2, e3 = output(p, s, table, memory, tick, t, f_r, z_hat, theta_hat, f_hat, force_measured)
        if not math.isfinite(u_law):
            return controller_fallback(p, s, tick)
        mode = mode_of(p, s)  # before commit: line_adaptive's guard trips there, from the next command on
        u = law_command(p, s, tick, u_law)
        commit(p, s, table, memory, tick, u)
        return u, u_law, f_r[0], e1, e2, e3, mode

    return controller_step


@njit(cache=True, error_model="numpy")
def law_command(p, s, tick: int, u_law: float) -> float:
    """The law's finite ``u_law`` through the actuator limits; the law commanded ``tick``."""
    u = _limited(p, s, tick, u_law)
    s.has_law_tick, s.law_tick = True, tick
    return u


#: ``Controller.compute`` compiled, for pac's laws: (u, u_unsaturated, F_r, e1, e2, e3, mode code).
controller_step = safety_chain(law_restart, law_output, law_mode, law_commit)


# Entry points for Python callers (the law classes): records travel as 1-element arrays.
@njit(cache=True, error_model="numpy")
def _restart_one(params, states, table, memory, has_u, u_applied) -> None:
    law_restart(params[0], states[0], table, memory, has_u, u_applied)


@njit(cache=True, error_model="numpy")
def _output_one(params, states, table, memory, tick, t, f0, f1, f2, f3, z_hat, theta_hat, f_hat, measured):
    return law_output(
        params[0], states[0], table, memory, tick, t, (f0, f1, f2, f3), z_hat, theta_hat, f_hat, measured
    )


@njit(cache=True, error_model="numpy")
def step_one(params, states, table, memory, tick, z_hat, theta_hat, f_hat, force_measured):
    """:func:`controller_step` on the records of 1-element arrays."""
    return controller_step(params[0], states[0], table, memory, tick, z_hat, theta_hat, f_hat, force_measured)


@njit(cache=True, error_model="numpy")
def fallback_one(params, states, tick):
    """:func:`controller_fallback` on the records of 1-element arrays."""
    return controller_fallback(params[0], states[0], tick)


@njit(cache=True, error_model="numpy")
def refused_one(params, z_hat, theta_hat, f_hat) -> bool:
    return estimate_refused(params[0], z_hat, theta_hat, f_hat)


@njit(cache=True, error_model="numpy")
def must_restart_one(states, tick) -> bool:
    return law_must_restart(states[0], tick)


@njit(cache=True, error_model="numpy")
def law_command_one(params, states, tick, u_law) -> float:
    return law_command(params[0], states[0], tick, u_law)


@njit(cache=True, error_model="numpy")
def _commit_one(params, states, table, memory, tick, u_applied) -> None:
    law_commit(params[0], states[0], table, memory, tick, u_applied)


class KernelLaw:
    """A law whose arithmetic is its kernel module's, through ``law_dispatch`` (the ``Law`` protocol).

    A subclass fills ``self.params[0]`` (its fields of :data:`CONTROLLER_PARAMS`) and sets
    ``params['law']``; the compiled loop copies those fields, so the node's law and the
    offline loop's are the same numbers through the same code.
    """

    mode = "active"
    uses_estimate = True
    uses_contact_force = False
    #: The law's arrays (line_adaptive's basis and learned harmonics); one complex zero otherwise.
    table = NO_TABLE
    memory = NO_TABLE

    def __init__(self, name: str, sample_period: float) -> None:
        self.params = np.zeros(1, CONTROLLER_PARAMS)
        self.params[0]["law"] = LAW_CODES[name]
        self.params[0]["dt"] = sample_period
        self.params[0]["uses_estimate"] = self.uses_estimate
        self.params[0]["uses_contact_force"] = self.uses_contact_force
        self.state = np.zeros(1, CONTROLLER_STATE)
        self.restart(None)

    def restart(self, u_applied: float | None) -> None:
        _restart_one(
            self.params, self.state, self.table, self.memory, u_applied is not None,
            0.0 if u_applied is None else float(u_applied),
        )  # fmt: skip

    def output(
        self,
        tick: int,
        t: float,
        f_r: np.ndarray,
        z_hat: np.ndarray,
        theta_hat: np.ndarray,
        contact_force_hat: float = math.nan,  # F_hat: read by the laws with uses_contact_force
        actuator_force: float = math.nan,  # the measurement's actuator force: read by line_adaptive
    ) -> tuple[float, tuple[float, float, float]]:
        u, e1, e2, e3 = _output_one(
            self.params, self.state, self.table, self.memory, int(tick), float(t), float(f_r[0]),
            float(f_r[1]), float(f_r[2]), float(f_r[3]), np.asarray(z_hat, dtype=np.float64),
            np.asarray(theta_hat, dtype=np.float64), float(contact_force_hat), float(actuator_force),
        )  # fmt: skip
        return u, (e1, e2, e3)

    def commit(self, tick: int, u_applied: float) -> None:
        _commit_one(self.params, self.state, self.table, self.memory, int(tick), float(u_applied))
