"""The car body moves: the vertical roof motion under a pantograph, from track irregularity.

Model (docs/vehicle_and_hardware.md, "The car body"): a rigid car body in bounce z and pitch phi
(nose up positive) on two bogies at +-a from its centre, each through a secondary suspension
(stiffness k, damping c per bogie). The bogie frames follow the track: each bogie's height is the
mean of its two wheelsets' track heights (half wheelbase b; primary suspension and bogie mass
neglected, which overstates what passes above the car body's modes and is stated as a limit).
The track's vertical profile is a stationary random process with a one-sided spatial PSD
S(Omega) [m^2 / (rad/m)], drawn as a sum of cosines (the spectral representation, Shinozuka):

    z_t(s) = sum_i A_i cos(Omega_i s + psi_i),   A_i = sqrt(2 S(Omega_i) dOmega_i),

psi_i uniform, seeded. The car is linear, so its steady response to each cosine is the cosine times
the frequency response H(Omega) of the roof point x (from the centre, towards the front), and the
roof height, velocity and acceleration at any time are closed-form sums: no integration, no
start-up transient, any time at O(N) cost. At speed v the car centre is at s = v t - behind
(``behind``: how far behind the first pantograph's car), so two pantographs of one train see the
same track at their own positions and times.

Per bogie in the frequency domain, w_f,r = Z_t e^(+-i Omega a) cos(Omega b), and with
K = k + i omega c (omega = v Omega):

    (-m omega^2 + 2 K) Z       = K (w_f + w_r)
    (-J omega^2 + 2 a^2 K) Phi = a K (w_f - w_r)
    Z_roof = Z + x Phi

``roof_response`` writes that; ``tests/test_car_body.py`` checks it against the car body's
state-space model through scipy.signal and against a time-domain integration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from pac_common.parameters import ParameterError
from pac_model.pantograph_file import PantographFile

from .sincos import sin_cos, sin_of


@dataclass(frozen=True)
class TrackSpectrum:
    """S(Omega) = A Omega_c^2 / ((Omega^2 + Omega_r^2)(Omega^2 + Omega_c^2)) [m^2/(rad/m)], one-sided,
    drawn over wavelengths ``shortest`` .. ``longest`` [m]."""

    name: str
    roughness: float  # A [m rad]
    omega_c: float  # [rad/m]
    omega_r: float  # [rad/m]
    shortest: float  # [m]
    longest: float  # [m]
    sources: str

    def psd(self, omega: np.ndarray) -> np.ndarray:
        o2 = np.asarray(omega, dtype=float) ** 2
        return self.roughness * self.omega_c**2 / ((o2 + self.omega_r**2) * (o2 + self.omega_c**2))


@dataclass(frozen=True)
class CarBody:
    """A rigid car body in bounce and pitch on two bogies; where its pantograph sits on the roof."""

    name: str
    mass: float  # m [kg]
    pitch_inertia: float  # J [kg m^2]
    half_bogie_distance: float  # a [m]
    half_wheelbase: float  # b [m]
    stiffness: float  # k per bogie [N/m]
    damping: float  # c per bogie [N s/m]
    pantograph_position: float  # x from the centre, towards the front [m]
    sources: str


#: Track profiles by name.
TRACKS: dict[str, TrackSpectrum] = {
    "german_low": TrackSpectrum(
        "german_low",
        4.032e-7,
        0.8246,
        0.0206,
        1.0,
        300.0,
        "the German high-speed track spectrum, low-interference class (vertical profile), as widely "
        "reproduced in vehicle-track dynamics (e.g. Zhai, Vehicle-Track Coupled Dynamics; the "
        "primary DB report was not available here: unconfirmed); the band 1-300 m is judgement "
        "(300 m: the spectrum's own corner 2 pi / Omega_r; 1 m: far above the car body's modes at "
        "any speed here)",
    ),
    "german_high": TrackSpectrum(
        "german_high",
        1.080e-6,
        0.8246,
        0.0206,
        1.0,
        300.0,
        "the same spectrum, high-interference class (A = 1.080e-6 m rad), same sources and band",
    ),
}

#: Car bodies by name.
CAR_BODIES: dict[str, CarBody] = {
    "high_speed_trailer": CarBody(
        "high_speed_trailer",
        40_000.0,
        2.08e6,
        8.75,
        1.25,
        0.8e6,
        40e3,
        8.75,
        "judgement, from the orders of magnitude of a 25 m high-speed trailer car: 40 t, J = m L^2 / 12 "
        "for L = 25 m, bogie centres 17.5 m apart, wheelbase 2.5 m, two air springs of 0.4 MN/m and "
        "20 kN s/m per bogie; this gives bounce at 1.0 Hz and pitch at 1.2 Hz, damping ratios "
        "0.16 and 0.18: within the 1-2 Hz of ride-comfort practice (docs/catenary_data.md "
        "section 9). The pantograph above the leading bogie (x = a): where pantographs usually "
        "sit, away from the car body's mid-length bending",
    ),
}


def roof_response(car: CarBody, omega: np.ndarray, speed: float) -> np.ndarray:
    """H(Omega): the roof height at the pantograph per unit track height, for a spatial harmonic of
    Omega [rad/m] passed at ``speed`` [m/s]."""
    omega = np.asarray(omega, dtype=float)
    w = speed * omega
    stiff = car.stiffness + 1j * w * car.damping
    a, b = car.half_bogie_distance, car.half_wheelbase
    front = np.exp(1j * omega * a) * np.cos(omega * b)
    rear = np.exp(-1j * omega * a) * np.cos(omega * b)
    bounce = stiff * (front + rear) / (-car.mass * w**2 + 2.0 * stiff)
    pitch = a * stiff * (front - rear) / (-car.pitch_inertia * w**2 + 2.0 * a * a * stiff)
    return bounce + car.pantograph_position * pitch


#: Cosines in a drawn roof motion (log-spaced bins over the track's band, one cosine each).
TERMS = 400


@dataclass(frozen=True)
class RoofMotion:
    """A drawn roof motion: cosines of amplitude ``amplitude`` [m], angular frequency ``frequency``
    [rad/s] and phase ``phase`` [rad] (``roof_at`` sums them), for one pantograph position."""

    amplitude: np.ndarray
    frequency: np.ndarray
    phase: np.ndarray

    def at(self, t: float) -> tuple[float, float, float]:
        """(height [m], velocity [m/s], acceleration [m/s^2]) of the roof at time t."""
        out = np.empty(3)
        roof_at(self.amplitude, self.frequency, self.phase, t, out)
        return float(out[0]), float(out[1]), float(out[2])

    def series(self, t: np.ndarray) -> np.ndarray:
        """(3, len(t)): height, velocity and acceleration at every time of t."""
        out = np.empty((3, len(t)))
        roof_series(self.amplitude, self.frequency, self.phase, np.asarray(t, dtype=float), out)
        return out


def track_harmonics(track: TrackSpectrum, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A_i [m], Omega_i [rad/m], psi_i [rad]): the seeded track profile's cosines. Each log-spaced
    bin's frequency is drawn inside it (no common period: the sum does not repeat)."""
    rng = np.random.default_rng([seed, 0x7AC])
    edges = np.geomspace(2 * math.pi / track.longest, 2 * math.pi / track.shortest, TERMS + 1)
    omega = edges[:-1] + rng.random(TERMS) * np.diff(edges)
    amplitude = np.sqrt(2.0 * track.psd(omega) * np.diff(edges))
    return amplitude, omega, rng.uniform(0.0, 2 * math.pi, TERMS)


