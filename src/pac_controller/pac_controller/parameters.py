"""Parameters of the reference generator and the backstepping controller."""

from __future__ import annotations

from dataclasses import dataclass

from pac_common.parameters import ParameterError, ParameterSet, parameter
from pac_common.registry import RegistryNames

#: The most supports a line map may name (a 100 km line of 50 m spans).
MAX_LINE_SUPPORTS = 2001


@dataclass(frozen=True)
class ReferenceParameters(ParameterSet):
    """Contact-force reference F_r: a piecewise-constant command through a 4th-order filter.

    Section 6 filters "a square sequence between 0 and F_N = 100 N" without giving
    the period or the filter; these are our documented choices (docs/design.md).
    """

    shape: str = parameter(
        "constant",
        "command before the filter: 'constant' (0 -> force_amplitude at t = 0), "
        "'step' (0 -> force_initial at t = 0, -> force_amplitude at step_time), "
        "'square' (force_amplitude / 0 alternating every period / 2, high first)",
        choices=("constant", "step", "square"),
        runtime=True,
    )
    force_amplitude: float = parameter(
        100.0, "F_N, the nominal contact force", "N", low=0.0, high=1000.0, runtime=True
    )
    force_initial: float = parameter(
        50.0, "first level of the 'step' shape", "N", low=0.0, high=1000.0, runtime=True
    )
    step_time: float = parameter(5.0, "time of the second level of 'step'", "s", low=0.0, runtime=True)
    period: float = parameter(4.0, "period of the 'square' shape", "s", low=0.01, high=3600.0, runtime=True)
    filter_bandwidth: float = parameter(
        20.0,
        "pole p of the critically damped filter p^4 / (s + p)^4",
        "rad/s",
        low=0.1,
        high=500.0,
        runtime=True,
    )


#: The control laws ``law`` selects: the keys of pac_controller.laws.LAWS (one line adds a law).
LAW_NAMES = RegistryNames("pac_controller.laws", "LAWS")
#: The forms of F_hat the fixed-gain laws (pid, lqr) can feed back (``force_estimate``);
#: pac_controller.laws.FORCE_ESTIMATE_NEEDS says what each needs of the observer.
FORCE_ESTIMATES = ("k_hat_z1", "contact_force_hat")
#: The laws with a compiled form (LawEntry.compiled): the compiled loop and the batch run these.
COMPILED_LAW_NAMES = RegistryNames("pac_controller.laws", "LAWS", lambda entry: entry.compiled)


@dataclass(frozen=True)
class ControllerParameters(ParameterSet):
    """Law selection, backstepping gains (eqs. (28), (35), (43)) and the law-agnostic actuator limits."""

    law: str = parameter(
        "adaptive_backstepping",
        "control law: 'adaptive_backstepping' (eq. (43) on z_hat, theta_hat), 'backstepping_known' "
        "(eq. (43) given the true theta: an oracle, needs k0, alpha, beta), 'pid' (PID on F_hat), "
        "'lqr' (LQ servo at design_stiffness), 'passive' (u = F_r), 'line_adaptive' (span-periodic "
        "learning on F_hat for a distributed line, with a do-no-harm guard), a law module of the registry "
        "(--help lists every law; docs/laws.md), or the path of your own law's Python file (docs/laws.md, "
        "'Your own law'). Fixed for a run (docs/laws.md)",
        choices=LAW_NAMES,
        or_file=".py",
    )
    mode: str = parameter(
        "active",
        "DEPRECATED, use law: 'passive' is law:=passive; 'active' runs the selected law",
        choices=("active", "passive"),
    )
    c1: float = parameter(
        40.0, "backstepping gain c1, eq. (28)", "1/s", low=0.0, low_open=True, high=1e4, runtime=True
    )
    c2: float = parameter(
        40.0, "backstepping gain c2, eq. (35)", "1/s", low=0.0, low_open=True, high=1e4, runtime=True
    )
    c3: float = parameter(
        50.0, "backstepping gain c3, eq. (43)", "1/s", low=0.0, low_open=True, high=1e4, runtime=True
    )
    u_min: float = parameter(-500.0, "actuator force lower limit", "N", low=-1e7, high=1e7, runtime=True)
    u_max: float = parameter(500.0, "actuator force upper limit", "N", low=-1e7, high=1e7, runtime=True)
    slew_rate_max: float = parameter(
        100000.0,
        "actuator force rate limit. The nominal loop needs <= 4.6 kN/s, but after a large transient "
        "(an observer restart) a limit below ~40 kN/s locks the loop in a rate-limit cycle "
        "(docs/design.md, safety chain)",
        "N/s",
        low=0.0,
        low_open=True,
        high=1e12,
        runtime=True,
    )
    fallback_force: float = parameter(
        100.0,
        "static uplift commanded in fallback (no fresh or no finite estimate)",
        "N",
        low=0.0,
        high=1000.0,
        runtime=True,
    )
    watchdog_ticks: int = parameter(
        20,
        "fallback after this many ticks without a fresh estimate (0: off, for lock-step runs)",
        "ticks",
        low=0,
        high=100000,
        runtime=True,
    )
    stiffness_hat_min: float = parameter(
        500.0,
        "k_hat is clamped below at this value in z1r = F_r / k_hat",
        "N/m",
        low=1.0,
        high=1e6,
        runtime=True,
    )

    @property
    def effective_law(self) -> str:
        """The law that runs: ``law``, or 'passive' when the deprecated ``mode`` says so."""
        return "passive" if self.mode == "passive" else self.law

    def check_consistency(self) -> None:
        if self.mode == "passive" and self.law not in ("adaptive_backstepping", "passive"):
            raise ParameterError(
                "mode", self.mode, f"'active' with law = {self.law} (mode is deprecated: use law)"
            )
        if self.u_max <= self.u_min:
            raise ParameterError("u_max", self.u_max, f"greater than u_min = {self.u_min:g} N")
        if not self.u_min <= self.fallback_force <= self.u_max:
            raise ParameterError(
                "fallback_force",
                self.fallback_force,
                f"within [u_min, u_max] = [{self.u_min:g}, {self.u_max:g}] N",
            )


