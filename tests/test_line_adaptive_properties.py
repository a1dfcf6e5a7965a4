"""line_adaptive's do-no-harm guard at its exact span, and its learning step by property.

The guard's contract (line_adaptive's module docstring): spans 1 .. ``line_runin_spans`` - 1 give
the passive sigma_b; at the end of every learning span the RMS of sigma_b over the last
``GUARD_SPANS`` spans is compared with ``line_guard_ratio`` times it, judged once
``line_guard_spans`` spans have been learned; one span above ``GUARD_HARD_FACTOR`` times the limit
trips at once; the fall-back is to passive, latched.  Here the force estimate is imposed (an open
loop): span j's error is a_j cos(w_s t), so its sigma_b is a_j / sqrt(2) exactly, whatever the law
commands, and the span the guard trips at is known in advance.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pac_controller.line_adaptive import GUARD_HARD_FACTOR, GUARD_SPANS, LineAdaptiveLaw
from pac_controller.parameters import LawParameters
from pac_model.parameters import TrackParameters

pytestmark = pytest.mark.unit

DT = 1e-3
F_R = 150.0
TRACK = TrackParameters(speed_kmh=300.0, span_length=55.0)
LAWS = LawParameters()
PASSIVE = 10.0  # N, the error's amplitude over the passive spans


def imposed(
    amplitudes: list[float], bias: list[float] | None = None, laws: LawParameters = LAWS
) -> tuple[LineAdaptiveLaw, list[str]]:
    """Span j's F_hat = F_r + b_j - a_j cos(w_s t) (b_j = 0 unless ``bias`` is given) while the
    actuator applies what the law asks: the law's mode at the first tick of every span, and one
    more entry: the mode after the last span."""
    law = LineAdaptiveLaw(TRACK, laws, DT)
    n, w = law.period_ticks, law.omega_span
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    modes = []
    for j, a in enumerate(amplitudes):
        modes.append(law.mode)
        b = 0.0 if bias is None else bias[j]
        for i in range(n):
            k = j * n + i
            u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R + b - a * math.cos(w * k * DT))
            law.commit(k, u)
    modes.append(law.mode)
    return law, modes


def first_judged_span() -> int:
    """The span at whose end the guard first judges: the line_guard_spans-th learning span."""
    return LAWS.line_runin_spans + max(LAWS.line_guard_spans, GUARD_SPANS) - 1


def amplitudes(learning: list[float], passive: float = PASSIVE) -> list[float]:
    """Span 0 (the start transient), the passive spans, then the learning spans' amplitudes."""
    return [3 * passive] + [passive] * (LAWS.line_runin_spans - 1) + learning


#: (line_guard_ratio, the passive spans' amplitude [N]) for the hard limit: the default, a limit
#: below and one above 3 (the limit scales with the ratio, not against it), and a passive sigma
#: below 1 N (any sigma_p > 0 is a scale, however small).
HARD_LIMIT_CASES = [(1.0, PASSIVE), (0.8, PASSIVE), (1.25, PASSIVE), (1.0, 0.5)]


@pytest.mark.parametrize("passive", [PASSIVE, 0.5])  # a passive sigma below 1 N is a scale too
def test_mild_harm_trips_the_guard_at_the_end_of_its_first_judged_span_exactly(passive):
    """1.5 times passive from the first learning span on: below the hard limit (3x), above the
    ratio (1x); only the judged rule can trip it, at the end of the first judged span."""
    assert 1.5 * LAWS.line_guard_ratio < GUARD_HARD_FACTOR * LAWS.line_guard_ratio
    ratio = 1.5 * LAWS.line_guard_ratio
    learning_spans = first_judged_span() - LAWS.line_runin_spans + 4
    law, modes = imposed(amplitudes([ratio * passive] * learning_spans, passive))
    judged = first_judged_span()
    assert law.tripped
    assert modes[judged] == "active"  # the span it judges ran active up to its end
    assert modes[judged + 1] == "passive"  # and the next one starts passive
    assert set(modes[judged + 1 :]) == {"passive"}  # latched
    assert law.last_sigma_ratio == pytest.approx(ratio, rel=1e-9)
    assert law.trip_reason == "harm"  # its feedforward then fades out over a span (test_line_control)


