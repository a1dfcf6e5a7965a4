"""line_adaptive's arithmetic, compiled: one span's sums, the secant step, the guard.

The law, its equations and its design are in ``line_adaptive.py`` (module docstring) and
docs/laws.md; the class there and the compiled dispatcher (``kernels.py``) both call these
functions, so neither imports the other's module to reach them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .kernel_common import ACTIVE, PASSIVE

#: An update smaller than this [N] in a harmonic says nothing about its response.
MIN_INFORMATIVE_STEP = 0.5
#: The guard judges the RMS of the last this many spans' sigma_b (learning is not monotone span by span).
GUARD_SPANS = 3
#: One span's sigma_b above this multiple of line_guard_ratio * sigma_b,passive trips the guard at once.
GUARD_HARD_FACTOR = 3.0
#: A back-off (contact loss or saturation in a span) scales the feedforward's harmonics by this.
GUARD_BACKOFF = 0.5
#: The first span whose momentum balance the guard judges: the start's transient (a pantograph set
#: down at rest on a wire at rest, the actuator rising to F_r) lasts into span 1, most where the run
#: starts inside a span (the trailing pantograph of a pair), so spans 0 and 1 are not judged.
BIAS_FIRST_SPAN = 2
#: Why the guard fell back (``line_trip_reason``): not at all; the span-periodic sigma of F_hat above
#: passive's (harm); the mean of F_hat off the actuator's (bias); contact loss in
#: ``line_guard_strikes`` spans (each one backed off first). Saturation backs off, never falls back:
#: what a clipped command could do harm by is the harm and loss checks' (docs/laws.md).
TRIP_NONE, TRIP_HARM, TRIP_BIAS, TRIP_LOSS = range(4)


#: Rows of the ``memory`` table (complex, one column per harmonic); S_h is stored as real parts.
#: REAL: the span's applied harmonics; FIT_W, FIT_Z: the line model fit's weights and samples.
U_FF, U_PREV, E_ACC, A_ACC, E_PREV, Z, S, SCRATCH, REAL, FIT_W, FIT_Z = range(11)
MEMORY_ROWS = 11
#: A map learned on an earlier pass over the same line (``line_map``; ``line_map.py``) lives in the
#: rows after these, on a design layout of S = line_supports - 1 spans (none without a layout): the
#: responses the map was learned with (Z_h, S_h: rows MAP_Z, MAP_S), then blocks of S rows each, one
#: row per span m of the layout: the map given (W_m, the harmonics span m starts from), what this
#: pass applied over span m (on the feedforward's phase, the hold's advance taken off) and its force
#: error E_m, and whether span m was recorded (MAP_SEEN: the real part of column 0).
MAP_Z, MAP_S = MEMORY_ROWS, MEMORY_ROWS + 1
MAP_GIVEN, MAP_APPLIED, MAP_ERROR, MAP_SEEN = range(4)


def map_spans(supports: int) -> int:
    """The spans a map covers on a design layout of ``supports`` supports (0: no layout, no map)."""
    return supports - 1 if supports >= 2 else 0


@njit(cache=True, inline="always")
def map_row(spans: int, block: int, m: int) -> int:
    """The row of span m in ``block`` (MAP_GIVEN, MAP_APPLIED, ...) of a map of ``spans`` spans."""
    return MEMORY_ROWS + 2 + block * spans + m


def memory_rows(supports: int) -> int:
    """Rows of line_adaptive's ``memory`` on a design layout of ``supports`` supports."""
    spans = map_spans(supports)
    return map_row(spans, MAP_SEEN + 1, 0) if spans else MEMORY_ROWS


#: Rows of the ``table`` after the span's N phases (row N: the hold's advance): the nominal
#: pantograph's dynamic stiffnesses at each harmonic (line_adaptive.line_model_rows), the hold's
#: gain and the harmonic's angular frequency.
MODEL_C, MODEL_B, MODEL_DET, MODEL_HOLD, MODEL_OMEGA = range(1, 6)
TABLE_EXTRA_ROWS = 6


# -- complex arithmetic on (real, imaginary) pairs ---------------------------------------------------
# Plain arithmetic, not any library's own loop: the law's numbers are the same in every front (the
# class and the compiled loop call these), and tests compare them with the numpy law at the
# tolerance rounding allows, on any CPU (tests/test_line_kernels.py).
@njit(cache=True, inline="always")
def _cmul(ar: float, ai: float, br: float, bi: float) -> tuple[float, float]:
    """(ar + i ai)(br + i bi)."""
    return ar * br - ai * bi, ar * bi + ai * br


@njit(cache=True, inline="always")
def _cdiv(ar: float, ai: float, br: float, bi: float) -> tuple[float, float]:
    """(ar + i ai) / (br + i bi) by Smith's scaling (no overflow of |b|^2 for large b)."""
    if abs(br) >= abs(bi):
        rat = bi / br
        scl = 1.0 / (br + bi * rat)
        return (ar + ai * rat) * scl, (ai - ar * rat) * scl
    rat = br / bi
    scl = 1.0 / (bi + br * rat)
    return (ar * rat + ai) * scl, (ai * rat - ar) * scl


@njit(cache=True, inline="always")
def _cabs(re: float, im: float) -> float:
    """|re + i im| without overflow (libm's hypot)."""
    return math.hypot(re, im)


@njit(cache=True)
def _sum_real(row: np.ndarray, n: int) -> float:
    """Sum of the real parts of ``row[:n]`` (n <= a few hundred harmonics: a plain sum's rounding,
    n eps relative, is far below what the law resolves)."""
    total = 0.0
    for i in range(n):
        total += row[i].real
    return total


