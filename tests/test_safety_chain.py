"""The safety chain by its contract, branch by branch (controller.py's module docstring, docs/design.md).

The contract: a law never sees a non-finite value of what it reads (the fallback answers it);
a non-finite law output is answered by the fallback too; the fallback commands ``fallback_force``
reached within the slew limit; every command is slew limited from the last one (over at least
one period, also at or before the last command's tick) and then saturated; a law whose previous
command was not its own (start, fallback, a tick not after its last one) restarts bumplessly from
the actuator's force; the watchdog falls back exactly when the last fresh estimate is
``watchdog_ticks`` ticks old.  The compiled chain (``kernels.controller_step``) is what both the
node's controller and the compiled loop run; a law without a compiled form is called from Python
between the same compiled parts, and must give the same commands.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest

from pac_controller import kernels
from pac_controller.controller import Controller, watchdog_fallback_tick
from pac_controller.kernels import KernelLaw, limit_command
from pac_controller.laws import make_controller
from pac_controller.parameters import LAW_NAMES, ControllerParameters, ReferenceParameters
from pac_controller.user_law import UserLaw
from pac_model.parameters import CatenaryParameters, PantographParameters, TrackParameters

pytestmark = pytest.mark.unit

DT = 1e-3
PANTO, CAT = PantographParameters(), CatenaryParameters()
TRACK = TrackParameters(speed_kmh=300.0, span_length=55.0)
THETA = np.asarray(CAT.theta, dtype=float)
SLEW = 1000.0  # N/s: 1 N per tick at DT
CHAIN = ControllerParameters(slew_rate_max=SLEW, u_min=-500.0, u_max=500.0, fallback_force=100.0)


def controller(law: str, params: ControllerParameters = CHAIN, reference=None) -> Controller:
    params = dataclasses.replace(params, law=law)
    return make_controller(PANTO, TRACK, params, reference or ReferenceParameters(), DT, catenary=CAT)


def estimate(k: int) -> tuple[np.ndarray, np.ndarray, float]:
    """A plausible estimate for tick k: the pantograph near its static uplift, F_hat near 100 N."""
    z = np.array([0.02 + 1e-3 * math.sin(0.05 * k), 0.03, 1e-3 * math.cos(0.05 * k), 0.0])
    return z, THETA, 100.0 + 20.0 * math.sin(0.03 * k)


# -- the slew limit ------------------------------------------------------------------------
@pytest.mark.parametrize("ticks_since", [1, 0, -3])
def test_slew_limit_allows_one_period_at_and_before_the_last_commands_tick(ticks_since):
    """A command at the last command's tick, or before it (a fallback tick extrapolated ahead of a
    returning estimate), may still move by one period's worth, not zero and not backwards."""
    step = SLEW * DT
    up = limit_command(500.0, 100.0, True, ticks_since, SLEW, DT, -500.0, 500.0)
    down = limit_command(-500.0, 100.0, True, ticks_since, SLEW, DT, -500.0, 500.0)
    assert up == pytest.approx(100.0 + step, rel=1e-12)
    assert down == pytest.approx(100.0 - step, rel=1e-12)
    # A command already within one period's step passes unchanged.
    assert limit_command(100.4, 100.0, True, ticks_since, SLEW, DT, -500.0, 500.0) == 100.4


@pytest.mark.parametrize("law", ["adaptive_backstepping", "pid", "lqr"])
def test_the_first_command_is_not_rate_limited(law):
    """No command before: nothing to limit the rate from; only the saturation applies."""
    z, th, f = estimate(0)
    cmd = controller(law).compute(0, z + np.array([0.01, 0.0, 0.0, 0.0]), th, f + 50.0)
    assert abs(cmd.u_unsaturated) > 10 * SLEW * DT  # the case would show a rate limit
    assert cmd.u == min(max(cmd.u_unsaturated, CHAIN.u_min), CHAIN.u_max)


