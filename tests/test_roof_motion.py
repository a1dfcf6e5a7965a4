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
from pac_model.pantograph_file import Table1Values
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_plant.hardware.car_body import roof_force
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Plant

pytestmark = pytest.mark.unit

SPEED_KMH = 300.0
PERIOD = 1e-3


def _plant(pantograph: PantographParameters | None = None, **options: object) -> Plant:
    """The lumped plant on a line of constant stiffness (alpha = 0: an LTI system, so what an extra
    force adds to the response is lsim's), linear contact, with ``options``."""
    return Plant(
        pantograph or PantographParameters(),
        TrackParameters(speed_kmh=SPEED_KMH),
        CatenaryParameters(alpha=0.0),
        PlantOptions(**options),  # type: ignore[arg-type]
        PERIOD,
    )


def _added_response(
    ticks: int, pantograph: PantographParameters | None = None, **options: object
) -> tuple[Plant, np.ndarray, np.ndarray]:
    """(the plant with ``options``, the heights it gives minus those of the plant without them under
    the same commands (zero: the model is linear), and its roof heights), ticks 0 .. ticks - 1."""
    moving, fixed = _plant(pantograph, **options), _plant(pantograph)
    z_on, z_off, roof = np.empty((ticks, 4)), np.empty((ticks, 4)), np.empty(ticks)
    for k in range(ticks):
        z_on[k], z_off[k], roof[k] = moving.z, fixed.z, moving.truth().roof_height
        moving.advance(0.0)
        fixed.advance(0.0)
    return moving, z_on - z_off, roof


def _frame_force_response(p: Table1Values, force: np.ndarray, t: np.ndarray) -> np.ndarray:
    """scipy.signal.lsim of the 2-DOF of ``p`` on the wire's spring k0, from rest, driven by the
    force ``force`` [N] on the frame at the times ``t``."""
    k0 = CatenaryParameters().k0
    m1, b1, k1, m2, b2 = p["m1"], p["b1"], p["k1"], p["m2"], p["b2"]
    a = np.array(
        [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-(k1 + k0) / m1, k1 / m1, -b1 / m1, b1 / m1],  # the wire's spring k0 on the head
            [k1 / m2, -k1 / m2, b1 / m2, -(b1 + b2) / m2],
        ]
    )
    b = np.array([[0.0], [0.0], [0.0], [1.0 / m2]])
    _, _, x = signal.lsim((a, b, np.eye(4), np.zeros((4, 1))), force, t, X0=np.zeros(4))
    return x


def _assert_close_to(got: np.ndarray, want: np.ndarray, highest: float) -> None:
    """got = want to (omega h)^2 / 12 of each state's largest value, omega = 2 pi ``highest`` [Hz]
    (the input's highest frequency): the plant holds each tick's mean force (the exact impulse),
    lsim interpolates the input linearly, and the two differ by O((omega h)^2) there."""
    bound = (2 * math.pi * highest * PERIOD) ** 2 / 12
    for i in range(4):
        scale = np.max(np.abs(want[:, i]))
        assert np.max(np.abs(got[:, i] - want[:, i])) < bound * scale, i


def test_the_pantograph_rides_on_the_roof_as_the_base_excited_model_says():
    """z with the roof moving minus z on a fixed base equals lsim of the 2-DOF whose frame damper
    b2 goes to the roof: m2 z2'' gains b2 z_roof', from rest.

    The roof enters only through that damper (the paper's 2-DOF has no roof spring), so a roof
    ignored, a damper to the ground, or the roof's sign flipped each fail."""
    ticks = 8000
    moving, got, roof = _added_response(ticks, roof_motion="german_high", roof_seed=3)
    fine = np.arange(ticks * 10) * (PERIOD / 10)
    assert moving.roof is not None
    height, velocity, _ = moving.roof.series(fine)
    p = dataclasses.asdict(PantographParameters())
    want = _frame_force_response(p, p["b2"] * velocity, fine)[::10]  # type: ignore[arg-type]
    np.testing.assert_allclose(roof, height[::10], rtol=0, atol=1e-15)  # the truth's roof field
    # The roof moved millimetres and the pantograph answered (not a vacuous comparison) ...
    assert np.ptp(roof) > 5e-3 and np.max(np.abs(want[:, 1])) > 1e-5
    # ... as lsim says (measured 1.5e-5 of the peak; the car body passes little above 5 Hz)
    _assert_close_to(got, want, 5.0)


