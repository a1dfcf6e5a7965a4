"""Several pantographs on one FE line: the leading one equals a lone pantograph until the trailing
one's wave can reach it (arrival time from the contact wire's wave speed, not from the model), the
static state of two close pantographs against an independent static solve (superposition), the
endless window with two contact points against a long fixed line, the plant's per-pantograph truth,
and the refusals of bad ``pantographs`` values (one line, exit 2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pac_common.parameters import ParameterError
from pac_model.parameters import PantographParameters, TrackParameters
from pac_plant.catenary.catenary_file import load_catenary
from pac_plant.catenary.integrator import ContactSimulation, PassivePantograph
from pac_plant.catenary.line import Line
from pac_plant.catenary.pantographs import paper_pantograph, three_mass_pantograph
from pac_plant.fe_plant import FEPlant, window_periods
from pac_plant.parameters import PlantOptions

pytestmark = pytest.mark.offline

LINE = load_catenary("benchmark_55m")
SPACING = 200.0  # m, the benchmark's two-pantograph case
DT = 1e-3


def _window_run(speed_kmh: float, two: bool, steps: int) -> np.ndarray:
    """Contact forces (steps x contacts) of passive 3-mass pantographs on the plant's endless window
    laid out for SPACING, from rest (heads just touching, uplift from t = 0)."""
    periods, start = window_periods(LINE.data, SPACING)
    line = Line(LINE.data, LINE.numerics, n_spans=periods * len(LINE.data.spans))
    force = 0.00097 * speed_kmh**2 + 70.0
    passive = (PassivePantograph(three_mass_pantograph(), SPACING, force),) if two else ()
    sim = ContactSimulation(
        line,
        three_mass_pantograph(),
        DT,
        speed_kmh / 3.6,
        start * LINE.data.period,
        endless=True,
        passive=passive,
        window_lag=SPACING,
    )
    out = np.empty((steps, 1 + len(passive)))
    for k in range(steps):
        sim.step(force)
        out[k] = sim.contact_forces
    assert sim.offset > 0.0  # the window did shift
    return out


@pytest.mark.slow
@pytest.mark.parametrize("speed_kmh", [250.0, 320.0])
def test_the_leading_pantograph_equals_a_lone_one_until_the_trailing_wave_can_reach_it(speed_kmh):
    """The trailing pantograph's disturbance runs forward along the contact wire at c = sqrt(T / rho)
    over ground while the leading one runs away at v: it closes the 200 m at c - v. Before that the
    leading pantograph's force is the lone pantograph's (rounding only: < 1 uN); after, it is not
    (> 1 N within 3 s; measured: 0.7 s after the arrival at 250 km/h, 1.9 s at 320 km/h, where the
    wave closes in at only 39 m/s)."""
    c = math.sqrt(LINE.data.contact.tension / LINE.data.contact.rho)  # 127.7 m/s: the data, not the model
    v = speed_kmh / 3.6
    arrival = SPACING / (c - v)  # 3.44 s at 250 km/h, 5.16 s at 320 km/h
    steps = int((arrival + 3.0) / DT)
    lone, two = _window_run(speed_kmh, False, steps), _window_run(speed_kmh, True, steps)
    t = DT * np.arange(1, steps + 1)
    diff = np.abs(two[:, 0] - lone[:, 0])
    assert np.std(lone[:, 0]) > 10.0  # the leading pantograph does feel the line
    assert diff[t < arrival].max() < 1e-6, diff[t < arrival].max()
    assert diff[t >= arrival].max() > 1.0, diff[t >= arrival].max()
    # The trailing pantograph rides the disturbed wire from the start: it differs from the lone one.
    assert np.abs(two[:, 1] - lone[:, 0]).max() > 1.0


@pytest.mark.parametrize("lag", [5.0, 0.3])
def test_two_close_pantographs_at_rest_stay_in_the_static_solution_of_both_forces(lag):
    """Two pantographs 5 m or 0.3 m apart (0.3 m: in one element, where the Woodbury cross terms
    between the contacts are large), different uplifts, speed 0: the static solution of both point
    forces (``Line.solve_static``, superposition, no time stepping) is an equilibrium of the step:
    200 steps later the line has not moved from it by more than 1e-9 of its deflection and each
    contact force is its uplift."""
    line = Line(LINE.data, LINE.numerics, n_spans=4)
    forces = (80.0, 50.0)
    sim = ContactSimulation(
        line,
        three_mass_pantograph(),
        DT,
        0.0,
        2 * LINE.data.period + 20.0,
        passive=(PassivePantograph(paper_pantograph(), lag, forces[1]),),
    )
    sim.start_static(forces[0])
    f = np.zeros(line.n_dof)
    for x, fk in zip(sim.x - sim.lags, forces, strict=True):
        dofs, n = line.contact_interpolation(x)
        f[dofs] += fk * n
    static = line.solve_static(f)
    for _ in range(200):
        sim.step(forces[0])
    scale = np.abs(static).max()
    assert scale > 1e-3  # the forces do lift the wire (mm)
    assert np.abs(sim.d - static).max() < 1e-9 * scale
    np.testing.assert_allclose(sim.contact_forces, forces, rtol=1e-9)
    # A wrong cross term would show: the two uplifts interact (the trailing one's 50 N lifts the
    # wire under the leading one by a visible fraction of what its own 80 N does).
    dofs, n = line.contact_interpolation(sim.x)
    alone = np.zeros(line.n_dof)
    alone[dofs] = forces[0] * n
    lone = line.solve_static(alone)
    assert float(n @ static[dofs]) > 1.2 * float(n @ lone[dofs])


@pytest.mark.slow
def test_two_pantographs_on_the_endless_window_equal_a_long_fixed_line():
    """The window laid out for a 200 m spacing (10 + 4 spans) shifting 4 times gives both contact
    forces of a fixed 22-span line (the window drops waves far behind the trailing pantograph),
    within 1 mN."""
    periods, start = window_periods(LINE.data, SPACING)
    assert periods == 14 and start == 8  # 10 spans + ceil(200 / 55) = 4 at the rear
    x0 = start * LINE.data.period
    v = 300 / 3.6
    forces = {}
    for endless, n_spans in ((True, periods), (False, 22)):
        line = Line(LINE.data, LINE.numerics, n_spans=n_spans)
        passive = (PassivePantograph(three_mass_pantograph(), SPACING, 150.0),)
        sim = ContactSimulation(line, paper_pantograph(), DT, v, x0, endless=endless, passive=passive)
        sim.start_static(150.0)
        out = []
        while sim.position < x0 + 5.5 * LINE.data.period:
            sim.step(150.0)
            out.append(sim.contact_forces)
        forces[endless] = np.array(out)
        if endless:
            assert sim.offset == pytest.approx(4 * LINE.data.period)
            np.testing.assert_allclose(sim.contact_positions, sim.position - np.array([0.0, SPACING]))
    assert forces[False][:, 1].std() > 5.0  # the trailing pantograph does see the line
    assert np.abs(forces[True] - forces[False]).max() < 1e-3


def _plant(**options) -> FEPlant:
    return FEPlant(
        PantographParameters(),
        TrackParameters(speed_kmh=300.0),
        None,
        PlantOptions(catenary_model="fe", **options),
        1e-3,
    )


@pytest.mark.slow
def test_the_plant_controls_the_trailing_pantograph_and_reports_both():
    """pantographs 0, 200 with the trailing one controlled: observer and controller see the trailing
    one (its heights, force and position), the truth per pantograph lists both in order."""
    plant = _plant(pantographs=(0.0, SPACING), controlled_pantograph=1)
    assert plant.line.n_spans == 14
    for _ in range(500):
        plant.advance(120.0)
    truth = plant.truth()
    lead, trail = plant.pantograph_truths()
    assert (lead.controlled, trail.controlled) == (False, True)
    assert trail.contact_position == pytest.approx(lead.contact_position - SPACING)
    assert truth.contact_position == trail.contact_position
    assert truth.contact_force == trail.contact_force and truth.contact_uplift == trail.contact_uplift
    # the passive leading one presses with the EN 50367 target at 300 km/h (157.3 N) on average
    assert lead.contact_force > 50.0 and trail.contact_force > 0.0


@pytest.mark.slow
def test_the_compiled_closed_loop_with_two_pantographs_equals_the_core_objects():
    """closed_loop.run (the compiled loop_tick on the packed FE buffers) == the core objects stepped
    tick by tick (the nodes' path), with the trailing pantograph controlled by line_adaptive: every
    field of every record."""
    import dataclasses

    from pac_rig.closed_loop import build_cores, run, run_cores
    from pac_rig.simulate import scenario_from_flat

    def fields(rec):
        return [
            np.asarray(getattr(part, f.name), dtype=object).ravel().tolist()
            for part in (rec.measurement, rec.truth, rec.estimate, rec.command)
            for f in dataclasses.fields(part)
        ]

    flat = {"catenary_model": "fe", "duration": 0.4, "law": "line_adaptive", "observer": "contact_force"}
    two = scenario_from_flat({**flat, "pantographs": (0.0, SPACING), "controlled_pantograph": 1})
    compiled = [fields(rec) for rec in run(two)]
    # Equal field by field, NaN where both are NaN (fields a ground-datum run leaves unmeasured).
    np.testing.assert_equal(compiled, [fields(rec) for rec in run_cores(two, *build_cores(two))])
    # The window: 4 periods added at the rear, the first pantograph starts 4 periods further on
    # (support 8, not 4), the controlled one 200 m behind it.
    assert next(iter(run(two))).truth.contact_position == pytest.approx(8 * 55.0 - SPACING)


@pytest.mark.parametrize(
    ("options", "name", "allowed"),
    [
        ({"pantographs": (0.0, -200.0)}, "pantographs", "1 to 4 finite values, each in [0, 1000] m"),
        ({"pantographs": (0.0, 1500.0)}, "pantographs", "1 to 4 finite values, each in [0, 1000] m"),
        ({"pantographs": (0.0, 200.0, 100.0)}, "pantographs", "0 first, then increasing"),
        ({"pantographs": (50.0,)}, "pantographs", "0 first, then increasing"),
        ({"pantographs": (0.0, 200.0), "controlled_pantograph": 2}, "controlled_pantograph", "[0, 1]"),
        ({"all_pantographs_active": True}, "all_pantographs_active", "true with two pantographs"),
        (
            {"pantographs": (0.0, 100.0, 200.0), "all_pantographs_active": True},
            "all_pantographs_active",
            "true with two pantographs",
        ),
    ],
)
def test_bad_pantograph_layouts_are_refused_by_name(options, name, allowed):
    with pytest.raises(ParameterError) as err:
        PlantOptions(catenary_model="fe", **options)
    assert err.value.name == name and allowed in str(err.value)


def test_several_pantographs_need_the_fe_line():
    with pytest.raises(ParameterError, match="several need catenary_model fe"):
        PlantOptions(pantographs=(0.0, 200.0))


@pytest.mark.slow
def test_simulate_refuses_a_negative_spacing_with_one_line_exit_2(tmp_path):
    from conftest import simulate_refusal

    line = simulate_refusal(
        tmp_path / "bag", "catenary_model:=fe", "pantographs:=[0.0, -200.0]", "duration:=0.01"
    )
    assert "'pantographs'" in line and "-200" in line and "each in [0, 1000] m" in line


@pytest.mark.slow
def test_simulate_refuses_a_passive_pantograph_file_that_does_not_exist(tmp_path):
    from conftest import simulate_refusal

    line = simulate_refusal(
        tmp_path / "bag",
        "catenary_model:=fe",
        "pantographs:=[0.0, 200.0]",
        "passive_pantograph:=/no/such.yaml",
    )
    assert "'passive_pantograph'" in line and "/no/such.yaml" in line
