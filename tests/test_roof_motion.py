"""The car body moves, in the plant: the pantograph's base rides on the roof (roof_motion).

The references are independent of the plant's integration: scipy.signal.lsim of the linear
base-excited pantograph, and scipy.integrate.quad of the roof's force. docs/vehicle_and_hardware.md,
"The car body in the plant".
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import integrate, signal

from pac_common.parameters import ParameterError
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_plant.hardware.car_body import roof_force
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Plant

pytestmark = pytest.mark.unit

SPEED_KMH = 300.0
PERIOD = 1e-3


def _plant(roof: str) -> Plant:
    """The paper's lumped plant on a line of constant stiffness (alpha = 0: an LTI system, so the
    roof's part of the response is lsim's), linear contact, with or without the moving roof."""
    return Plant(
        PantographParameters(),
        TrackParameters(speed_kmh=SPEED_KMH),
        CatenaryParameters(alpha=0.0),
        PlantOptions(roof_motion=roof, roof_seed=3),
        PERIOD,
    )


def test_the_pantograph_rides_on_the_roof_as_the_base_excited_model_says():
    """z with the roof moving minus z on a fixed base (same commands: the model is linear) equals
    lsim of the 2-DOF with its frame damper b2 to the roof, m2 z2'' += b2 z_roof', from rest.

    The roof enters only through that damper (the paper's 2-DOF has no roof spring), so a roof
    ignored, a damper to the ground, or the roof's sign flipped each fail."""
    moving, fixed = _plant("german_high"), _plant("")
    ticks = 8000
    z_on, z_off, roof = np.empty((ticks, 4)), np.empty((ticks, 4)), np.empty(ticks)
    for k in range(ticks):
        z_on[k], z_off[k], roof[k] = moving.z, fixed.z, moving.truth().roof_height
        moving.advance(0.0)
        fixed.advance(0.0)
    p, k0 = PantographParameters(), CatenaryParameters().k0
    a = np.array(
        [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-(p.k1 + k0) / p.m1, p.k1 / p.m1, -p.b1 / p.m1, p.b1 / p.m1],  # the wire's spring k0
            [p.k1 / p.m2, -p.k1 / p.m2, p.b1 / p.m2, -(p.b1 + p.b2) / p.m2],
        ]
    )
    b = np.array([[0.0], [0.0], [0.0], [p.b2 / p.m2]])  # input: the roof's velocity
    fine = np.arange(ticks * 10) * (PERIOD / 10)
    assert moving.roof is not None
    height, velocity, _ = moving.roof.series(fine)
    _, _, x = signal.lsim((a, b, np.eye(4), np.zeros((4, 1))), velocity, fine, X0=np.zeros(4))
    want = x[::10]
    got = z_on - z_off
    np.testing.assert_allclose(roof, height[::10], rtol=0, atol=1e-15)  # the truth's roof field
    # The roof moved millimetres and the pantograph answered (not a vacuous comparison) ...
    assert np.ptp(roof) > 5e-3 and np.max(np.abs(want[:, 1])) > 1e-5
    # ... as lsim says, to 0.01 % of the response's largest value (measured 1.5e-5: the tick's held
    # mean force and lsim's linear interpolation of the velocity differ by O((omega h)^2)).
    for i in range(4):
        scale = np.max(np.abs(want[:, i]))
        assert np.max(np.abs(got[:, i] - want[:, i])) < 1e-4 * scale, i


@pytest.mark.parametrize(("stiffness", "damping"), [(0.0, 30.0), (160.0, 100.0), (5000.0, 0.0)])
def test_the_roof_force_is_its_mean_over_the_tick(stiffness, damping):
    """roof_force = (1/h) integral of k z_roof + c z_roof' over the tick, by quadrature of the
    roof's own height and velocity: a sample instead of the mean, or k and c swapped, fail."""
    plant = _plant("german_low")
    roof = plant.roof
    assert roof is not None
    for t0 in (0.0, 0.4137, 7.25):
        t1 = t0 + 0.01
        want = integrate.quad(lambda t: stiffness * roof.at(t)[0] + damping * roof.at(t)[1], t0, t1, epsabs=0)
        got = roof_force(roof.amplitude, roof.frequency, roof.phase, stiffness, damping, t0, t1)
        assert got == pytest.approx(want[0] / (t1 - t0), rel=1e-9, abs=1e-12)


def test_a_fixed_base_has_no_roof():
    """The default: no roof motion, roof_height 0, the plant's force is the command and uplift."""
    plant = _plant("")
    assert plant.roof is None and plant.truth().roof_height == 0.0
    assert plant._with_roof(12.5) == 12.5