def test_below_the_ratio_the_guard_stays_out():
    law, modes = imposed(amplitudes([0.9 * LAWS.line_guard_ratio * PASSIVE] * 12))
    assert not law.tripped and set(modes) == {"active"}
    assert law.last_sigma_ratio == pytest.approx(0.9 * LAWS.line_guard_ratio, rel=1e-9)


@pytest.mark.parametrize(("ratio", "passive"), HARD_LIMIT_CASES)
def test_one_span_above_the_hard_limit_trips_at_its_own_end(ratio, passive):
    laws = dataclasses.replace(LAWS, line_guard_ratio=ratio)
    limit = GUARD_HARD_FACTOR * ratio
    bad = 2  # the third learning span: long before the guard judges
    learning = [0.5 * ratio * passive] * 6
    learning[bad] = 1.05 * limit * passive
    law, modes = imposed(amplitudes(learning, passive), laws=laws)
    span = LAWS.line_runin_spans + bad
    assert law.tripped and law.trip_reason == "harm"
    assert modes[span] == "active" and modes[span + 1] == "passive"


@pytest.mark.parametrize(("ratio", "passive"), HARD_LIMIT_CASES)
def test_one_span_just_below_the_hard_limit_is_forgiven_once_it_leaves_the_judged_spans(ratio, passive):
    """The judged RMS covers the last GUARD_SPANS spans only: an early bad span below the hard
    limit is out of it by the time the guard judges."""
    laws = dataclasses.replace(LAWS, line_guard_ratio=ratio)
    limit = GUARD_HARD_FACTOR * ratio
    learning = [0.5 * ratio * passive] * (first_judged_span() - LAWS.line_runin_spans + 3)
    learning[1] = 0.95 * limit * passive
    law, modes = imposed(amplitudes(learning, passive), laws=laws)
    assert not law.tripped and set(modes) == {"active"}


def strikes_after_a_span_with_lost_ticks(
    lost: int,
    bias: float = 0.0,
    lost_passive: int = 0,
    start_bias: float = 0.0,
    level: float = 0.0,
    laws: LawParameters = LAWS,
) -> int:
    """The back-offs counted after the first learning span, in which ``lost`` ticks had F_hat =
    ``bias`` + ``level`` (a loss, or a near loss, read through an estimate whose mean is ``bias``
    off in every span) and the rest the passive spans' error; the last passive span lost
    ``lost_passive`` ticks likewise; span 0 (the start's transient) has ``start_bias`` added."""
    law = LineAdaptiveLaw(TRACK, laws, DT)
    n, w = law.period_ticks, law.omega_span
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    learning = laws.line_runin_spans
    for k in range((learning + 1) * n):
        span, i = divmod(k, n)
        f_hat = F_R + bias + (start_bias if span == 0 else 0.0) - PASSIVE * math.cos(w * k * DT)
        if (span == learning and i < lost) or (span == learning - 1 and i < lost_passive):
            f_hat = bias + level
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), f_hat)
        law.commit(k, u)
    return law.strikes


def test_a_span_backs_off_when_its_share_of_lost_ticks_exceeds_line_guard_loss():
    """line_guard_loss is a share of the span's ticks: just below it no back-off, just above it one."""
    n = LineAdaptiveLaw(TRACK, LAWS, DT).period_ticks
    allowed = LAWS.line_guard_loss * n
    assert strikes_after_a_span_with_lost_ticks(math.floor(allowed) - 1) == 0
    assert strikes_after_a_span_with_lost_ticks(math.ceil(allowed) + 1) == 1