# -- the law, compiled: the class below and pac_controller.kernels call these --------------------
@njit(cache=True, inline="always")
def _applied(table, memory, n: int, j: int) -> tuple[float, float]:
    """Harmonic j of the command the span applied, on the feedforward's phase with the hold's gain
    taken off (A_h / hold): what ``_learn`` steps from and identifies on."""
    return _cdiv(memory[A_ACC, j].real, memory[A_ACC, j].imag, table[n, j].real, table[n, j].imag)


@njit(cache=True, inline="always")
def _map_row(p, block: int, m: int) -> int:
    """The row of span m of the layout in ``block`` (MAP_GIVEN, MAP_APPLIED, ...) of the map's rows."""
    return map_row(p.line_supports - 1, block, m)


@njit(cache=True, error_model="numpy")
def line_restart(p, s, memory, has_u: bool) -> None:
    """Before the first command, or after commands that were not the law's (a fallback episode).

    What was learned is the line's, not the episode's: after a fallback the law resumes with it
    (the span the episode touched is not learned from, nor judged). The ticks tell a new run
    (they start again): then it forgets everything and runs in again from u = F_r.
    """
    if not has_u or s.line_last_commit < 0:
        line_forget(p, s, memory)
    else:
        s.line_restart_pending = True


@njit(cache=True, error_model="numpy")
def line_forget(p, s, memory) -> None:
    """Forget everything learned: the next span starts a new run-in (u = F_r), or, on a learned map
    (``line_map``), starts from the map: its identified responses, the guard's passive bar and U_0
    of the pass that learned it (the map itself is the line's, and stays)."""
    memory[:MEMORY_ROWS, :] = 0.0
    if p.line_supports >= 2:
        memory[_map_row(p, MAP_APPLIED, 0) :, :] = 0.0  # this pass's records (MAP_APPLIED on)
    s.line_open_span, s.line_last_commit, s.line_restart_pending, s.line_tainted_span = -1, -1, False, -1
    s.line_u_mean, s.line_clip_offset, s.line_a_mean, s.line_e_mean = 0.0, 0.0, 0.0, 0.0
    s.line_has_prev, s.line_start_tick = False, -1
    s.line_passive_var, s.line_passive_spans = 0.0, 0
    s.line_recent_var[:] = 0.0
    s.line_recent_passive_var[:] = 0.0
    s.line_last_sigma_ratio, s.line_tripped = 0.0, False
    s.line_stiffness, s.line_damping, s.line_model_valid = 0.0, 0.0, False
    s.line_pending_error, s.line_pending_reference = 0.0, 0.0
    s.line_pending_measured, s.line_pending_law = math.nan, 0.0
    s.line_passive_loss, s.line_strikes, s.line_last_bias = 0.0, 0, 0.0
    s.line_last_passive_loss = 0.0
    s.line_saturation_backoffs = 0
    s.line_trip_reason, s.line_fade_from = TRIP_NONE, -1
    s.line_cursor, s.line_first_span = 0, 0
    s.line_backoff_from = -1
    s.line_map_scale = 1.0
    if p.line_map:
        memory[Z, :] = memory[MAP_Z, :]
        memory[S, :] = memory[MAP_S, :]
        s.line_passive_var, s.line_passive_spans = p.line_map_passive_var, 1
        s.line_passive_loss = p.line_map_passive_loss
        s.line_stiffness, s.line_damping = p.line_map_stiffness, p.line_map_damping
        s.line_model_valid, s.line_u_mean = p.line_map_model_valid, p.line_map_u_mean
    _clear_sums(s, memory)


@njit(cache=True, inline="always")
def _runin(p) -> int:
    """The spans before the guard judges: ``line_runin_spans`` (the first passive), or on a learned map
    2 (spans 0 and 1 run on the map; the start's transient reaches into span 1, which a first pass
    runs passive: judged, it backed a map off for the whole pass)."""
    return 2 if p.line_map else p.line_runin_spans


@njit(cache=True, error_model="numpy")
def _load_map(p, s, memory, m: int) -> None:
    """U_h := the map's harmonics of span m of the layout (times the back-offs' scale; 0 off the map)."""
    inside = 0 <= m < p.line_supports - 1
    for j in range(p.line_harmonics):
        w = memory[_map_row(p, MAP_GIVEN, m), j] if inside else 0.0
        memory[U_FF, j] = complex(s.line_map_scale * w.real, s.line_map_scale * w.imag)