@dataclass(frozen=True)
class LawParameters(ParameterSet):
    """Design of the fixed-gain laws (pid, lqr) and of line_adaptive's learning and guard.

    The gains are computed from these in code (pac_controller.pid.design_pid,
    pac_controller.lqr.design_lqr; method and numbers in docs/laws.md), never set by hand.
    """

    design_stiffness: float = parameter(
        4000.0,
        "catenary stiffness of the linear design model of pid and lqr (the mean stiffness k0 of the line; "
        "on the FE line derived from it when not named: the mean static stiffness over a period of its "
        "design spans, docs/laws.md)",
        "N/m",
        low=0.0,
        low_open=True,
        high=1e6,
    )
    force_estimate: str = parameter(
        "k_hat_z1",
        "pid, lqr: the contact-force estimate F_hat they feed back: 'k_hat_z1' k_hat z_hat_1 of the "
        "paper's observer (eqs. (6), (8): needs its theta_hat), 'contact_force_hat' the estimate's own "
        "F_hat (what observer:=contact_force gives; derived from the observer when not named)",
        choices=FORCE_ESTIMATES,
    )
    design_delay_ticks: int = parameter(
        1, "command delay the pid and lqr designs assume (1: the rig's loop)", "ticks", low=0, high=10
    )
    pid_bandwidth: float = parameter(
        21.0,
        "pid: open-loop crossover frequency of the design (21: the highest with Ms <= 2 at 45 deg)",
        "rad/s",
        low=0.0,
        low_open=True,
        high=1000.0,
    )
    pid_phase_margin: float = parameter(
        45.0, "pid: phase margin at the crossover", "deg", low=10.0, high=80.0
    )
    pid_integral_ratio: float = parameter(
        4.0, "pid: integral time / derivative time Ti / Td (4: Ziegler-Nichols)", "", low=1.0, high=100.0
    )
    pid_derivative_filter: float = parameter(
        10.0, "pid: N, derivative filter time constant Td / N", "", low=2.0, high=100.0
    )
    lqr_force_scale: float = parameter(
        1.0,
        "lqr: contact-force error weighted as one unit of cost (Bryson)",
        "N",
        low=0.0,
        low_open=True,
        high=1e4,
    )
    lqr_velocity_scale: float = parameter(
        1.0,
        "lqr: head and frame velocity weighted as one unit of cost",
        "m/s",
        low=0.0,
        low_open=True,
        high=100.0,
    )
    lqr_integral_time: float = parameter(
        0.05,
        "lqr: the force-error integral is weighted as lqr_force_scale over this time",
        "s",
        low=0.0,
        low_open=True,
        high=100.0,
    )
    lqr_input_scale: float = parameter(
        100.0,
        "lqr: actuator force deviation weighted as one unit of cost",
        "N",
        low=0.0,
        low_open=True,
        high=1e5,
    )
    line_max_frequency: float = parameter(
        16.0,
        "line_adaptive: learns the harmonics of speed / span_length up to this frequency (16: above "
        "it the paper's pantograph moves the FE line's force by under 6 % of the command, and the "
        "lower harmonics' coupling swamps what a step there shows: docs/laws.md)",
        "Hz",
        low=0.0,
        low_open=True,
        high=200.0,
    )
    line_learning_gain: float = parameter(
        0.6,
        "line_adaptive: gamma, fraction of a harmonic's error removed per span",
        "",
        low=0.0,
        low_open=True,
        high=1.0,
    )
    line_step_max: float = parameter(
        50.0,
        "line_adaptive: largest change of one harmonic's amplitude per span",
        "N",
        low=0.0,
        low_open=True,
        high=1000.0,
    )
    line_probe_step: float = parameter(
        10.0,
        "line_adaptive: largest step of a harmonic whose response has not been identified yet",
        "N",
        low=0.0,
        low_open=True,
        high=1000.0,
    )
    line_forgetting: float = parameter(
        0.7,
        "line_adaptive: forgetting factor per span of the identified response of each harmonic",
        "",
        low=0.0,
        low_open=True,
        high=1.0,
    )
    line_prior_weight: float = parameter(
        25.0,
        "line_adaptive: weight of the prior response dF/du = 1, as a squared step",
        "N^2",
        low=0.0,
        low_open=True,
        high=1e6,
    )
    line_response_min: float = parameter(
        0.05,
        "line_adaptive: floor on the modulus of the identified response (bounds the step)",
        "",
        low=0.0,
        low_open=True,
        high=10.0,
    )
    line_effort_weight: float = parameter(
        0.01,
        "line_adaptive: mu, weight of the command's harmonics against the force error's in what "
        "each span's step minimises, |E_h|^2 + mu |U_h|^2 (0: cancel every harmonic's error)",
        "",
        low=0.0,
        high=10.0,
    )
    line_model_below: float = parameter(
        0.1,
        "line_adaptive: a harmonic whose response on the line model (the nominal pantograph on the "
        "impedance k_s + i c w fitted to every harmonic's identified response) is below this takes "
        "the model's response instead of its own identification (0: every harmonic its own)",
        "",
        low=0.0,
        high=10.0,
    )
    line_runin_spans: int = parameter(
        3,
        "line_adaptive: spans run passive at the start (spans 1.. give the guard's passive sigma)",
        "spans",
        low=2,
        high=100,
    )
    line_guard_ratio: float = parameter(
        1.0,
        "line_adaptive: fall back to passive when the sigma of F_hat's span-periodic part (learned "
        "band) exceeds this times the passive spans'",
        "",
        low=0.1,
        high=10.0,
    )
    line_guard_reference: str = parameter(
        "runin",
        "line_adaptive: what the guard's sigma and nearly-lost share are compared with: 'runin', "
        "the passive spans at the start; 'estimate', each span's own as it would have been passive, "
        "its error less the identified response to the harmonics applied (the share: planned, tick "
        "by tick) (follows a line whose spans differ; one span's sigma above three times the "
        "run-in's trips either way; derived on a pantograph behind another; docs/laws.md)",
        choices=("runin", "estimate"),
    )
    line_guard_spans: int = parameter(
        8,
        "line_adaptive: learning spans before the guard judges the RMS sigma of the last 3 spans "
        "(one span above three times the limit trips at once)",
        "spans",
        low=3,
        high=100,
    )
    line_guard_loss_spans: int = parameter(
        0,
        "line_adaptive: learning spans before a span's near-lost share is judged against the worst "
        "passive span's (line_guard_loss); before, only a span above that bar by three times "
        "line_guard_loss strikes, as the harm check waits out the learning's first spans (0: from "
        "the first learning span; derived 8 where the actuator is fast; docs/laws.md)",
        "spans",
        low=0,
        high=100,
    )
    line_guard_bias: float = parameter(
        0.25,
        "line_adaptive: fall back to passive when the mean of F_hat over a span differs from the mean "
        "actuator force (the pantograph's momentum balance) by more than this times the mean "
        "reference: an estimate whose mean is wrong",
        "",
        low=0.0,
        low_open=True,
        high=10.0,
    )
    line_guard_loss: float = parameter(
        0.01,
        "line_adaptive: back off (learned harmonics halved) when a learning span has more of its "
        "ticks with F_hat <= line_guard_loss_margin F_r than the worst passive span by more than this share",
        "",
        low=0.0,
        high=1.0,
    )
    line_guard_loss_margin: float = parameter(
        0.05,
        "line_adaptive: a tick counts as (nearly) lost when F_hat is below this times F_r: an estimate "
        "misses the millisecond dips of a contact loss, not the approach to one (docs/laws.md)",
        "",
        low=0.0,
        high=1.0,
    )
    line_guard_saturation: float = parameter(
        0.25,
        "line_adaptive: back off likewise (never fall back) when the actuator limits (u_min, u_max, "
        "slew_rate_max) changed more than this share of a span's commands (the anti-windup keeps the "
        "law sound with a fifth of them clipped: docs/laws.md)",
        "",
        low=0.0,
        high=1.0,
    )
    line_support_before: float = parameter(
        0.0,
        "line_adaptive: share of a span before each support of the design layout (line_supports) "
        "where the learned harmonics may raise the command but not lower it (with "
        "line_support_after; 0 and 0: nowhere; derived 0.02 where the actuator is fast against a "
        "span). Lowered there, the head meets the dip after the support with too little force and can "
        "lose contact where passive does not (docs/laws.md)",
        "",
        low=0.0,
        high=0.5,
    )
    line_support_after: float = parameter(
        0.0,
        "line_adaptive: share of a span after each support where the learned harmonics may raise "
        "the command but not lower it (line_support_before; derived 0.1 where the actuator is fast)",
        "",
        low=0.0,
        high=0.5,
    )
    line_actuator_lag: float = parameter(
        0.0,
        "line_adaptive: how long a command takes to act (an actuator's lag and delay): the zone about "
        "the supports starts that much earlier, since the force applied there follows earlier "
        "commands (0: not at all; derived as the actuator's lag plus delay where it is fast: "
        "docs/laws.md)",
        "s",
        low=0.0,
        high=1.0,
    )
    line_guard_strikes: int = parameter(
        3,
        "line_adaptive: the span that would back off on contact loss this many times falls back to "
        "passive instead",
        "spans",
        low=1,
        high=100,
    )
    line_supports: tuple = parameter(
        (0.0,),
        "line_adaptive: the design layout's support positions along the line, increasing (the line "
        "map a train carries: what the infrastructure manager publishes, not the drawn deviation); "
        "the law learns over each span's own length (phase = (x - x_m) / L_m) instead of the nominal "
        "span's period. Fewer than two: none (derived on a whole FE line, docs/laws.md)",
        "m",
        low=0.0,
        high=1e6,
        max_length=MAX_LINE_SUPPORTS,
    )
    line_overlaps: tuple = parameter(
        (0.0,),
        "line_adaptive: where the design layout's tension sections overlap, (start, end) pairs along the "
        "line, flat (design data, as line_supports). Over a span inside an overlap the learned harmonics "
        "are off (the contact passes between two wires), faded out over the span before it and back in "
        "over the span after; those spans teach nothing. Fewer than two values: none (derived on a "
        "whole FE line, docs/laws.md)",
        "m",
        low=0.0,
        high=1e6,
        max_length=MAX_LINE_SUPPORTS,
    )
    line_position_start: float = parameter(
        0.0,
        "line_adaptive: the contact point's position along the line at the first tick (derived with "
        "line_supports); then x = this + v t",
        "m",
        low=-1e6,
        high=1e6,
    )
    line_position_error: float = parameter(
        0.0,
        "line_adaptive: the error of the train's position along the line (odometry and line map): "
        "the law's x is the true one plus this (0.5: the bound of a line map, docs/laws.md)",
        "m",
        low=-100.0,
        high=100.0,
    )
    line_map: str = parameter(
        "",
        "line_adaptive: a map learned on an earlier pass of this train over this line (a JSON file, "
        "pac_controller.line_map): every span starts from its own learned harmonics, the responses "
        "frozen at the map's; it must fit this run's layout, speed and rate; '' none (docs/laws.md, "
        "'A map learned over passes')",
    )

    def check_consistency(self) -> None:
        overlaps = self.line_overlaps
        if len(overlaps) >= 2 and (
            len(overlaps) % 2 or any(not overlaps[i] < overlaps[i + 1] for i in range(0, len(overlaps), 2))
        ):
            raise ParameterError(
                "line_overlaps", overlaps, "(start, end) pairs, start < end, flat: an even count of values"
            )
