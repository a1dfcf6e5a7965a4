"""``line_adaptive``: span-periodic learning feedforward with an on-line identified line response.

For a distributed line (docs/catenary.md, docs/laws.md).  What the law knows: the
contact-force estimate F_hat (from the estimate: ``observer:=contact_force`` gives one
that does not assume F = k z1), the force it commands, the train speed v and the
nominal span length L.  Nothing of the line's matrices or the wire height.

The span makes the line's excitation periodic in time with period T = L / v, sampled
as N = round(T / dt) ticks, w_s = 2 pi / (N dt).  The law is the constant uplift plus a
periodic feedforward over the harmonics h = 1 .. H of w_s up to ``line_max_frequency``::

    u_k = F_r(t_k) + U_0^j + Re sum_h U_h^j exp(i h w_s (t_k + (d + 1/2) dt))       (span j)

(advanced over the d = ``design_delay_ticks`` ticks of command delay and the half
period of the hold: a feedforward can be, exactly).  Over span j the law accumulates
the Fourier coefficients of the force error e = F_r - F_hat::

    E_h^j = (2 / N) sum_{k in span j} e_k exp(-i h w_s t_k)

At the end of span j (j >= ``line_runin_spans`` - 1) each harmonic takes a secant
(Newton) step on its own identified response D_h = dE_h / dU_h (complex)::

    S_h <- lam S_h + |dU_h|^2,   Z_h <- lam Z_h + conj(dU_h) dE_h       (dU, dE: last span's changes)
    D_h = (Z_h - s0) / (S_h + s0)                (prior D = -1: F = u at low frequency, weight s0)
    |D_h| floored at ``line_response_min``
    D_h = -M_h(Z) where |M_h(Z)| < ``line_model_below``               (the line model, below)
    U_h^{j+1} = U_h^j - gamma (conj(D_h) E_h^j + mu U_h^j) / (|D_h|^2 + mu),
                each step clipped to ``line_step_max`` in modulus
                (``line_probe_step`` until D_h has been identified)

(lam = ``line_forgetting``, s0 = ``line_prior_weight``, gamma = ``line_learning_gain``,
mu = ``line_effort_weight``; an update with |dU_h| < 0.5 N carries no information and is
skipped.)  The step is a damped Gauss-Newton step on |E_h|^2 + mu |U_h|^2, whose minimum
leaves a harmonic's error where cancelling it would cost more than mu per unit: with mu = 0
(E_h = 0 on every harmonic, the law before) the feedforward at 280 km/h was +92 % worse than
passive with the line's true responses, and with mu = 0.01 -77 % (docs/laws.md, measured with
``pac_experiments.catenary.line_response``).  Where |D_h|^2 >> mu it is the secant (Newton) step
-gamma E_h / D_h.

The line model: the secant identifies a harmonic by what its own step did to its own error,
which on the FE line holds only for the harmonics that move the force: the line is periodic in
space, a command at one harmonic moves the force at the others (measured: 69 % of the
response matrix off its diagonal at 280 km/h), and a step of a weak harmonic (|D| of 0.04-0.1
at 12-20 Hz) shows mostly what the strong ones' steps did to it (identified 0.3-1.4).  So every
span the law fits a line impedance Z(w) = k_s + i c w (spring and wave damping, k_s, c >= 0)
to all the identified responses at once, each turned into an impedance sample through the
nominal pantograph (eqs. 3-4 with the line as Z at the head: M_h(Z) = Z C / (Z B + det)
times the hold's gain, ``line_model_rows``) and weighted by its information S_h and by
|dM/dZ|^2 there, so the strong harmonics decide it; a harmonic the model calls weak takes
the model's response.  With the line's true responses the fit of this model is within
10-20 % in gain and ~10 deg in phase at every harmonic (docs/laws.md).  A model that calls
the first harmonic weak has fitted no line and stands in for none.

Anti-windup: U_h^j in the step and in the secant is the harmonic the actuator *applied*
over span j (the Fourier coefficients of the command ``commit`` reports, on the
feedforward's own phase), not the one asked for.  Where the limits (+-500 N, 100 kN/s)
clip, asking for more changes nothing applied: the identified response would shrink, the
steps grow and the clipped share of a span grow without end (it reached 28 % at 360 km/h
and pulled the mean force 6.5 % below its target).

The mean: U_0 += gamma E_0 (E_0 the span's mean of F_r - F_a where the actuator's force F_a
is measured, by that momentum balance, since F_hat's mean can be off by more: +12 N with the
identified nominal on the realistic line, which held Fm 7 % below target; else of F_r - F_hat;
the static response is -1 exactly), plus C, the mean the limits took off the last span's command, measured
exactly on the applied command and given back (C^{j+1} = mean over span j of what the
limits removed; a fixed point that converges, the clipped share being below one).  In a
periodic steady state mean(F) = mean(u) (the pantograph's momentum balance), so U_0 stays
near 0 and C is what keeps the mean force on its target when the peaks clip.  (Scaling the
whole feedforward down to stay inside the limits was tried: sigma -59 % instead of -74 % at
300 km/h; clipping the few peaks costs less.  U_0 at gain 1 instead of C oscillated span to
span with the plant's masses x1.2.)

Why identified: the line's response u -> F at the span harmonics differs from any spring
model of it by up to ~90 deg in phase and a factor 5 in gain (docs/laws.md, measured), and
with a wrong phase beyond 90 deg a fixed learning filter diverges.

Do-no-harm guard: it judges sigma_b, the span-periodic part of F_hat in the learned band,
sigma_b^2 = (1/2) sum_h |E_h|^2 over a span (Parseval): what the law acts on and what the
EN 50318 statistics keep.  (The raw sigma of F_hat is blind under sensor noise: 10 um on
z1, z2 gave sigma(F_hat) ~210 N for sigma(F) ~35 N at 250 km/h, and the guard fell back
from a law that was lowering sigma(F) by 40 %.)  The spans 1 .. ``line_runin_spans`` - 1
run passive (u = F_r) and give the passive sigma_b,p.  At the end of every learning span
the RMS of sigma_b over the last ``GUARD_SPANS`` spans is compared with it: above
``line_guard_ratio`` sigma_b,p (judged once ``line_guard_spans`` spans have been learned:
the secant learning may rise above passive for its first spans; one span above
``GUARD_HARD_FACTOR`` times that trips at once: at 220 km/h a first span at 2.1x passive
was followed by -57 % once the responses were identified, so 2 was too tight), the law
falls back to passive for the rest of the run (``Command.mode`` "passive"; latched).
``line_guard_reference`` "estimate" judges the RMS against the same spans' own passive sigma_b
instead, each span's (1/2) sum_h |E_h - D_h A_h|^2 (A_h applied, D_h identified): a bar that
follows a line whose spans differ; the one-span check stays on the run-in's bar, which an
identification wrong in phase cannot blind (docs/laws.md, "The guard's bar"). The loss check's bar
then follows the spans too: each span's share of ticks nearly lost as F_hat would have been passive,
F_hat + sum_h Re(D_h U_h b_h) - U_0 tick by tick (U_h planned: A_h is known only at the span's end),
with the run-in's bar behind it at ``GUARD_HARD_FACTOR`` times the margin.

What F_hat cannot show, the guard judges on what it cannot bend (docs/laws.md, "A guard that an
estimate cannot blind"): the mean, by the pantograph's momentum balance over a span,
mean(F) = mean(F_a) + (roof spring, momentum change: a few N), so |mean(F_hat - F_a)| above
``line_guard_bias`` mean(F_r) (F_a the actuator force the measurement reports, or the law's own
commands when it is not told it) falls back at once, from span 1 on; contact loss (ticks with
F_hat less the last span's bias <= ``line_guard_loss_margin`` F_r, nearly lost, above the worst
passive span's share (or the span's own estimated, above) by ``line_guard_loss``; before
``line_guard_loss_spans`` learning spans, by ``GUARD_HARD_FACTOR`` times that, as the harm check
waits out the learning's first spans)
and saturation (a share of the commands the limits changed above ``line_guard_saturation``) back
off, the harmonics U_h halved, and the ``line_guard_strikes``-th time fall back. A fallback fades
the feedforward as learned out over one span, u_ff (1 - (k - k_trip) / N), then U = 0: stepped
off, the feedforward would itself kick the head off the wire.

Overlaps of tension sections (``line_overlaps``, the design's section plan): over an overlap's
spans the contact passes from one wire to the other, nothing like the spans the harmonics were
learned on. There the harmonics are off (U_0 + C stay), faded by a raised cosine over the span
before and the span after (``overlap_window``), and those spans neither teach nor are judged. Told
nothing, the law lowered its command just past the overlap's inner supports and lost contact
there more than passive on 11 of 20 report lines at 300 km/h (docs/laws.md, point 8).

State: the law's numbers are fields of the controller's records (``kernels.CONTROLLER_PARAMS`` /
``CONTROLLER_STATE``, the ``line_`` fields), its per-harmonic arrays rows of two complex tables
(``table``: the basis and the hold's advance; ``memory``: U_h, E_h, ...).  The arithmetic is the
compiled functions below, which the class (through ``kernels.KernelLaw``) and the compiled closed
loop (``pac_rig.loop``) both call.  Every complex operation is written as numpy performs it on
this machine's vector paths (fused multiply-adds in products, the pairwise sum, ``abs``), so the
law gives the numbers numpy's array expressions gave, bit for bit (``tests/test_line_kernels.py``);
the one exception is the angle of a floored response (libm's atan2 instead of numpy's vector
one: a few ulp, only where the floor applies).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pac_model.parameters import PantographParameters, TrackParameters

from .kernels import KernelLaw
from .line_adaptive_kernels import (  # noqa: F401 - re-exported: the law's constants and steps
    A_ACC,
    E_ACC,
    E_PREV,
    GUARD_BACKOFF,
    GUARD_HARD_FACTOR,
    GUARD_SPANS,
    MAP_GIVEN,
    MAP_S,
    MAP_Z,
    MEMORY_ROWS,
    MIN_INFORMATIVE_STEP,
    SCRATCH,
    TABLE_EXTRA_ROWS,
    U_FF,
    U_PREV,
    S,
    Z,
    line_commit,
    line_feedforward,
    line_forget,
    line_next_map,
    line_output,
    line_restart,
    map_row,
    map_spans,
    memory_rows,
)
from .line_map import LineMap, LineMapError, read_line_map
from .parameters import LawParameters

#: The law's design where the actuator is hardware (limited range and rate), which the rig's
#: realistic scenarios pair with a whole drawn line and the 3-mass pantograph on its identified
#: 2-DOF (docs/laws.md, "On the realistic line"): the command's harmonics weighted more (mu), for
#: the actuator's range; only the harmonics up to 4 Hz, because above the 3-mass frame's first
#: anti-resonance (4.9 Hz) the head balance's F_hat errs by as much as the force there once the law
#: commands (10.9 N against 2.2 N passive at 4-8 Hz, measured), so the law cannot see what its
#: harmonics do; and every harmonic the line model calls weak (response below 1) on the model,
#: because on spans that differ the secant identifies a weak harmonic on the span-to-span
#: differences, not on its own step. Chosen on design lines of the realistic scenario (line seeds
#: 0-19), not on the lines reported (100-119). The ideal actuator keeps the law's defaults, which
#: its +-500 N allow.
DESIGN_FOR_ACTUATOR_AS_HARDWARE = (
    ("line_effort_weight", 0.05),
    ("line_max_frequency", 4.0),
    ("line_model_below", 1.0),
)

#: The law's design where, besides, the actuator is fast against a span (its lag and delay at most
#: FAST_ACTUATOR_SPAN_SHARE of the time a span takes to pass): about each support of the design
#: layout, from 0.02 of a span plus the actuator's lag and delay before it to 0.10 after it, the
#: learned harmonics only raise the command, since lowered there the head meets the dip after the
#: support with too little force (every lost tick the traces showed lay in it); and a span's
#: contact loss strikes only above three times its bar until 8 spans are learned, as the harm check
#: waits out the learning's first spans (docs/laws.md, "On the realistic line", points 9 and 10).
#: The zone's edges came from traces, the loss check's numbers are the harm check's; checked on the
#: design lines (seeds 0-19) before the report lines. On a slow actuator the zone before the support
#: spans a third of it and takes nearly all of the gain, and the loss rule changed no design run:
#: there the law keeps DESIGN_FOR_ACTUATOR_AS_HARDWARE alone.
DESIGN_FOR_FAST_ACTUATOR = (
    ("line_support_before", 0.02),
    ("line_support_after", 0.1),
    ("line_guard_loss_spans", 8),
)

#: The largest lag and delay, as a share of a span's passing time, for which an actuator counts as
#: fast (judgement: the electromechanical actuator's 25 ms is 0.03-0.05 of a span at 250-350 km/h,
#: the pneumatic one's 220 ms 0.28-0.39; nothing between them was measured).
FAST_ACTUATOR_SPAN_SHARE = 0.1


#: The design values on a pantograph with others ahead of it: the harm check's bar from each span's
#: own passive sigma_b as the identified responses say it would have been ("estimate"), not from
#: the run-in's few spans. The wave of the one ahead makes the spans this one meets differ (its
#: sigma per 0.66 s ranged 56-101 N on a design line), so a bar from the run-in tripped where the law
#: was still lowering sigma; measured on design lines 0-9 (docs/realistic_scenario.md, "Two
#: pantographs 200 m apart"). The check of one span against the run-in's bar stays behind it.
DESIGN_BEHIND_ANOTHER = (("line_guard_reference", "estimate"),)

#: The design values on a pantograph with another active one behind it (both of a pair active,
#: ``all_pantographs_active``): the effort weight mu that spares the one behind. A leader that lowers
#: its own force's sigma sends a stronger wave back to its follower (+8.6 % of the follower's sigma at
#: 300 km/h with mu = 0.05, the follower passive); the follower's own law takes back only part of it
#: (half of what a passive follower's spans do not share lies in 8-20 Hz, above the learned 4 Hz
#: band: docs/laws.md, "Both of a pair active"). Chosen on design lines 0-9 at
#: 300 km/h among 0.05 (the design for an actuator as hardware), 0.5 and 1.5 as the smallest whose
#: follower stayed within +5 % of its passive pair's sigma on every line (docs/realistic_scenario.md,
#: "Both active"); a judgement between the two pantographs' gains, not a fit.
DESIGN_AHEAD_OF_ACTIVE = (("line_effort_weight", 0.5),)


def design_for_actuator(lag: float, span_time: float) -> tuple[tuple[str, float], ...]:
    """The law's design values for an actuator as hardware whose command acts ``lag`` [s] late (its
    time constant plus its delay) on spans that take ``span_time`` [s] to pass:
    DESIGN_FOR_ACTUATOR_AS_HARDWARE, and where the actuator is fast DESIGN_FOR_FAST_ACTUATOR with the
    zone started ``lag`` earlier (``line_actuator_lag``)."""
    if lag > FAST_ACTUATOR_SPAN_SHARE * span_time:
        return DESIGN_FOR_ACTUATOR_AS_HARDWARE
    # To the microsecond: a value that does not move with the last bits of a sum (campaign keys hash it).
    return (*DESIGN_FOR_ACTUATOR_AS_HARDWARE, *DESIGN_FOR_FAST_ACTUATOR, ("line_actuator_lag", round(lag, 6)))


#: ``LineAdaptiveLaw.trip_reason`` by ``line_trip_reason`` (line_adaptive_kernels.TRIP_*).
TRIP_REASONS = ("", "harm", "bias", "loss")


def line_model_rows(pantograph: PantographParameters, omega: np.ndarray, dt: float) -> np.ndarray:
    """The line model's constants at the angular frequencies ``omega`` (rows C, B, det, hold, omega).

    Eqs. (3)-(4) in the frequency domain with the line as an impedance Z(w) at the head:
    (A + Z) z1 - C z2 = 0, -C z1 + B z2 = u, F = Z z1, with A = m1 s^2 + b1 s + k1,
    B = m2 s^2 + (b1 + b2) s + k1, C = b1 s + k1 (s = i w), so that
    F / u = Z C / (Z B + det), det = A B - C^2; times the zero-order hold's gain sinc(w dt / 2)
    (its half-tick lag the feedforward advances).
    """
    p = pantograph
    s = 1j * omega
    a = p.m1 * s * s + p.b1 * s + p.k1
    b = p.m2 * s * s + (p.b1 + p.b2) * s + p.k1
    c = p.b1 * s + p.k1
    hold = np.sinc(omega * dt / (2.0 * math.pi))
    return np.array([c, b, a * b - c * c, hold + 0j, omega + 0j])


def overlap_spans(supports: np.ndarray, overlaps: tuple) -> np.ndarray:
    """1.0 for each span of the layout ``supports`` whose middle lies inside one of the (start, end)
    pairs ``overlaps`` (flat, ``line_overlaps``; fewer than two values: none), else 0.0."""
    if len(supports) < 2 or len(overlaps) < 2:
        return np.zeros(max(len(supports) - 1, 0))
    pairs = np.asarray(overlaps, dtype=float).reshape(-1, 2)
    middle = 0.5 * (supports[:-1] + supports[1:])
    inside = (middle[:, None] > pairs[:, 0]) & (middle[:, None] < pairs[:, 1])
    return inside.any(axis=1).astype(float)


class LineAdaptiveLaw(KernelLaw):
    """The law of the module docstring: its numbers in the controller's records, its arrays in
    ``table`` / ``memory``, its arithmetic the compiled functions above (through
    ``line_adaptive_kernels``: each compiled law has its kernel module)."""

    uses_estimate = True
    uses_contact_force = True

    def __init__(
        self,
        track: TrackParameters,
        laws: LawParameters,
        sample_period: float,
        pantograph: PantographParameters | None = None,
    ) -> None:
        """``pantograph``: the nominal one (Table 1 if not given), for the line model."""
        dt = sample_period
        speed = track.speed_kmh / 3.6
        n = max(2, round(track.span_length / speed / dt))
        w = 2.0 * math.pi / (n * dt)
        h = max(1, min(int(laws.line_max_frequency * 2.0 * math.pi / w), n // 2 - 1))
        orders = np.arange(1, h + 1)
        # table[p, h-1] = exp(i h w p dt): one span of every harmonic, by phase index p = tick mod N;
        # table[N] = exp(i h w dt / 2): the hold's half period; then the line model's rows.
        # then the design layout's supports, row-major in the real parts (line_supports).
        supports = np.asarray(laws.line_supports if len(laws.line_supports) >= 2 else (), dtype=float)
        layout_rows = -(-len(supports) // h)
        table = np.zeros((n + TABLE_EXTRA_ROWS + layout_rows, h), dtype=np.complex128)
        table[:n] = np.exp(1j * np.outer(np.arange(n), orders) * w * dt)
        table[n] = np.exp(1j * orders * w * 0.5 * dt)
        table[n + 1 : n + TABLE_EXTRA_ROWS] = line_model_rows(
            pantograph or PantographParameters(), orders * w, dt
        )
        table[n + TABLE_EXTRA_ROWS :].real.flat[: len(supports)] = supports
        # Span m in an overlap of two tension sections (line_overlaps): 1 in the imaginary part of support m.
        table[n + TABLE_EXTRA_ROWS :].imag.flat[: max(len(supports) - 1, 0)] = overlap_spans(
            supports, laws.line_overlaps
        )
        self.table = table
        self.supports = supports  # the design layout (line_supports; empty: none)
        self.memory = np.zeros((memory_rows(len(supports)), h), dtype=np.complex128)
        super().__init__("line_adaptive", dt)
        p = self.params[0]
        self.map_passes = 0  # passes the map this run starts from was learned over (0: none)
        if laws.line_map:
            self._load(read_line_map(laws.line_map), supports, n, h, laws.line_map)
        p["line_period"], p["line_harmonics"], p["line_delay"] = n, h, laws.design_delay_ticks
        p["line_gain"], p["line_step_max"] = laws.line_learning_gain, laws.line_step_max
        p["line_probe_step"] = min(laws.line_probe_step, laws.line_step_max)
        p["line_forgetting"], p["line_prior_weight"] = laws.line_forgetting, laws.line_prior_weight
        p["line_response_min"], p["line_runin_spans"] = laws.line_response_min, laws.line_runin_spans
        p["line_effort_weight"] = laws.line_effort_weight
        p["line_model_below"] = laws.line_model_below
        p["line_guard_ratio"] = laws.line_guard_ratio
        p["line_guard_after"] = max(laws.line_guard_spans, GUARD_SPANS)
        p["line_guard_estimate"] = laws.line_guard_reference == "estimate"
        p["line_guard_bias"], p["line_guard_loss"] = laws.line_guard_bias, laws.line_guard_loss
        p["line_guard_loss_margin"] = laws.line_guard_loss_margin
        p["line_guard_saturation"] = laws.line_guard_saturation
        p["line_guard_strikes"] = laws.line_guard_strikes
        p["line_guard_loss_after"] = laws.line_guard_loss_spans
        p["line_supports"] = len(supports)
        p["line_support_before"], p["line_support_after"] = laws.line_support_before, laws.line_support_after
        p["line_actuator_lag_ticks"] = round(laws.line_actuator_lag / dt)
        p["line_position_start"] = laws.line_position_start + laws.line_position_error
        p["line_step_distance"] = speed * dt
        self.dt = dt
        self.omega_span = w
        self.restart(None)

    # -- what the tests and reports read ---------------------------------------------------
    period_ticks = property(lambda self: int(self.params[0]["line_period"]))
    harmonics = property(lambda self: int(self.params[0]["line_harmonics"]))
    delay = property(lambda self: int(self.params[0]["line_delay"]))
    basis = property(lambda self: self.table[: self.period_ticks])
    ahead = property(lambda self: self.table[self.period_ticks])
    u_ff = property(lambda self: self.memory[U_FF])
    tripped = property(lambda self: bool(self.state[0]["line_tripped"]))
    last_sigma_ratio = property(lambda self: float(self.state[0]["line_last_sigma_ratio"]))
    strikes = property(lambda self: int(self.state[0]["line_strikes"]))
    saturation_backoffs = property(lambda self: int(self.state[0]["line_saturation_backoffs"]))

    @property
    def trip_reason(self) -> str:
        """Why the guard fell back: "" (it did not), "harm", "bias" or "loss"."""
        return TRIP_REASONS[int(self.state[0]["line_trip_reason"])]

    @property
    def start_tick(self) -> int | None:
        """The tick the law's spans count from (None: no command yet since it forgot)."""
        tick = int(self.state[0]["line_start_tick"])
        return None if tick < 0 else tick

    @property
    def gain(self) -> float:
        """gamma, ``line_learning_gain`` (settable: a test flips its sign to force harm)."""
        return float(self.params[0]["line_gain"])

    @gain.setter
    def gain(self, value: float) -> None:
        self.params[0]["line_gain"] = value

    @property
    def mode(self) -> str:  # type: ignore[override]
        return "passive" if self.tripped else "active"

    def forget(self) -> None:
        """Forget everything learned: the next span starts a new run-in (u = F_r, bumpless from rest)."""
        _forget_one(self.params, self.state, self.memory)

    def _load(self, learned: LineMap, supports: np.ndarray, n: int, h: int, source: str) -> None:
        """Start from a map learned on an earlier pass (``line_map``), checked against this run."""
        learned.check_fits(supports, n, h, source)
        p = self.params[0]
        spans = map_spans(len(supports))
        first = map_row(spans, MAP_GIVEN, 0)
        self.memory[first : first + spans] = learned.harmonics
        self.memory[MAP_Z] = learned.response_z
        self.memory[MAP_S] = learned.response_s
        p["line_map"] = True
        self.map_passes = learned.passes
        p["line_map_passive_var"] = learned.passive_sigma**2
        p["line_map_passive_loss"] = learned.passive_loss
        p["line_map_stiffness"], p["line_map_damping"] = learned.line_stiffness, learned.line_damping
        p["line_map_model_valid"], p["line_map_u_mean"] = learned.model_valid, learned.u_mean

    def next_map(self, memory: np.ndarray | None = None, state: np.ndarray | None = None) -> LineMap:
        """The map for the next pass over this line (``line_next_map``), from this pass as it ended:
        the law's own arrays, or a compiled loop's (``memory``, ``state``: ``CompiledLoop.memory``,
        ``controller_state``), which ran on copies of them."""
        memory = self.memory if memory is None else memory
        state = self.state if state is None else state
        p, s = self.params[0], state[0]
        spans = map_spans(int(p["line_supports"]))
        if not spans:
            raise LineMapError(
                "line_adaptive", "line_supports", int(p["line_supports"]),
                "a design layout of at least two supports: a map is learned per span of it",
            )  # fmt: skip
        if not s["line_passive_spans"] or not s["line_passive_var"] > 0.0:
            raise LineMapError(
                "line_adaptive", "line_runin_spans", int(p["line_runin_spans"]),
                "a pass with passive spans that saw the line: the map carries their sigma as the guard's bar",
            )  # fmt: skip
        out = np.zeros((spans, self.harmonics), dtype=np.complex128)
        _next_map_one(self.params, state, self.table, memory, out)
        passive_var = s["line_passive_var"] / s["line_passive_spans"]
        return LineMap(
            supports=self.supports.copy(), period_ticks=self.period_ticks, harmonics=out,
            response_z=memory[Z].copy(),
            response_s=memory[S].real.copy(), passive_sigma=math.sqrt(passive_var),
            passive_loss=float(s["line_passive_loss"]), line_stiffness=float(s["line_stiffness"]),
            line_damping=float(s["line_damping"]), model_valid=bool(s["line_model_valid"]),
            u_mean=float(s["line_u_mean"]), passes=self.map_passes + 1,
        )  # fmt: skip

    def feedforward(self, tick: int) -> float:
        """U_0 + C + w Re sum_h U_h exp(i h w_s (t + (d + 1/2) dt)) for the command of ``tick`` (w:
        the overlap window, 1 off overlaps)."""
        return _feedforward_one(self.params, self.state, self.table, self.memory, int(tick))


@njit(cache=True, error_model="numpy")
def _feedforward_one(params, states, table, memory, tick):
    return line_feedforward(params[0], states[0], table, memory, tick)


@njit(cache=True, error_model="numpy")
def _forget_one(params, states, memory) -> None:
    line_forget(params[0], states[0], memory)


@njit(cache=True, error_model="numpy")
def _next_map_one(params, states, table, memory, out) -> None:
    line_next_map(params[0], states[0], table, memory, out)
