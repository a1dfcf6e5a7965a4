"""line_adaptive on a whole line: told the design layout (the line map a train carries), it learns
over each span's own length instead of the nominal span's period (line_adaptive_kernels.locate);
the layout and the start are derived from the line the plant runs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pac_controller.line_adaptive import LineAdaptiveLaw
from pac_controller.line_adaptive_kernels import locate
from pac_controller.parameters import LawParameters
from pac_model.parameters import TrackParameters
from pac_plant.catenary.catenary_file import load_catenary
from pac_rig import composition

DT = 1e-3


def _law(supports: tuple[float, ...], start: float = 0.0, error: float = 0.0, speed_kmh: float = 300.0):
    laws = LawParameters(line_supports=supports, line_position_start=start, line_position_error=error)
    return LineAdaptiveLaw(TrackParameters(speed_kmh=speed_kmh, span_length=55.0), laws, DT)


@pytest.mark.unit
def test_a_span_of_the_layout_is_found_and_its_phase_scaled_to_its_own_length():
    """Spans of 50, 60 and 55 m: the position v t falls in the span whose supports bracket it, and
    the phase index is floor(N (x - x_m) / L_m), N the nominal span's ticks, whatever L_m is."""
    law = _law((0.0, 50.0, 110.0, 165.0))
    p, table = law.params[0], law.table
    n, step = law.period_ticks, 300 / 3.6 * DT
    for x, span, fraction in ((0.0, 0, 0.0), (25.0, 0, 0.5), (80.0, 1, 0.5), (110.0 + 41.25, 2, 0.75)):
        tick = round(x / step)
        found, phase = locate(p, table, tick, 0)
        assert found == span
        assert abs(phase - n * fraction) <= n * step / 50.0 + 1  # one tick's distance, in phase
    # The cursor may start anywhere: the search walks both ways.
    assert locate(p, table, round(80.0 / step), 2)[0] == 1
    # The position error moves x: +0.5 m shifts the phase by 0.5 / L of a span.
    shifted = _law((0.0, 50.0, 110.0, 165.0), error=0.5)
    assert locate(shifted.params[0], shifted.table, 0, 0)[1] == int(n * 0.5 / 50.0)


