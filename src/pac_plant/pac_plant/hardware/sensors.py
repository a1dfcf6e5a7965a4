"""Sensors as on a train: what the observer gets from the plant's truth (docs/vehicle_and_hardware.md,
"The sensors").

On a train the pantograph's base rides on the roof, and what is measured is measured from there:
frame and head positions *relative to the roof* (a laser or draw-wire sensor from the roof to
the frame, the head's travel against the frame), head and frame accelerometers (inertial: they
read absolute acceleration, the roof's included), and optionally a load cell under the head's
collector strip, which reads the contact force plus the inertia of the strip above it,
F_cell = F + m_s z1'' (what RTRI corrects with head accelerometers). Everything on the pantograph
sits at line voltage, so its signals reach the train through fibre links: latency.

Each channel has noise (a standard deviation, added last), a bandwidth (a first-order low-pass
f_c) and a latency L (whole ticks). Per tick k, for the true quantity x_k:

    y_k = a y_(k-1) + (1 - a) x_k,   a = exp(-2 pi f_c h)     (the low-pass; y_0 = x_0)
    m_k = y_(k-L) + sigma n_k                                  (y_j = y_0 for j < 0)

The low-pass is the exact response of 1 / (s / (2 pi f_c) + 1) to x held over (t_(k-1), t_k]
(``tests/test_sensors.py`` checks it against scipy.signal). ``ground`` is today's sensing: z1, z2
from a fixed datum on the ground, noise and quantisation as ``noise_std`` and ``quantisation``
say (the plant does that; this core is not called).

Suites are entries of :data:`SENSORS` (name -> :class:`SensorSuite`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common.parameters import ParameterError

#: Channels, in the order of the compiled records and of :func:`sensor_step`'s output.
HEAD_POSITION, FRAME_POSITION, HEAD_ACCELERATION, FRAME_ACCELERATION, HEAD_FORCE = range(5)
CHANNELS = ("head_position", "frame_position", "head_acceleration", "frame_acceleration", "head_force")
#: Most ticks of latency a channel holds (64 ms at the default 1 kHz).
MAX_LATENCY_TICKS = 64


@dataclass(frozen=True)
class Channel:
    """One sensor: noise standard deviation (its unit: m, m/s^2 or N), bandwidth f_c [Hz] (inf: no
    low-pass) and latency [s] (rounded to whole ticks)."""

    noise: float
    bandwidth: float
    latency: float


@dataclass(frozen=True)
class SensorSuite:
    """What a pantograph carries: positions from the ``datum`` ('ground' or 'roof'), and each
    channel (None: not fitted)."""

    name: str
    datum: str
    head_position: Channel | None
    frame_position: Channel | None
    head_acceleration: Channel | None
    frame_acceleration: Channel | None
    head_force: Channel | None
    #: m_s: the collector strip above the load cell [kg] (its inertia is in what the cell reads).
    strip_mass: float
    sources: str

    def channels(self) -> tuple[Channel | None, ...]:
        return tuple(getattr(self, name) for name in CHANNELS)


#: Fibre-linked position sensors (frame and head travel).
_POSITION = Channel(0.1e-3, 200.0, 0.002)
#: Head and frame accelerometers.
_ACCELEROMETER = Channel(0.05, 50.0, 0.002)
#: A fibre-Bragg-grating load cell under the collector strip.
_LOAD_CELL = Channel(2.0, 20.0, 0.003)

_TRAIN_SOURCES = (
    "positions relative to the roof, 0.1 mm noise, 200 Hz, 2 ms: judgement (a laser or draw-wire "
    "sensor resolves 0.1 mm; the fibre link's 'a few ms' of docs/catenary_data.md section 9); "
    "accelerometers 0.05 m/s^2 noise, 50 Hz, 2 ms: judgement, 50 Hz the band RTRI reaches with "
    "several head accelerometers (section 9); "
)

#: Sensor suites by name (the ``sensors`` parameter).
SENSORS: dict[str, SensorSuite] = {
    "ground": SensorSuite(
        "ground",
        "ground",
        None,
        None,
        None,
        None,
        None,
        0.0,
        "today's rig: z1, z2 from a fixed datum on the ground (noise_std, quantisation)",
    ),
    "train": SensorSuite(
        "train",
        "roof",
        _POSITION,
        _POSITION,
        _ACCELEROMETER,
        _ACCELEROMETER,
        None,
        0.0,
        _TRAIN_SOURCES + "no load cell",
    ),
    "train_load_cell": SensorSuite(
        "train_load_cell",
        "roof",
        _POSITION,
        _POSITION,
        _ACCELEROMETER,
        _ACCELEROMETER,
        _LOAD_CELL,
        1.0,
        _TRAIN_SOURCES + "a fibre-Bragg-grating load cell, 2 N noise (the 2-5 N resolution of "
        "section 9, its fine end), 20 Hz (RTRI's accelerometer correction holds to ~20 Hz with "
        "one accelerometer), 3 ms; the strip above it 1 kg: judgement (a carbon strip with its "
        "horn-to-horn carrier weighs a few kg, about half of it per cell)",
    ),
}

SENSOR_PARAMS = np.dtype(
    [
        ("roof_datum", "b1"),
        ("fitted", "i8", 5),  # 1: fitted (numba takes no arrays of bool in a record)
        ("noise", "f8", 5),
        ("pole", "f8", 5),  # a = exp(-2 pi f_c h); 0: no low-pass
        ("latency", "i8", 5),  # ticks
        ("strip_mass", "f8"),
    ]
)

SENSOR_STATE = np.dtype(
    [
        ("started", "b1"),
        ("filtered", "f8", 5),  # y_k
        ("ring", "f8", (5, MAX_LATENCY_TICKS + 1)),  # y_k .. y_(k-L), y_k at ``head``
        ("head", "i8"),
    ]
)


def sensor_suite(name: str) -> SensorSuite:
    """The suite ``name`` of :data:`SENSORS`; a ParameterError (one line) for another name."""
    suite = SENSORS.get(name)
    if suite is None:
        raise ParameterError("sensors", name, "one of " + ", ".join(SENSORS))
    return suite


def sensor_records(suite: SensorSuite, sample_period: float) -> tuple[np.ndarray, np.ndarray]:
    """The parameter and state records (1-element arrays) of ``suite`` at ``sample_period``."""
    params = np.zeros(1, SENSOR_PARAMS)
    p = params[0]
    p["roof_datum"], p["strip_mass"] = suite.datum == "roof", suite.strip_mass
    for i, channel in enumerate(suite.channels()):
        if channel is None:
            continue
        ticks = int(round(channel.latency / sample_period))
        if ticks > MAX_LATENCY_TICKS:
            raise ParameterError(
                "sensors", suite.name, f"a latency of at most {MAX_LATENCY_TICKS} sample periods"
            )
        p["fitted"][i], p["noise"][i], p["latency"][i] = 1, channel.noise, ticks
        p["pole"][i] = math.exp(-2 * math.pi * channel.bandwidth * sample_period)
    return params, np.zeros(1, SENSOR_STATE)


@njit(cache=True, error_model="numpy")
def sensor_step(p, s, z1, z2, a1, a2, roof, force, noise, out) -> None:
    """One tick's readings into ``out[:5]`` (NaN for a channel not fitted): head and frame heights
    z1, z2 and accelerations a1, a2 from the ground [m, m/s^2], the roof's height ``roof`` [m], the
    contact force [N], and this tick's standard normal ``noise[:5]``."""
    datum = roof if p.roof_datum else 0.0
    true = (z1 - datum, z2 - datum, a1, a2, force + p.strip_mass * a1)
    width = s.ring.shape[1]
    s.head = (s.head + 1) % width
    for i in range(5):
        if not p.fitted[i]:
            out[i] = np.nan
            continue
        x = true[i]
        y = x if not s.started else p.pole[i] * s.filtered[i] + (1.0 - p.pole[i]) * x
        s.filtered[i] = y
        if not s.started:  # at rest before the first sample: every older reading is this one
            s.ring[i, :] = y
        s.ring[i, s.head] = y
        out[i] = s.ring[i, (s.head - p.latency[i]) % width] + p.noise[i] * noise[i]
    s.started = True


