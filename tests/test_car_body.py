"""The car body's roof motion (pac_plant.hardware.car_body) against independent references: the
frequency response of the car body's state-space model (scipy.signal), a time-domain integration
of its equations of motion over the drawn track (scipy.integrate), and the RMS against the
integral of the track's PSD times the response."""

import math

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import quad

from pac_plant.hardware.car_body import CAR_BODIES, TRACKS, roof_motion, roof_response, track_harmonics

pytestmark = pytest.mark.unit

CAR = CAR_BODIES["high_speed_trailer"]
TRACK = TRACKS["german_low"]
V = 300 / 3.6


def state_space():
    """The car body as x' = A x + B u, x = (z, phi, z', phi'), u = (w_f, w_r, w_f', w_r') the bogie
    heights and rates: each bogie's suspension force k (w - z_end) + c (w' - z_end'), z_end the car
    body's height above it; m z'' = F_f + F_r, J phi'' = a (F_f - F_r). Built by evaluating those
    forces, not from the closed form of roof_response."""
    m, j, a, k, c = CAR.mass, CAR.pitch_inertia, CAR.half_bogie_distance, CAR.stiffness, CAR.damping

    def accelerations(x, u):
        z, phi, dz, dphi = x
        f_front = k * (u[0] - (z + a * phi)) + c * (u[2] - (dz + a * dphi))
        f_rear = k * (u[1] - (z - a * phi)) + c * (u[3] - (dz - a * dphi))
        return np.array([(f_front + f_rear) / m, a * (f_front - f_rear) / j])

    eye4 = np.eye(4)
    A = np.zeros((4, 4))
    B = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    for i in range(4):
        A[2:, i] = accelerations(eye4[i], np.zeros(4))
        B[2:, i] = accelerations(np.zeros(4), eye4[i])
    C = np.array([[1.0, CAR.pantograph_position, 0.0, 0.0]])
    return A, B, C, accelerations


def test_frequency_response_matches_the_state_space_model():
    """H(Omega) of roof_response == the state-space model's response (scipy.signal.ss2tf, freqs) to
    the two bogies' inputs, each the mean of its wheelsets' track heights."""
    A, B, C, _ = state_space()
    omega = np.geomspace(2 * math.pi / TRACK.longest, 2 * math.pi / TRACK.shortest, 300)
    w = V * omega
    h = []
    for j in range(4):
        num, den = signal.ss2tf(A, B, C, np.zeros((1, 4)), input=j)
        h.append(signal.freqs(num[0], den, worN=w)[1])
    b, a = CAR.half_wheelbase, CAR.half_bogie_distance
    front = np.exp(1j * omega * a) * np.cos(omega * b)
    rear = np.exp(-1j * omega * a) * np.cos(omega * b)
    reference = front * (h[0] + 1j * w * h[2]) + rear * (h[1] + 1j * w * h[3])
    np.testing.assert_allclose(roof_response(CAR, omega, V), reference, rtol=1e-8, atol=1e-12)
    # The modes the docs state: bounce 1.0 Hz, pitch 1.2 Hz (damped, from the state matrix).
    modes = sorted({round(abs(e.imag) / (2 * math.pi), 2) for e in np.linalg.eigvals(A)})
    assert modes == pytest.approx([1.0, 1.21], abs=0.02)


@pytest.mark.slow
def test_roof_motion_matches_a_time_integration():
    """The closed-form roof motion == the car body's state-space model run by scipy.signal.lsim from
    rest over the drawn track (each wheelset on the track at its own place), once the start-up has
    decayed (damping ratio 0.16 at 1 Hz: e^-12 after 12 s)."""
    A, B, C, _ = state_space()
    amp, om, psi = track_harmonics(TRACK, seed=11)
    a, b = CAR.half_bogie_distance, CAR.half_wheelbase
    t = np.arange(0.0, 14.0, 5e-4)
    heights, rates = [], []
    for offset in (a + b, a - b, -a + b, -a - b):  # the four wheelsets
        arg = np.outer(V * t + offset, om) + psi
        heights.append(np.cos(arg) @ amp)
        rates.append(-V * (np.sin(arg) @ (amp * om)))
    u = np.column_stack(
        [
            (heights[0] + heights[1]) / 2,
            (heights[2] + heights[3]) / 2,
            (rates[0] + rates[1]) / 2,
            (rates[2] + rates[3]) / 2,
        ]
    )
    _, integrated, _ = signal.lsim((A, B, C, np.zeros((1, 4))), u, t)
    late = t >= 12.0
    closed = roof_motion(TRACK, CAR, V, seed=11).series(t[late])[0]
    scale = np.sqrt(np.mean(closed**2))
    assert np.max(np.abs(integrated[late] - closed)) < 1e-4 * scale


def test_rms_matches_the_integral_of_the_psd():
    """RMS of the roof height and acceleration over 300 s == sqrt(integral of S(Omega) |H|^2
    (omega^n)^2 dOmega) over the drawn band, by quad; the track itself against the plain integral."""
    motion = roof_motion(TRACK, CAR, V, seed=3)
    t = np.arange(0.0, 300.0, 2e-3)
    z, _, acc = motion.series(t)
    band = (2 * math.pi / TRACK.longest, 2 * math.pi / TRACK.shortest)
    bounce = 2 * math.pi * 1.0 / V  # the resonances, in rad/m
    points = [bounce, 1.2 * bounce]

    def rms(power):
        def f(o):
            return TRACK.psd(o) * abs(roof_response(CAR, o, V)) ** 2 * (V * o) ** (2 * power)

        return math.sqrt(quad(f, *band, points=points, limit=500)[0])

    assert np.sqrt(np.mean(acc**2)) == pytest.approx(rms(2), rel=0.05)
    assert np.sqrt(np.mean(z**2)) == pytest.approx(rms(0), rel=0.15)  # long waves: few cycles in 300 s
    amp, _, _ = track_harmonics(TRACK, seed=3)
    assert math.sqrt(np.sum(amp**2) / 2) == pytest.approx(
        math.sqrt(quad(TRACK.psd, *band, limit=500)[0]), rel=0.02
    )


def test_a_car_behind_runs_over_the_same_track_later():
    """The roof of a car 200 m behind is the first car's roof 200 m / v later."""
    first = roof_motion(TRACK, CAR, V, seed=5)
    behind = roof_motion(TRACK, CAR, V, seed=5, behind=200.0)
    t = np.linspace(3.0, 4.0, 101)
    np.testing.assert_allclose(behind.series(t), first.series(t - 200.0 / V), atol=1e-9)