@pytest.mark.parametrize(("stiffness", "damping"), [(0.0, 30.0), (160.0, 100.0), (5000.0, 0.0)])
def test_the_roof_force_is_its_mean_over_the_tick(stiffness, damping):
    """roof_force = (1/h) integral of k z_roof + c z_roof' over the tick, by quadrature of the
    roof's own height and velocity: a sample instead of the mean, or k and c swapped, fail."""
    plant = _plant(roof_motion="german_low")
    roof = plant.roof
    assert roof is not None
    for t0 in (0.0, 0.4137, 7.25):
        t1 = t0 + 0.01
        want = integrate.quad(lambda t: stiffness * roof.at(t)[0] + damping * roof.at(t)[1], t0, t1, epsabs=0)
        got = roof_force(roof.amplitude, roof.frequency, roof.phase, stiffness, damping, t0, t1)
        assert got == pytest.approx(want[0] / (t1 - t0), rel=1e-9, abs=1e-12)


def test_a_fixed_base_has_no_roof():
    """The default: no roof motion, roof_height 0, the plant's force is the command and uplift."""
    plant = _plant()
    assert plant.roof is None and plant.truth().roof_height == 0.0
    assert plant._with_roof(12.5) == 12.5


#: Two benchmark-like 3-mass pantographs 200 m apart on the FE line's endless window at 300 km/h.
PAIR = {
    "catenary_model": "fe",
    "speed_kmh": SPEED_KMH,
    "pantograph": "three_mass",
    "passive_pantograph": "three_mass",
    "pantographs": (0.0, 200.0),
    "duration": 1.0,
}


def _pair_forces(ticks: int, **values: object) -> np.ndarray:
    """Each pantograph's contact force (ticks x 2, in the order of ``pantographs``) of the FE plant
    of PAIR with ``values``, the controlled one pressed by its own uplift through the ideal
    actuator: the force each passive one gets, so that which one is controlled changes nothing of
    the physics."""
    from pac_rig.closed_loop import build_cores
    from pac_rig.simulate import scenario_from_flat

    plant = build_cores(scenario_from_flat({**PAIR, **values}))[0]
    forces = np.empty((ticks, 2))
    for k in range(ticks):
        forces[k] = [p.contact_force for p in plant.pantograph_truths()]  # type: ignore[attr-defined]
        plant.advance(plant.own_uplift)
    return forces


@pytest.mark.offline
def test_each_pantograph_of_a_train_rides_on_the_roof_at_its_own_place():
    """Every car of the train runs over the same track: the pantograph 200 m behind rides on the
    roof motion the first one had 200 m earlier, whether it is the rig's controlled one or a passive
    one. Two runs of the same train, the first pantograph controlled in one and the second in the
    other, give each pantograph the same force to rounding (the DOFs are stacked in another order);
    a passive pantograph on a fixed roof, or on the controlled one's roof, fails by newtons."""
    ticks = 1000
    first = _pair_forces(ticks, roof_motion="german_high", roof_seed=2, controlled_pantograph=0)
    second = _pair_forces(ticks, roof_motion="german_high", roof_seed=2, controlled_pantograph=1)
    fixed = _pair_forces(ticks, controlled_pantograph=0)
    scale = np.max(np.abs(first))
    np.testing.assert_allclose(second, first, rtol=0, atol=1e-9 * scale)
    # The roof is felt by both (not a vacuous comparison): newtons on each pantograph.
    assert np.all(np.max(np.abs(first - fixed), axis=0) > 1.0)


@pytest.mark.offline
def test_the_compiled_loop_moves_the_roof_under_the_passive_pantographs(tmp_path):
    """simulate's compiled loop and the core objects stepped tick by tick (``compiled=False``) write
    the same bag, byte for byte, on a train of two pantographs with the roof moving: the loop gives
    the passive one its roof force as FEPlant.advance does."""
    from test_loop import messages_of

    from pac_rig.simulate import scenario_from_flat, simulate_to_bag

    s = scenario_from_flat({**PAIR, "duration": 0.3, "roof_motion": "german_high", "law": "passive"})
    fast = simulate_to_bag(s, tmp_path / "fast")
    slow = simulate_to_bag(s, tmp_path / "slow", compiled=False)
    assert (fast.ticks, fast.diverged) == (slow.ticks, slow.diverged) == (300, None)
    got, want = messages_of(tmp_path / "fast"), messages_of(tmp_path / "slow")
    assert sum(topic == "/pantograph_truth" for topic, _, _ in got) == fast.ticks
    assert got == want