def test_roof_motion_with_several_pantographs_is_refused_in_one_line():
    with pytest.raises(ParameterError, match="invalid parameter 'roof_motion' = 'german_low'"):
        PlantOptions(catenary_model="fe", pantographs=(0.0, 200.0), roof_motion="german_low")


@pytest.mark.offline
@pytest.mark.parametrize(
    "values",
    [
        {"duration": 2.0, "shape": "square", "period": 0.4, "roof_motion": "german_high"},
        {"duration": 0.3, "catenary_model": "fe", "pantograph": "three_mass", "roof_motion": "german_low"},
    ],
    ids=["lumped", "fe"],
)
def test_the_compiled_loop_rides_on_the_roof_as_the_core_objects(values):
    """A closed-loop run with the roof moving: the compiled loop and the core objects stepped tick
    by tick give the same ticks bit for bit, and the roof under the pantograph is the car body
    model's."""
    from pac_rig.closed_loop import build_cores, run, run_cores
    from pac_rig.simulate import scenario_from_flat

    s = scenario_from_flat(values)
    compiled = list(run(s))
    plant, observer, controller = build_cores(s)
    roof = plant.roof
    stepped = list(run_cores(s, plant, observer, controller))
    assert len(compiled) == len(stepped) == s.loop.ticks
    for a, b in zip(compiled, stepped, strict=True):  # assert_equal: NaN (no FE line) equals NaN
        np.testing.assert_equal(dataclasses.astuple(a.truth), dataclasses.astuple(b.truth))
        np.testing.assert_equal(dataclasses.astuple(a.command), dataclasses.astuple(b.command))
    assert roof is not None
    times = np.array([r.truth.time for r in compiled])
    heights = np.array([r.truth.roof_height for r in compiled])
    np.testing.assert_allclose(heights, roof.series(times)[0], rtol=0, atol=1e-15)
    assert np.ptp(heights) > 1e-4


@pytest.mark.offline
def test_a_trains_sensors_measure_from_the_roof_in_a_closed_loop_run():
    """Sensors as on a train, in the plant: with the roof moving and a suite of ideal channels (no
    noise, no low-pass, no latency: what is left is the datum), every tick's z1, z2 equal the true
    heights minus the roof's height, and the accelerometers read the heights' second derivative
    (central differences of the true velocities, to O(h^2)). A roof not subtracted fails by
    millimetres."""
    from pac_plant.hardware.sensors import Channel, Sensors, SensorSuite
    from pac_rig.closed_loop import build_cores, run_cores
    from pac_rig.simulate import scenario_from_flat

    s = scenario_from_flat(
        {"duration": 2.0, "roof_motion": "german_high", "sensors": "train", "shape": "square", "period": 0.4}
    )
    plant, observer, controller = build_cores(s)
    exact = Channel(0.0, math.inf, 0.0)
    plant.sensors = Sensors(
        SensorSuite("exact", "roof", *([exact] * 5), 0.0, "a test's"), s.loop.sample_period
    )
    records = list(run_cores(s, plant, observer, controller))
    y = np.array([(r.measurement.z1, r.measurement.z2) for r in records])
    z = np.array([r.truth.z for r in records])
    roof = np.array([r.truth.roof_height for r in records])
    assert all(r.measurement.from_roof for r in records)
    np.testing.assert_array_equal(y, z[:, :2] - roof[:, None])
    assert np.ptp(roof) > 1e-3  # the roof moved millimetres: not subtracting it fails above
    accelerations = np.array(
        [(r.measurement.head_acceleration, r.measurement.frame_acceleration) for r in records]
    )
    central = (z[2:, 2:] - z[:-2, 2:]) / (2 * s.loop.sample_period)
    # Away from the square wave's steps (the force jumps there: no derivative to compare with).
    smooth = np.abs(np.diff([r.truth.u_applied for r in records]))[:-1] < 1e-6
    smooth &= np.abs(np.diff([r.truth.u_applied for r in records]))[1:] < 1e-6
    error = np.abs(accelerations[1:-1] - central)[smooth]
    assert np.max(error) < 1e-3 * np.max(np.abs(central[smooth])) + 1e-6


def test_the_ground_suite_measures_as_today():
    """sensors = ground (the default): z1, z2 from the ground, no accelerometer, no load cell."""
    plant = _plant("german_low")
    m = plant.measurement()
    assert plant.sensors is None and not m.from_roof
    assert (m.z1, m.z2) == (float(plant.z[0]), float(plant.z[1]))
    assert all(math.isnan(v) for v in (m.head_acceleration, m.frame_acceleration, m.head_force))