@pytest.mark.parametrize("loss_spans", [1, 8])
def test_before_line_guard_loss_spans_only_a_loss_above_the_hard_bar_strikes(loss_spans):
    """With line_guard_loss_spans, the first learning span is judged against GUARD_HARD_FACTOR times
    line_guard_loss over the passive spans' share: just below that no back-off, just above it one;
    from the loss_spans-th learning span on (1: the first) the bar is line_guard_loss again. (A
    small line_guard_loss: a few lost ticks, which do not move the span's sigma_b to the harm
    check's hard limit.)"""
    laws = dataclasses.replace(LAWS, line_guard_loss=0.003, line_guard_loss_spans=loss_spans)
    n = LineAdaptiveLaw(TRACK, laws, DT).period_ticks
    bar, hard = laws.line_guard_loss * n, GUARD_HARD_FACTOR * laws.line_guard_loss * n
    between = math.ceil(bar) + 1
    assert bar < between < math.floor(hard) - 1
    judged = loss_spans <= 1  # the first learning span is learned span 1
    assert strikes_after_a_span_with_lost_ticks(between, laws=laws) == (1 if judged else 0)
    assert strikes_after_a_span_with_lost_ticks(math.floor(hard) - 1, laws=laws) == (1 if judged else 0)
    assert strikes_after_a_span_with_lost_ticks(math.ceil(hard) + 1, laws=laws) == 1
    default = dataclasses.replace(laws, line_guard_loss_spans=0)  # judges every learning span
    assert strikes_after_a_span_with_lost_ticks(between, laws=default) == 1


def test_a_tick_counts_as_nearly_lost_below_the_margin_times_the_reference():
    """line_guard_loss_margin is a share of F_r: an estimate just under margin x F_r counts as a
    near loss, one just above it does not (F_hat misses the millisecond dips of a real loss)."""
    n = LineAdaptiveLaw(TRACK, LAWS, DT).period_ticks
    lost = math.ceil(LAWS.line_guard_loss * n) + 1
    near = LAWS.line_guard_loss_margin * F_R
    assert strikes_after_a_span_with_lost_ticks(lost, level=0.9 * near) == 1
    assert strikes_after_a_span_with_lost_ticks(lost, level=1.1 * near) == 0


def passive_bar_after_near_losses_in_span_1(level: float, start_bias: float) -> float:
    """The guard's passive loss bar after span 1 (a passive span) had 20 ticks with F_hat = ``level``
    and span 0 (the start's transient) an estimate ``start_bias`` high in every tick."""
    law = LineAdaptiveLaw(TRACK, LAWS, DT)
    n, w = law.period_ticks, law.omega_span
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    for k in range(2 * n):
        span, i = divmod(k, n)
        f_hat = F_R + (start_bias if span == 0 else 0.0) - PASSIVE * math.cos(w * k * DT)
        if span == 1 and i < 20:
            f_hat = level
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), f_hat)
        law.commit(k, u)
    return float(law.state[0]["line_passive_loss"])


def test_the_starts_mean_moves_no_near_loss_count_of_the_next_span():
    """Span 0's mean (the start's transient, 20 N high here) is not taken off span 1's estimate: ticks
    half a newton above margin x F_r count no near loss, half a newton below they do (20 of the span's
    ticks: the bar is their share)."""
    n = LineAdaptiveLaw(TRACK, LAWS, DT).period_ticks
    near = LAWS.line_guard_loss_margin * F_R
    assert LAWS.line_runin_spans >= 2  # span 1 is passive: its count sets the bar
    assert passive_bar_after_near_losses_in_span_1(near + 0.5, start_bias=20.0) == 0.0
    assert passive_bar_after_near_losses_in_span_1(near - 0.5, start_bias=20.0) == 20 / n


def test_lost_ticks_are_counted_on_the_estimate_less_its_mean_bias():
    """F_hat's mean 15 N high in every span (within line_guard_bias): a loss reads F_hat = 15 N,
    above line_guard_loss_margin F_r, and is counted only once the last span's bias is taken off.
    Counted so in the passive spans too, they set the bar: as many lost ticks in a learning span
    as in the worst passive one are no back-off."""
    n = LineAdaptiveLaw(TRACK, LAWS, DT).period_ticks
    bias, lost = 0.1 * F_R, math.ceil(2 * LAWS.line_guard_loss * n)
    assert bias > LAWS.line_guard_loss_margin * F_R and bias < LAWS.line_guard_bias * F_R
    assert strikes_after_a_span_with_lost_ticks(lost, bias) == 1
    assert strikes_after_a_span_with_lost_ticks(lost, bias, lost_passive=lost) == 0
    # The start's transient has its own mean (span 0 is not judged): it shifts no later count.
    assert strikes_after_a_span_with_lost_ticks(lost, start_bias=LAWS.line_guard_bias * F_R * 5) == 1