@pytest.mark.offline
@pytest.mark.parametrize(
    "values",
    [
        {"duration": 2.0, "shape": "square", "period": 0.4, "roof_motion": "german_high"},
        {"duration": 0.3, "catenary_model": "fe", "pantograph": "three_mass", "roof_motion": "german_low"},
        {"duration": 1.0, "nominal_pantograph": "three_mass_identified_2dof", "aero_turbulence": 0.1},
        {
            "duration": 0.5,
            "catenary_model": "fe",
            "pantograph": "three_mass",
            "roof_motion": "german_low",
            "aero_turbulence": 0.08,
        },
    ],
    ids=["lumped", "fe", "turbulence", "fe_roof_and_turbulence"],
)
def test_the_compiled_loop_rides_on_the_roof_as_the_core_objects(values):
    """A closed-loop run with the roof moving (or the turbulent uplift on, or both, as the realistic
    scenario has them): the compiled loop and the core objects stepped tick by tick give the same
    ticks bit for bit, and the roof under the pantograph is the car body model's."""
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
    if roof is None:  # the turbulence alone
        assert plant.gusts is not None and all(r.truth.roof_height == 0.0 for r in compiled)
        return
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
    plant = _plant(roof_motion="german_low")
    m = plant.measurement()
    assert plant.sensors is None and not m.from_roof
    assert (m.z1, m.z2) == (float(plant.z[0]), float(plant.z[1]))
    assert all(math.isnan(v) for v in (m.head_acceleration, m.frame_acceleration, m.head_force))


def test_the_turbulent_uplift_has_its_stated_rms_and_band():
    """The drawn fluctuation: RMS = aero_turbulence x the mean uplift (the cosines' sum of A^2 / 2,
    and over 10 minutes of the series), its power inside 0.5-20 Hz and flat there
    (scipy.signal.welch against S = sigma^2 / 19.5 Hz)."""
    from pac_plant.hardware.turbulence import BAND, gusts

    sigma = 0.08 * 157.3
    wind = gusts(sigma, 4)
    assert math.sqrt(np.sum(wind.amplitude**2) / 2) == pytest.approx(sigma, rel=1e-12)
    rate = 200.0
    t = np.arange(int(600 * rate)) / rate
    force = wind.series(t)[0]
    assert np.std(force) == pytest.approx(sigma, rel=0.02)
    f, psd = signal.welch(force, fs=rate, nperseg=int(40 * rate))
    inside = (f > 1.0) & (f < 19.0)
    level = sigma**2 / (BAND[1] - BAND[0])
    assert np.mean(psd[inside]) == pytest.approx(level, rel=0.05)
    assert np.all(np.abs(np.convolve(psd[inside], np.ones(40) / 40, "valid") / level - 1.0) < 0.3)
    assert np.max(psd[(f > 25.0)]) < 1e-3 * level and np.max(psd[f < 0.3]) < 0.1 * level


def test_the_turbulent_uplift_acts_on_the_frame():
    """z with the turbulence minus z without it equals lsim of the 2-DOF driven by the drawn force
    on the frame (the actuator's mass); a pantograph with no uplift of its own is refused in one
    line."""
    ticks = 4000
    from pac_plant.hardware.turbulence import BAND

    nominal = PantographParameters(nominal_pantograph="three_mass_identified_2dof")
    moving, got, _ = _added_response(ticks, nominal, aero_turbulence=0.08, aero_turbulence_seed=4)
    assert moving.gusts is not None and moving.own_uplift > 100.0
    fine = np.arange(ticks * 10) * (PERIOD / 10)
    want = _frame_force_response(dataclasses.asdict(moving.pantograph), moving.gusts.series(fine)[0], fine)[
        ::10
    ]  # type: ignore[arg-type]
    assert np.max(np.abs(want[:, 0])) > 1e-4
    _assert_close_to(got, want, BAND[1])  # measured 1.2e-4 of the peak against a bound of 1.3e-3
    with pytest.raises(ParameterError, match="invalid parameter 'aero_turbulence' = 0.08"):
        _plant(aero_turbulence=0.08)
