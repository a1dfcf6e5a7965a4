"""The contact-force statistics and EN 50367 criteria against independent references.

References: Python's ``statistics`` module (mean, population deviation) on plain lists,
the analytic gain of a zero-phase Butterworth filter, the EN 50367 target values as
published (docs/catenary_data.md) and hand-counted spans.
"""

from __future__ import annotations

import math
import statistics as pystats

import numpy as np
import pytest

from pac_common import contact_statistics as cs

pytestmark = pytest.mark.unit


def test_statistics_match_python_statistics_on_a_list():
    rng = np.random.default_rng(3)
    force = list(100.0 + 45.0 * rng.standard_normal(2001))
    s = cs.statistics(np.array(force))
    mean, sd = pystats.fmean(force), pystats.pstdev(force)
    assert s.contact_force_mean == pytest.approx(mean, rel=1e-12)
    assert s.contact_force_std == pytest.approx(sd, rel=1e-10)
    assert s.statistical_min == pytest.approx(mean - 3 * sd, rel=1e-10)
    assert s.statistical_max == pytest.approx(mean + 3 * sd, rel=1e-10)
    assert s.contact_force_min == min(force) and s.contact_force_max == max(force)
    lost = sum(1 for f in force if f <= 0.0)
    assert lost > 0  # the record does lose contact: the count below is exercised
    assert s.contact_loss_percent == pytest.approx(100.0 * lost / len(force), rel=1e-12)


def test_contact_loss_counts_the_given_loss_force_and_nan_when_empty():
    s = cs.statistics(np.array([1.0, 2.0, 3.0, 4.0]), loss_force=np.array([1.0, 0.0, -1.0, 4.0]))
    assert s.contact_loss_percent == 50.0
    assert all(math.isnan(v) for v in cs.statistics(np.zeros(0)).as_dict().values())
    with pytest.raises(ValueError, match="loss_force"):
        cs.statistics(np.ones(3), loss_force=np.ones(2))


@pytest.mark.parametrize(("freq", "cutoff"), [(5.0, 20.0), (20.0, 20.0), (40.0, 20.0), (10.0, 5.0)])
def test_lowpass_gain_is_the_butterworth_gain_squared(freq, cutoff):
    """Forwards-backwards applies |H|^2 with no phase shift; H is the digital Butterworth of order
    n = 4 (bilinear transform, pre-warped at fc): |H|^2 = 1 / (1 + (tan(pi f dt) / tan(pi fc dt))^(2n))."""
    dt = 1e-3
    t = np.arange(0.0, 6.0, dt)
    y = cs.lowpass(np.sin(2 * math.pi * freq * t), dt, cutoff)
    mid = (t > 2.0) & (t < 4.0)  # away from the start/end transients
    # Project on sin and cos over whole periods: gain and phase of the steady state.
    s, c = np.sin(2 * math.pi * freq * t[mid]), np.cos(2 * math.pi * freq * t[mid])
    a, b = 2 * np.mean(y[mid] * s), 2 * np.mean(y[mid] * c)
    ratio = math.tan(math.pi * freq * dt) / math.tan(math.pi * cutoff * dt)
    expected = 1.0 / (1.0 + ratio ** (2 * cs.LOWPASS_ORDER))
    assert math.hypot(a, b) == pytest.approx(expected, rel=2e-3, abs=1e-4)
    assert abs(b) < 1e-3  # zero phase


def test_contact_statistics_sees_only_the_window_and_filters_before_it():
    """A 60 Hz ripple is removed (gain 1/(1+3^8) ~ 1.5e-4); the window excludes a 1000 N spike."""
    dt = 1e-3
    t = np.arange(0, 4, dt)
    x = 50.0 * t
    f = 100 + 10 * np.sin(2 * math.pi * 2 * t) + 20 * np.sin(2 * math.pi * 60 * t)
    f[x > 180.0] = 1000.0  # outside [50, 150] m, and far enough for the filter's reach
    s = cs.contact_statistics(f, x, dt, 50.0, 150.0)
    # The window holds exactly 4 periods of the 2 Hz wave: mean 100, sigma 10 / sqrt(2).
    assert s.contact_force_mean == pytest.approx(100.0, abs=0.05)
    assert s.contact_force_std == pytest.approx(10 / math.sqrt(2), rel=5e-3)
    assert s.contact_force_max == pytest.approx(110.0, abs=0.1)
    assert s.contact_loss_percent == 0.0
    raw = cs.contact_statistics(f, x, dt, 50.0, 150.0, cutoff=None)
    assert raw.contact_force_std == pytest.approx(math.sqrt(10**2 / 2 + 20**2 / 2), rel=5e-3)
    with pytest.raises(ValueError, match="no samples"):
        cs.contact_statistics(f, x, dt, 500.0, 600.0)


