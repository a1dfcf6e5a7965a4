"""FE catenary: statics, wave speed, stiffness profile, energy, slack droppers,
Woodbury against a direct solve, mesh/step convergence of the contact-force statistics."""

import math

import numpy as np
import pytest
from fe_step_oracle import NumpyStep

from pac_common.contact_statistics import contact_statistics
from pac_plant.catenary.data import CatenaryData, NumericalOptions
from pac_plant.catenary.integrator import ContactSimulation, PassivePantograph
from pac_plant.catenary.line import DOFS_PER_NODE, WC, Line
from pac_plant.catenary.pantographs import paper_pantograph, three_mass_pantograph

pytestmark = pytest.mark.offline

DATA = CatenaryData()


@pytest.fixture(scope="module")
def line10():
    return Line()


@pytest.mark.slow
def test_static_sag_meets_the_target_presag_at_every_dropper(line10):
    dr = line10.droppers
    achieved = -line10.w_static[dr.wc]
    assert len(dr.node) == 90
    assert np.max(np.abs(achieved - dr.target_sag)) < 2e-3
    assert np.all(dr.static_tension > 0.0)  # every dropper hangs in tension
    # Messenger sags far more than the contact wire (it carries the droppers).
    assert np.min(line10.w_static[dr.wm]) < -0.3


@pytest.mark.slow
def test_transverse_wave_speed_is_sqrt_t_over_rho():
    """A pulse on the bare contact wire (no droppers, no supports) travels at sqrt(T / rho) within 2 %."""
    line = Line(n_spans=2, droppers=False, supports=False, options=NumericalOptions(element_size=0.25))
    sim = ContactSimulation(line, paper_pantograph(), 2.5e-4, 0.0, 2.0, damping=False)
    x = line.x
    x0, s = 55.0, 2.0
    d = np.zeros(line.n_dof)
    d[DOFS_PER_NODE * np.arange(line.n_nodes) + WC] = 0.01 * np.exp(-(((x - x0) / s) ** 2))
    wc = DOFS_PER_NODE * np.arange(line.n_nodes) + WC
    d[wc + 1] = -2 * (x - x0) / s**2 * d[wc]
    sim.set_line_state(d, np.zeros(line.n_dof))
    peaks = []
    times = []
    for k in range(1, 1201):
        sim.step(0.0)
        if k % 200 == 0:
            w = sim.d[DOFS_PER_NODE * np.arange(line.n_nodes) + WC]
            right = x > x0 + 5.0
            i = np.flatnonzero(right)[np.argmax(w[right])]
            # Parabola through the three nodes around the maximum.
            a, b, c = w[i - 1], w[i], w[i + 1]
            peaks.append(x[i] + 0.5 * (a - c) / (a - 2 * b + c) * (x[i + 1] - x[i]))
            times.append(sim.time)
    speed = np.polyfit(times, peaks, 1)[0]
    expected = DATA.contact.wave_speed
    assert speed == pytest.approx(expected, rel=0.02)
    assert abs(speed - expected) / expected < 0.02


def test_static_stiffness_profile_along_a_span():
    line = Line(n_spans=6)
    L = DATA.span
    xs = np.linspace(2 * L, 3 * L, 111)
    k = line.static_stiffness(xs)
    k_next = line.static_stiffness(xs + L)
    assert np.max(np.abs(k - k_next) / k) < 0.02  # periodic with the span
    i_max, i_min = int(np.argmax(k)), int(np.argmin(k))
    assert min(xs[i_max] - 2 * L, 3 * L - xs[i_max]) < 1.0  # highest at a support
    assert abs(xs[i_min] - 2.5 * L) < 0.25 * L  # lowest around mid-span
    mid = float(line.static_stiffness(np.array([2.5 * L]))[0])
    estimate = 4 * (DATA.contact.tension + DATA.messenger.tension) / L  # 2.76 kN/m
    assert 0.7 * estimate < mid < 1.3 * estimate
    assert k[i_max] > 2.0 * k[i_min]


def _hamiltonian(sim, force):
    return sim.energy() - force * sim.p[sim.panto.input]


