"""The moving window on a whole line (``catenary/window.py``): the step on the spans around the
pantographs is the whole line's step with the line held at rest outside them, checked against the
whole line's own step with that rule applied from outside (an independent reference for the
window's rows, solve, droppers and hand-over), and a window over the whole line is the whole line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pac_common.parameters import ParameterError
from pac_plant.catenary.catenary_file import load_catenary
from pac_plant.catenary.integrator import ContactSimulation, PassivePantograph
from pac_plant.catenary.line import DOFS_PER_NODE, Line
from pac_plant.catenary.pantographs import three_mass_pantograph
from pac_plant.catenary.sections import SectionedLine

pytestmark = pytest.mark.offline

ROOT = Path(__file__).resolve().parents[1]
WHOLE_SHORT = str(ROOT / "tests" / "data" / "catenary_whole_short.yaml")
SPEED = 250.0 / 3.6
FORCE = 150.0


def short_line(seed: int) -> Line:
    return Line(load_catenary(WHOLE_SHORT).line(seed))


def pair(line: Line, spans: float, x0: float, steps: int, lag: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(forces, largest |d| difference per step) of the windowed step against the whole line's step
    with the state outside the window set to rest before and after every step."""
    passive = (PassivePantograph(three_mass_pantograph(), lag, 120.0),) if lag else ()

    def make(spans: float) -> ContactSimulation:
        return ContactSimulation(
            line, three_mass_pantograph(), 1e-3, SPEED, x0, passive=passive, window_spans=spans
        )

    window, whole = make(spans), make(0.0)
    c = window.constants
    forces, gaps = [], []
    for _ in range(steps):
        g = int(np.searchsorted(c.window_x, window.x + SPEED * 1e-3, side="right"))
        keep = np.zeros(line.n_dof, dtype=bool)
        keep[c.window_rows[g, 2] : c.window_rows[g, 3]] = True
        for vec in (whole.d, whole.v, whole.a):
            vec[~keep] = 0.0
        window.step(FORCE)
        whole.step(FORCE)
        for vec in (whole.d, whole.v, whole.a):
            vec[~keep] = 0.0
        assert window.state.counters[7] == g  # the window the rule names
        forces.append((window.contact_force, whole.contact_force))
        gaps.append(float(np.max(np.abs(window.d - whole.d))))
    return np.array(forces), np.array(gaps)


def test_the_moving_window_is_the_whole_line_held_at_rest_outside_it() -> None:
    """A 3-span window over a 7-span line: it moves on four times in 5 s; at every step its force and
    its whole state equal the whole line's step with the rest rule applied from outside."""
    line = short_line(3)
    assert len(line.rest_slack) > 0, "a line with droppers slack at rest (their rest load in the window)"
    forces, gaps = pair(line, 3.0, float(line.layout.support_x[1]), 5000)
    assert np.std(forces[:, 1]) > 5.0
    np.testing.assert_allclose(forces[:, 0], forces[:, 1], rtol=0, atol=1e-7)
    assert np.max(gaps) < 1e-10  # [m]; the deviations are ~1e-2 m


def test_a_second_pantograph_and_an_overlap_stay_in_the_window() -> None:
    """Two pantographs 60 m apart through the first overlap of the sectioned line: the window holds
    both (it grows by their spacing) and both wires of the overlap (two sections' rows)."""
    line = SectionedLine(load_catenary("realistic_3km_sections").line(100))
    first_overlap = float(line.section_x[1, 0])
    forces, gaps = pair(line, 4.0, first_overlap - 40.0, 3000, lag=60.0)
    np.testing.assert_allclose(forces[:, 0], forces[:, 1], rtol=0, atol=1e-7)
    assert np.max(gaps) < 1e-10


def test_a_line_at_rest_stays_at_rest_with_a_slack_dropper_just_outside_the_window() -> None:
    """Line seed 3 with a 2.5-span window: a dropper slack at rest hangs 6 nodes past window 1's
    end. Its rest load reaches into the window (A^-1 decays over ~20 nodes) and is balanced only if
    the window takes that dropper too: then nothing moves (as on the whole line,
    test_catenary_realistic); left out, the window's end sags by ~1e-8 m."""
    line = short_line(3)
    sim = ContactSimulation(line, three_mass_pantograph(), 1e-3, 0.0, 150.0, window_spans=2.5)
    c = sim.constants
    end_node = c.window_rows[1, 3] // DOFS_PER_NODE
    assert c.window_x[0] <= 150.0 < c.window_x[1]
    assert any(0 < node - end_node < 10 for node in line.droppers.node[line.rest_slack])
    for _ in range(200):
        sim.step(0.0)
    assert sim.state.counters[7] == 1
    # Rounding of the rest load against its droppers' release: 1e-21 to 8e-15 m measured over
    # OpenBLAS's kernels (the rest solution is a LAPACK solve); the dropper left out gives 9e-9 m.
    assert np.max(np.abs(sim.d)) < 1e-12


