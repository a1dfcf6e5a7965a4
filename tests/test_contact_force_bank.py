"""The contact-force observer's filter bank over the frame mass, by its contract (contact_force.py).

The bank holds one filter per m2 in (1 +- ``frame_mass_range``) m2_nominal, ``frame_mass_step``
apart; each filter's innovation energy forgets with the time constant ``frame_mass_window``, and
the estimate is the filter with the smallest.  The pantograph here is simulated exactly (the
2-DOF model of eqs. (3)-(4) sampled with a zero-order hold), with an unknown contact force on the
head and a frame mass that the test sets, and changes, as it likes.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg

from pac_model import model
from pac_model.parameters import PantographParameters, TrackParameters
from pac_observer.contact_force import ContactForceObserver, frame_mass_scales
from pac_observer.parameters import ObserverParameters

pytestmark = pytest.mark.unit

DT = 1e-3
PANTO = PantographParameters()


def sampled_pantograph(m2_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Gamma) of x = (z1, z2, z1', z2') with inputs (F on the head, u on the frame), held."""
    p = replace(PANTO, m2=PANTO.m2 * m2_scale)
    a = np.zeros((6, 6))
    a[:4, :4] = model.state_matrix(p)
    a[2, 4] = -1.0 / p.m1  # F pushes the head down
    a[3, 5] = 1.0 / p.m2  # u lifts the frame
    e = scipy.linalg.expm(a * DT)
    return e[:4, :4], e[:4, 4:]


def run(observer: ContactForceObserver, schedule: list[tuple[float, float]], seed: int = 3) -> np.ndarray:
    """The plant with m2 scaled by schedule's value from its time on; the bank's selected m2 scale
    at every tick."""
    rng = np.random.default_rng(seed)
    r = observer.params.position_noise
    x = np.zeros(4)
    duration = schedule[-1][0]
    ticks = int(round(duration / DT))
    selected = np.empty(ticks)
    segments = [(round(t0 / DT), sampled_pantograph(scale)) for t0, scale in schedule[:-1]]
    u = 0.0
    for k in range(ticks):
        t = k * DT
        phi, gamma = [seg for k0, seg in segments if k0 <= k][-1]
        y = x[:2] + r * rng.standard_normal(2)
        observer.update(k, (y[0], y[1]), u)
        selected[k] = observer.frame_mass_scale
        force = 120.0 + 20.0 * math.sin(2 * math.pi * 3.0 * t)
        u = 100.0 + 40.0 * math.sin(2 * math.pi * 1.3 * t) + 20.0 * math.sin(2 * math.pi * 7.0 * t)
        x = phi @ x + gamma @ np.array([force, u])
    return selected


def bank(**options) -> ContactForceObserver:
    params = ObserverParameters(observer="contact_force", **options)
    return ContactForceObserver(PANTO, TrackParameters(), params, DT)


def test_the_bank_spans_its_whole_range_in_equal_steps():
    for mass_range, step in ((0.3, 0.025), (0.2, 0.1), (0.05, 0.025), (0.0, 0.025)):
        scales = frame_mass_scales(ObserverParameters(frame_mass_range=mass_range, frame_mass_step=step))
        count = round(2 * mass_range / step) + 1
        assert len(scales) == count, (mass_range, step, scales)
        assert scales.min() == pytest.approx(1.0 - mass_range, abs=1e-12)
        assert scales.max() == pytest.approx(1.0 + mass_range, abs=1e-12)
        assert np.any(np.abs(scales - 1.0) < 1e-12)
        if count > 1:
            np.testing.assert_allclose(np.diff(scales), step, rtol=1e-9)


@pytest.mark.parametrize("edge", [-1.0, 1.0])
def test_the_bank_finds_a_frame_mass_at_either_end_of_its_range(edge):
    observer = bank()
    scale = 1.0 + edge * observer.params.frame_mass_range
    selected = run(observer, [(0.0, scale), (1.5, scale)])
    assert selected[-1] == pytest.approx(scale, abs=1e-12)


@pytest.mark.parametrize("window", [None, 0.2])
def test_after_a_mass_change_the_bank_reselects_within_a_few_windows(window):
    """The frame mass x1.2 from t = 1.5 s: the bank had settled on the nominal filter and must
    select the new mass (within one step of the bank) and keep it, a few windows after the change.

    Why a few: the filter of the new mass carries the energy E1 of its old error, forgetting it
    as exp(-t / window), while the nominal filter's grows to E2 (1 - exp(-t / window)); the bank
    switches when the first falls below ``BANK_HYSTERESIS`` times the second, after
    window ln(1 + E1 / (0.9 E2)): proportional to the window, 4 of them for E1 / E2 ~ 50."""
    observer = bank() if window is None else bank(frame_mass_window=window)
    window, step = observer.params.frame_mass_window, observer.params.frame_mass_step
    change = 1.5
    selected = run(observer, [(0.0, 1.0), (change, 1.2), (change + 6 * window, 1.2)])
    k_change = round(change / DT)
    assert selected[k_change - 1] == pytest.approx(1.0, abs=1e-12)
    away = np.flatnonzero(np.abs(selected - 1.2) > step + 1e-9)
    settled = away[-1] + 1  # from here on within one step of 1.2
    assert settled < len(selected)
    delay = (settled - k_change) * DT
    assert 0.0 < delay <= 4.0 * window, delay