def test_a_fallback_episode_taints_its_own_span_only():
    """Commands that were not the law's (a fallback episode, then restart) in span 0: that span
    teaches nothing, and the next one counts again: spans 1 .. line_runin_spans - 1 all give the
    guard's passive sigma_b, as without the episode."""
    counts = []
    for episode in (False, True):
        law = LineAdaptiveLaw(TRACK, LAWS, DT)
        n, w = law.period_ticks, law.omega_span
        f_r = np.array([F_R, 0.0, 0.0, 0.0])
        for k in range((LAWS.line_runin_spans + 1) * n):
            if episode and k == n // 2:
                law.restart(F_R)
            u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), F_R - PASSIVE * math.cos(w * k * DT))
            law.commit(k, u)
        counts.append(int(law.state[0]["line_passive_spans"]))
    assert counts == [LAWS.line_runin_spans - 1] * 2


def modes_with_a_biased_mean(bias: list[float]) -> tuple[LineAdaptiveLaw, list[str]]:
    """The passive spans' error in every span, F_hat's mean off the momentum balance by bias_j."""
    return imposed([PASSIVE] * len(bias), bias)


def test_a_mean_off_the_momentum_balance_by_more_than_line_guard_bias_trips_at_the_first_judged_span():
    """|mean(F_hat) - mean(F_a)| above line_guard_bias times the mean reference trips at the end of
    span 2 (spans 0 and 1 hold the start's transient and are not judged: a bias there alone trips
    nothing); just below the bound, nothing trips (over the passive spans: F_hat is imposed here, so
    once the law learns it would chase the mean error it cannot move)."""
    bound = LAWS.line_guard_bias * F_R
    assert LAWS.line_runin_spans >= 3  # span 2 is still passive: the trip moves nothing
    law, modes = modes_with_a_biased_mean(
        [5.0 * bound, 5.0 * bound] + [0.9 * bound] * (LAWS.line_runin_spans - 2)
    )
    assert not law.tripped and set(modes) == {"active"}
    for sign in (1.0, -1.0):
        law, modes = modes_with_a_biased_mean([0.0, 0.0] + [sign * 1.1 * bound] * 3)
        assert law.trip_reason == "bias"
        assert modes[2] == "active" and modes[3] == "passive"  # judged at the end of span 2
        # The start's transient in spans 0 and 1 does not hide a bias that follows it.
        law, modes = modes_with_a_biased_mean([sign * 5.0 * bound] * 2 + [sign * 1.1 * bound] * 3)
        assert law.trip_reason == "bias" and modes[2] == "active" and modes[3] == "passive"


# -- the learning step by property ----------------------------------------------------------
def span_errors(law: LineAdaptiveLaw, f_hat: np.ndarray, harmonic: int) -> np.ndarray:
    """|E_h| of every span: (2 / N) |sum e_k exp(-i h w_s t_k)| with e = F_r - F_hat."""
    n = law.period_ticks
    spans = len(f_hat) // n
    t = np.arange(n) * DT
    e = (F_R - f_hat[: spans * n]).reshape(spans, n)
    return np.abs(2.0 / n * (e @ np.exp(-1j * harmonic * law.omega_span * t)))