def test_contact_columns_prepared_outside_the_window_are_the_whole_lines() -> None:
    """A plant may solve the contact columns of a stretch ahead before it gets there
    (``prepare_contact_columns``); outside the window the window's solve cannot hold them, so the
    step solves them on the whole line."""
    line = short_line(3)
    x0 = float(line.layout.support_x[1])
    sims = [
        ContactSimulation(line, three_mass_pantograph(), 1e-3, SPEED, x0, window_spans=w) for w in (2.5, 0.0)
    ]
    for sim in sims:
        for _ in range(100):
            sim.step(FORCE)
        far = float(line.layout.support_x[-2])
        sim.prepare_contact_columns(far, far + 5.0)
    assert sims[0].state.counters[7] == 0  # still the first window
    ready = np.flatnonzero(sims[1].state.unit_ready)
    far_nodes = ready[line.x[ready] > far - 1.0]
    assert len(far_nodes) >= 10 and DOFS_PER_NODE * far_nodes.min() >= sims[0].constants.window_rows[0, 1]
    got, want = sims[0].state.unit_patches[far_nodes], sims[1].state.unit_patches[far_nodes]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.max(np.abs(want)))


def test_a_window_over_the_whole_line_is_the_whole_line() -> None:
    line = short_line(1)
    runs = []
    for spans in (0.0, 50.0):
        sim = ContactSimulation(
            line, three_mass_pantograph(), 1e-3, SPEED, float(line.layout.support_x[1]), window_spans=spans
        )
        runs.append(np.array([(sim.step(FORCE), sim.contact_force)[1] for _ in range(4000)]))
        if spans:
            assert sim.constants.window_x.shape == (1,) and tuple(sim.constants.window_rows[0]) == (
                0,
                line.n_dof,
                0,
                line.n_dof,
            )
    # The same algebra, a solve chunked another way: equal to rounding.
    np.testing.assert_allclose(runs[1], runs[0], rtol=0, atol=1e-8)


@pytest.mark.parametrize("spans", [4.0, 10.0])
def test_every_window_holds_its_contacts_with_spans_to_spare(spans: float) -> None:
    """While window g is in use (x below its hand-over point, above the one before), the rearmost
    contact has spans / 2 mean spans of line behind it in the window and the reference point
    spans / 2 - 1 ahead, except where the line ends first."""
    line = SectionedLine(load_catenary("realistic_3km_sections").line(101))
    lag = 200.0
    sim = ContactSimulation(
        line,
        three_mass_pantograph(),
        1e-3,
        SPEED,
        300.0,
        passive=(PassivePantograph(three_mass_pantograph(), lag, 120.0),),
        window_spans=spans,
    )
    c = sim.constants
    mean_span = float(np.mean(np.diff(line.layout.support_x)))
    x_nodes = line.x
    for g in range(c.window_x.shape[0]):
        lo_node, hi_node = c.window_rows[g, 2] // DOFS_PER_NODE, (c.window_rows[g, 3] - 1) // DOFS_PER_NODE
        x_from = c.window_x[g - 1] if g else lag
        x_to = min(c.window_x[g], float(line.x[-1]))
        assert x_nodes[lo_node] <= max(x_from - lag - spans / 2 * mean_span, 0.0) + 1e-9
        assert x_nodes[hi_node] >= min(x_to + (spans / 2 - 1) * mean_span, float(line.x[-1])) - 1e-9
        # The rows solved reach PAD beyond the rows kept (where the line goes on).
        assert c.window_rows[g, 0] <= c.window_rows[g, 2] and c.window_rows[g, 1] >= c.window_rows[g, 3]


def test_a_moving_window_is_refused_where_it_cannot_work() -> None:
    from pac_model.parameters import PantographParameters, TrackParameters
    from pac_plant.fe_plant import FEPlant
    from pac_plant.parameters import PlantOptions

    for catenary, spans in (("benchmark_55m", 10.0), (WHOLE_SHORT, 1.0)):
        options = PlantOptions(catenary_model="fe", catenary=catenary, fe_window_spans=spans)
        with pytest.raises(ParameterError) as info:
            FEPlant(PantographParameters(), TrackParameters(speed_kmh=300.0), None, options, 1e-3)
        assert info.value.name == "fe_window_spans" and "\n" not in str(info.value)