def test_slew_limit_scales_with_the_ticks_since_the_last_command_then_saturates():
    assert limit_command(500.0, 100.0, True, 7, SLEW, DT, -500.0, 500.0) == pytest.approx(107.0, rel=1e-12)
    assert limit_command(900.0, 0.0, False, 1, SLEW, DT, -500.0, 500.0) == 500.0  # first: saturation only
    assert limit_command(900.0, 499.5, True, 1, SLEW, DT, -500.0, 500.0) == 500.0  # slew, then the limit
    assert limit_command(-900.0, -499.5, True, 1, SLEW, DT, -500.0, 500.0) == -500.0


# -- refusals: non-finite estimate, non-finite law output ----------------------------------
def drive(ctrl: Controller, ticks: range) -> None:
    for k in ticks:
        z, th, f = estimate(k)
        ctrl.compute(k, z, th, f)


def assert_fallback_step(cmd, before: float) -> None:
    """The fallback command: toward fallback_force by at most one period's slew, asked for exactly."""
    assert cmd.mode == "fallback"
    assert cmd.u_unsaturated == CHAIN.fallback_force
    assert cmd.tracking_error == (0.0, 0.0, 0.0)  # no law error: the law did not command this
    expected = min(max(CHAIN.fallback_force, before - SLEW * DT), before + SLEW * DT)
    assert cmd.u == pytest.approx(expected, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("law", [name for name in LAW_NAMES if name != "passive"])
@pytest.mark.parametrize("bad", ["z_hat", "theta_hat"])
def test_a_non_finite_estimate_never_reaches_a_law_that_reads_it(law, bad):
    ctrl = controller(law)
    drive(ctrl, range(30))
    before = ctrl.last_u
    z, th, f = estimate(30)
    z, th = z.copy(), th.copy()
    (z if bad == "z_hat" else th)[1] = math.nan
    cmd = ctrl.compute(30, z, th, f)
    assert_fallback_step(cmd, before)
    assert ctrl.law_tick is None  # the law restarts at its next command


def test_the_passive_law_ignores_a_non_finite_estimate():
    ctrl = controller("passive")
    cmd = ctrl.compute(5, np.full(4, math.nan), np.full(3, math.inf), math.nan)
    assert cmd.mode == "passive"
    assert cmd.u == pytest.approx(ctrl.reference.at(5 * DT)[0], rel=1e-12)


def test_a_non_finite_force_estimate_falls_back_only_for_the_law_that_reads_it():
    line = controller("line_adaptive")
    drive(line, range(10))
    before = line.last_u
    z, th, _ = estimate(10)
    assert_fallback_step(line.compute(10, z, th, math.nan), before)
    for law in ("adaptive_backstepping", "pid", "lqr"):
        other = controller(law)
        assert other.compute(10, z, th, math.nan).mode == "active", law


@pytest.mark.parametrize("law", ["adaptive_backstepping", "pid", "lqr"])
def test_a_non_finite_law_output_is_answered_by_the_fallback(law):
    """Finite but absurd estimates make the law's arithmetic overflow: its output never reaches
    the actuator."""
    ctrl = controller(law)
    drive(ctrl, range(20))
    before = ctrl.last_u
    z = np.array([1e308, -1e308, 1e308, -1e308])
    theta = np.array([1e308, 1e308, 1e308])
    probe = copy.deepcopy(ctrl)
    u_law, _ = probe.law.output(20, 20 * DT, probe.reference.at(20 * DT), z, theta, 1e308)
    assert not math.isfinite(u_law)  # the case does reach the branch
    assert_fallback_step(ctrl.compute(20, z, theta, 1e308), before)


# -- the fallback: force, slew, return -------------------------------------------------------
def test_the_fallback_reaches_its_force_at_the_slew_rate_and_stays_there():
    ctrl = controller("passive", reference=ReferenceParameters(shape="constant", force_amplitude=300.0))
    ctrl.last_u, ctrl.last_tick = 300.0, 99  # the actuator at 300 N
    cmds = [ctrl.fallback(k) for k in range(100, 400)]
    expected = np.maximum(300.0 - SLEW * DT * np.arange(1, 301), CHAIN.fallback_force)
    np.testing.assert_allclose([c.u for c in cmds], expected, rtol=1e-12)
    assert cmds[-1].u == CHAIN.fallback_force
    # Each says F_r at its own time (the reference still rising from 0 here).
    f_r = [ctrl.reference.at(k * DT)[0] for k in range(100, 400)]
    np.testing.assert_allclose([c.force_reference for c in cmds], f_r, rtol=1e-12)
    assert f_r[0] < 0.9 * f_r[-1]


def test_a_fallback_at_a_tick_not_after_the_last_command_is_still_slew_limited():
    ctrl = controller("passive")
    ctrl.last_u, ctrl.last_tick = 300.0, 50
    assert ctrl.fallback(50).u == pytest.approx(299.0, rel=1e-12)
    assert ctrl.fallback(40).u == pytest.approx(298.0, rel=1e-12)


@pytest.mark.parametrize("law", ["pid", "lqr"])
def test_after_a_fallback_the_law_returns_bumplessly_from_the_actuators_force(law):
    """The law's first command after a fallback continues from the force the actuator holds (its
    integrator set so), and is its own again (active)."""
    ctrl = controller(law)
    drive(ctrl, range(200))
    fallback = ctrl.compute(200, np.full(4, math.nan), THETA, math.nan)
    assert fallback.mode == "fallback"
    z, th, f = estimate(201)
    back = ctrl.compute(201, z, th, f)
    assert back.mode == "active"
    assert back.u_unsaturated == pytest.approx(fallback.u, rel=1e-9, abs=1e-9)
    assert ctrl.law_tick == 201


@pytest.mark.parametrize("law", ["pid", "lqr"])
def test_a_stale_tick_restarts_the_law_from_the_actuators_force(law):
    """An estimate whose tick is not after the law's last command (a new run, a re-sent sample
    the node did not catch) restarts the law: bumpless, not from its old integrator."""
    ctrl = controller(law)
    drive(ctrl, range(300))
    last = ctrl.last_u
    z, th, f = estimate(10)
    cmd = ctrl.compute(10, z, th, f)
    assert cmd.mode == "active"
    assert cmd.u_unsaturated == pytest.approx(last, rel=1e-9, abs=1e-9)


def test_the_line_laws_commands_are_passive_once_its_guard_has_tripped():
    """Through the chain: one span far above the passive spans' force error trips line_adaptive's
    guard at its end; from the next command on the commands say passive, the feedforward fades
    out over that span (within the ramp 1 - j / N of its peak) and from the span after they are F_r."""
    fast = dataclasses.replace(CHAIN, slew_rate_max=1e9)  # the limits do not shape the fade
    ctrl = controller("line_adaptive", fast, ReferenceParameters(shape="constant"))
    law = ctrl.law
    n, w = law.period_ticks, law.omega_span
    runin = law.params[0]["line_runin_spans"]
    modes, offsets = [], []
    for k in range((runin + 3) * n):
        span = k // n
        a = 10.0 if span < runin else 100.0  # the first learning span: 10x passive
        f_r = ctrl.reference.at(k * DT)[0]
        cmd = ctrl.compute(k, *estimate(k)[:2], f_r - a * math.cos(w * k * DT))
        modes.append(cmd.mode)
        offsets.append(cmd.u - f_r)
        if span == runin + 2:
            assert cmd.u == pytest.approx(f_r, rel=1e-12)
    assert set(modes[: (runin + 1) * n]) == {"active"}
    assert set(modes[(runin + 1) * n :]) == {"passive"}
    peak = max(abs(x) for x in offsets[runin * n : (runin + 1) * n])
    fading = np.abs(offsets[(runin + 1) * n : (runin + 2) * n])
    assert peak > 0.0 and np.all(fading <= (1.0 - np.arange(n) / n) * peak + 1e-9)


@pytest.mark.parametrize("law", ["pid", "lqr"])
def test_the_same_tick_again_restarts_the_law_from_the_force_commanded(law):
    """A tick computed again (not after the law's last) restarts the law: its command continues
    from the force the actuator was given for that tick, not from what the law asked."""
    ctrl = controller(law)
    drive(ctrl, range(300))
    z, th, f = estimate(300)
    z = z + np.array([0.02, 0.0, 0.0, 0.0])  # a jump the slew limit holds back
    first = ctrl.compute(300, z, th, f)
    assert first.saturated and abs(first.u_unsaturated - first.u) > 5.0
    again = ctrl.compute(300, z, th, f)
    assert again.u_unsaturated == pytest.approx(first.u, rel=1e-9, abs=1e-9)


# -- one chain: the Python path of a law without a compiled form -----------------------------
class PythonLaw:
    """A shipped law seen through the Law protocol only (not a KernelLaw): the controller calls it
    from Python between the compiled parts of the chain."""

    def __init__(self, law: KernelLaw) -> None:
        self.inner = law
        self.uses_estimate = law.uses_estimate
        self.uses_contact_force = law.uses_contact_force

    @property
    def mode(self) -> str:
        return self.inner.mode

    def restart(self, u_applied):
        self.inner.restart(u_applied)

    def output(self, tick, t, f_r, z_hat, theta_hat, contact_force_hat=math.nan):
        return self.inner.output(tick, t, f_r, z_hat, theta_hat, contact_force_hat)

    def commit(self, tick, u_applied):
        self.inner.commit(tick, u_applied)


def episode(ctrl: Controller) -> list:
    """Every branch of the chain: answers, a non-finite z_hat, a non-finite F_hat, watchdog
    fallbacks (ahead of and at the last tick), a gap, a stale tick, a new run."""
    out = []
    for k in range(400):
        z, th, f = estimate(k)
        if k in (50, 51):
            z = np.full(4, math.nan)
        if k == 120:
            f = math.inf
        if 200 <= k < 230:  # the watchdog's fallbacks instead of answers
            out.append(ctrl.fallback(k + 3))
            continue
        if k in (300, 301, 302):  # lost estimates: a gap
            continue
        out.append(ctrl.compute(k, z, th, f))
    for k in (350, 10, 11, 12):  # a stale tick, then a new run
        z, th, f = estimate(k)
        out.append(ctrl.compute(k, z, th, f))
    return out


@pytest.mark.parametrize("law", LAW_NAMES)
def test_a_law_called_from_python_gets_the_same_commands_as_the_compiled_chain(law):
    compiled = controller(law)
    # the law's compiled form: a kernel law's record, or a law module's chain (user_law.UserLaw)
    assert isinstance(compiled.law, KernelLaw) or (
        isinstance(compiled.law, UserLaw) and compiled.law.file.compiled
    )
    twin = controller(law)
    python = Controller(PythonLaw(twin.law), twin.params, twin.reference.params, DT, name=law)
    a, b = episode(compiled), episode(python)
    assert [c.mode for c in a] == [c.mode for c in b]
    assert "fallback" in {c.mode for c in a}
    assert a == b  # within one machine, the same arithmetic: equal bit for bit


class ConstantLaw:
    """The least a Law declares: it reads the estimate, says nothing of F_hat."""

    mode = "active"
    uses_estimate = True

    def restart(self, u_applied):
        pass

    def output(self, tick, t, f_r, z_hat, theta_hat):
        return 123.0, (0.0, 0.0, 0.0)

    def commit(self, tick, u_applied):
        pass


def test_a_python_law_that_does_not_say_it_reads_the_force_estimate_is_not_refused_for_it():
    ctrl = Controller(ConstantLaw(), CHAIN, ReferenceParameters(), DT)
    z, th, _ = estimate(0)
    assert ctrl.compute(0, z, th, math.nan).mode == "active"
    assert ctrl.compute(1, np.full(4, math.nan), th, 100.0).mode == "fallback"


@pytest.mark.parametrize("law", ["pid", "lqr"])
def test_a_new_controller_starts_its_law_afresh_whatever_the_law_did_before(law):
    """A controller around a law that has run (the law's records are the controller's) restarts it
    before its first command, even at a later tick: the command is a fresh law's."""
    used = controller(law)
    drive(used, range(300))
    again = Controller(used.law, used.params, used.reference.params, DT, name=law)
    fresh = controller(law)
    z, th, f = estimate(400)
    assert again.compute(400, z, th, f) == fresh.compute(400, z, th, f)


# -- the watchdog ------------------------------------------------------------------------------
@pytest.mark.parametrize("watchdog_ticks", [1, 20, 100])
def test_the_watchdog_falls_back_at_exactly_its_tick(watchdog_ticks):
    """Half a period before ``watchdog_ticks`` ticks have passed: nothing; half a period after:
    the fallback, for the tick the loop has reached."""
    before = watchdog_fallback_tick((watchdog_ticks - 0.5) * DT, DT, watchdog_ticks, 1000, 1000)
    at = watchdog_fallback_tick((watchdog_ticks + 0.5) * DT, DT, watchdog_ticks, 1000, 1000)
    assert before == (watchdog_ticks - 1, None)
    assert at == (watchdog_ticks, 1000 + watchdog_ticks)


def test_the_watchdog_never_commands_a_tick_already_commanded_and_is_off_at_zero():
    # Fallbacks already went out up to tick 1030: the next one is 1031, not 1000 + age.
    assert watchdog_fallback_tick(25.5 * DT, DT, 20, 1000, 1030) == (25, 1031)
    assert watchdog_fallback_tick(1e6 * DT, DT, 0, 1000, 1000)[1] is None


@pytest.mark.parametrize("watchdog_ticks", [1, 20])
def test_the_node_asks_the_watchdog_with_its_clock_and_sends_that_tick(monkeypatch, watchdog_ticks):
    """controller_node.on_watchdog without DDS: the clock is the test's, the publisher records."""
    from pac_controller import controller_node

    sent = []
    node = controller_node.ControllerNode.__new__(controller_node.ControllerNode)
    node.core = controller("pid", dataclasses.replace(CHAIN, watchdog_ticks=watchdog_ticks))
    node.loop = type("Loop", (), {"sample_period": DT})()
    node.active, node.run_last_tick, node.in_fallback = True, None, False
    node.last_estimate_tick, node.last_estimate_wall = 1000, 50.0
    node.fallback_episodes = node.fallback_commands = 0
    node.core.last_u, node.core.last_tick = 150.0, 1000
    node.publish = lambda cmd, age: sent.append((cmd.tick, cmd.mode, age))
    node.get_logger = lambda: type("Log", (), {"warning": lambda *a, **k: None})()
    now = [50.0 + (watchdog_ticks - 0.5) * DT]
    monkeypatch.setattr(controller_node.time, "monotonic", lambda: now[0])
    node.on_watchdog()
    assert sent == []
    now[0] = 50.0 + (watchdog_ticks + 0.5) * DT
    node.on_watchdog()
    w = watchdog_ticks
    assert sent == [(1000 + w, "fallback", w)] and node.in_fallback and node.fallback_episodes == 1
    now[0] = 50.0 + (watchdog_ticks + 1.5) * DT
    node.on_watchdog()  # the same episode goes on, one tick later
    assert sent[1:] == [(1001 + w, "fallback", w + 1)]
    assert node.fallback_episodes == 1 and node.fallback_commands == 2


def test_the_compiled_records_keep_the_capabilities_of_each_law():
    """The chain asks the records what a law reads, not which law it is."""
    for law in LAW_NAMES:
        record = controller(law).record[0]
        assert bool(record["uses_estimate"]) == (law != "passive"), law
        assert bool(record["uses_contact_force"]) == (law == "line_adaptive"), law
    assert kernels.MODES[2] == "fallback"


def test_the_estimate_check_reads_the_estimate_it_is_given_and_no_further():
    """Every element of z_hat (4) and theta_hat (3) is checked, and nothing past them: the compiled
    check has no bounds checks, so a loop one element too long would read whatever memory follows
    (and might refuse a sound estimate, or pass by chance). Run as Python, where it would raise."""
    check = kernels.estimate_refused.py_func
    p = dataclasses.make_dataclass("P", ["uses_estimate", "uses_contact_force"])(True, False)
    z_hat, theta_hat = np.zeros(4), np.zeros(3)
    assert not check(p, z_hat, theta_hat, math.nan)
    for values, i in ((z_hat, 3), (theta_hat, 2)):
        values[i] = math.inf
        assert check(p, z_hat, theta_hat, 0.0)
        values[i] = 0.0