def test_energy_is_conserved_without_damping():
    """Undamped line + 3-mass pantograph in contact under a constant uplift: H drifts < 1e-9 relative."""
    line = Line(n_spans=2)
    undamped = three_mass_pantograph(dampings=(0.0, 0.0, 0.0))
    sim = ContactSimulation(line, undamped, 1e-3, 0.0, 30.0, damping=False)
    force = 60.0
    sim.start_static(force)
    v = np.zeros(line.n_dof)
    v[DOFS_PER_NODE * np.arange(line.n_nodes) + WC] = 0.05 * np.sin(8 * np.pi * line.x / line.length)
    h_static = _hamiltonian(sim, force)
    sim.set_line_state(sim.d, v)
    h0 = _hamiltonian(sim, force)
    kick = h0 - h_static
    assert kick > 0.01  # J
    worst = 0.0
    for _ in range(2000):
        sim.step(force)
        assert sim.in_contact and len(sim.slack) == 0  # the linear regime the identity holds in
        worst = max(worst, abs(_hamiltonian(sim, force) - h0))
    assert worst < 1e-9 * kick
    # With damping on, the same start loses energy.
    sim2 = ContactSimulation(line, three_mass_pantograph(), 1e-3, 0.0, 30.0, damping=True)
    sim2.start_static(force)
    sim2.set_line_state(sim2.d, v)
    for _ in range(2000):
        sim2.step(force)
    assert _hamiltonian(sim2, force) < h0 - 0.01 * kick


def test_dropper_goes_slack_under_a_large_uplift():
    line = Line(n_spans=3)
    x = DATA.span + DATA.dropper_positions[4]  # at the mid-span dropper of span 2
    sim = ContactSimulation(line, paper_pantograph(), 1e-3, 0.0, x)
    sim.start_static(50.0)
    assert len(sim.slack) == 0
    for k in range(3000):
        sim.step(50.0 + min(k, 1000) * 0.4)  # ramp to 450 N, then hold
    e = sim.dropper_elongation()
    assert len(sim.slack) >= 1
    assert np.all(e[sim.slack] < 0.0)  # slack ones are really compressed (length < L0)
    taut = np.setdiff1d(np.arange(len(e)), sim.slack)
    assert np.all(e[taut] >= 0.0)  # and no taut one is
    assert sim.contact_force == pytest.approx(450.0, rel=0.02)  # settled: F = uplift


def test_woodbury_step_equals_a_direct_solve():
    """One step with the contact and slack droppers active equals the dense direct solve of the same step."""
    line = Line(n_spans=2)
    panto = paper_pantograph()
    sim = ContactSimulation(line, panto, 1e-3, 80.0, 20.0)
    sim.start_static(100.0)
    for k in range(200):  # ramp the uplift until a step ends with a dropper slack
        d, v, a, p, vp, ap = (np.copy(q) for q in (sim.d, sim.v, sim.a, sim.p, sim.vp, sim.ap))
        x_new = sim.x + sim.speed * sim.dt
        force = 100.0 + 5.0 * k
        sim.step(force)
        if sim.in_contact and len(sim.slack):
            break
    assert sim.in_contact and len(sim.slack) >= 1  # the step really exercised both corrections
    n, m = line.n_dof, panto.n
    c0, c1 = 4 / sim.dt**2, 2 / sim.dt
    mm, kk = line.M.dense(), line.K.dense()
    cc = sim.alpha * mm + sim.beta * kk
    big = np.zeros((n + m, n + m))
    big[:n, :n] = kk + c0 * mm + c1 * cc
    pk = panto.stiffness + np.diag(panto.ground_stiffness)
    big[n:, n:] = pk + c0 * np.diag(panto.mass) + c1 * panto.damping
    rhs = np.zeros(n + m)
    rhs[:n] = mm @ (c0 * d + 4 / sim.dt * v + a) + cc @ (c1 * d + v)
    rhs[n:] = np.diag(panto.mass) @ (c0 * p + 4 / sim.dt * vp + ap) + panto.damping @ (c1 * p + vp)
    rhs[n:] += np.diag(panto.ground_stiffness) @ sim.roof_rest
    rhs[n + panto.input] += force
    dofs, shape = line.contact_interpolation(x_new)
    g = np.zeros(n + m)
    g[dofs] = -shape
    g[n + panto.head] = 1.0
    big += sim.kp * np.outer(g, g)
    rhs += sim.kp * line.static_height(x_new) * g
    for j in sim.slack:
        gj = np.zeros(n + m)
        gj[line.droppers.wm[j]], gj[line.droppers.wc[j]] = 1.0, -1.0
        kj = line.droppers.stiffness[j]
        big -= kj * np.outer(gj, gj)
        rhs += kj * line.droppers.elongation0[j] * gj
    q = np.linalg.solve(big, rhs)
    np.testing.assert_allclose(sim.d, q[:n], atol=1e-10)
    np.testing.assert_allclose(sim.p, q[n:], atol=1e-10)


def _passive_sigma(h: float, dt: float) -> float:
    line = Line(n_spans=6, options=NumericalOptions(element_size=h))
    v = 300 / 3.6
    force = 0.00097 * 300**2 + 70
    sim = ContactSimulation(line, three_mass_pantograph(), dt, v, DATA.span)
    sim.start_static(force)
    xs, fs = [], []
    while sim.x + v * dt < 4.2 * DATA.span:
        sim.step(force)
        xs.append(sim.x)
        fs.append(sim.contact_force)
    stats = contact_statistics(np.array(fs), np.array(xs), dt, 2 * DATA.span, 4 * DATA.span)
    return stats.contact_force_std


