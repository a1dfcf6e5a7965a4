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
from pac_observer.observer import OBSERVER_CONSTS, OBSERVER_STATE
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


def synthetic_bank(positions: list[float], energy: list[float]) -> tuple[np.ndarray, ...]:
    """A bank whose filter f holds x = (p_f, p_f, 0, 0, 0) still (Phi = I, Gamma = 0, no gain): its
    innovation for y = (0, 0) is -(p_f, p_f), so its new energy is lam E_f + 2 p_f^2 / r^2."""
    n = len(positions)
    xs = np.zeros((n, 5))
    xs[:, 0] = xs[:, 1] = positions
    phis = np.repeat(np.eye(5)[None], n, axis=0)
    return phis, np.zeros((n, 5)), np.zeros((n, 5, 2)), xs, np.array(energy, float), np.zeros((n, 2))


def bank_step(selected: int, positions: list[float], energy: list[float]) -> tuple[int, np.ndarray]:
    """contact_force_bank_step run as Python (where a read past an array's end raises) on a synthetic
    bank with lam = 1, r = 1; (the selection after it, the bank's energies after it)."""
    from pac_observer.contact_force import contact_force_bank_step

    states = np.zeros(1, OBSERVER_STATE).view(np.recarray)
    consts = np.zeros(1, OBSERVER_CONSTS).view(np.recarray)
    consts[0].cf_forget, consts[0].cf_inv_r2 = 1.0, 1.0
    states[0].cf_selected = selected
    arrays = synthetic_bank(positions, energy)
    contact_force_bank_step.py_func(states[0], consts[0], arrays, 0.0, 0.0, 0.0)
    return int(states[0].cf_selected), arrays[4]


def test_the_bank_selects_the_least_energy_of_this_step_with_hysteresis():
    """Energies before the step (0.2, 0.1, 5); this step adds 0, 1 and 0: the least is filter 0's
    0.2, not filter 1's 1.1 although filter 1's was the least before the step. From filter 2
    (energy 5) the bank switches to 0 (0.2 < 0.9 x 5); from filter 1 (1.1) it switches too; it
    stays on a filter whose energy the best does not undercut by 10 %."""
    moves = [0.0, math.sqrt(0.5), 0.0]
    selected, energy = bank_step(2, moves, [0.2, 0.1, 5.0])
    np.testing.assert_allclose(energy, [0.2, 1.1, 5.0], rtol=1e-15)
    assert selected == 0
    assert bank_step(1, moves, [0.2, 0.1, 5.0])[0] == 0
    assert bank_step(1, [0.0, 0.0], [1.0, 1.05])[0] == 1  # 1.0 is not below 0.9 x 1.05
    assert bank_step(1, [0.0, 0.0], [0.9, 1.1])[0] == 0  # 0.9 is below 0.9 x 1.1 = 0.99
    assert bank_step(1, [0.0, 0.0], [0.9, 1.0])[0] == 1  # 0.9 x 1.0 is 0.9 exactly: not below it
    assert bank_step(2, [0.0, 0.0, 0.0], [0.5, 0.5, 1.0])[0] == 0  # of equal energies, the first


def test_a_bank_of_one_filter_reads_nothing_past_it():
    """frame_mass_range 0: one filter, always selected (run as Python: a read past the bank raises)."""
    selected, energy = bank_step(0, [0.1], [3.0])
    assert selected == 0 and energy[0] == pytest.approx(3.02, rel=1e-15)


@pytest.mark.parametrize(("mass_range", "step"), [(0.3, 0.025), (0.2, 0.1), (0.0, 0.025)])
def test_the_bank_starts_on_the_nominal_frame_mass(mass_range, step):
    """Before any sample, and after a reset, the selected filter is the nominal pantograph's
    (scale 1), wherever it sits in the bank."""
    observer = bank(frame_mass_range=mass_range, frame_mass_step=step)
    assert observer.frame_mass_scale == 1.0
    run(observer, [(0.0, 1.0 + mass_range), (0.5, 1.0 + mass_range)])
    observer.reset()
    assert observer.frame_mass_scale == 1.0
