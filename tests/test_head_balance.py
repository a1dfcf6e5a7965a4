"""The head-balance observer (pac_observer.head_balance): the contact force from the head's equation
of motion, its accelerometer and the positions measured from the roof; its mean from the actuator's
force. Checked against the plant's own contact force, between the compiled loop and the core
objects, and where it cannot run (no head accelerometer)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import simulate_refusal

from pac_model.parameters import PantographParameters, TrackParameters
from pac_observer.head_balance import HeadBalanceObserver
from pac_observer.observer import ObserverDivergedError
from pac_observer.parameters import ObserverParameters
from pac_rig import composition
from pac_rig.composition import CompositionError

SQUARE = {"shape": "square", "period": 0.4, "observer": "head_balance", "law": "passive"}


def _exact_sensors(plant, sample_period: float) -> None:
    """The train's suite with ideal channels: no noise, no low-pass, no latency (the roof's datum
    is what is left of a train's sensing)."""
    from pac_plant.hardware.sensors import Channel, Sensors, SensorSuite

    exact = Channel(0.0, math.inf, 0.0)
    plant.sensors = Sensors(SensorSuite("exact", "roof", *([exact] * 5), 0.0, "a test's"), sample_period)


@pytest.mark.offline
def test_the_head_balance_is_the_plants_contact_force_with_the_roof_moving():
    """On the lumped plant whose pantograph is the nominal one, the roof moving (german_high) and the
    force reference a square wave: with exact sensors F_hat follows the plant's own contact force
    k(t) z1 (an independent reference: the plant's line, not the head's equation) to within what
    the backward difference of the deflection costs (b1 times the O(dt) error of the velocity at the
    square wave's steps: 2.0 N RMS for a force of 45 N sigma when this was written). Without the
    accelerometer term (F_raw = k1 dz + b1 dz') the error is the head's inertia, m1 z1'', 21 N."""
    from pac_rig.closed_loop import build_cores, run_cores
    from pac_rig.simulate import scenario_from_flat

    s = scenario_from_flat({**SQUARE, "duration": 4.0, "roof_motion": "german_high", "sensors": "train"})
    plant, observer, controller = build_cores(s)
    assert isinstance(observer, HeadBalanceObserver)
    _exact_sensors(plant, s.loop.sample_period)
    records = list(run_cores(s, plant, observer, controller))
    settled = slice(int(2.0 / s.loop.sample_period), None)  # the mean has taken its window (2 s)
    force = np.array([r.truth.contact_force for r in records])[settled]
    estimate = np.array([r.estimate.contact_force_hat for r in records])[settled]
    inertia = s.pantograph.m1 * np.array([r.measurement.head_acceleration for r in records])[settled]
    error = estimate - force
    assert np.std(force) > 20.0  # the square wave and the roof excite the head
    assert np.sqrt(np.mean(error**2)) < 0.1 * np.std(force)
    assert np.sqrt(np.mean(error**2)) < 0.2 * np.std(inertia)  # the accelerometer's term matters


@pytest.mark.offline
@pytest.mark.parametrize("catenary_model", ["lumped", "fe"])
def test_the_compiled_loop_runs_the_head_balance_as_the_core_objects(catenary_model):
    """A train's noisy sensors, the roof moving: the compiled loop and the core objects stepped tick
    by tick give the same estimates and commands bit for bit (the FE line with the 3-mass plant)."""
    from pac_rig.closed_loop import build_cores, run, run_cores
    from pac_rig.simulate import scenario_from_flat

    values = {**SQUARE, "duration": 1.0, "roof_motion": "german_low", "sensors": "train"}
    if catenary_model == "fe":
        values.update(catenary_model="fe", pantograph="three_mass", duration=0.3)
        values["nominal_pantograph"] = "three_mass_identified_2dof"
    s = scenario_from_flat(values)
    compiled = list(run(s))
    stepped = list(run_cores(s, *build_cores(s)))
    assert len(compiled) == len(stepped) == s.loop.ticks
    for a, b in zip(compiled, stepped, strict=True):
        np.testing.assert_equal(dataclasses.astuple(a.estimate), dataclasses.astuple(b.estimate))
        np.testing.assert_equal(dataclasses.astuple(a.command), dataclasses.astuple(b.command))
    assert np.std([r.estimate.contact_force_hat for r in compiled]) > 1.0


@pytest.mark.unit
def test_the_estimate_starts_at_the_actuators_force_and_its_mean_follows_it():
    """First sample: F_hat = F_a (whatever the deflection's rest length). Then, the head at rest and
    the actuator's force stepped, the mean follows it: the plain mean of the samples at first,
    then over the window T (a first sample with F_a = 0 does not hold the mean off for T)."""
    core = HeadBalanceObserver(
        PantographParameters(), TrackParameters(), ObserverParameters(head_balance_window=2.0), 1e-3
    )
    assert core.update(0, (0.01, 0.02), 0.0, 0.0).contact_force_hat == pytest.approx(0.0, abs=1e-9)
    for tick in range(1, 101):
        est = core.update(tick, (0.01, 0.02), 100.0, 0.0)
    assert est.contact_force_hat == pytest.approx(100.0 * 100 / 101, rel=1e-9)  # the plain mean
    for tick in range(101, 10_001):
        est = core.update(tick, (0.01, 0.02), 100.0, 0.0)
    assert est.contact_force_hat == pytest.approx(100.0, abs=0.01)


