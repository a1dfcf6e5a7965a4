"""The actuator as hardware (pac_plant.hardware.actuators) against independent references: the
step response of a first-order lag behind a transport delay by scipy.signal (and its closed form),
the rate-limited lag by a numerical ODE solution, the range and the rate limit as properties."""

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import quad, solve_ivp

from pac_plant.hardware.actuators import ACTUATOR_STEPS, ACTUATORS, Actuator, actuator_model

pytestmark = pytest.mark.unit

DT = 1e-3
F0 = 120.0  # the static force the range is about [N]


def run(actuator: Actuator, commands: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean force over each tick, force at each tick's end) for the commands held tick by tick."""
    means, ends = np.empty(commands.size), np.empty(commands.size)
    for k, u in enumerate(commands):
        means[k] = actuator.apply(u)
        ends[k] = actuator.force
    return means, ends


@pytest.mark.parametrize(
    ("tau", "delay"),
    [
        (ACTUATORS["electromechanical"].time_constant, ACTUATORS["electromechanical"].delay),
        (ACTUATORS["pneumatic"].time_constant, ACTUATORS["pneumatic"].delay),
        (0.015, 0.0055),  # a delay that is not a whole number of ticks
    ],
)
def test_step_response_is_a_lag_behind_a_delay(tau, delay):
    """A 60 N step (inside the range, below the rate limit's knee): the force at every tick is the
    response of 1 / (tau s + 1) to the step delayed by D, as scipy.signal.lsim gives it, and each
    tick's mean force is its integral over the tick (quad of the closed form)."""
    model = dataclasses.replace(ACTUATORS["electromechanical"], time_constant=tau, delay=delay)
    assert 60.0 < model.force_range and 60.0 < model.rate_limit * tau  # no limit binds here
    ticks = int(5 * (tau + delay) / DT)
    means, ends = run(Actuator(model, F0, DT), np.full(ticks, F0 + 60.0))
    t = (np.arange(ticks) + 1) * DT  # the end of each tick
    # scipy: the continuous lag on a fine grid with the step at t = D (a grid point).
    fine = 1e-5
    grid = np.arange(0.0, t[-1] + fine / 2, fine)
    step = np.where(grid >= delay - fine / 2, 60.0, 0.0)
    _, response, _ = signal.lsim(signal.lti([1.0], [tau, 1.0]), step, grid, interp=False)
    reference = np.interp(t, grid, response)
    assert np.max(np.abs(ends - F0 - reference)) < 1e-6
    closed = lambda s: 60.0 * (1.0 - math.exp(-(s - delay) / tau)) if s > delay else 0.0  # noqa: E731
    for k in range(ticks):
        expected = quad(closed, k * DT, (k + 1) * DT, points=[delay])[0] / DT
        assert abs(means[k] - F0 - expected) < 1e-9
    # The delay itself: nothing moves before D, the force is moving from the first tick after it.
    before = int(math.floor(delay / DT + 1e-9))
    assert np.all(ends[:before] == F0) and ends[before] > F0
    # tau: 63.2 % of the step one tau after the delay (the definition of a time constant).
    at_tau = np.interp(delay + tau, t, ends - F0)
    assert at_tau == pytest.approx(60.0 * (1.0 - math.exp(-1.0)), abs=60.0 * DT / tau)


def test_the_rate_limited_lag_matches_the_ode_solution():
    """Steps larger than the range and the rate limit's knee (r tau = 100 N): the force follows
    df/dt = clip((d(t - D) - f) / tau, -r, r) with d clipped to F0 +- R, solved numerically."""
    model = ACTUATORS["electromechanical"]
    r, tau, delay, span = model.rate_limit, model.time_constant, model.delay, model.force_range
    commands = np.concatenate([np.full(100, F0 + 400.0), np.full(150, F0 - 400.0), np.full(50, F0 + 30.0)])
    means, ends = run(Actuator(model, F0, DT), commands)

    def demand(s: float) -> float:
        k = math.floor((s - delay) / DT + 1e-9)
        u = F0 if k < 0 else commands[min(k, commands.size - 1)]
        return min(max(u, F0 - span), F0 + span)

    def rhs(s, f):
        return [min(max((demand(s) - f[0]) / tau, -r), r)]

    # Integrated piece by piece between the demand's jumps (the solver steps onto each one).
    t = (np.arange(commands.size) + 1) * DT
    breaks = [0.0, delay + 100 * DT, delay + 250 * DT, t[-1]]
    reference, f = np.empty(commands.size), F0
    for a, b in zip(breaks, breaks[1:], strict=False):
        sol = solve_ivp(rhs, (a, b), [f], dense_output=True, rtol=1e-11, atol=1e-9, max_step=DT / 4)
        inside = (t > a) & (t <= b)
        reference[inside] = sol.sol(t[inside])[0]
        f = sol.y[0, -1]
    assert np.max(np.abs(ends - reference)) < 1e-5
    # The ramps: 5 kN/s exactly while the error exceeds r tau (200 N step: 20 ms of ramp).
    k0 = int(delay / DT) + 100
    np.testing.assert_allclose(np.diff(ends[k0 : k0 + 19]), -r * DT, rtol=1e-9)


def test_range_and_rate_hold_for_any_command():
    """Random commands far beyond the range: every tick's force and mean stay in F0 +- R, and the
    force never moves faster than the rate limit."""
    rng = np.random.default_rng(7)
    for name in ("electromechanical", "pneumatic"):
        model = ACTUATORS[name]
        commands = np.repeat(rng.uniform(F0 - 1000.0, F0 + 1000.0, 60), 50)  # held 50 ms each
        means, ends = run(Actuator(model, F0, DT), commands)
        forces = np.concatenate([[F0], ends])
        low, high = F0 - model.force_range, F0 + model.force_range
        assert low <= forces.min() and forces.max() <= high
        assert low <= means.min() and means.max() <= high
        assert np.max(np.abs(np.diff(forces))) <= model.rate_limit * DT * (1 + 1e-12)
        assert np.max(np.abs(np.diff(forces))) > 0.9 * model.rate_limit * DT  # the limit was reached


def test_ideal_passes_the_command_unchanged():
    """Today's actuator: the mean force is the command itself, bit for bit."""
    ideal = Actuator(actuator_model("ideal"), F0, DT)
    assert ideal.ideal and ACTUATORS["ideal"].step == "ideal"
    commands = np.random.default_rng(3).normal(100.0, 300.0, 500)
    means, _ = run(ideal, commands)
    assert np.array_equal(means, commands)


def test_an_unknown_actuator_is_one_line():
    with pytest.raises(ValueError, match="invalid parameter 'actuator' = 'hydraulic': allowed one of ideal"):
        actuator_model("hydraulic")


@pytest.mark.offline
def test_the_loop_applies_the_actuators_force():
    """A closed-loop run with the electromechanical actuator: the compiled loop and the core objects
    give the same ticks bit for bit, and PlantTruth.u_applied is the actuator's mean force for the
    commands the controller sent (command_delay_ticks later), fed to a fresh actuator here."""
    from pac_rig.closed_loop import build_cores, run, run_cores
    from pac_rig.simulate import scenario_from_flat

    values = {
        "duration": 1.0, "actuator": "electromechanical", "actuator_static_force": 100.0,
        "command_delay_ticks": 2, "shape": "square", "period": 0.4,
    }  # fmt: skip
    s = scenario_from_flat(values)
    compiled = list(run(s))
    stepped = list(run_cores(s, *build_cores(s)))
    assert len(compiled) == len(stepped) == s.loop.ticks
    for a, b in zip(compiled, stepped, strict=True):  # assert_equal: NaN (no FE line) equals NaN
        np.testing.assert_equal(dataclasses.astuple(a.truth), dataclasses.astuple(b.truth))
        np.testing.assert_equal(dataclasses.astuple(a.command), dataclasses.astuple(b.command))
    commands = np.array([r.command.u for r in compiled])
    applied = np.array([r.truth.u_applied for r in compiled])
    sent = np.concatenate([np.zeros(2), commands[:-2]])  # what the plant got at ticks 0 .. K-1
    reference = Actuator(ACTUATORS["electromechanical"], 100.0, s.loop.sample_period)
    means = np.array([reference.apply(u) for u in sent[:-1]])
    assert np.array_equal(applied[1:], means)  # truth at tick k: the force over [t_k-1, t_k]
    assert np.max(np.abs(sent[:-1] - means)) > 10.0  # the square wave's steps: the lag shows
    assert 0.0 <= applied.min() and applied.max() <= 200.0


def test_the_step_dispatch_in_use_is_what_the_registry_gives():
    """actuator_dispatch.py (the installed copy) is written from ACTUATOR_STEPS; a change there without
    ``python -m pac_plant.hardware.actuator_dispatch_source --write`` fails here."""
    from pathlib import Path

    from pac_plant.hardware import actuator_dispatch, actuator_dispatch_source

    text = actuator_dispatch_source.actuator_dispatch_source(ACTUATOR_STEPS)
    assert Path(actuator_dispatch.__file__).read_text() == text
    assert actuator_dispatch.ACTUATOR_STEP_CODES == {name: code for code, name in enumerate(ACTUATOR_STEPS)}


@pytest.mark.parametrize("name", list(ACTUATORS))
def test_each_variant_names_a_registered_step_and_its_records_carry_its_code(name):
    model = ACTUATORS[name]
    assert model.step in ACTUATOR_STEPS
    actuator = Actuator(model, F0, DT)
    assert actuator.params[0]["kind"] == list(ACTUATOR_STEPS).index(model.step)


def test_an_unknown_step_code_gives_a_nan_force():
    from pac_plant.hardware.actuators import actuator_apply_one

    actuator = Actuator(actuator_model("electromechanical"), F0, DT)
    actuator.params[0]["kind"] = len(ACTUATOR_STEPS)
    assert np.isnan(actuator_apply_one(actuator.params, actuator.state, F0))
