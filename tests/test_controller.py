"""Reference generator and backstepping law (eqs. (23)-(43)) with the true state and true theta."""

import math

import numpy as np
import pytest

from pac_common.parameters import ParameterError, RateParameters
from pac_controller.backstepping import BacksteppingController, product_derivatives, reciprocal_derivatives
from pac_controller.laws import make_controller
from pac_controller.parameters import ControllerParameters, ReferenceParameters
from pac_controller.reference import ForceReference, filtered_step
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Plant

pytestmark = pytest.mark.unit

DT = RateParameters().sample_period  # the nodes' default rate
PANTO, TRACK, CAT = PantographParameters(), TrackParameters(), CatenaryParameters()


def numeric_derivative(f, t, h=1e-5):
    return (f(t + h) - f(t - h)) / (2 * h)


def test_filtered_step_derivatives():
    p = 20.0
    for tau in (0.01, 0.1, 0.3, 1.0):
        s = filtered_step(tau, p)
        for n in range(1, 4):
            assert s[n] == pytest.approx(
                numeric_derivative(lambda x, n=n: filtered_step(x, p)[n - 1], tau), rel=1e-5, abs=1e-6 * p**n
            )
    assert np.all(filtered_step(0.0, p) == 0.0)
    assert filtered_step(5.0, p)[0] == pytest.approx(1.0, abs=1e-12)


def test_square_reference_levels_and_purity():
    ref = ForceReference(ReferenceParameters(shape="square", period=4.0, force_amplitude=100.0))
    assert ref.command(1.0) == 100.0 and ref.command(3.0) == 0.0 and ref.command(41.0) == 100.0
    assert ref.at(1.9)[0] == pytest.approx(100.0, abs=1e-9)
    assert ref.at(3.9)[0] == pytest.approx(0.0, abs=1e-9)
    assert ref.at(401.9)[0] == pytest.approx(100.0, abs=1e-9)  # old steps are forgotten exactly
    late = ref.at(7.3)
    ref.at(0.1)
    np.testing.assert_array_equal(ref.at(7.3), late)  # a pure function of time


def test_step_reference():
    ref = ForceReference(
        ReferenceParameters(shape="step", force_initial=50.0, force_amplitude=120.0, step_time=2.0)
    )
    assert ref.at(1.99)[0] == pytest.approx(50.0, abs=1e-6)
    assert ref.at(4.0)[0] == pytest.approx(120.0, abs=1e-6)


def test_quotient_derivatives():
    k = lambda t: 4000 + 2000 * math.cos(9.67 * t - 0.7)  # noqa: E731
    f = lambda t: 100 * (1 - math.exp(-3 * t))  # noqa: E731

    def derivs(fun, t):
        h = 1e-3
        vals = [fun(t + i * h) for i in range(-2, 3)]
        return np.array(
            [
                vals[2],
                (vals[3] - vals[1]) / (2 * h),
                (vals[3] - 2 * vals[2] + vals[1]) / h**2,
                (vals[4] - 2 * vals[3] + 2 * vals[1] - vals[0]) / (2 * h**3),
            ]
        )

    t = 0.4
    got = product_derivatives(derivs(f, t), reciprocal_derivatives(derivs(k, t)))
    want = derivs(lambda x: f(x) / k(x), t)
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-9)


def closed_loop_true_state(ticks, params, reference, delay=0, z0=None, each=None):
    """Plant + controller fed the true state and true theta (no observer)."""
    plant = Plant(PANTO, TRACK, CAT, PlantOptions(), DT, z0=z0)
    ctrl = make_controller(PANTO, TRACK, params, reference, DT)
    pending = [0.0] * delay
    for k in range(ticks):
        cmd = ctrl.compute(k, plant.z, CAT.theta)
        if each is not None:
            each(k, plant, cmd)
        pending.append(cmd.u)
        plant.advance(pending.pop(0))
    return plant


@pytest.mark.parametrize("delay", [0, 1])
def test_tracks_with_true_state(delay):
    errors = []
    closed_loop_true_state(
        5000,
        ControllerParameters(),
        ReferenceParameters(),
        delay=delay,
        each=lambda k, p, c: errors.append(p.truth().contact_force - c.force_reference) if k > 2000 else None,
    )
    # sampled (ZOH) actuation costs ~0.015 N at delay 0; one more tick of delay ~0.05 N
    assert np.max(np.abs(errors)) < (0.03 if delay == 0 else 0.1)