@njit(cache=True, error_model="numpy")
def sensor_series(params, state, z1, z2, a1, a2, roof, force, noise, out) -> None:
    """:func:`sensor_step` over ticks 0 .. len(z1) - 1 (1-element record arrays; ``noise`` and
    ``out`` one row per tick)."""
    p, s = params[0], state[0]
    for k in range(z1.shape[0]):
        sensor_step(p, s, z1[k], z2[k], a1[k], a2[k], roof[k], force[k], noise[k], out[k])


def sensor_noise(seed: int, ticks: int, block: int = 0) -> np.ndarray:
    """Standard normal noise of ticks ``block`` x ticks .. (``block`` + 1) x ticks - 1, one row of 5
    channels each: a pure function of (seed, block). The plant draws it a block of ticks at a time
    (one generator per block: seeding one per tick cost ~0.1 ms a tick, more than a tick of the
    compiled loop)."""
    return np.random.default_rng([seed, 0x5E5, block]).standard_normal((ticks, 5))


class Sensors:
    """One pantograph's sensor suite: its records and the compiled step."""

    def __init__(self, suite: SensorSuite, sample_period: float) -> None:
        self.suite = suite
        self.params, self.state = sensor_records(suite, sample_period)

    def series(self, z1, z2, a1, a2, roof, force, noise) -> np.ndarray:
        """(ticks, 5): the readings of consecutive ticks (continuing from the present state)."""
        arrays = [np.ascontiguousarray(x, dtype=np.float64) for x in (z1, z2, a1, a2, roof, force)]
        out = np.empty((arrays[0].size, 5))
        sensor_series(self.params, self.state, *arrays, np.ascontiguousarray(noise, dtype=np.float64), out)
        return out
