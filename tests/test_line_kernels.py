"""The compiled line_adaptive law and contact-force observer against the numpy code they replaced.

line_adaptive's outputs must not change when it is compiled: the shipped law (its compiled
functions, which the class and the compiled loop call) is driven side by side with the numpy
implementation it replaced (tests/line_adaptive_oracle.py) on random force estimates, with
and without the actuator clipping it, and the two must give the same commands bit for bit.
"""

import math

import line_adaptive_oracle as oracle
import numpy as np
import pytest

from pac_controller.line_adaptive import LineAdaptiveLaw
from pac_controller.parameters import LawParameters
from pac_model.parameters import PantographParameters, TrackParameters
from pac_observer.contact_force import ContactForceObserver
from pac_observer.parameters import ObserverParameters

pytestmark = pytest.mark.offline

SPAN = 50.0


def drive(law, speed_seed: int, spans: int, u_max: float, gain_sign: float = 1.0):
    """Outputs of ``law`` on a random span-periodic force (plus noise) that follows the command."""
    rng = np.random.default_rng(speed_seed)
    dt = 1e-3
    law.gain *= gain_sign
    n = law.period_ticks
    w = 2 * math.pi / (n * dt)
    amps = rng.uniform(5.0, 60.0, 6)
    phases = rng.uniform(0.0, 2 * math.pi, 6)
    f_r = 150.0
    out = []
    u_applied = f_r
    for k in range(spans * n):
        t = k * dt
        periodic = sum(
            a * math.cos((j + 1) * w * t + ph) for j, (a, ph) in enumerate(zip(amps, phases, strict=True))
        )
        f_hat = f_r + periodic + 0.7 * (u_applied - f_r) + rng.normal(0.0, 3.0)
        u, errors = law.output(k, t, np.array([f_r, 0.0, 0.0, 0.0]), np.zeros(4), np.zeros(3), f_hat)
        u_cmd = min(u, u_max)
        law.commit(k, u_cmd)
        out.append((u, *errors, law.mode))
        u_applied = u_cmd
    return out


@pytest.mark.parametrize(
    "speed, seed, u_max, gain_sign, laws",
    [
        (300.0, 1, math.inf, 1.0, {}),
        (250.0, 2, 200.0, 1.0, {}),  # the limits clip: anti-windup and the mean given back
        (360.0, 3, math.inf, -1.0, {}),  # forced to harm: the guard trips
        (200.0, 4, 190.0, 1.0, {"line_max_frequency": 60.0, "design_delay_ticks": 2}),  # H > 8: blocks
        (160.0, 6, math.inf, 1.0, {"line_max_frequency": 200.0}),  # H > 128: numpy's sums recurse
        (330.0, 5, math.inf, 1.0, {"line_response_min": 0.9, "line_forgetting": 0.3}),  # the floor applies
    ],
)
def test_compiled_law_gives_the_numpy_laws_commands(speed, seed, u_max, gain_sign, laws):
    track = TrackParameters(speed_kmh=speed, span_length=SPAN)
    params = LawParameters(**laws)
    compiled, reference = LineAdaptiveLaw(track, params, 1e-3), oracle.LineAdaptiveLaw(track, params, 1e-3)
    assert compiled.harmonics == reference.harmonics and compiled.period_ticks == reference.period_ticks
    spans = 14
    a = drive(compiled, seed, spans, u_max, gain_sign)
    b = drive(reference, seed, spans, u_max, gain_sign)
    modes = [row[-1] for row in a]
    assert modes == [row[-1] for row in b]
    got, want = np.array([row[:-1] for row in a]), np.array([row[:-1] for row in b])
    if laws.get("line_response_min", 0.0) > 0.5:
        # The floored response's angle: libm's atan2 against numpy's vector one (a few ulp).
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(compiled.u_ff, reference.u_ff, rtol=1e-12, atol=1e-9)
    else:
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(compiled.u_ff, reference.u_ff)
    if gain_sign < 0:
        assert "passive" in modes  # the case did exercise the guard
    else:
        assert modes[-1] == "active"


def test_restart_forgets_what_was_learned():
    track = TrackParameters(speed_kmh=300.0, span_length=SPAN)
    law = LineAdaptiveLaw(track, LawParameters(), 1e-3)
    drive(law, 7, 8, math.inf)
    assert np.abs(law.u_ff).max() > 0.0
    law.restart(123.0)
    fresh = LineAdaptiveLaw(track, LawParameters(), 1e-3)
    np.testing.assert_array_equal(law.memory, fresh.memory)
    for name in law.state.dtype.names:  # the law's memory; line_stack and line_values are scratch
        if name.startswith("line_") and name not in ("line_stack", "line_values"):
            assert law.state[0][name].tobytes() == fresh.state[0][name].tobytes(), name


def kalman_step(x, y, u, phi, gamma, gain):
    """The filter's period as the observer computed it before it was compiled (numpy, loops)."""
    pred = np.empty(5)
    for i in range(5):
        s = gamma[i] * u
        for j in range(5):
            s += phi[i, j] * x[j]
        pred[i] = s
    innovation = np.array([y[0] - pred[0], y[1] - pred[1]])
    new = np.array([pred[i] + gain[i, 0] * innovation[0] + gain[i, 1] * innovation[1] for i in range(5)])
    return new, innovation


def test_contact_force_observer_matches_the_numpy_filter():
    """The observer's compiled update (gaps included) equals the numpy filter period by period."""
    rng = np.random.default_rng(11)
    obs = ContactForceObserver(PantographParameters(), TrackParameters(), ObserverParameters(), 1e-3)
    x = np.zeros(5)
    x[:4] = ObserverParameters().z_hat0
    tick, y_prev = None, None
    for step in range(400):
        gap = 1 if step % 37 else 3
        tick = 0 if tick is None else tick + gap
        y = rng.normal(0.0, 0.01, 2)
        u = rng.uniform(-200.0, 300.0)
        est = obs.update(tick, (y[0], y[1]), u)
        if y_prev is None:
            x[0], x[1] = y
            innovation = np.zeros(2)
        else:
            for j in range(1, gap + 1):
                y_j = y_prev + (j / gap) * (y - y_prev)
                x, innovation = kalman_step(x, y_j, u, obs.phi, obs.gamma, obs.gain)
        y_prev = y
        np.testing.assert_array_equal(est.z_hat, x[:4])
        assert est.contact_force_hat == x[4]
        np.testing.assert_array_equal(est.innovation, innovation)