def test_contact_loss_is_counted_on_the_unfiltered_force():
    """A 2 ms lift-off that the 20 Hz filter smooths away is still contact loss."""
    dt = 1e-3
    x = np.arange(0, 2000) * 0.1
    f = np.full(x.size, 100.0)
    f[1000:1002] = 0.0
    s = cs.contact_statistics(f, x, dt, 0.0, 200.0)
    assert s.contact_force_min > 0.0  # the filtered force never reaches 0
    assert s.contact_loss_percent == pytest.approx(100.0 * 2 / 2000)


@pytest.mark.parametrize(
    ("speed", "published"), [(250, 130.6), (300, 157.3), (320, 169.3), (360, 195.7), (0, 70.0)]
)
def test_target_mean_force_matches_the_published_values(speed, published):
    assert cs.target_mean_force(speed) == pytest.approx(published, abs=0.05)


@pytest.mark.parametrize(
    ("mean", "std", "sigma_ok", "min_ok"),
    [
        (100.0, 30.0, True, True),
        (100.0, 30.1, False, True),
        (100.0, 33.4, False, False),
        (100.0, 33.3, False, True),
    ],
)
def test_en50367_criteria(mean, std, sigma_ok, min_ok):
    v = cs.en50367_criteria(mean, std)
    assert (v.sigma_ok, v.statistical_min_ok) == (sigma_ok, min_ok)
    assert v.passed == (sigma_ok and min_ok)
    assert cs.en50367_passed(np.array([mean, math.nan]), np.array([std, 1.0])).tolist() == [v.passed, False]


def test_whole_spans_inside_an_interval():
    assert cs.whole_spans(30.0, 250.0, 55.0) == (55.0, 220.0)
    assert cs.whole_spans(110.0, 220.0, 55.0) == (110.0, 220.0)
    assert cs.whole_spans(110.0 + 1e-12, 220.0 - 1e-12, 55.0) == (110.0, 220.0)  # rounding
    with pytest.raises(ValueError, match="no whole span"):
        cs.whole_spans(60.0, 150.0, 55.0)
    with pytest.raises(ValueError, match="span_length"):
        cs.whole_spans(0.0, 100.0, 0.0)


def test_the_worst_span_is_the_whole_span_that_lost_most_counted_by_hand():
    # Supports of unequal spans; the record starts inside span 0 and ends inside span 3.
    supports = np.array([0.0, 50.0, 110.0, 160.0, 220.0])
    x = np.arange(20.0, 200.0, 1.0)  # 1 m per sample
    force = np.full(x.size, 100.0)
    force[(x >= 60.0) & (x < 66.0)] = 0.0  # 6 of span 1's 60 samples: 10 %
    force[(x >= 120.0) & (x < 125.0)] = -1.0  # 5 of span 2's 50 samples: 10 %,
    force[x == 150.0] = 0.0  # and one more: 6 of 50, 12 %
    force[(x >= 20.0) & (x < 40.0)] = 0.0  # span 0 is cut by the record: not a span's share
    assert cs.worst_span_loss_percent(force, x, supports) == pytest.approx(12.0)
    assert cs.statistics(force).contact_loss_percent == pytest.approx(100.0 * 32 / x.size)


def test_a_span_reached_within_one_sample_counts_and_none_whole_is_nan():
    supports = np.array([0.0, 50.0, 100.0])
    x = np.arange(0.5, 100.0, 1.0)  # from half a sample after the support to half one before the next
    force = np.where(x < 50.0, 0.0, 100.0)
    assert cs.worst_span_loss_percent(force, x, supports) == 100.0
    inside = np.arange(10.0, 40.0, 1.0)
    assert math.isnan(cs.worst_span_loss_percent(np.zeros(inside.size), inside, supports))
    assert math.isnan(cs.worst_span_loss_percent(force, np.full(x.size, np.nan), supports))
