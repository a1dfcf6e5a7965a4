"""Sensors as on a train (pac_plant.hardware.sensors): positions relative to the roof are the truth
minus the roof's motion, each channel's low-pass is the continuous filter (scipy.signal), its
latency whole ticks, its noise the stated standard deviation; the load cell reads the strip's
inertia with the force."""

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from pac_plant.hardware.car_body import CAR_BODIES, TRACKS, roof_motion
from pac_plant.hardware.sensors import (
    CHANNELS,
    FRAME_POSITION,
    HEAD_ACCELERATION,
    HEAD_FORCE,
    HEAD_POSITION,
    SENSORS,
    Channel,
    Sensors,
    sensor_noise,
    sensor_suite,
)

pytestmark = pytest.mark.unit

DT = 1e-3
T = np.arange(2000) * DT
V = 300 / 3.6


def a_run():
    """A pantograph on a moving roof: the roof of the car body model at 300 km/h, the frame riding
    on it and the head on the frame (heights from the ground), with their accelerations and a
    contact force."""
    roof, _, roof_acc = roof_motion(
        TRACKS["german_high"], CAR_BODIES["high_speed_trailer"], V, seed=2
    ).series(T)
    w1, w2 = 2 * math.pi * 3.7, 2 * math.pi * 11.0
    z2 = roof + 0.02 * np.sin(w1 * T)
    z1 = z2 + 0.005 * np.sin(w2 * T + 0.3)
    a2 = roof_acc - 0.02 * w1**2 * np.sin(w1 * T)
    a1 = a2 - 0.005 * w2**2 * np.sin(w2 * T + 0.3)
    force = 120.0 + 30.0 * np.sin(2 * math.pi * 5.5 * T)
    return z1, z2, a1, a2, roof, force


def clean(suite, **changes):
    """``suite`` with every fitted channel changed as ``changes`` say (noise, bandwidth, latency)."""
    return dataclasses.replace(
        suite,
        **{n: dataclasses.replace(c, **changes) for n in CHANNELS if (c := getattr(suite, n)) is not None},
    )


def read(suite, run, noise=None):
    return Sensors(suite, DT).series(*run, np.zeros((T.size, 5)) if noise is None else noise)


def test_positions_are_measured_from_the_roof():
    """Ideal channels (no noise, no low-pass, no latency): the head and frame readings are the heights
    from the ground minus the roof's height, the accelerometers the absolute accelerations."""
    run = a_run()
    z1, z2, a1, a2, roof, force = run
    assert np.sqrt(np.mean(roof**2)) > 1e-3  # the roof moves by millimetres: a test of something
    out = read(clean(SENSORS["train"], noise=0.0, bandwidth=math.inf, latency=0.0), run)
    np.testing.assert_allclose(out[:, HEAD_POSITION], z1 - roof, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out[:, FRAME_POSITION], z2 - roof, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(out[:, HEAD_ACCELERATION], a1)
    assert np.all(np.isnan(out[:, HEAD_FORCE]))  # no load cell in this suite
    # The ground datum (today's sensing) sees the heights themselves.
    ground = dataclasses.replace(SENSORS["train"], datum="ground")
    out = read(clean(ground, noise=0.0, bandwidth=math.inf, latency=0.0), run)
    np.testing.assert_array_equal(out[:, HEAD_POSITION], z1)


def test_a_channel_is_the_continuous_low_pass_and_its_latency():
    """With the suite's bandwidth and latency (noise off), each position reading is the continuous
    first-order low-pass 1 / (s / 2 pi f_c + 1) of (height - roof), run by scipy.signal.lsim over the
    input held over each tick, delayed by the latency in whole ticks."""
    suite = clean(SENSORS["train_load_cell"], noise=0.0)
    run = a_run()
    z1, _, a1, _, roof, force = run
    out = read(suite, run)
    for index, true in ((HEAD_POSITION, z1 - roof), (HEAD_FORCE, force + suite.strip_mass * a1)):
        channel = suite.channels()[index]
        pole = 2 * math.pi * channel.bandwidth
        # lsim holds u[i] over [t_i, t_i+1): the reading at tick k holds x_k over (t_k-1, t_k].
        lag_filter = signal.StateSpace([[-pole]], [[pole]], [[1.0]], [[0.0]])  # y = x: X0 is y(0)
        _, y, _ = signal.lsim(lag_filter, np.append(true[1:], true[-1]), T, X0=[true[0]], interp=False)
        lag = round(channel.latency / DT)
        expected = np.concatenate([np.full(lag, y[0]), y[: T.size - lag]])
        np.testing.assert_allclose(out[:, index], expected, rtol=1e-9, atol=1e-12)


def test_noise_has_the_stated_deviation():
    """Ideal channels but the noise: reading - truth has the suite's standard deviation per channel."""
    suite = clean(SENSORS["train_load_cell"], bandwidth=math.inf, latency=0.0)
    run = a_run()
    z1, _, a1, _, roof, force = run
    out = read(suite, run, sensor_noise(4, T.size))
    for index, true in (
        (HEAD_POSITION, z1 - roof),
        (HEAD_ACCELERATION, a1),
        (HEAD_FORCE, force + suite.strip_mass * a1),
    ):
        assert np.std(out[:, index] - true) == pytest.approx(suite.channels()[index].noise, rel=0.05)
    assert np.array_equal(sensor_noise(4, 10), sensor_noise(4, 10))


def test_the_plants_suite_noise_is_a_pure_function_of_seed_and_tick():
    """The rows the plant adds (``Plant.noise_rows``, the compiled loop's) are the same numbers
    whatever the order they are asked in, across a block's end, and what ``sensor_noise`` draws for
    that block: tick k's row depends on (noise_seed, k) only."""
    from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
    from pac_plant.parameters import PlantOptions
    from pac_plant.plant import Plant

    def plant():
        options = PlantOptions(sensors="train", noise_seed=9)
        return Plant(PantographParameters(), TrackParameters(), CatenaryParameters(), options, DT)

    block = Plant._NOISE_BLOCK
    late = plant().noise_rows(2 * block - 3, 2 * block + 3)  # across the second block's end first
    early = plant().noise_rows(0, 2 * block + 3)
    np.testing.assert_array_equal(late, early[2 * block - 3 :])
    want = np.concatenate([sensor_noise(9, block, 1), sensor_noise(9, block, 2)[:3]])
    np.testing.assert_array_equal(early[block:], want)
    assert late.shape == (6, len(CHANNELS))


def test_suites_and_one_line_errors():
    assert SENSORS["ground"].datum == "ground" and all(c is None for c in SENSORS["ground"].channels())
    assert isinstance(SENSORS["train"].head_position, Channel)
    with pytest.raises(ValueError, match="invalid parameter 'sensors' = 'lidar': allowed one of ground"):
        sensor_suite("lidar")