# -- where the train is: the period (tick mod N) or the design layout's spans (line_supports > 0) ---
@njit(cache=True, inline="always")
def _support(p, table, m: int) -> float:
    """The design layout's support m [m along the line] (rows after the line model's, row-major)."""
    h = p.line_harmonics
    return table[p.line_period + TABLE_EXTRA_ROWS + m // h, m % h].real


@njit(cache=True, error_model="numpy")
def locate(p, table, tick: int, guess: int) -> tuple[int, int]:
    """(span, phase index) of the contact point at ``tick``: on the design layout, the span m with
    support m <= x < support m + 1 (x = line_position_start + tick v dt, what the train's line map
    says) and the phase index floor(N (x - x_m) / L_m), the span's own length scaled to the basis's
    N ticks; without a layout, (tick div N, tick mod N) as the period of the nominal span.
    ``guess``: a span near it (the search walks from there: the train moves by under a tick's
    distance per call)."""
    n = p.line_period
    count = p.line_supports
    if count < 2:
        return tick // n, tick % n
    x = p.line_position_start + tick * p.line_step_distance
    m = min(max(guess, 0), count - 2)
    while m > 0 and x < _support(p, table, m):
        m -= 1
    while m < count - 2 and x >= _support(p, table, m + 1):
        m += 1
    start = _support(p, table, m)
    phase = int(math.floor(n * (x - start) / (_support(p, table, m + 1) - start)))
    return m, min(max(phase, 0), n - 1)


@njit(cache=True, inline="always")
def _in_overlap(p, table, m: int) -> bool:
    """Whether span m of the design layout lies in an overlap of two tension sections (the
    imaginary part of support m's entry, ``line_overlaps``)."""
    if not 0 <= m < p.line_supports - 1:
        return False
    h = p.line_harmonics
    return table[p.line_period + TABLE_EXTRA_ROWS + m // h, m % h].imag != 0.0


@njit(cache=True, error_model="numpy")
def overlap_window(p, table, m: int, phase: int) -> float:
    """The share of the learned harmonics kept at phase index ``phase`` of span m: 0 over an overlap
    of two tension sections (the contact passes from one wire to the other there: nothing like the
    spans the harmonics were learned on), a raised cosine down over the span before it and up over
    the span after (stepped, the harmonics would kick the head as a stepped fallback does), else 1;
    1 everywhere on a learned map (``line_map``)."""
    if p.line_supports < 2 or p.line_map:
        # On a learned map every span's harmonics are its own, an overlap's too (learned from the
        # error an earlier pass recorded over it, ``_end_of_span``): no window.
        return 1.0
    if _in_overlap(p, table, m):
        return 0.0
    frac = (phase + 0.5) / p.line_period
    share = 1.0
    if _in_overlap(p, table, m + 1):
        share = 0.5 * (1.0 + math.cos(math.pi * frac))
    if _in_overlap(p, table, m - 1):
        share = min(share, 0.5 * (1.0 - math.cos(math.pi * frac)))
    return share


#: Width of the ramp [share of a span] over which ``support_lift`` goes from holding the harmonics'
#: negative part to passing all of it (stepped, the command would jump by what was held).
SUPPORT_RAMP = 0.05


@njit(cache=True, error_model="numpy")
def support_lift(p, phase: int) -> float:
    """The share of the learned harmonics' negative part kept at phase index ``phase`` of a span:
    0 from ``line_support_before`` of a span before a support of the design layout to
    ``line_support_after`` after it (there the harmonics only raise the command), 1 beyond a
    raised-cosine ramp of SUPPORT_RAMP on either side; 1 everywhere without a layout or a zone.
    The zone starts earlier by the actuator's lag (``line_actuator_lag_ticks``, as a share of the
    span's N ticks): the force it applies there follows the commands of that long before."""
    before, after = p.line_support_before, p.line_support_after
    if p.line_supports < 2 or (before <= 0.0 and after <= 0.0):
        return 1.0
    before += p.line_actuator_lag_ticks / p.line_period
    frac = (phase + 0.5) / p.line_period
    outside = min(frac - after, 1.0 - before - frac)  # distance to the zone (< 0: in it)
    if outside <= 0.0:
        return 0.0
    if outside >= SUPPORT_RAMP:
        return 1.0
    return 0.5 * (1.0 - math.cos(math.pi * outside / SUPPORT_RAMP))


@njit(cache=True, inline="always")
def _windowed(p, table, m: int) -> bool:
    """Whether ``overlap_window`` is below 1 anywhere on span m of the layout."""
    return _in_overlap(p, table, m) or _in_overlap(p, table, m - 1) or _in_overlap(p, table, m + 1)


@njit(cache=True, error_model="numpy")
def line_feedforward(p, s, table, memory, tick: int) -> float:
    """U_0 + C + w Re sum_h U_h exp(i h w_s (t + (d + 1/2) dt)) for the command of ``tick`` (w: the
    overlap window of the design layout, ``overlap_window``; 1 without one); on a learned map, over
    an overlap, the sum's positive part only; about a support, its negative part held by
    ``support_lift``."""
    n, h = p.line_period, p.line_harmonics
    m, phase = locate(p, table, tick + p.line_delay, s.line_cursor)
    share = overlap_window(p, table, m, phase)
    if share <= 0.0:
        return s.line_u_mean + s.line_clip_offset
    for j in range(h):
        ur, ui = _cmul(memory[U_FF, j].real, memory[U_FF, j].imag, table[n, j].real, table[n, j].imag)
        pr, pi = _cmul(ur, ui, table[phase, j].real, table[phase, j].imag)
        memory[SCRATCH, j] = complex(pr, pi)
    harmonics = _sum_real(memory[SCRATCH], h)
    if p.line_map and _in_overlap(p, table, m):
        # Over an overlap a map's harmonics only raise the command: lowered there, where the incoming
        # wire takes the head, the contact was lost (docs/laws.md, "A map learned over passes").
        harmonics = max(harmonics, 0.0)
    if harmonics < 0.0:  # around a support, likewise (support_lift; docs/laws.md)
        harmonics *= support_lift(p, phase)
    return s.line_u_mean + s.line_clip_offset + (harmonics if share == 1.0 else share * harmonics)


@njit(cache=True, error_model="numpy")
def line_output(
    p, s, table, memory, tick: int, f_r0: float, f_hat: float, force_measured: float
) -> tuple[float, float, float, float]:
    """(u_law, error, u_ff, sigma ratio): F_r + the feedforward, faded out over one span once the
    guard has tripped (then 0)."""
    error = f_r0 - f_hat
    s.line_pending_error, s.line_pending_reference = error, f_r0  # what commit accumulates
    s.line_pending_measured = force_measured
    new_run = s.line_restart_pending and s.line_last_commit >= 0 and tick <= s.line_last_commit
    fade = fade_factor(s.line_tripped, s.line_fade_from, tick, p.line_period)
    fade *= backoff_factor(s.line_backoff_from, tick, p.line_period)
    u_ff = 0.0 if fade <= 0.0 or new_run else fade * line_feedforward(p, s, table, memory, tick)
    s.line_pending_law = f_r0 + u_ff
    return f_r0 + u_ff, error, u_ff, s.line_last_sigma_ratio


@njit(cache=True, inline="always")
def fade_factor(tripped: bool, fade_from: int, tick: int, n: int) -> float:
    """The share of the feedforward kept at ``tick``: 1 until the guard trips, then a ramp to 0 over
    the next n ticks (one span) from ``fade_from``, the tick it tripped at: a fallback that stepped
    the feedforward off would itself kick the pantograph off the wire."""
    if not tripped:
        return 1.0
    return max(0.0, 1.0 - (tick - fade_from) / n)


@njit(cache=True, inline="always")
def backoff_factor(backoff_from: int, tick: int, n: int) -> float:
    """The share of the feedforward kept at ``tick`` while a back-off ramps it down: from 1 at
    ``backoff_from`` to GUARD_BACKOFF n ticks (one span) later (1 without a back-off): halved in one
    step at a span's end, the feedforward jumped by half its value there, which on the ideal rig at
    280 km/h itself lost contact (0.11 %) where the law without the loss check kept it."""
    if backoff_from < 0:
        return 1.0
    return 1.0 - (1.0 - GUARD_BACKOFF) * min(1.0, max(0.0, (tick - backoff_from) / n))


@njit(cache=True, error_model="numpy")
def _accumulate(table, memory, row: int, phase: int, weight: float, h: int) -> None:
    """memory[row] += weight conj(basis[phase])."""
    for j in range(h):
        br, bi = table[phase, j].real, -table[phase, j].imag
        cr, ci = _cmul(weight, 0.0, br, bi)
        memory[row, j] = complex(memory[row, j].real + cr, memory[row, j].imag + ci)


@njit(cache=True, error_model="numpy")
def line_commit(p, s, table, memory, tick: int, u_applied: float) -> None:
    """The force commanded for ``tick``: accumulate this span's E_h, A_h; learn at its end."""
    n, h = p.line_period, p.line_harmonics
    if s.line_restart_pending:
        s.line_restart_pending = False
        if s.line_last_commit >= 0 and tick <= s.line_last_commit:
            line_forget(p, s, memory)  # a new run
        elif s.line_start_tick >= 0:  # resume: the episode's spans teach nothing
            _clear_sums(s, memory)
            s.line_open_span = -1
            s.line_tainted_span = _span_of(p, s, table, tick)
    s.line_last_commit = tick
    if s.line_start_tick < 0:
        s.line_start_tick = tick
        s.line_cursor, phase = locate(p, table, tick, s.line_cursor)
        # A run that starts past the middle of a span (the train's map a little behind a support)
        # counts its spans from the next: that piece is too short to hold the start's transient,
        # which would otherwise run into the passive spans and the first learning one (span -1).
        late = p.line_supports >= 2 and 2 * phase >= p.line_period
        s.line_first_span = s.line_cursor + (1 if late else 0)
        if p.line_map:
            _load_map(p, s, memory, s.line_cursor)
    span = _span_of(p, s, table, tick)
    if s.line_open_span >= 0 and span != s.line_open_span:
        # The open span's last tick never came (no estimate for it, live): close it now, or its
        # sums would run on into the next span and the next step be taken on two spans' worth.
        _end_of_span(p, s, table, memory, s.line_open_span)
    s.line_open_span = span
    e = s.line_pending_error
    _, e_phase = locate(p, table, tick, s.line_cursor)
    _accumulate(table, memory, E_ACC, e_phase, (2.0 / n) * e, h)
    # The command as the actuator's limits let it through, on the feedforward's own phase.
    applied = u_applied - s.line_pending_reference - s.line_u_mean - s.line_clip_offset
    _, phase = locate(p, table, tick + p.line_delay, s.line_cursor)
    _accumulate(table, memory, A_ACC, phase, (2.0 / n) * applied, h)
    s.line_a_mean += applied / n
    # E_0 by the momentum balance where the actuator's force is measured: mean(F) = mean(F_a) up to
    # a few N, where F_hat's mean can be off by more (+12 N on the realistic line: Fm 7 % low).
    told = math.isfinite(s.line_pending_measured)
    s.line_e_mean += (s.line_pending_reference - s.line_pending_measured if told else e) / n
    # The guard's sums: the momentum balance's two sides, F_hat <= 0, a command the limits changed.
    f_hat = s.line_pending_reference - e
    measured = s.line_pending_measured if told else u_applied
    s.line_span_ticks += 1
    s.line_bias_sum += f_hat - measured
    s.line_reference_sum += s.line_pending_reference
    # Nearly lost: F_hat (less its mean's bias) below a margin of F_r. F_hat misses the millisecond
    # dips of a loss (the sensors' bandwidth) but not all of the approach to one (docs/laws.md: the
    # margin is a compromise between the realistic line's losses and the ideal rig's false alarms).
    near = p.line_guard_loss_margin * s.line_pending_reference
    s.line_loss_ticks += 1 if f_hat - s.line_last_bias <= near else 0
    if p.line_guard_estimate:
        # The loss check's bar follows the spans as the harm check's does: this tick as it would have
        # been passive, F_hat less the identified response to what the feedforward planned (docs/laws.md,
        # "The guard's bar").
        f_passive = f_hat + _planned_response(p, s, table, memory, tick, e_phase)
        s.line_passive_loss_ticks += 1 if f_passive - s.line_last_bias <= near else 0
    s.line_clip_ticks += 1 if u_applied != s.line_pending_law else 0
    if _span_of(p, s, table, tick + 1) != span:
        _end_of_span(p, s, table, memory, span)
        s.line_open_span = -1


@njit(cache=True, error_model="numpy")
def _planned_response(p, s, table, memory, tick: int, phase: int) -> float:
    """F_hat_passive - F_hat at ``tick`` (phase index ``phase``) as the identified responses say:
    sum_h Re(D_h U_h b_h) - U_0, times the share of the feedforward kept (fade, back-off). From
    E_h = E_h,passive + D_h A_h (``_passive_estimate_var``) with the harmonics planned, U_h, for the
    applied A_h, which only the span's end knows, and the static response -1 for the mean. Where the
    support zone held the plan's negative part the law applied less than planned: the estimate then
    counts F_hat_passive higher, and the bar lower, than it was (the check is the stricter there)."""
    share = fade_factor(s.line_tripped, s.line_fade_from, tick, p.line_period)
    share *= backoff_factor(s.line_backoff_from, tick, p.line_period)
    if share <= 0.0:
        return 0.0
    for j in range(p.line_harmonics):
        d_r, d_i = _identified(p, memory, j)
        r_r, r_i = _cmul(d_r, d_i, memory[U_FF, j].real, memory[U_FF, j].imag)
        q_r, q_i = _cmul(r_r, r_i, table[phase, j].real, table[phase, j].imag)
        memory[SCRATCH, j] = complex(q_r, q_i)
    return share * (_sum_real(memory[SCRATCH], p.line_harmonics) - s.line_u_mean)


@njit(cache=True, error_model="numpy")
def _span_of(p, s, table, tick: int) -> int:
    """The span of ``tick`` counted from the run's first (0): of the nominal period N from the
    first command, or of the design layout from the span the first command fell in. Moves the
    layout's search cursor to it."""
    if p.line_supports < 2:
        return (tick - s.line_start_tick) // p.line_period
    s.line_cursor, _ = locate(p, table, tick, s.line_cursor)
    return s.line_cursor - s.line_first_span


@njit(cache=True, error_model="numpy")
def _clear_sums(s, memory) -> None:
    memory[E_ACC, :] = 0.0
    memory[A_ACC, :] = 0.0
    s.line_a_mean = 0.0
    s.line_e_mean = 0.0
    s.line_span_ticks, s.line_bias_sum, s.line_reference_sum = 0, 0.0, 0.0
    s.line_loss_ticks, s.line_passive_loss_ticks, s.line_clip_ticks = 0, 0, 0


@njit(cache=True, error_model="numpy")
def _end_of_span(p, s, table, memory, span: int) -> None:
    if span == s.line_tainted_span:
        s.line_tainted_span = -1
        _clear_sums(s, memory)
        return
    if p.line_supports >= 2 and s.line_span_ticks != p.line_period and s.line_span_ticks > 0:
        # A span of the layout lasts its own number of ticks, not N: the sums were weighted by 1/N.
        scale = p.line_period / s.line_span_ticks
        for j in range(p.line_harmonics):
            memory[E_ACC, j] = complex(scale * memory[E_ACC, j].real, scale * memory[E_ACC, j].imag)
            memory[A_ACC, j] = complex(scale * memory[A_ACC, j].real, scale * memory[A_ACC, j].imag)
        s.line_a_mean *= scale
        s.line_e_mean *= scale
    # Every span of the layout is recorded for the next pass's map (``line_next_map``; nothing
    # without a layout), an overlap's too.
    _record_span(p, s, table, memory, s.line_first_span + span, span >= 1)
    if _windowed(p, table, s.line_first_span + span):
        # An overlap or a span next to one: the contact passes between two wires there, nothing
        # like the spans the harmonics are learned on, so what it applied and saw teaches this pass
        # nothing and is not judged (a map's next span still loads); the next pass's map takes a
        # step on the span's own error.
        if p.line_map:
            _load_map(p, s, memory, s.line_first_span + span + 1)
        _clear_sums(s, memory)
        return
    # The guard's variance: the span-periodic part of F_hat in the learned band (Parseval on
    # E_h), what the law acts on and the EN 50318 statistics keep. The raw variance of F_hat
    # is blind under sensor noise: 10 um on z1, z2 gave sigma(F_hat) ~210 N for sigma(F) ~35 N.
    h = p.line_harmonics
    for j in range(h):
        a = _cabs(memory[E_ACC, j].real, memory[E_ACC, j].imag)
        memory[SCRATCH, j] = complex(a * a, 0.0)
    var = 0.5 * _sum_real(memory[SCRATCH], h)
    ticks = max(s.line_span_ticks, 1)
    loss = s.line_loss_ticks / ticks
    # The pantograph's momentum balance over a span: its mean contact force is the mean force on it,
    # the actuator's (what the observer is told), up to the roof spring's and the momentum's small
    # terms; a mean of F_hat - F_applied beyond line_guard_bias times the mean reference is an
    # estimate whose mean is wrong, which the band the law judges below cannot show (docs/laws.md).
    bias, reference = s.line_bias_sum / ticks, s.line_reference_sum / ticks
    if span >= BIAS_FIRST_SPAN and not s.line_tripped and not abs(bias) <= p.line_guard_bias * abs(reference):
        _trip(s, TRIP_BIAS)
    s.line_last_bias = bias if span >= 1 else 0.0
    back_off = False
    runin = _runin(p)
    if 1 <= span < runin and not p.line_map:  # a map brings the passive spans' bar
        s.line_passive_var += var
        s.line_passive_spans += 1
        s.line_passive_loss = max(s.line_passive_loss, loss)
    elif span >= runin and s.line_passive_spans and not s.line_tripped:
        sigma_p = math.sqrt(s.line_passive_var / s.line_passive_spans)
        s.line_recent_var[span % GUARD_SPANS] = var
        if p.line_guard_estimate:
            s.line_recent_passive_var[span % GUARD_SPANS] = _passive_estimate_var(p, table, memory)
        learned = span - runin + 1  # learning spans so far
        m = min(learned, GUARD_SPANS)
        total, passive_total = -0.0, -0.0
        for i in range(m):
            total += s.line_recent_var[i]
            passive_total += s.line_recent_passive_var[i]
        if p.line_guard_estimate:
            # The bar follows a line whose spans differ: the same spans' passive sigma_b as the
            # identified responses say it would have been (docs/laws.md, "The guard's bar"). A
            # response identified wrong by more than 60 deg in phase can make it read a diverging
            # law as below 1: the check of one span against the run-in's bar stays behind it.
            ratio = math.sqrt((0.0 + total) / passive_total) if passive_total > 0.0 else 0.0
        else:
            ratio = math.sqrt((0.0 + total) / m) / sigma_p if sigma_p > 0.0 else 0.0
        s.line_last_sigma_ratio = ratio
        span_ratio = math.sqrt(var) / sigma_p if sigma_p > 0.0 else 0.0
        judged = learned >= p.line_guard_after and not s.line_last_sigma_ratio <= p.line_guard_ratio
        if judged or not span_ratio <= GUARD_HARD_FACTOR * p.line_guard_ratio:
            _trip(s, TRIP_HARM)
        else:
            # The loss check's bar: the worst passive span's share, or with the estimate this span's
            # own share as it would have been passive (counted tick by tick in line_commit).
            bar = s.line_passive_loss
            if p.line_guard_estimate:
                bar = s.line_last_passive_loss = s.line_passive_loss_ticks / ticks
            back_off = _struck(p, s, loss, bar, s.line_clip_ticks / ticks, learned)
    if s.line_backoff_from >= 0:
        # This span ramped a back-off down: its feedforward is now GUARD_BACKOFF U_h, and what it
        # applied (a ramp's mixture) teaches nothing; the next span steps on from there.
        s.line_backoff_from = -1
        if p.line_map:  # every later span's map at the scale backed off to
            s.line_map_scale *= GUARD_BACKOFF
            _load_map(p, s, memory, s.line_first_span + span + 1)
        else:
            for j in range(p.line_harmonics):
                u = memory[U_FF, j]
                memory[U_FF, j] = complex(GUARD_BACKOFF * u.real, GUARD_BACKOFF * u.imag)
    elif (p.line_map or span >= runin - 1) and not s.line_tripped:
        _learn(p, s, table, memory, span)
        if back_off:  # the step as learned, ramped down to GUARD_BACKOFF of it over the next span
            s.line_backoff_from = s.line_last_commit + 1
    _clear_sums(s, memory)


@njit(cache=True, error_model="numpy")
def _passive_estimate_var(p, table, memory) -> float:
    """sigma_b^2 the span would have had passive: (1/2) sum_h |E_h - D_h A_h|^2, A_h the harmonics
    applied (on the feedforward's phase, the hold's gain taken off, as ``_learn`` identifies on) and
    D_h the response identified before this span (``_identified``): E_h = E_h,passive + D_h A_h."""
    n, h = p.line_period, p.line_harmonics
    for j in range(h):
        a_r, a_i = _applied(table, memory, n, j)
        d_r, d_i = _identified(p, memory, j)
        r_r, r_i = _cmul(d_r, d_i, a_r, a_i)
        e = _cabs(memory[E_ACC, j].real - r_r, memory[E_ACC, j].imag - r_i)
        memory[SCRATCH, j] = complex(e * e, 0.0)
    return 0.5 * _sum_real(memory[SCRATCH], h)


@njit(cache=True, error_model="numpy")
def _struck(p, s, loss: float, bar: float, clipped: float, learned: int) -> bool:
    """Whether the ``learned``-th learning span backs off: more of its ticks nearly lost (F_hat less
    the last span's bias) than ``bar``, passive's share, by ``line_guard_loss`` (a strike; by
    GUARD_HARD_FACTOR times that before ``line_guard_loss_after`` learning spans), or more of its
    commands changed by the limits than ``line_guard_saturation``. The ``line_guard_strikes``-th
    strike falls back instead (and does not back off); saturation alone only backs off."""
    # The run-in's two spans are the bar (without the estimate); where the line's next spans dip
    # deeper, passive's own share there exceeds it while the learning's first spans are still a
    # transient, which the estimate's responses are still identifying (docs/laws.md).
    early = learned < p.line_guard_loss_after
    margin = (GUARD_HARD_FACTOR if early else 1.0) * p.line_guard_loss
    # The run-in's bar stays behind an estimated one at three times the margin, as the harm check's
    # one span does: responses identified wrong read passive's share high (docs/laws.md).
    lost = loss > bar + margin or loss > s.line_passive_loss + GUARD_HARD_FACTOR * p.line_guard_loss
    if lost:
        s.line_strikes += 1
        if s.line_strikes >= p.line_guard_strikes:
            _trip(s, TRIP_LOSS)
            return False
        return True
    if clipped > p.line_guard_saturation:
        s.line_saturation_backoffs += 1
        return True
    return False


@njit(cache=True, error_model="numpy")
def _trip(s, reason: int) -> None:
    """Fall back to passive (latched): the feedforward as learned fades out over the next span
    (``fade_factor``) from the last tick committed."""
    s.line_tripped = True
    s.line_trip_reason = reason
    s.line_fade_from = s.line_last_commit


@njit(cache=True, error_model="numpy")
def _record_span(p, s, table, memory, m: int, learned_from: bool) -> None:
    """Span m of the layout as this pass saw it: the harmonics applied (the hold's advance taken off,
    as ``_learn`` steps from them) and the force error, for the next pass's map (``line_next_map``).
    ``learned_from`` False (span 0, the start's transient): recorded as not seen."""
    if not 0 <= m < p.line_supports - 1:
        return
    n = p.line_period
    for j in range(p.line_harmonics):
        a_r, a_i = _applied(table, memory, n, j)
        memory[_map_row(p, MAP_APPLIED, m), j] = complex(a_r, a_i)
        memory[_map_row(p, MAP_ERROR, m), j] = memory[E_ACC, j]
    memory[_map_row(p, MAP_SEEN, m), 0] = 1.0 if learned_from else 0.0


@njit(cache=True, error_model="numpy")
def line_next_map(p, s, table, memory, out) -> None:
    """The map for the next pass over the line, into ``out`` (S rows of H harmonics): each span
    recorded this pass takes the law's step on its own error, from what was applied over it,

        W_m = A_m - gamma (conj(D_h) E_m + mu A_m) / (|D_h|^2 + mu),   clipped to line_step_max,

    with D_h as identified at the end of this pass (a pass on a map keeps the map's); a span not
    recorded keeps the map this pass was given (0 on a first pass). Iterative learning over passes:
    the within-pass law's step (``_step``), on each span's own error instead of the last span's."""
    if p.line_supports < 2:
        return
    work = memory.copy()  # _step's rows (REAL, E_ACC, U_FF) are overwritten
    for m in range(p.line_supports - 1):
        if not work[_map_row(p, MAP_SEEN, m), 0].real > 0.0:
            out[m, :] = work[_map_row(p, MAP_GIVEN, m), :]
            continue
        for j in range(p.line_harmonics):
            work[REAL, j] = work[_map_row(p, MAP_APPLIED, m), j]
            work[E_ACC, j] = work[_map_row(p, MAP_ERROR, m), j]
        for j in range(p.line_harmonics):
            _step(p, s, table, work, j)
        out[m, :] = work[U_FF, :]


@njit(cache=True, error_model="numpy")
def _learn(p, s, table, memory, span: int) -> None:
    """The secant update of every harmonic, the line model's fit, then one step per harmonic
    (module docstring). On a learned map: the next span's harmonics from the map, the responses
    frozen (a span's own shape differs from the next one's, so the change between spans says nothing
    of the response), the mean learned as on a first pass."""
    if p.line_map:
        if span >= 1:  # span 0's mean holds the start's transient
            s.line_u_mean += p.line_gain * s.line_e_mean
        s.line_clip_offset = -s.line_a_mean
        _load_map(p, s, memory, s.line_first_span + span + 1)
        return
    n, h, lam = p.line_period, p.line_harmonics, p.line_forgetting
    for j in range(h):
        # Anti-windup: step from, and identify on, the harmonics applied (module docstring).
        real_r, real_i = _applied(table, memory, n, j)
        e_r, e_i = memory[E_ACC, j].real, memory[E_ACC, j].imag
        s_h, z_r, z_i = memory[S, j].real, memory[Z, j].real, memory[Z, j].imag
        if s.line_has_prev:
            du_r, du_i = real_r - memory[U_PREV, j].real, real_i - memory[U_PREV, j].imag
            de_r, de_i = e_r - memory[E_PREV, j].real, e_i - memory[E_PREV, j].imag
            du_abs = _cabs(du_r, du_i)
            if du_abs > MIN_INFORMATIVE_STEP:
                s_h = lam * s_h + du_abs * du_abs
                zr, zi = _cmul(lam, 0.0, z_r, z_i)
                cr, ci = _cmul(du_r, -du_i, de_r, de_i)
                z_r, z_i = zr + cr, zi + ci
        memory[S, j] = complex(s_h, 0.0)
        memory[Z, j] = complex(z_r, z_i)
        memory[U_PREV, j] = complex(real_r, real_i)
        memory[E_PREV, j] = complex(e_r, e_i)
        memory[REAL, j] = complex(real_r, real_i)
    if p.line_model_below > 0.0:
        _fit_line(p, s, table, memory)
    for j in range(h):
        _step(p, s, table, memory, j)
    s.line_has_prev = True
    s.line_u_mean += p.line_gain * s.line_e_mean
    # C: the mean the limits took off is known exactly from the applied command (module docstring).
    s.line_clip_offset = -s.line_a_mean


@njit(cache=True, error_model="numpy")
def _identified(p, memory, j: int) -> tuple[float, float]:
    """D_h = (Z_h - s0) / (S_h + s0), unfloored."""
    prior = p.line_prior_weight
    return _cdiv(memory[Z, j].real - prior, memory[Z, j].imag, memory[S, j].real + prior, 0.0)


@njit(cache=True, error_model="numpy")
def _fit_line(p, s, table, memory) -> None:
    """k_s, c of the line impedance Z(w) = k_s + i c w that, on the nominal pantograph, gives the
    identified responses: each harmonic's D_h turned into an impedance sample, weighted by its
    information S_h and by how much D moves with Z there (|dD/dZ|^2 at the last fit)."""
    n, h = p.line_period, p.line_harmonics
    for j in range(h):
        c_r, c_i = table[n + MODEL_C, j].real, table[n + MODEL_C, j].imag
        b_r, b_i = table[n + MODEL_B, j].real, table[n + MODEL_B, j].imag
        t_r, t_i = table[n + MODEL_DET, j].real, table[n + MODEL_DET, j].imag
        hold, omega = table[n + MODEL_HOLD, j].real, table[n + MODEL_OMEGA, j].real
        r_r, r_i = _identified(p, memory, j)
        d_r, d_i = _cdiv(-r_r, -r_i, hold, 0.0)  # the force's response, the hold's gain taken off
        nr, ni = _cmul(d_r, d_i, t_r, t_i)
        pr, pi = _cmul(d_r, d_i, b_r, b_i)
        zs_r, zs_i = _cdiv(nr, ni, c_r - pr, c_i - pi)
        # |dD/dZ|^2 = |C det / (Z B + det)^2|^2 at the last fit's Z
        q_r, q_i = _cmul(s.line_stiffness + 0.0, s.line_damping * omega, b_r, b_i)
        q_r, q_i = q_r + t_r, q_i + t_i
        qq_r, qq_i = _cmul(q_r, q_i, q_r, q_i)
        g_r, g_i = _cmul(c_r, c_i, t_r, t_i)
        g_r, g_i = _cdiv(g_r, g_i, qq_r, qq_i)
        g = _cabs(g_r, g_i)
        weight = memory[S, j].real * (g * g)
        finite = math.isfinite(zs_r) and math.isfinite(zs_i) and math.isfinite(weight)
        memory[FIT_W, j] = complex(weight if finite else 0.0, 0.0)
        memory[FIT_Z, j] = complex(zs_r, zs_i) if finite else 0.0
    total = _sum_real(memory[FIT_W], h)
    if not total > 0.0:
        return
    for j in range(h):
        memory[SCRATCH, j] = complex(memory[FIT_W, j].real * memory[FIT_Z, j].real, 0.0)
    stiffness = _sum_real(memory[SCRATCH], h) / total
    for j in range(h):
        omega = table[n + MODEL_OMEGA, j].real
        memory[SCRATCH, j] = complex(memory[FIT_W, j].real * omega * memory[FIT_Z, j].imag, 0.0)
    moment = _sum_real(memory[SCRATCH], h)
    for j in range(h):
        omega = table[n + MODEL_OMEGA, j].real
        memory[SCRATCH, j] = complex(memory[FIT_W, j].real * (omega * omega), 0.0)
    s.line_stiffness = max(stiffness, 0.0)
    s.line_damping = max(moment / _sum_real(memory[SCRATCH], h), 0.0)
    # A model that calls the first harmonic weak (near F = u at low frequency on any real line) has
    # not fitted the line (e.g. Z = 0): it stands in for no harmonic.
    m_r, m_i = _model_response(s, table, n, 0)
    s.line_model_valid = _cabs(m_r, m_i) >= p.line_model_below


@njit(cache=True, error_model="numpy")
def _model_response(s, table, n: int, j: int) -> tuple[float, float]:
    """The force's response to U_h on the line model (with the hold): Z C / (Z B + det) sinc."""
    omega, hold = table[n + MODEL_OMEGA, j].real, table[n + MODEL_HOLD, j].real
    z_r, z_i = s.line_stiffness + 0.0, s.line_damping * omega
    m_r, m_i = _cmul(z_r, z_i, table[n + MODEL_C, j].real, table[n + MODEL_C, j].imag)
    q_r, q_i = _cmul(z_r, z_i, table[n + MODEL_B, j].real, table[n + MODEL_B, j].imag)
    m_r, m_i = _cdiv(m_r, m_i, q_r + table[n + MODEL_DET, j].real, q_i + table[n + MODEL_DET, j].imag)
    return _cmul(m_r, m_i, hold, 0.0)


@njit(cache=True, error_model="numpy")
def _step(p, s, table, memory, j: int) -> None:
    """U_h <- A_h - gamma (conj(D_h) E_h + mu A_h) / (|D_h|^2 + mu), clipped (module docstring)."""
    n = p.line_period
    floor, mu = p.line_response_min, p.line_effort_weight
    real_r, real_i = memory[REAL, j].real, memory[REAL, j].imag
    e_r, e_i = memory[E_ACC, j].real, memory[E_ACC, j].imag
    r_r, r_i = _identified(p, memory, j)
    if _cabs(r_r, r_i) < floor:
        angle = math.atan2(r_i, r_r)
        r_r, r_i = _cmul(floor, 0.0, math.cos(angle), math.sin(angle))
    if p.line_model_below > 0.0 and s.line_model_valid:
        # The line model's response where it says the harmonic is weak (module docstring).
        m_r, m_i = _model_response(s, table, n, j)
        if _cabs(m_r, m_i) < p.line_model_below:
            r_r, r_i = -m_r, -m_i
    # The step towards min |E_h|^2 + mu |U_h|^2 on the response (module docstring):
    # -gamma (conj(D) E + mu U) / (|D|^2 + mu).
    c_r, c_i = _cmul(r_r, -r_i, e_r, e_i)
    w_r, w_i = _cmul(mu, 0.0, real_r, real_i)
    modulus = _cabs(r_r, r_i)
    g_r, g_i = _cmul(-p.line_gain, 0.0, c_r + w_r, c_i + w_i)
    st_r, st_i = _cdiv(g_r, g_i, modulus * modulus + mu, 0.0)
    # A harmonic whose response has not been identified yet (only the prior F = u, which can be
    # off by 180 deg) takes a probing step of at most probe_step: it identifies more than it risks.
    limit = p.line_step_max if memory[S, j].real > 0.0 else p.line_probe_step
    shrink = _cabs(st_r, st_i) / limit
    if not shrink <= 1.0:  # np.maximum(1.0, x): NaN propagates
        st_r, st_i = _cdiv(st_r, st_i, shrink, 0.0)
    else:
        st_r, st_i = _cdiv(st_r, st_i, 1.0, 0.0)
    memory[U_FF, j] = complex(real_r + st_r, real_i + st_i)


# -- the law's four functions of the controller's step (kernel_common; called by law_dispatch) ---------
@njit(cache=True, error_model="numpy")
def line_adaptive_restart(p, s, table, memory, has_u: bool, u_applied: float) -> None:
    line_restart(p, s, memory, has_u)


@njit(cache=True, error_model="numpy")
def line_adaptive_output(
    p, s, table, memory, tick: int, t: float, f_r, z_hat, theta_hat, f_hat: float, force_measured: float
) -> tuple[float, float, float, float]:
    return line_output(p, s, table, memory, tick, f_r[0], f_hat, force_measured)


@njit(cache=True, error_model="numpy")
def line_adaptive_mode(p, s) -> int:
    """Passive once the guard has tripped (latched), active before."""
    return PASSIVE if s.line_tripped else ACTIVE


@njit(cache=True, error_model="numpy")
def line_adaptive_commit(p, s, table, memory, tick: int, u_applied: float) -> None:
    line_commit(p, s, table, memory, tick, u_applied)
