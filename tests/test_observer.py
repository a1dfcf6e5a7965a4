"""Adaptive observer core (eq. (17)): convergence, Lyapunov decrease (eq. (65)), conditioning, divergence."""

import math

import numpy as np
import pytest

from pac_common.parameters import RateParameters
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters
from pac_observer.observer import AdaptiveObserver, ObserverDivergedError
from pac_observer.parameters import ObserverParameters
from pac_plant.parameters import PlantOptions
from pac_plant.plant import Plant

pytestmark = pytest.mark.unit

DT = RateParameters().sample_period  # the nodes' default rate
PANTO, TRACK, CAT = PantographParameters(), TrackParameters(), CatenaryParameters()


def uplift(k):
    """Open-loop actuator force: a smooth rise to a 100 N passive uplift."""
    return 100.0 * (1.0 - math.exp(-k * DT / 0.1))


def open_loop(observer, ticks, force=uplift, each=None):
    plant = Plant(PANTO, TRACK, CAT, PlantOptions(), DT)
    est = None
    for k in range(ticks):
        y = plant.measurement()
        est = observer.update(y.tick, (y.z1, y.z2), y.actuator_force)
        if each is not None:
            each(k, plant, observer, est)
        plant.advance(force(k))
    return plant, est


def test_converges_on_open_loop_plant_data():
    obs = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)
    errors, state_errors = [], []

    def record(k, plant, _obs, est):
        if k >= 3000:
            k_true = plant.truth().stiffness
            errors.append((est.stiffness_hat - k_true) / k_true)
            state_errors.append(np.max(np.abs(est.z_hat - plant.z) / np.array([0.03, 0.03, 0.5, 0.5])))

    _, est = open_loop(obs, 6000, each=record)
    np.testing.assert_allclose(est.theta_hat, CAT.theta, rtol=2e-3)
    assert max(state_errors) < 1e-4
    assert 100 * math.sqrt(np.mean(np.square(errors))) < 0.05  # percent
    # The initial guess was 25 % off: the estimate really moved.
    assert abs(est.theta_hat[0] - 3000.0) > 900.0


def test_lyapunov_function_decreases_at_rate_rho():
    """V = eps^T S_z eps + e_theta^T S_theta e_theta, eps = e_z - Lambda e_theta (eqs. (57), (60)):
    V(t) <= V(0) exp(-min(rho_z, rho_theta) t) (eq. (65)) until V reaches the discretisation floor."""
    params = ObserverParameters(z_hat0=(0.01, -0.01, 0.1, 0.0))
    obs = AdaptiveObserver(PANTO, TRACK, params, DT)
    rho = min(params.rho_z, params.rho_theta)
    values = []

    def record(k, plant, o, _est):
        e_theta = CAT.theta - o.theta_hat
        eps = plant.z - o.z_hat - o.lam @ e_theta
        values.append(eps @ o.s_z @ eps + e_theta @ o.s_theta @ e_theta)

    open_loop(obs, 3000, each=record)
    v = np.array(values)
    bound = v[0] * np.exp(-rho * DT * np.arange(v.size))
    checked = bound > 1e-9
    assert checked.sum() > 1000
    assert np.all(v[checked] <= bound[checked] * (1.0 + 1e-6))
    assert v[-1] < 1e-10


def test_wind_up_without_excitation_is_harmless():
    """z1 = 0 for 5 s (no contact force, so no information on theta): S_theta is forgotten down to
    its floor; when the force returns the RLS step stays a contraction and theta_hat converges."""
    obs = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)

    def force(k):
        return 0.0 if k < 5000 else 100.0 * (1.0 - math.exp(-(k - 5000) * DT / 0.1))

    seen = []
    plant, est = open_loop(obs, 9000, force=force, each=lambda k, p, o, e: seen.append(e.theta_hat.copy()))
    assert np.min(np.linalg.eigvalsh(obs.s_theta)) > 0.0
    assert np.all(np.isfinite(seen))
    # No overshoot of the k0 estimate beyond a physically sane range at any tick.
    assert max(abs(t[0]) for t in seen) < 2e4
    np.testing.assert_allclose(est.theta_hat, CAT.theta, rtol=5e-3)


def test_divergence_is_reported_and_state_left_untouched():
    obs = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)
    _, est = open_loop(obs, 200)
    before = (obs.tick, obs.theta_hat.copy(), obs.xi.copy())
    with pytest.raises(ObserverDivergedError, match="not finite"):
        obs.update(obs.tick + 1, (1e308, -1e308), 1e308)
    with pytest.raises(ObserverDivergedError):
        obs.update(obs.tick + 1, (math.nan, 0.0), 100.0)
    assert obs.tick == before[0]
    np.testing.assert_array_equal(obs.theta_hat, before[1])
    np.testing.assert_array_equal(obs.xi, before[2])
    # and it goes on from where it was
    obs.update(obs.tick + 1, (0.0, 0.0), 100.0)


def test_a_divergence_inside_a_bridged_gap_names_the_tick_it_failed_at():
    """Three ticks in one update, the sample NaN: y is interpolated from the last sample, so the
    first period of the gap already fails; the error names that tick and the state is untouched."""
    obs = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)
    open_loop(obs, 100)
    last, before = obs.tick, obs.xi.copy()
    with pytest.raises(ObserverDivergedError) as failed:
        obs.update(last + 3, (math.nan, 0.0), 100.0)
    assert failed.value.tick == last + 1 and f"tick {last + 1}:" in str(failed.value)
    assert obs.tick == last
    np.testing.assert_array_equal(obs.xi, before)


def test_the_first_innovation_is_the_sample_against_the_initial_estimate():
    """The a priori innovation y - C z_hat at the first sample: against z_hat0 (not zero here)."""
    obs = AdaptiveObserver(PANTO, TRACK, ObserverParameters(z_hat0=(0.01, 0.02, 0.0, 0.0)), DT)
    est = obs.update(0, (0.015, 0.005), 0.0)
    np.testing.assert_allclose(est.innovation, [0.005, -0.015], rtol=1e-12)


def test_stale_tick_is_refused():
    obs = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)
    obs.update(0, (0.0, 0.0), 0.0)
    obs.update(1, (0.0, 0.0), 0.0)
    with pytest.raises(ValueError, match="after 1"):
        obs.update(1, (0.0, 0.0), 0.0)


def test_lost_samples_are_bridged():
    """Dropping every 7th sample (a realtime loop losing messages) barely changes the estimate."""
    full = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)
    gappy = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)
    plant = Plant(PANTO, TRACK, CAT, PlantOptions(), DT)
    for k in range(5000):
        y = plant.measurement()
        a = full.update(k, (y.z1, y.z2), y.actuator_force)
        if k % 7 != 3:
            b = gappy.update(k, (y.z1, y.z2), y.actuator_force)
        plant.advance(uplift(k))
    assert b.tick == a.tick == 4999
    np.testing.assert_allclose(b.theta_hat, a.theta_hat, rtol=1e-3)
    np.testing.assert_allclose(b.z_hat[:2], a.z_hat[:2], atol=1e-6)


def test_reset_restores_initial_conditions():
    obs = AdaptiveObserver(PANTO, TRACK, ObserverParameters(), DT)
    open_loop(obs, 300)
    obs.reset()
    assert obs.tick == -1
    np.testing.assert_array_equal(obs.theta_hat, (3000.0, 0.0, 0.0))
    np.testing.assert_array_equal(obs.s_theta, np.eye(3))
