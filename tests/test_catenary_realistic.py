"""A realistic line: droppers that carry tension only at rest. Each physics check compares with an
independent reference and is shown to fail on the wrong physics (a taut-only static solve, the rest
load left out of the dynamics)."""

from __future__ import annotations

import numpy as np
import pytest

from pac_plant.catenary.data import CatenaryData
from pac_plant.catenary.imperfections import apply_imperfections
from pac_plant.catenary.integrator import ContactSimulation
from pac_plant.catenary.line import WC, WM, Line, beam_matrices, gravity_load
from pac_plant.catenary.pantographs import paper_pantograph

pytestmark = pytest.mark.offline


def deviated_line(seed: int = 1) -> Line:
    """A 6-span benchmark-like line whose droppers were cut for 5 mm random height errors (seed 1:
    4 of them would have to push, so they hang slack)."""
    return Line(apply_imperfections(CatenaryData(n_spans=6), 0.005, 0.0, seed), n_spans=6)


# -- 1. static state: droppers carry tension only --------------------------------------------------
def static_residual(line: Line, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(residual at the free DOFs [N], dropper forces [N], total upward support reaction [N]) of the
    tension-only line in the state ``w``, assembled here from the element matrices and the dropper
    law T = k max(e, 0) with e = H + w_m - w_c - L0 (not from the line's own static solve)."""
    d, dr = line.data, line.droppers
    n = line.n_dof
    k = np.zeros((n, n))
    f = np.zeros(n)
    for e, h in enumerate(line.h):
        for wire, off in ((d.contact, WC), (d.messenger, WM)):
            ke, _ = beam_matrices(wire, h)
            dofs = [4 * e + off, 4 * e + off + 1, 4 * (e + 1) + off, 4 * (e + 1) + off + 1]
            k[np.ix_(dofs, dofs)] += ke
            f[dofs] += gravity_load(wire, h, d.gravity)
    half = 0.5 * d.dropper_rho * dr.length0
    np.add.at(f, dr.wc, -(d.clamp_mass_contact + half) * d.gravity)
    np.add.at(f, dr.wm, -(d.clamp_mass_messenger + half) * d.gravity)
    elongation = dr.height + w[dr.wm] - w[dr.wc] - dr.length0
    tension = dr.stiffness * np.maximum(elongation, 0.0)
    np.add.at(f, dr.wc, tension)  # a dropper pulls the contact wire up and the messenger down
    np.add.at(f, dr.wm, -tension)
    springs = np.zeros(n)
    for node in line.support_nodes:
        springs[4 * node + WC] = -d.steady_arm_stiffness * w[4 * node + WC]
        springs[4 * node + WM] = -d.messenger_support_stiffness * w[4 * node + WM]
    r = k @ w - f - springs  # = the anchors' reactions at the anchored DOFs, zero elsewhere
    free = np.ones(n, dtype=bool)
    free[line.fixed] = False
    return r[free], tension, float(np.sum(r[line.fixed]) + np.sum(springs))


def total_weight(line: Line) -> float:
    """The line's weight from its data alone [N]: wires, clamps, droppers."""
    d, dr = line.data, line.droppers
    wires = (d.contact.rho + d.messenger.rho) * line.length
    clamps = len(dr.node) * (d.clamp_mass_contact + d.clamp_mass_messenger)
    return d.gravity * (wires + clamps + d.dropper_rho * float(np.sum(dr.length0)))


#: Residual force allowed at a free DOF [N]: round-off of the banded solves (the forces are ~100 N,
#: a dropper's stiffness 2e5 N/m: a wrongly pushing dropper 1 mm short leaves ~200 N).
RESIDUAL = 1e-5


def test_slack_dropper_at_rest_carries_no_force_and_the_line_balances_its_weight() -> None:
    line = deviated_line()
    dr = line.droppers
    assert len(line.rest_slack) >= 2, "the deviation should leave droppers slack at rest"
    residual, tension, reaction = static_residual(line, line.w_static)
    # Equilibrium of the tension-only law at every free DOF, a slack dropper carrying nothing.
    assert np.max(np.abs(residual)) < RESIDUAL
    assert np.all(tension[line.rest_slack] == 0.0)
    assert np.all(dr.elongation0[line.rest_slack] < 0.0)
    assert np.all(dr.static_tension[line.rest_slack] == 0.0)
    taut = np.setdiff1d(np.arange(len(dr.node)), line.rest_slack)
    assert np.all(dr.elongation0[taut] >= 0.0)
    # The supports (anchors, steady arms, messenger supports) carry exactly the weight.
    weight = total_weight(line)
    assert abs(reaction - weight) < 1e-9 * weight
    # Mutation: the taut-only solve (every dropper a spring that may push) is not this equilibrium.
    w_taut = line.solve_static(line.f_static)
    residual_taut, _, _ = static_residual(line, w_taut)
    assert np.max(np.abs(residual_taut)) > 1e3 * RESIDUAL


def test_a_line_whose_droppers_all_hang_taut_is_unchanged() -> None:
    """The tension-only solve leaves a line without slack droppers as the linear solve gives it."""
    line = Line(CatenaryData(), n_spans=4)
    assert len(line.rest_slack) == 0
    assert np.array_equal(line.w_static, line.solve_static(line.f_static))
    assert not np.any(line.rest_load())


def rest_run(line: Line, compiled: bool, rest_load: bool = True) -> tuple[float, np.ndarray]:
    """(largest line deviation [m], slack droppers) after 0.2 s of a line at rest: the pantograph
    sits just touching with no uplift (F = 0), nothing should move."""
    sim = ContactSimulation(line, paper_pantograph(), 1e-3, 0.0, line.x[-1] / 2)
    if not rest_load and len(sim.constants.y_rest):
        sim.constants.y_rest[:] = 0.0
    for _ in range(200):
        if compiled:
            sim.step(0.0)
        else:
            sim.step_reference(0.0)
    return float(np.max(np.abs(sim.d))), sim.slack


def test_the_tension_only_rest_state_is_at_rest_in_the_dynamics() -> None:
    line = deviated_line()
    for compiled in (True, False):
        moved, slack = rest_run(line, compiled)
        assert moved < 1e-9
        assert np.array_equal(slack, line.rest_slack)
    # Mutation: the dynamics without the rest load (the taut K about the tension-only state) move.
    moved, _ = rest_run(line, True, rest_load=False)
    assert moved > 1e-4