def roof_motion(
    track: TrackSpectrum, car: CarBody, speed: float, seed: int, behind: float = 0.0
) -> RoofMotion:
    """The roof motion under a pantograph of a car whose centre is ``behind`` [m] behind the first
    car's, at ``speed`` [m/s] over the track drawn by ``seed``: at time t the car centre is at
    s = speed t - behind, so every car of the train runs over the same drawn track."""
    if not speed > 0.0:
        raise ParameterError("speed_kmh", speed * 3.6, "a positive speed for a moving car body")
    amplitude, omega, phase = track_harmonics(track, seed)
    h = roof_response(car, omega, speed)
    return RoofMotion(amplitude * np.abs(h), speed * omega, phase + np.angle(h) - omega * behind)


# One cosine's share of each sum, written once: the per-tick kernels below that compute their angles
# and the compiled loop's, which keeps them from tick to tick, add the same numbers in the same order.
@njit(cache=True, inline="always")
def _angle(w: float, phase: float, t: float) -> float:
    return w * t + phase


@njit(cache=True, inline="always")
def _roof_term(a: float, w: float, c: float, s: float) -> tuple[float, float, float]:
    """One cosine's height, minus its velocity, minus its acceleration."""
    return a * c, a * w * s, a * w * w * c


@njit(cache=True, inline="always")
def _mean_term(a: float, w: float, s0: float, s1: float) -> float:
    """One cosine's integral over [t0, t1] (its height's, times h)."""
    return a * (s1 - s0) / w


@njit(cache=True, inline="always")
def _rise_term(a: float, c0: float, c1: float) -> float:
    """One cosine's rise over [t0, t1]."""
    return a * (c1 - c0)


@njit(cache=True, inline="always")
def _held(stiffness: float, damping: float, mean_height: float, rise: float, h: float) -> float:
    if damping == 0.0:
        return stiffness * mean_height / h
    return (stiffness * mean_height + damping * rise) / h


@njit(cache=True, error_model="numpy")
def cosines_at(frequency, phase, t: float, cos_out, sin_out) -> None:
    """cos and sin of every cosine's angle, frequency t + phase, at t (the loop keeps a tick's, so
    that the next tick starts from them: ``roof_from``, ``held_force``)."""
    for i in range(frequency.shape[0]):
        sin_out[i], cos_out[i] = sin_cos(_angle(frequency[i], phase[i], t))