@pytest.mark.slow
def test_mesh_and_step_convergence_of_contact_force_sigma():
    """Halving the element size and the time step together changes sigma by less than 2 %."""
    coarse = _passive_sigma(0.5, 1e-3)
    fine = _passive_sigma(0.25, 5e-4)
    assert abs(coarse - fine) / fine < 0.02
    assert fine > 5.0  # a real dynamic response


@pytest.mark.slow
def test_fe_plant_has_the_plant_interface_and_settles_on_the_uplift():
    """FEPlant (catenary_model fe): slow run under a held u, F -> u, truth consistent with the line."""
    from pac_common import messages
    from pac_model.parameters import PantographParameters, TrackParameters
    from pac_plant.fe_plant import FEPlant
    from pac_plant.parameters import PlantOptions
    from pac_plant.plants import make_plant

    options = PlantOptions(catenary_model="fe")
    plant = make_plant(PantographParameters(), TrackParameters(speed_kmh=5.0), None, options, 1e-3)
    assert isinstance(plant, FEPlant)
    t0 = plant.truth()
    assert t0.contact_force == 0.0 and t0.z == (0.0, 0.0, 0.0, 0.0)  # starts touching, at rest
    for _ in range(8000):  # the slow mode (b2 = 30 N s/m only) decays in ~1.4 s
        plant.advance(100.0)
    truth, y = plant.truth(), plant.measurement()
    assert truth.contact_force == pytest.approx(100.0, rel=0.03)
    assert y.z1 == truth.z[0] and y.actuator_force == 100.0
    k_line = float(plant.line.static_stiffness(np.array([plant.sim.x]))[0])
    assert truth.stiffness == pytest.approx(k_line, rel=1e-9)
    assert truth.contact_uplift == pytest.approx(truth.contact_force / truth.stiffness, rel=0.05)
    assert truth.contact_position == pytest.approx(4 * DATA.span + 8.0 * 5.0 / 3.6, rel=1e-9)
    # fe_datum static_wire: the same state measured from the static wire under the contact point.
    import dataclasses

    fixed_z = plant.z
    plant.options = dataclasses.replace(options, fe_datum="static_wire")
    sag = plant.datum - plant.line.static_height(plant.sim.x)  # pre-sag here, relative to the start
    assert sag > 0.01  # 11 m into the span: the wire hangs lower than at the support
    np.testing.assert_allclose(plant.z[:2], fixed_z[:2] + sag, rtol=0, atol=1e-12)
    fields = messages.truth_fields(truth, 0, applied_command_tick=3999)
    assert fields["contact_uplift"] == truth.contact_uplift and math.isfinite(fields["support_uplift"])


def test_endless_window_equals_a_long_fixed_line():
    """A 6-span moving window over 5 spans (3 shifts) gives the contact force of a fixed 12-span line."""
    forces = {}
    for endless, n_spans in ((True, 6), (False, 12)):
        line = Line(n_spans=n_spans)
        v = 100.0
        sim = ContactSimulation(line, three_mass_pantograph(), 1e-3, v, 2 * DATA.span, endless=endless)
        sim.start_static(150.0)
        f = []
        for _ in range(int(5 * DATA.span / (v * 1e-3))):
            sim.step(150.0)
            f.append(sim.contact_force)
        forces[endless] = np.array(f)
        if endless:
            assert sim.offset == pytest.approx(3 * DATA.span)
            assert sim.position == pytest.approx(7 * DATA.span, abs=0.2)
    assert np.std(forces[False]) > 10.0
    # What the window drops (waves far behind, the far end) changes F by less than 1 mN here.
    np.testing.assert_allclose(forces[True], forces[False], rtol=0, atol=1e-3)


def test_live_lockstep_rig_on_the_fe_line_equals_the_offline_loop(rigs, tmp_path):
    """plant_node with catenary_model fe, 4 processes over DDS in lock step == pac_rig.closed_loop."""
    from conftest import assert_lockstep_equals_offline

    duration = 1.0
    fe = {"catenary_model": "fe", "speed_kmh": 300.0, "span_length": 55.0}
    rig = rigs("fe_lockstep", duration=duration, timing_mode="lockstep", params={"all": fe})
    rig.start()
    rig.wait_finished(timeout=180)
    assert set(rig.exit_codes().values()) == {0}, {n: p.log()[-500:] for n, p in rig.processes.items()}
    columns = {"plant_truth": ["contact_force", "contact_uplift"], "measurement": ["z1"], "command": ["u"]}
    offline = assert_lockstep_equals_offline(
        rig.bag_path, {"duration": duration, **fe}, tmp_path / "offline", columns
    )
    assert np.max(offline["plant_truth"]["contact_force"]) > 10.0  # the run pressed on the wire