@pytest.mark.unit
def test_without_a_layout_the_span_is_the_nominal_period():
    law = _law((0.0,))
    p, n = law.params[0], law.period_ticks
    assert p["line_supports"] == 0
    for tick in (0, n - 1, n, 5 * n + 3):
        assert locate(p, law.table, tick, 0) == (tick // n, tick % n)


@pytest.mark.unit
def test_the_layout_derived_is_the_design_of_the_line_the_plant_runs():
    """On a whole drawn line (realistic_3km) the derived supports are those of the plant's line
    (its layout, to 1 mm) and the start is where the plant's contact point starts; the line's
    deviation (the seed's other stream) is not in them. A period derives nothing."""
    from pac_rig.closed_loop import build_cores
    from pac_rig.simulate import scenario_from_flat

    given = {"law": "line_adaptive", "catenary_model": "fe", "catenary": "realistic_3km", "line_seed": 3}
    values, notes = composition.derive(given)
    assert any("line_supports" in note for note in notes)
    plant, _, _ = build_cores(scenario_from_flat({**values, "duration": 0.01}))
    np.testing.assert_allclose(values["line_supports"], plant.line.layout.support_x, rtol=0, atol=5e-4)
    assert values["line_position_start"] == pytest.approx(plant.sim.x - plant.sim.lags[0], abs=5e-4)
    other = load_catenary("realistic_3km").design_supports(4)
    assert other is not None and len(other) > 2 and not np.allclose(other[:5], values["line_supports"][:5])
    periodic, _ = composition.derive({"law": "line_adaptive", "catenary_model": "fe"})
    assert "line_supports" not in periodic
    # With a second pantograph 200 m behind, the run starts at the first support past 200 m.
    two, _ = composition.derive({**given, "pantographs": (0.0, 200.0), "controlled_pantograph": 1})
    supports = np.array(two["line_supports"])
    assert two["line_position_start"] == pytest.approx(supports[np.searchsorted(supports, 200.0)] - 200.0)


@pytest.mark.offline
@pytest.mark.slow
@pytest.mark.timeout(900)  # three 20-span runs of the realistic scenario
def test_the_recommended_law_lowers_sigma_on_a_short_realistic_run():
    """realistic_electromechanical at 300 km/h on a design line (seed 5), 20 spans: over spans
    12..20 of the design layout line_adaptive's EN 50318 sigma is at least 10 % below the passive
    run's on the same line and window (-29 % when written), it has not fallen back, and it loses
    contact no more than passive there; as a user gets it (the head balance, the line map and the
    law's design for a fast actuator derived) and with the fast actuator's part of that design
    named off (the support zone and the loss check's wait, as on a slow actuator)."""
    from pac_common.contact_statistics import contact_statistics
    from pac_controller.line_adaptive import DESIGN_FOR_FAST_ACTUATOR
    from pac_rig.closed_loop import run
    from pac_rig.simulate import scenario_from_flat

    off = {name: type(value)(0) for name, value in DESIGN_FOR_FAST_ACTUATOR} | {"line_actuator_lag": 0.0}
    given = {"scenario": "realistic_electromechanical", "line_seed": 5, "speed_kmh": 300.0}
    given["force_amplitude"] = 157.3
    supports = load_catenary("realistic_3km").design_supports(5)
    assert supports is not None
    stats, modes = {}, {}
    for name, law, settings in (
        ("passive", "passive", {}),
        ("defaults", "line_adaptive", {}),
        ("zone off", "line_adaptive", off),
    ):
        values, _ = composition.derive({**given, **settings, "law": law})
        start = values.get("line_position_start", supports[1])
        duration = (supports[22] - start) / (300.0 / 3.6)
        records = list(run(scenario_from_flat({**values, "duration": round(duration, 3)})))
        force = np.array([r.truth.contact_force for r in records])
        x = np.array([r.truth.contact_position for r in records])
        stats[name] = contact_statistics(force, x, 1e-3, supports[12], supports[20])
        modes[name] = {r.command.mode for r in records[-500:]}
    passive = stats["passive"]
    for name in ("defaults", "zone off"):
        assert stats[name].contact_force_std < 0.9 * passive.contact_force_std, (name, stats)
        assert modes[name] == {"active"}, name
        assert stats[name].contact_loss_percent <= passive.contact_loss_percent, name
    assert stats["zone off"].contact_force_std != stats["defaults"].contact_force_std  # they differ


@pytest.mark.unit
def test_a_span_longer_than_the_nominal_is_judged_by_its_shape_not_by_its_ticks():
    """The same error shape on every span, a cos(2 pi (x - x_m) / L_m): the passive spans 50 m
    long, the learning spans 60 m (20 % more ticks each). Each span's harmonic sums are taken over
    its own ticks, so its sigma_b is a / sqrt(2) whatever its length, and the guard's ratio of the
    learning spans to the passive ones is 1 (not 60 / 50). The error is imposed (an open loop) and
    its phase computed here from the supports, not by the law's own lookup."""
    laws = LawParameters()
    passive_spans = laws.line_runin_spans
    supports = np.concatenate(
        [50.0 * np.arange(passive_spans + 1), 50.0 * passive_spans + 60.0 * np.arange(1, 5)]
    )
    law = _law(tuple(supports))
    speed, amplitude = 300 / 3.6, 10.0
    f_r = np.array([150.0, 0.0, 0.0, 0.0])
    ticks = int(supports[-1] / (speed * DT)) - 1
    for k in range(ticks):
        x = speed * k * DT
        m = int(np.searchsorted(supports, x, side="right")) - 1
        shape = math.cos(2 * math.pi * (x - supports[m]) / (supports[m + 1] - supports[m]))
        u, _ = law.output(k, k * DT, f_r, np.zeros(4), np.zeros(3), 150.0 - amplitude * shape)
        law.commit(k, u)
    assert not law.tripped
    # 1 to the sampling of the cosine by each span's ticks (1e-7 here); 1.2 were sums by tick count.
    assert law.last_sigma_ratio == pytest.approx(1.0, abs=1e-3)


def _trips_on_a_biased_start(start_ticks: int, biased_ticks: int) -> bool:
    """Spans of exactly N ticks from support 0; the train starts ``start_ticks`` into span 0 and
    F_hat's mean is 5 times ``line_guard_bias`` F_r off for its first ``biased_ticks`` ticks, then on
    it (the actuator applies what the law asks): whether the guard fell back on the bias."""
    f_r, n = 150.0, 500
    speed = 100.0  # m/s: 0.1 m a tick, so the spans are N = 500 ticks of 50 m
    supports = tuple(50.0 * np.arange(10))
    laws = LawParameters(
        line_supports=supports, line_position_start=0.1 * start_ticks + 0.05, design_delay_ticks=0
    )
    law = LineAdaptiveLaw(TrackParameters(speed_kmh=3.6 * speed, span_length=50.0), laws, DT)
    assert law.period_ticks == n
    bias = 5.0 * laws.line_guard_bias * f_r
    reference = np.array([f_r, 0.0, 0.0, 0.0])
    for k in range(6 * n):
        f_hat = f_r + (bias if k < biased_ticks else 0.0)
        u, _ = law.output(k, k * DT, reference, np.zeros(4), np.zeros(3), f_hat)
        law.commit(k, u)
    return law.trip_reason == "bias"


@pytest.mark.unit
def test_a_run_that_starts_past_a_spans_middle_counts_its_spans_from_the_next():
    """The start's transient is spans 0 and 1 (not judged by the momentum balance). A run that starts
    past the middle of a span (the train's map just behind a support) counts that piece as part of
    it: its spans 0 and 1 are the two whole spans after it. One that starts before the middle counts
    the piece as span 0. Each is shown by a bias over exactly its transient (not judged) and over one
    span more (judged: a fallback)."""
    n = 500
    for start in (300, 490):  # past the middle: the piece (200, 10 ticks) is no span of its own
        piece = n - start
        assert not _trips_on_a_biased_start(start, piece + 2 * n)
        assert _trips_on_a_biased_start(start, piece + 3 * n)
    for start in (0, 200):  # before it: the piece is span 0
        piece = n - start
        assert not _trips_on_a_biased_start(start, piece + n)
        assert _trips_on_a_biased_start(start, piece + 2 * n)


def _overlap_law(overlaps: tuple[float, ...]) -> LineAdaptiveLaw:
    """Ten spans of 50 m at 100 m/s (N = 500 ticks a span, no command delay), with ``overlaps``."""
    laws = LawParameters(
        line_supports=tuple(50.0 * np.arange(11)), line_overlaps=overlaps, design_delay_ticks=0
    )
    return LineAdaptiveLaw(TrackParameters(speed_kmh=360.0, span_length=50.0), laws, DT)


def _zone_law(before: float, after: float, lag: float = 0.0) -> LineAdaptiveLaw:
    """Ten spans of 50 m at 100 m/s (N = 500 ticks a span, no command delay), with a zone about the
    supports where the harmonics may only raise the command, and an actuator lag [s]."""
    laws = LawParameters(
        line_supports=tuple(50.0 * np.arange(11)),
        design_delay_ticks=0,
        line_support_before=before,
        line_support_after=after,
        line_actuator_lag=lag,
    )
    return LineAdaptiveLaw(TrackParameters(speed_kmh=360.0, span_length=50.0), laws, DT)


@pytest.mark.unit
@pytest.mark.parametrize("lag", [0.0, 0.1])
def test_about_a_support_the_harmonics_only_raise_the_command(lag):
    """Zone 0.1 of a span before each support (plus the actuator's lag: 0.1 s is 10 m, 0.2 of a
    span, at 100 m/s) to 0.15 after: there the feedforward is never below its mean (U_0 + C) and
    equals the law told no zone wherever the harmonics raise it; outside the zone and its ramps
    (0.05 of a span) it is the plain law's. Judged from the position, not the law's lookup."""
    plain, zoned = _zone_law(0.0, 0.0), _zone_law(0.1, 0.15, lag)
    rng = np.random.default_rng(5)
    harmonics = rng.normal(size=plain.harmonics) + 1j * rng.normal(size=plain.harmonics)
    for law in (plain, zoned):
        law.memory[0] = 30.0 * harmonics  # U_FF: row 0
    mean = zoned.state[0]["line_u_mean"] + zoned.state[0]["line_clip_offset"]
    before = 0.1 + lag * 100.0 / 50.0
    counted = {"held": 0, "raised": 0, "outside": 0}
    for tick in range(10 * 500):
        fraction = (0.1 * tick % 50.0) / 50.0
        to_zone = min(fraction - 0.15, 1.0 - before - fraction)  # < 0: in the zone
        whole, got = plain.feedforward(tick), zoned.feedforward(tick)
        if to_zone < -1e-3:
            assert got >= mean - 1e-9
            if whole >= mean:
                assert got == whole
                counted["raised"] += 1
            else:
                counted["held"] += 1
        elif to_zone > 0.05 + 1e-3:
            assert got == whole
            counted["outside"] += 1
    assert min(counted.values()) > 50


@pytest.mark.unit
def test_the_learned_harmonics_are_off_over_an_overlap_and_faded_next_to_it():
    """An overlap over spans 5 and 6 (250..350 m): the feedforward's harmonics are 0 there, a raised
    cosine down over span 4 and up over span 7, whole elsewhere. Judged against the same law told no
    overlap, with the window computed here from the position, not by the law's lookup."""
    plain, windowed = _overlap_law((0.0,)), _overlap_law((250.0, 350.0))
    rng = np.random.default_rng(3)
    harmonics = rng.normal(size=plain.harmonics) + 1j * rng.normal(size=plain.harmonics)
    for law in (plain, windowed):
        law.memory[0] = 20.0 * harmonics  # U_FF: row 0
    checked = {"off": 0, "faded": 0, "whole": 0}
    for tick in range(0, 10 * 500, 7):
        x = 0.1 * tick
        span, fraction = int(x // 50.0), (x % 50.0) / 50.0
        share = 1.0
        if span in (5, 6):
            share = 0.0
        elif span == 4:
            share = 0.5 * (1.0 + math.cos(math.pi * fraction))
        elif span == 7:
            share = 0.5 * (1.0 - math.cos(math.pi * fraction))
        # the law evaluates its window at the middle of the tick's phase cell, at most 1/(2N) of a
        # span away, where the cosine's slope is at most pi/2 per span
        whole = plain.feedforward(tick)
        bound = math.pi / 2 * 0.5 / plain.period_ticks * abs(whole) + 1e-9
        assert windowed.feedforward(tick) == pytest.approx(share * whole, abs=bound)
        checked["off" if share == 0.0 else "whole" if share == 1.0 else "faded"] += 1
    assert min(checked.values()) > 50 and np.abs(harmonics).max() > 0.5


@pytest.mark.unit
def test_the_spans_of_an_overlap_and_next_to_it_teach_nothing():
    """An error the law learns from on every span: its harmonics change at the end of each learning
    span but not at the ends of spans 4-7 (the overlap over 5 and 6 and the faded spans beside it)."""
    law = _overlap_law((250.0, 350.0))
    reference = np.array([150.0, 0.0, 0.0, 0.0])
    changed = {}
    before = law.memory[0].copy()
    for k in range(10 * 500 - 1):
        x = 0.1 * k
        error = 10.0 * math.cos(2 * math.pi * (x % 50.0) / 50.0)
        u, _ = law.output(k, k * DT, reference, np.zeros(4), np.zeros(3), 150.0 - error)
        law.commit(k, u)
        if k % 500 == 499:
            changed[k // 500] = not np.array_equal(law.memory[0], before)
            before = law.memory[0].copy()
    assert not law.tripped
    learning = [span for span in range(LawParameters().line_runin_spans - 1, 9) if span not in (4, 5, 6, 7)]
    assert learning and all(changed[span] for span in learning)
    assert not any(changed[span] for span in (4, 5, 6, 7))


@pytest.mark.unit
def test_the_overlaps_derived_are_those_of_the_line_the_plant_runs():
    """On a line of tension sections (realistic_3km_sections) the derived overlaps are where the
    plant's sections overlap (to 1 mm); a line of one tension length derives none."""
    from pac_rig.closed_loop import build_cores
    from pac_rig.simulate import scenario_from_flat

    given = {
        "law": "line_adaptive",
        "catenary_model": "fe",
        "catenary": "realistic_3km_sections",
        "line_seed": 118,
    }
    values, notes = composition.derive(given)
    assert any("line_overlaps" in note for note in notes)
    plant, _, _ = build_cores(scenario_from_flat({**values, "duration": 0.01}))
    extent = plant.line.section_x
    overlaps = np.column_stack((extent[1:, 0], extent[:-1, 1]))
    assert len(overlaps) >= 2
    np.testing.assert_allclose(np.reshape(values["line_overlaps"], (-1, 2)), overlaps, rtol=0, atol=5e-4)
    single, _ = composition.derive({**given, "catenary": "realistic_3km"})
    assert "line_overlaps" not in single
