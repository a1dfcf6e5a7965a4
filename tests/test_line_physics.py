"""The FE line's masses and statics against the catenary's data, at tolerances any CPU meets.

Independent references: the line's mass and weight from its data (wire densities times length,
clamp masses, each dropper's own mass), the lumped dropper masses the module docstring states
(clamp masses and half of the dropper's own mass on each wire's node), and the vertical
equilibrium of the whole line in its static state (support and anchor reactions carry its
weight).  Tolerances: sums of a few hundred terms of a size near 1e2..1e4 in double precision,
and a static solve of a well conditioned banded system: relative 1e-9 is far above rounding and
far below any modelling change (one dropper's clamp mass is ~4e-4 of the line's weight).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pac_plant.catenary.data import CatenaryData
from pac_plant.catenary.line import DOFS_PER_NODE, WC, WM, Line, beam_matrices, gravity_load

pytestmark = pytest.mark.unit

DATA = CatenaryData(n_spans=4)


@pytest.fixture(scope="module")
def line() -> Line:
    return Line(DATA)


def diagonal(banded: np.ndarray, dofs: np.ndarray) -> np.ndarray:
    return banded[0, dofs]


def test_each_dropper_lumps_its_clamp_and_half_its_own_mass_on_each_wire(line):
    bare = Line(DATA, droppers=False)
    assert np.array_equal(bare.x, line.x)  # the same mesh: the difference is the droppers
    dr = line.droppers
    assert len(dr.node) == sum(len(s.dropper_positions) for s in DATA.spans) * DATA.n_spans
    half = 0.5 * DATA.dropper_rho * dr.length0
    contact = diagonal(line.M.ab, dr.wc) - diagonal(bare.M.ab, dr.wc)
    messenger = diagonal(line.M.ab, dr.wm) - diagonal(bare.M.ab, dr.wm)
    np.testing.assert_allclose(contact, DATA.clamp_mass_contact + half, rtol=1e-9)
    np.testing.assert_allclose(messenger, DATA.clamp_mass_messenger + half, rtol=1e-9)
    # Nothing else of the mass changes (off the dropper nodes, and off the diagonal).
    rest = line.M.ab.copy()
    rest[0, dr.wc] -= contact
    rest[0, dr.wm] -= messenger
    np.testing.assert_allclose(rest, bare.M.ab, rtol=0, atol=1e-12 * np.abs(bare.M.ab).max())


def test_the_lines_load_is_its_weight(line):
    """The translational loads of the free DOFs sum to the weight of everything but the half
    elements at the two anchors (whose load goes straight into the anchor)."""
    d, dr = DATA, line.droppers
    rho = d.contact.rho + d.messenger.rho
    carried = rho * (line.length - 0.5 * line.h[0] - 0.5 * line.h[-1])
    carried += len(dr.node) * (d.clamp_mass_contact + d.clamp_mass_messenger)
    carried += d.dropper_rho * dr.length0.sum()
    translational = np.concatenate(
        [DOFS_PER_NODE * np.arange(line.n_nodes) + WC, DOFS_PER_NODE * np.arange(line.n_nodes) + WM]
    )
    free = np.setdiff1d(translational, line.fixed)
    assert line.f_static[free].sum() == pytest.approx(-d.gravity * carried, rel=1e-9)


def test_the_static_line_rests_on_its_supports_and_anchors(line):
    """Vertical equilibrium of the whole line in its static state: the steady arms, the messenger
    supports and the four anchor reactions (each from its end element's beam equation) carry the
    line's weight, computed from the data."""
    d, dr, w = DATA, line.droppers, line.w_static
    weight = d.gravity * (
        (d.contact.rho + d.messenger.rho) * line.length
        + len(dr.node) * (d.clamp_mass_contact + d.clamp_mass_messenger)
        + d.dropper_rho * dr.length0.sum()
    )
    supports = np.asarray(line.support_nodes)
    reaction = -d.steady_arm_stiffness * w[DOFS_PER_NODE * supports + WC].sum()
    reaction -= d.messenger_support_stiffness * w[DOFS_PER_NODE * supports + WM].sum()
    last = line.n_nodes - 1
    for wire, off in ((d.contact, WC), (d.messenger, WM)):
        for e, end in ((0, 0), (last - 1, 2)):  # the anchored node: the element's a or b end
            ke, _ = beam_matrices(wire, line.h[e])
            dofs = [4 * e + off, 4 * e + off + 1, 4 * (e + 1) + off, 4 * (e + 1) + off + 1]
            reaction += (ke @ w[dofs] - gravity_load(wire, line.h[e], d.gravity))[end]
    assert reaction == pytest.approx(weight, rel=1e-9)


def test_every_dropper_pulls_in_the_static_state(line):
    """The static state the dynamics start from has no slack dropper: every one pulls."""
    assert np.all(line.droppers.static_tension > 0.0)


def test_the_supports_add_their_springs_and_masses_at_the_support_nodes_only():
    """The steady arm (on the contact wire) and the messenger support (on the messenger) at each
    support node: a line with supports differs from one without by exactly their stiffnesses and
    masses on those two DOFs of the support nodes (the anchored ones stay constrained)."""
    data = dataclasses.replace(DATA, steady_arm_mass=2.5, messenger_support_mass=1.5)
    held, bare = Line(data, droppers=False), Line(data, droppers=False, supports=False)
    want_k, want_m = np.zeros(held.n_dof), np.zeros(held.n_dof)
    for n in held.support_nodes:
        for dof, k, m in (
            (DOFS_PER_NODE * n + WC, data.steady_arm_stiffness, data.steady_arm_mass),
            (DOFS_PER_NODE * n + WM, data.messenger_support_stiffness, data.messenger_support_mass),
        ):
            if dof not in held.fixed:
                want_k[dof], want_m[dof] = k, m
    assert np.count_nonzero(want_k) == 2 * len(held.support_nodes) > 0
    scale_k, scale_m = np.abs(bare.K.ab).max(), np.abs(bare.M.ab).max()
    np.testing.assert_allclose(held.K.ab[0] - bare.K.ab[0], want_k, rtol=0, atol=1e-12 * scale_k)
    np.testing.assert_allclose(held.M.ab[0] - bare.M.ab[0], want_m, rtol=0, atol=1e-12 * scale_m)
    np.testing.assert_allclose(held.K.ab[1:], bare.K.ab[1:], rtol=0, atol=1e-12 * scale_k)
    np.testing.assert_allclose(held.M.ab[1:], bare.M.ab[1:], rtol=0, atol=1e-12 * scale_m)


def test_the_static_contact_wire_sits_at_its_design_presag_at_every_dropper(line):
    """The dropper lengths are solved for the contact wire's pre-sag at every dropper (the solve
    stops when the lengths move less than 1e-9 m): the static state meets it, and each dropper's
    stiffness is EA over its own length."""
    dr = line.droppers
    np.testing.assert_allclose(-line.w_static[dr.wc], dr.target_sag, rtol=0, atol=1e-6)
    np.testing.assert_allclose(dr.stiffness, DATA.dropper_ea / dr.length0, rtol=1e-12)