# -- the compiled step (step.fe_step) against the numpy step (fe_step_oracle.NumpyStep) ---------
#: Largest difference allowed between the two paths, relative to the largest value of each
#: quantity: rounding (sums in another order, the two-chunk solve, the M-only right-hand side).
COMPILED_TOLERANCE = 1e-9


def _twin_simulations(line, endless=False, x0=None):
    make = lambda: ContactSimulation(  # noqa: E731
        line, three_mass_pantograph(), 1e-3, 300 / 3.6, DATA.span if x0 is None else x0, endless=endless
    )
    return make(), make()


def _assert_same_state(fast, ref):
    for name in ("d", "v", "a", "p", "vp", "ap"):
        got, want = getattr(fast, name), getattr(ref, name)
        scale = max(float(np.max(np.abs(want))), 1e-30)
        assert np.max(np.abs(got - want)) <= COMPILED_TOLERANCE * scale, name
    assert fast.in_contact == ref.in_contact
    np.testing.assert_array_equal(fast.slack, ref.slack)
    assert fast.delta == pytest.approx(ref.delta, rel=COMPILED_TOLERANCE, abs=1e-15)
    assert fast.x == ref.x and fast.offset == ref.offset
    # The active set's diagnostics, which the line runs report: passes taken, steps left unsettled.
    assert fast.active_set_passes_max == ref.active_set_passes_max >= 1
    assert fast.active_set_unconverged == ref.active_set_unconverged
    assert fast.steps == ref.steps