def test_backstepping_lyapunov_decrease():
    """With the exact state the errors obey e' = H_c e (eq. (47) with y_tilde = 0), so
    V_c = |e|^2 / 2 satisfies V_c' = -sum c_i e_i^2 <= -2 min(c) V_c (eq. (44)).
    A wrong alpha_1' or alpha_2' breaks this."""
    params = ControllerParameters(c1=30.0, c2=40.0, c3=50.0, u_min=-1e5, u_max=1e5, slew_rate_max=1e12)
    z0 = np.array([0.03, 0.035, 0.0, 0.0])  # at rest, ~120 N of contact force; F_r rises from 0
    v = []
    closed_loop_true_state(
        400,
        params,
        ReferenceParameters(shape="constant"),
        z0=z0,
        each=lambda k, p, c: v.append(0.5 * float(np.sum(np.square(c.tracking_error)))),
    )
    v = np.array(v)
    bound = v[0] * np.exp(-2.0 * 30.0 * DT * np.arange(v.size))
    assert v[0] > 1e-6
    # the held (ZOH) input leaves a floor near 4e-8 V(0); above it the continuous-time rate holds
    assert np.all(v <= bound + 1e-6 * v[0])
    assert v[-1] < 1e-4 * v[0]


@pytest.mark.parametrize(
    "params", [ControllerParameters(law="passive"), ControllerParameters(mode="passive")]
)
def test_passive_law_is_the_filtered_reference(params):
    """law:=passive, and the deprecated mode:=passive that selects it."""
    ctrl = make_controller(PANTO, TRACK, params, ReferenceParameters(), DT)
    cmd = ctrl.compute(700, np.zeros(4), np.array([3000.0, 0.0, 0.0]))
    assert cmd.u == pytest.approx(ForceReference(ReferenceParameters()).at(0.7)[0])
    assert cmd.mode == "passive"


def test_saturation_and_non_finite():
    params = ControllerParameters(u_min=-10.0, u_max=10.0, fallback_force=0.0)
    ctrl = make_controller(PANTO, TRACK, params, ReferenceParameters(), DT)
    cmd = ctrl.compute(1000, np.zeros(4), CAT.theta)
    assert cmd.saturated and cmd.u == 10.0 and cmd.u_unsaturated > 10.0
    fallback = ctrl.compute(1001, np.array([math.nan, 0, 0, 0]), CAT.theta)
    assert fallback.mode == "fallback" and fallback.u == 0.0
    assert ctrl.compute(1002, np.zeros(4), np.array([math.inf, 0, 0])).mode == "fallback"


def test_slew_rate_limit():
    params = ControllerParameters(slew_rate_max=1000.0, u_min=-1e5, u_max=1e5)  # 1 N per tick
    ctrl = make_controller(PANTO, TRACK, params, ReferenceParameters(shape="constant"), DT)
    from pac_model.model import static_equilibrium

    k = CAT.k0 * (1 + CAT.alpha * math.cos(TRACK.omega * 3.0 - CAT.beta))
    first = ctrl.compute(3000, static_equilibrium(100.0, k, PANTO), CAT.theta)  # about 100 N
    second = ctrl.compute(3001, np.zeros(4), CAT.theta)  # the law now asks for far more
    assert abs(second.u_unsaturated - first.u) > 100.0
    assert second.u - first.u == pytest.approx(1.0) and second.saturated
    later = ctrl.compute(3011, np.zeros(4), CAT.theta)  # 10 ticks later: at most 10 N more
    assert later.u - second.u == pytest.approx(10.0)


def test_a_new_controller_has_commanded_nothing():
    """Before its first command a controller reports none: no last command, its tick -1 (the node's
    first fallback goes out at the estimate's own tick, max(tick, last tick + 1)), no law tick; and
    its first command, a fallback at tick 0, is the fallback force at once (no rate limit from a
    command that never was)."""
    ctrl = make_controller(PANTO, TRACK, ControllerParameters(), ReferenceParameters(), DT)
    assert ctrl.last_u is None and ctrl.last_tick == -1 and ctrl.law_tick is None
    first = ctrl.fallback(max(0, ctrl.last_tick + 1))
    assert first.tick == 0 and first.u == ControllerParameters().fallback_force
    assert ctrl.last_u == first.u and ctrl.last_tick == 0


def test_fallback_force_must_be_within_limits():
    with pytest.raises(ParameterError, match="fallback_force"):
        ControllerParameters(u_min=0.0, u_max=50.0, fallback_force=100.0)


def test_stiffness_hat_is_clamped():
    ctrl = BacksteppingController(PANTO, TRACK, ControllerParameters(), ReferenceParameters(), DT)
    k = ctrl.stiffness_hat_derivatives(0.0, np.array([-100.0, 0.0, 0.0]))
    np.testing.assert_array_equal(k, [500.0, 0.0, 0.0, 0.0])