def follow(spans: int, u_max: float = math.inf) -> tuple[LineAdaptiveLaw, np.ndarray, np.ndarray, np.ndarray]:
    """The known linear response F = F_r + d + (u_applied - F_r) one tick late, d two harmonics of
    the span (40 N and 15 N), the actuator limited to ``u_max``: (law, F_hat, asked, applied)."""
    law = LineAdaptiveLaw(TRACK, LAWS, DT)
    n, w = law.period_ticks, law.omega_span
    f_r = np.array([F_R, 0.0, 0.0, 0.0])
    f_hats, asked, applied = np.empty(spans * n), np.empty(spans * n), np.empty(spans * n)
    u_applied = F_R
    for k in range(spans * n):
        t = k * DT
        f_hat = F_R + 40 * math.cos(w * t) + 15 * math.sin(3 * w * t + 0.4) + (u_applied - F_R)
        u, _ = law.output(k, t, f_r, np.zeros(4), np.zeros(3), f_hat)
        u_applied = min(u, u_max)
        law.commit(k, u_applied)
        f_hats[k], asked[k], applied[k] = f_hat, u, u_applied
    return law, f_hats, asked, applied


def test_the_learning_step_lowers_the_error_harmonics_on_a_known_linear_response():
    """dF/du = 1 at low frequency (the prior D = -1 is the truth but for the one tick of delay the
    law advances by): from the first learning span on, |E_h| of both disturbed harmonics falls
    span after span until it is small."""
    spans = 14
    law, f_hats, _, _ = follow(spans)
    first = LAWS.line_runin_spans  # the first span run with a learned step
    for harmonic, size in ((1, 40.0), (3, 15.0)):
        err = span_errors(law, f_hats, harmonic)
        assert err[1] == pytest.approx(size, rel=0.02)  # passive: the disturbance itself
        falling = err[first : first + 4]
        assert np.all(np.diff(falling) < 0.0), (harmonic, err)
        assert err[-1] < 0.1 * size, (harmonic, err)
    assert not law.tripped


def test_what_the_limits_take_off_the_mean_is_given_back_the_next_span():
    """u <= F_r + 30 N against peaks of up to 55 N: the feedforward's peaks are clipped, which takes
    ~2 N off the applied command's mean every span. The law measures that loss on the applied
    command and adds it back the next span (C), so once the loss has settled the force's mean
    (mean(F) = mean(u) here) is on F_r in every span, within a few percent of the loss: not only
    after the slow mean correction U_0 (gain gamma per span) has caught up with it."""
    spans = 20
    law, f_hats, asked, applied = follow(spans, u_max=F_R + 30.0)
    n = law.period_ticks
    loss = (asked - applied).reshape(spans, n).mean(axis=1)
    mean_force = f_hats.reshape(spans, n).mean(axis=1) - F_R
    settled = slice(spans // 2, spans)
    assert np.all(loss[settled] > 1.0), loss  # the limits do take the mean off, every span
    assert np.all(np.abs(np.diff(loss[settled])) < 0.05), loss
    assert np.all(np.abs(mean_force[settled]) < 0.03 * loss[settled]), (mean_force, loss)


def test_with_the_estimated_bar_the_run_ins_bar_stays_behind_at_the_hard_factor():
    """F_hat imposed, deaf to u: the estimate of each span as it would have been passive reads the
    learning span's lost ticks as passive's own, the blind spot of an identification gone wrong.
    The run-in's share still stands behind it at GUARD_HARD_FACTOR times line_guard_loss: a span
    between one and that many times the margin strikes on the run-in's bar alone, not with the
    estimated one; above it, with either."""
    laws = dataclasses.replace(LAWS, line_guard_loss=0.003)
    estimate = dataclasses.replace(laws, line_guard_reference="estimate")
    n = LineAdaptiveLaw(TRACK, laws, DT).period_ticks
    bar, hard = laws.line_guard_loss * n, GUARD_HARD_FACTOR * laws.line_guard_loss * n
    between = math.ceil(bar) + 1
    assert bar < between < math.floor(hard) - 1
    assert strikes_after_a_span_with_lost_ticks(between, laws=laws) == 1
    assert strikes_after_a_span_with_lost_ticks(between, laws=estimate) == 0
    assert strikes_after_a_span_with_lost_ticks(math.floor(hard) - 1, laws=estimate) == 0
    assert strikes_after_a_span_with_lost_ticks(math.ceil(hard) + 1, laws=estimate) == 1