def test_compiled_step_equals_the_numpy_step_on_random_states():
    """Random line and pantograph states (contact on and off, droppers slack and taut, the window
    shift due): one compiled step equals one numpy step to rounding."""
    line = Line(n_spans=4)
    rng = np.random.default_rng(7)
    seen_slack = seen_free = seen_shift = 0
    for trial in range(24):
        shift = trial % 6 == 5  # just before the endless window's shift point
        x0 = (line.n_spans // 2 + 1) * DATA.span - 0.01 if shift else float(rng.uniform(60.0, 160.0))
        fast, ref = _twin_simulations(line, endless=True, x0=x0)
        d = rng.normal(0.0, 10 ** rng.uniform(-4.0, -2.5), line.n_dof)
        v = rng.normal(0.0, 0.05, line.n_dof)
        head = line.static_height(x0) + rng.normal(0.0, 0.004)
        p = ref.panto.static_positions(head, 0.0) + rng.normal(0.0, 1e-3, 3)
        for sim in (fast, ref):
            sim.set_line_state(d, v)
        fast.p = ref.p = p
        fast.vp = ref.vp = rng.normal(0.0, 0.1, 3)
        fast.ap = ref.ap = rng.normal(0.0, 1.0, 3)
        fast.in_contact = ref.in_contact = bool(trial % 2)
        force = float(rng.uniform(0.0, 300.0))
        fast.step(force)
        NumpyStep(ref)(force)
        _assert_same_state(fast, ref)
        seen_slack += len(ref.slack) > 0
        seen_free += not ref.in_contact
        seen_shift += ref.offset > 0.0
    assert seen_slack >= 3 and seen_free >= 3 and seen_shift >= 3  # every branch was exercised


def _assert_slack_exactly_where_compressed(sim, k):
    """A dropper is in the step's slack set exactly when its elongation, computed from the line's
    displacements (not by the step), is negative. 1 nm: rounding and the truncated contact columns
    are orders below it; a dropper decided wrongly is off by the step's own motion, 1e-5 m and more."""
    e = sim.dropper_elongation()
    slack = np.zeros(len(e), dtype=bool)
    slack[sim.slack] = True
    assert np.all(e[slack] < 1e-9) and np.all(e[~slack] > -1e-9), k
    return slack


@pytest.mark.parametrize(
    ("speed", "x0"),
    [(80.0, 20.0), (0.0, DATA.span + DATA.dropper_positions[4])],
    ids=["moving", "at_a_dropper"],
)
def test_every_step_ends_with_the_droppers_slack_that_are_compressed_and_no_other(speed, x0):
    """The active set's fixed point, checked from the state each step ends in: a dropper is in the
    slack set exactly when its elongation (computed from the line's displacements, not by the step)
    is negative. A run that pushes the head up until droppers go slack near it, then drops the
    uplift until the head leaves the wire, so that both the contact and the droppers change sets:
    moving, and standing at a dropper, where the contact's own push decides that dropper's set."""
    line = Line(n_spans=3)
    sim = ContactSimulation(line, paper_pantograph(), 1e-3, speed, x0)
    sim.start_static(100.0)
    seen_slack = seen_loss = 0
    for k in range(400):
        sim.step(100.0 + 5.0 * k if k < 200 else 0.0)  # up to 1.1 kN, then none
        slack = _assert_slack_exactly_where_compressed(sim, k)
        seen_slack += bool(slack.any())
        seen_loss += not sim.in_contact
    assert sim.active_set_unconverged == 0 and sim.active_set_passes_max >= 2
    assert seen_slack >= 10 and seen_loss >= 10  # both sets changed during the run


def test_two_contacts_and_slack_droppers_every_step_ends_on_its_sets():
    """Two pantographs pressing hard enough to slacken droppers under both, the leading one's
    uplift swinging until it leaves the wire: each step ends on its sets, checked from the state
    it ends in. A contact touches exactly when its head is above the wire at its point (head
    height against the static height plus the line's displacement there), and then presses with
    kp times that penetration; a dropper is slack exactly when it is compressed. Several contacts
    with slack droppers is the case where the contacts' coefficients follow the droppers'."""
    line = Line(n_spans=4)
    passive = (PassivePantograph(three_mass_pantograph(), 30.0, 400.0),)
    sim = ContactSimulation(line, paper_pantograph(), 1e-3, 40.0, 80.0, passive=passive)
    sim.start_touching()
    heads = sim.constants.p_heads
    both_with_slack = lost = 0
    for k in range(1500):
        sim.step(350.0 + 300.0 * math.sin(2 * math.pi * 7.0 * k * 1e-3))
        slack = _assert_slack_exactly_where_compressed(sim, k)
        touching = sim.state.touching.astype(bool)
        for c, x in enumerate(sim.x - sim.lags):
            dofs, n = line.contact_interpolation(x)
            penetration = sim.p[heads[c]] - line.static_height(x) - float(n @ sim.d[dofs])
            assert (penetration > -1e-9) if touching[c] else (penetration < 1e-9), (k, c)
            want = sim.kp * penetration if touching[c] else 0.0
            assert sim.contact_forces[c] == pytest.approx(want, rel=1e-6, abs=1e-6), (k, c)
        both_with_slack += bool(touching.all() and slack.any())
        lost += not touching[0]
    assert sim.active_set_unconverged == 0
    assert both_with_slack >= 100 and lost >= 20  # the sets the test is about were there


def test_a_steady_contact_settles_in_one_active_set_pass_per_step():
    """At rest under a constant uplift nothing changes set: each step starts from the last step's
    contact and slack sets (its warm start) and settles in one pass. A step that took two would
    double the cost of every step of a run and report it in the line runs' pass count."""
    line = Line(n_spans=3)
    sim = ContactSimulation(line, paper_pantograph(), 1e-3, 0.0, DATA.span + DATA.dropper_positions[4])
    sim.start_static(50.0)
    for _ in range(20):
        sim.step(50.0)
        assert sim.in_contact
    assert sim.active_set_passes_max == 1 and sim.contact_force == pytest.approx(50.0, rel=1e-6)


def test_a_step_whose_active_set_does_not_settle_keeps_the_set_it_solved_for(monkeypatch):
    """With one pass allowed, a step that starts with a contact set its solution contradicts does
    not settle: it keeps that set (the state is the solution computed for it), counts the step,
    and reports the penetration as the numpy step does. The pass limit is compiled in, so the
    compiled step's own source runs as Python (``fe_step.py_func``) with the limit patched."""
    from pac_plant.catenary import step

    monkeypatch.setattr(step, "MAX_ACTIVE_SET_PASSES", 1)  # the numpy step reads it too
    line = Line(n_spans=4)
    x0 = 100.0
    for in_contact, lift in ((False, 0.02), (True, -0.02)):  # head 2 cm into the wire / below it
        fast, ref = _twin_simulations(line, x0=x0)
        p = ref.panto.static_positions(line.static_height(x0) + lift, 0.0)
        for sim in (fast, ref):
            sim.p = p
            sim.in_contact = in_contact
        assert step.fe_step.py_func(fast.constants, fast.state, 150.0) == step.STEP_OK
        NumpyStep(ref)(150.0)
        _assert_same_state(fast, ref)
        assert fast.active_set_unconverged == 1 and fast.in_contact == in_contact
        # The penetration the kept set's solution has: into the wire when the contact was kept
        # off, out of it when kept on; reported as at most zero while off.
        # Off: exactly 0 (a clamp). On: the numpy step's, to the rounding of two implementations
        # (the same tolerance as every other field, _assert_same_state).
        kept = 0.0 if not in_contact else pytest.approx(ref.delta, rel=COMPILED_TOLERANCE, abs=1e-15)
        assert fast.delta == kept and (ref.delta < 0.0) == in_contact


def test_the_contact_point_is_found_in_the_element_that_holds_it_at_both_ends_of_the_line():
    """hermite_weights (the compiled step's locate) gives the element whose nodes enclose x, the first
    at the line's start and the last at its end (its last node included), with weights that
    interpolate: (1, 0, 0, 0) at the element's first node, (0, 0, 1, 0) at its second."""
    from pac_plant.catenary.step import hermite_weights

    x_nodes = Line(n_spans=2).x
    last = x_nodes.shape[0] - 2
    first_h, last_h = x_nodes[1] - x_nodes[0], x_nodes[-1] - x_nodes[-2]
    cases = [
        (x_nodes[0], 0, (1.0, 0.0, 0.0, 0.0)),
        (x_nodes[0] + 0.5 * first_h, 0, None),
        (x_nodes[1], 1, (1.0, 0.0, 0.0, 0.0)),
        (x_nodes[-2] + 0.5 * last_h, last, None),
        (x_nodes[-1], last, (0.0, 0.0, 1.0, 0.0)),
    ]
    for x, element, at_node in cases:
        e, n = hermite_weights(x_nodes, float(x))
        assert e == element and x_nodes[e] <= x <= x_nodes[e + 1], x
        if at_node is not None:
            np.testing.assert_allclose(n, at_node, rtol=0, atol=1e-12, err_msg=f"x = {x}")
        assert n[0] + n[2] == pytest.approx(1.0, abs=1e-12)  # the shapes of w sum to one


def _random_spd_band(rng: np.random.Generator, n: int, kd: int) -> tuple[np.ndarray, np.ndarray]:
    """(A, ab): a random SPD n x n matrix with kd sub-diagonals (all non-zero, diagonally dominant)
    and its LAPACK lower band storage ab[k, j] = A[j + k, j]."""
    a = np.zeros((n, n))
    for k in range(1, min(kd, n - 1) + 1):
        off = rng.uniform(-1.0, 1.0, n - k)
        a += np.diag(off, k) + np.diag(off, -k)
    a += np.diag(2.0 * kd + rng.uniform(1.0, 2.0, n))  # diagonally dominant: SPD
    ab = np.zeros((kd + 1, n))
    for k in range(min(kd, n - 1) + 1):
        ab[k, : n - k] = np.diag(a, -k)
    return a, ab


def test_a_chunked_solve_of_a_load_on_a_few_rows_is_the_whole_solves_rows():
    """chunk_solve told that b is zero outside rows first..last and that only rows from keep on
    are wanted: those rows bit for bit the whole solve's whatever its scratch held (NaN here), for
    loads inside one chunk, across a chunk's bound and at the ends."""
    from pac_plant.catenary.banded import CHUNKS, KD, chunk_factor, chunk_solve

    rng = np.random.default_rng(11)
    _, ab = _random_spd_band(rng, 1000, KD)
    factors, starts, bounds = chunk_factor(ab)
    n = ab.shape[1]
    cases = [(500, 501, 420), (bounds[3], bounds[3] + 2, bounds[3] - 80), (0, 3, 0), (n - 2, n, n - 90)]
    for first, last, keep in [*cases, (300, 700, 0), (10, 11, 990)]:
        b = np.zeros(n)
        b[first:last] = rng.uniform(-1.0, 1.0, last - first)
        whole = b.copy()
        chunk_solve(factors, starts, bounds, whole, np.zeros((factors.shape[0], CHUNKS)), whole[:0])
        part = b.copy()
        chunk_solve(
            factors,
            starts,
            bounds,
            part,
            np.full((factors.shape[0], CHUNKS), np.nan),
            part[:0],
            first,
            last,
            keep,
        )
        assert part[keep:].tobytes() == whole[keep:].tobytes(), (first, last, keep)
        below = part[:keep]  # each row b's or the whole solve's (the sweep's last groups)
        assert np.all(
            (below.view(np.int64) == b[:keep].view(np.int64))
            | (below.view(np.int64) == whole[:keep].view(np.int64))
        )


@pytest.mark.parametrize("compiled", [True, False])
def test_the_banded_cholesky_solve_is_a_dense_solve(compiled):
    """band_chol_solve on chol_factor's factor solves A x = b as a dense solve does, for an SPD matrix
    of the line's band width (7 sub-diagonals, all non-zero here) and at sizes below it. Also run as
    plain Python (``py_func``: the same source interpreted, every index checked), so that a loop
    that reads or writes past the vector fails instead of passing silently."""
    from pac_plant.catenary.banded import band_chol_solve, chol_factor

    rng = np.random.default_rng(11)
    kd = 7
    solve = band_chol_solve if compiled else band_chol_solve.py_func
    for n in (1, 3, kd + 1, 40):
        a, ab = _random_spd_band(rng, n, kd)
        b = rng.normal(size=n)
        x = b.copy()
        solve(chol_factor(ab), x)
        np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-12, atol=1e-14, err_msg=f"n = {n}")