@pytest.mark.unit
def test_at_rest_the_estimate_is_the_actuators_force_and_the_velocities_are_differences_over_a_gap():
    """The head at rest with a steady actuator force: F_hat = F_a at every sample (eq. (3) at rest:
    the contact force balances the applied one), whatever the deflection's rest length or b1. The
    first sample's velocities are 0; later ones are the positions' differences over the ticks
    between two samples (a missed sample widens the difference, it does not scale it)."""
    head = PantographParameters()
    core = HeadBalanceObserver(head, TrackParameters(), ObserverParameters(), 1e-3)
    y0 = (0.01, 0.025)
    first = core.update(0, y0, 120.0, 0.0)
    np.testing.assert_array_equal(first.z_hat, [*y0, 0.0, 0.0])
    np.testing.assert_array_equal(first.innovation, 0.0)  # no prediction, hence no innovation
    for tick in range(1, 50):
        est = core.update(tick, y0, 120.0, 0.0)
        assert est.contact_force_hat == pytest.approx(120.0, abs=1e-9)
    # Both moving (the roof-relative deflection steady), then three ticks with one sample.
    v1, v2 = 0.02, 0.05
    est = core.update(50, (y0[0] + v1 * 1e-3, y0[1] + v2 * 1e-3), 120.0, 0.0)
    np.testing.assert_allclose(est.z_hat[2:], [v1, v2], rtol=1e-9)
    est = core.update(53, (y0[0] + v1 * 4e-3, y0[1] + v2 * 4e-3), 120.0, 0.0)
    np.testing.assert_allclose(est.z_hat[2:], [v1, v2], rtol=1e-9)


@pytest.mark.unit
def test_past_its_first_window_the_mean_follows_the_actuator_exponentially_over_it():
    """C_k = C_{k-1} + w (F_a - F_raw - C_{k-1}) with w = 1 - exp(-dt/T) once the plain mean's
    weight 1/(k + 1) is below it: after a step of F_a from 100 to 200 N (the head at rest), F_hat
    = 200 - 100 exp(-k dt / T) at the k-th sample after it (the module docstring's filter, solved)."""
    window, dt = 0.05, 1e-3
    core = HeadBalanceObserver(
        PantographParameters(), TrackParameters(), ObserverParameters(head_balance_window=window), dt
    )
    for tick in range(200):  # past the plain mean's 50 samples: C is F_a - F_raw
        core.update(tick, (0.01, 0.02), 100.0, 0.0)
    for k in range(1, 101):
        est = core.update(199 + k, (0.01, 0.02), 200.0, 0.0)
        if k in (1, 10, 100):
            assert est.contact_force_hat == pytest.approx(
                200.0 - 100.0 * math.exp(-k * dt / window), rel=1e-9
            )


@pytest.mark.unit
def test_a_non_finite_actuator_force_never_enters_the_mean():
    """A NaN actuator force (a load cell's dropout) is refused and leaves the state as it was: the
    next sample's estimate is the one the run without it gives."""
    cores = [HeadBalanceObserver(PantographParameters(), TrackParameters(), ObserverParameters(), 1e-3)]
    cores.append(HeadBalanceObserver(PantographParameters(), TrackParameters(), ObserverParameters(), 1e-3))
    for core in cores:
        for tick in range(20):
            core.update(tick, (0.01, 0.02 + 1e-5 * tick), 100.0 + tick, 0.1)
    before = cores[0].state.copy()
    with pytest.raises(ObserverDivergedError):
        cores[0].update(20, (0.01, 0.0202), math.nan, 0.1)
    np.testing.assert_array_equal(cores[0].state, before)
    after, without = (core.update(21, (0.01, 0.0203), 130.0, 0.1) for core in cores)
    assert after.contact_force_hat == without.contact_force_hat  # one machine, same operations
    np.testing.assert_array_equal(after.z_hat, without.z_hat)


@pytest.mark.unit
def test_a_missing_accelerometer_reading_never_becomes_an_estimate():
    """A NaN acceleration raises ObserverDivergedError and leaves the state as it was."""
    core = HeadBalanceObserver(PantographParameters(), TrackParameters(), ObserverParameters(), 1e-3)
    with pytest.raises(ObserverDivergedError):
        core.update(0, (0.0, 0.0), 100.0, math.nan)
    assert core.tick == -1
    core.update(0, (0.0, 0.0), 100.0, 0.0)
    before = core.state.copy()
    with pytest.raises(ObserverDivergedError):
        core.update(1, (0.0, 0.0), 100.0, math.nan)
    np.testing.assert_array_equal(core.state, before)


@pytest.mark.unit
def test_a_law_on_the_force_estimate_runs_on_the_head_balance_where_the_head_has_an_accelerometer():
    values, notes = composition.derive({"law": "line_adaptive", "sensors": "train"})
    assert values["observer"] == "head_balance" and "head accelerometer" in notes[0]
    values, _ = composition.derive({"law": "line_adaptive"})
    assert values["observer"] == "contact_force"  # the ground's sensing: as before
    composition.check_pair("line_adaptive", "head_balance", None, "train_load_cell")
    with pytest.raises(CompositionError) as info:
        composition.check_pair("line_adaptive", "head_balance", None, "ground")
    assert "sensors 'ground'" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.offline
@pytest.mark.slow
def test_simulate_refuses_the_head_balance_without_a_head_accelerometer_in_one_line(tmp_path):
    line = simulate_refusal(tmp_path / "bag", "law:=line_adaptive", "observer:=head_balance")
    assert "observer 'head_balance' reads a head accelerometer" in line


@pytest.mark.unit
def test_the_head_balance_warms_up_as_a_node_does_before_its_first_sample():
    """The node loads the compiled step on a copy before the loop (warm_up): it must not raise (it
    did: the copy was fed no head acceleration, and the live observer stopped before tick 0), and
    the observer itself stays untouched."""
    core = HeadBalanceObserver(PantographParameters(), TrackParameters(), ObserverParameters(), 1e-3)
    core.warm_up()
    assert core.tick == -1