@njit(cache=True, error_model="numpy")
def sines_at(frequency, phase, t: float, sin_out) -> None:
    """sin of every cosine's angle at t (what a force with no rate term needs: ``held_force``)."""
    for i in range(frequency.shape[0]):
        sin_out[i] = sin_of(_angle(frequency[i], phase[i], t))


@njit(cache=True, error_model="numpy")
def roof_from(amplitude, frequency, cos_t, sin_t, out) -> None:
    """out[:3] = roof height, velocity and acceleration from the angles' cos and sin at one time:
    the sum of the cosines and its derivatives."""
    z = v = acc = 0.0
    for i in range(amplitude.shape[0]):
        dz, dv, da = _roof_term(amplitude[i], frequency[i], cos_t[i], sin_t[i])
        z, v, acc = z + dz, v - dv, acc - da
    out[0], out[1], out[2] = z, v, acc


@njit(cache=True, error_model="numpy")
def roof_at(amplitude, frequency, phase, t: float, out) -> None:
    """out[:3] = roof height, velocity and acceleration at t (``roof_from``, its angles computed
    here: no arrays, so a compiled tick that calls it allocates nothing)."""
    z = v = acc = 0.0
    for i in range(amplitude.shape[0]):
        s, c = sin_cos(_angle(frequency[i], phase[i], t))
        dz, dv, da = _roof_term(amplitude[i], frequency[i], c, s)
        z, v, acc = z + dz, v - dv, acc - da
    out[0], out[1], out[2] = z, v, acc


@njit(cache=True, error_model="numpy")
def roof_series(amplitude, frequency, phase, t, out) -> None:
    """:func:`roof_at` at every time of ``t`` into the columns of ``out`` (3 x len(t))."""
    one = np.empty(3)
    for k in range(t.shape[0]):
        roof_at(amplitude, frequency, phase, t[k], one)
        out[0, k], out[1, k], out[2, k] = one[0], one[1], one[2]


@njit(cache=True, error_model="numpy")
def held_force(
    amplitude, frequency, stiffness: float, damping: float, h: float, sin0, sin1, cos0, cos1
) -> float:
    """The mean over a tick [t0, t1] of length h of k z_roof + c z_roof': what a roof spring k and
    damper c pass to the mass they join when the roof moves (its base excitation), from the angles'
    sin and cos at t0 and t1 (cos unread when c = 0). The mean, not a sample: the plant holds the
    tick's forces over the tick (zero-order hold), and the mean is the held force that carries the
    tick's impulse exactly (closed form: the cosines' integral, and z_roof(t1) - z_roof(t0))."""
    mean_height = 0.0
    rise = 0.0
    if damping == 0.0:  # (the turbulent uplift's: no rate term, so none of the cosines it needs)
        for i in range(amplitude.shape[0]):
            mean_height += _mean_term(amplitude[i], frequency[i], sin0[i], sin1[i])
    else:
        for i in range(amplitude.shape[0]):
            mean_height += _mean_term(amplitude[i], frequency[i], sin0[i], sin1[i])
            rise += _rise_term(amplitude[i], cos0[i], cos1[i])
    return _held(stiffness, damping, mean_height, rise, h)


@njit(cache=True, error_model="numpy")
def roof_force(amplitude, frequency, phase, stiffness: float, damping: float, t0: float, t1: float) -> float:
    """``held_force`` over [t0, t1], its angles computed here (no arrays: the compiled loop calls it
    for every passive pantograph's roof each tick). A tick's interval is [t_k, t_k+1] with
    t_k = k dt, so that consecutive ticks share their boundary to the bit (the compiled loop keeps
    the controlled roof's angles at t_k+1 for the next tick instead of computing them again)."""
    mean_height = 0.0
    rise = 0.0
    for i in range(amplitude.shape[0]):
        w = frequency[i]
        s0, c0 = sin_cos(_angle(w, phase[i], t0))
        s1, c1 = sin_cos(_angle(w, phase[i], t1))
        mean_height += _mean_term(amplitude[i], w, s0, s1)
        if damping != 0.0:
            rise += _rise_term(amplitude[i], c0, c1)
    return _held(stiffness, damping, mean_height, rise, t1 - t0)


def roof_attachment(chain: PantographFile) -> tuple[float, float]:
    """(k, c): the roof spring and damper of a pantograph file's actuator mass, the one mass the
    roof's motion may reach here (the plant adds it as a force on that mass, with the actuator's);
    a chain with another mass on the roof: ParameterError (one line)."""
    others = [i for i, j, _ in (*chain.springs, *chain.dampers) if j < 0 and i != chain.actuator]
    if others:
        raise ParameterError(
            "roof_motion",
            chain.path or chain.name,
            "a pantograph whose only mass on the roof is the actuator's (this one has "
            f"'{chain.mass_names[others[0]]}' on it too)",
        )
    k = sum(v for i, j, v in chain.springs if j < 0)
    c = sum(v for i, j, v in chain.dampers if j < 0)
    return float(k), float(c)