@pytest.mark.parametrize("compiled", [True, False])
def test_the_banded_cholesky_is_the_dense_one_and_refuses_what_is_not_positive_definite(compiled):
    """band_cholesky's L (LAPACK lower band storage) equals numpy's dense Cholesky factor to
    rounding, on SPD matrices of the line's band width and below it; a matrix with a negative
    pivot, or a NaN, is refused with ValueError. band_chol_solve_columns gives each column's
    band_chol_solve to the bit, also when told where the loads start and which rows are wanted.
    Also as plain Python (``py_func``: every index checked)."""
    from pac_plant.catenary.banded import band_chol_solve, band_chol_solve_columns, band_cholesky, chol_factor

    rng = np.random.default_rng(12)
    kd = 7
    factor = band_cholesky if compiled else band_cholesky.py_func
    for n in (1, 3, kd + 1, 40):
        a, ab = _random_spd_band(rng, n, kd)
        low = factor(ab)
        dense = np.linalg.cholesky(a)
        for k in range(min(kd, n - 1) + 1):
            np.testing.assert_allclose(low[k, : n - k], np.diag(dense, -k), rtol=1e-13, atol=1e-15)
        b = rng.normal(size=(n, 5))
        together = b.copy()
        (band_chol_solve_columns if compiled else band_chol_solve_columns.py_func)(chol_factor(ab), together)
        for c in range(5):
            alone = b[:, c].copy()
            band_chol_solve(chol_factor(ab), alone)
            np.testing.assert_array_equal(together[:, c], alone)
        # Loads from row `first` on, rows from `stop` on wanted: the same bits there.
        first, stop = n // 3, n // 2
        b[:first] = 0.0
        whole, part = b.copy(), b.copy()
        band_chol_solve_columns(chol_factor(ab), whole)
        band_chol_solve_columns(chol_factor(ab), part, first, stop)
        np.testing.assert_array_equal(part[stop:], whole[stop:])
        bad = ab.copy()
        bad[0, n // 2] = -1.0
        with pytest.raises(ValueError, match="not positive definite"):
            factor(bad)
        bad[0, n // 2] = np.nan
        with pytest.raises(ValueError, match="not positive definite"):
            factor(bad)


def test_fast_kernels_equal_the_banded_reference():
    """Chunked solve (8 LDL^T chains in vector lanes) = one banded Cholesky solve; the M-only
    right-hand side = M x1 + beta K w; a stored contact-column or slack-dropper patch = the full
    column A^-1 e_i or A^-1 g_j (outside the patch: < 1e-19 and < 1e-18 of the peak)."""
    from pac_plant.catenary.banded import KD, band_chol_solve, chunk_solve
    from pac_plant.catenary.newmark import newmark_rhs, newmark_rhs_mass
    from pac_plant.catenary.step import _unit_patches, unit_start

    line = Line(n_spans=4)
    sim, _ = _twin_simulations(line)
    c = sim.constants
    rng = np.random.default_rng(3)
    for _ in range(5):
        d, v, a = (rng.normal(0.0, s, line.n_dof) for s in (1e-3, 0.05, 5.0))
        for q in (d, v, a):
            q[line.fixed] = 0.0
        rhs = np.empty(line.n_dof)
        scratch = np.empty((2, line.n_dof))
        newmark_rhs(sim._m, sim._k, d, v, a, sim.dt, sim.alpha, sim.beta, scratch[0], scratch[1], rhs)
        want = rhs.copy()
        band_chol_solve(sim._chol, want)
        got, tail = np.empty_like(d), np.empty_like(d)
        z = np.zeros(line.n_dof + 2 * KD)
        newmark_rhs_mass(c.m_pad, d, v, a, sim.dt, sim.alpha, sim.beta, z, tail, got)
        work = np.zeros_like(sim.state.chunk_work)
        chunk_solve(c.chunk_factors, c.chunk_starts, c.chunk_bounds, got, work, tail)
        assert np.max(np.abs(got - want)) < 1e-12 * np.max(np.abs(want))
        plain = rhs.copy()
        chunk_solve(c.chunk_factors, c.chunk_starts, c.chunk_bounds, plain, work, tail[:0])
        assert np.max(np.abs(plain - want)) < 1e-13 * np.max(np.abs(want))
    # Slack-dropper patches against the full columns A^-1 g_j: outside the patch < 1e-18 of the
    # column's peak (measured 5.8e-19; a dropper column is the difference of two unit columns,
    # so its peak is smaller than theirs), 200x below the rounding of the peak itself.
    width = c.ydrop_patches.shape[1]
    dr = line.droppers
    whole = np.zeros((line.n_dof, len(dr.node)))  # A^-1 g_j over the whole line
    for j, node in enumerate(dr.node):
        lo = unit_start(line.n_dof, width, int(node))
        col = np.zeros(line.n_dof)
        col[[dr.wm[j], dr.wc[j]]] = 1.0, -1.0
        band_chol_solve(sim._chol, col)
        whole[:, j] = col
        peak = np.max(np.abs(col))
        np.testing.assert_array_equal(c.ydrop_patches[j], col[lo : lo + width])
        assert np.max(np.abs(np.concatenate([col[:lo], col[lo + width :]]))) < 1e-18 * peak
    # D = G^T A^-1 G from the patches: the whole columns' within the same 1e-18.
    coupling = whole[dr.wm, :] - whole[dr.wc, :]
    assert np.max(np.abs(c.ddrop - coupling)) < 1e-18 * np.max(np.abs(coupling))
    # Contact-column patches against full columns, at a support, a dropper and mid-element nodes.
    node = 2 * line.nodes_per_span
    for i in (node, node + 9, node + 50):
        sim.state.unit_ready[i] = 0
        sim.state.work[0, :] = 0.0
        _unit_patches(c, sim.state, i)
        width = sim.state.unit_patches.shape[2]
        lo = unit_start(line.n_dof, width, i)
        for r in range(2):
            col = np.zeros(line.n_dof)
            col[4 * i + r] = 1.0
            band_chol_solve(sim._chol, col)
            peak = np.max(np.abs(col))
            assert np.max(np.abs(sim.state.unit_patches[i, r] - col[lo : lo + width])) < 1e-13 * peak
            whole = np.zeros(line.n_dof)  # the chunked solve of the whole column: bit for bit
            whole[4 * i + r] = 1.0
            chunk_solve(c.chunk_factors, c.chunk_starts, c.chunk_bounds, whole, work, whole[:0])
            assert sim.state.unit_patches[i, r].tobytes() == whole[lo : lo + width].tobytes()
            outside = np.concatenate([col[:lo], col[lo + width :]])
            assert np.max(np.abs(outside)) < 1e-19 * peak


@pytest.mark.slow
def test_compiled_reference_run_equals_the_numpy_run():
    """The 300 km/h reference run (10-span line, 3-mass, passive): contact force, uplift and
    slack droppers of the compiled path equal the numpy path's over the whole run."""
    line = Line()
    fast, ref = _twin_simulations(line)
    force = 0.00097 * 300**2 + 70
    fast.start_static(force)
    ref.start_static(force)
    f_fast, f_ref, slack = [], [], 0
    ref_step = NumpyStep(ref)
    while ref.x + ref.speed * ref.dt < 6.5 * DATA.span:
        fast.step(force)
        ref_step(force)
        f_fast.append(fast.contact_force)
        f_ref.append(ref.contact_force)
        slack = max(slack, len(ref.slack))
        np.testing.assert_array_equal(fast.slack, ref.slack)
    f_fast, f_ref = np.array(f_fast), np.array(f_ref)
    assert slack >= 1  # droppers went slack on the way
    assert np.max(np.abs(f_fast - f_ref)) <= COMPILED_TOLERANCE * np.max(np.abs(f_ref))
    assert fast.uplift() == pytest.approx(ref.uplift(), rel=COMPILED_TOLERANCE)


def test_packed_buffers_hold_every_array_bit_for_bit_and_share_its_memory() -> None:
    """``pack`` leaves arrays of zeros to the new buffer's zero pages; a negative zero, integers
    and numbers are copied, and each view is the buffer's memory."""
    from pac_plant.catenary.packing import pack

    rng = np.random.default_rng(3)
    arrays = (
        np.zeros((3, 5)),
        np.full(7, -0.0),
        rng.standard_normal((2, 3, 4)),
        np.arange(-4, 5, dtype=np.int64),
        np.zeros(9, dtype=np.int64),
        rng.standard_normal(1),
    )
    floats, ints, layout, views = pack(arrays, ("f2", "f1", "f3", "i1", "i1", "f1"))
    for arr, view in zip(arrays, views, strict=True):
        assert view.shape == arr.shape and view.dtype == arr.dtype
        assert view.tobytes() == arr.tobytes()
        assert np.shares_memory(view, ints if arr.dtype == np.int64 else floats)
    assert np.signbit(views[1]).all()
    assert layout[2, 1:].tolist() == [2, 3, 4]
