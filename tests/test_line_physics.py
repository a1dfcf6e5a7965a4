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
from pathlib import Path

import numpy as np
import pytest

from pac_plant.catenary.catenary_file import load_catenary
from pac_plant.catenary.data import CatenaryData, WireData
from pac_plant.catenary.layout import WS
from pac_plant.catenary.line import DOFS_PER_NODE, WC, WM, Line, beam_matrices, gravity_load, string_matrices

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


# -- a stitched line: the messenger a string, a stitch wire at an anchor and one in the line -----------
STITCHED_FILE = Path(__file__).parent / "data" / "catenary_unequal_stitched.yaml"


@pytest.fixture(scope="module")
def stitched() -> Line:
    """Four spans of the unequal stitched test line (period of three): a stitch wire at support 0
    (an anchor: half of it, anchored there) and at support 3 (inside the line, both ends clamped
    to the messenger)."""
    f = load_catenary(str(STITCHED_FILE))
    return Line(dataclasses.replace(f.data, n_spans=4), f.numerics)


def stitch_wires(line: Line) -> list[tuple[float, float, float, float]]:
    """Each stitch wire as (start, end, rho, tension) from the data alone: half its length either
    side of its support, cut at the line's ends (where it is anchored)."""
    spans, out, x0 = line.data.spans, [], 0.0
    for s in range(line.n_spans + 1):
        st = spans[s % len(spans)].stitch
        if st is not None:
            a, b = max(0.0, x0 - st.length / 2), min(line.length, x0 + st.length / 2)
            out.append((a, b, st.rho, st.tension))
        if s < line.n_spans:
            x0 += spans[s % len(spans)].length
    return out


def stitched_weight(line: Line) -> float:
    d, dr = line.data, line.droppers
    mass = (d.contact.rho + d.messenger.rho) * line.length
    mass += sum(rho * (b - a) for a, b, rho, _ in stitch_wires(line))
    mass += len(dr.node) * (d.clamp_mass_contact + d.clamp_mass_messenger) + d.dropper_rho * dr.length0.sum()
    return d.gravity * mass


def test_the_stitched_test_line_has_a_stitch_wire_at_an_anchor_and_one_inside(stitched):
    wires = stitch_wires(stitched)
    assert [a == 0.0 for a, *_ in wires] == [True, False]
    assert len(stitched.layout.stitches) == 2
    # Stitch droppers hang from the stitch wires: more droppers than the spans' own.
    own = sum(len(stitched.data.spans[s % 3].dropper_positions) for s in range(4))
    assert len(stitched.droppers.node) > own


def test_the_stitched_lines_load_is_its_weight(stitched):
    """As for the plain line: the translational loads of the free DOFs (contact wire, messenger,
    stitch wires) sum to the line's weight less the half elements at the anchors: both wires' end
    elements and the anchored stitch wire's first element."""
    line, d = stitched, stitched.data
    carried = stitched_weight(line) / d.gravity
    carried -= 0.5 * (d.contact.rho + d.messenger.rho) * (line.h[0] + line.h[-1])
    carried -= sum(0.5 * rho * line.h[0] for a, _, rho, _ in stitch_wires(line) if a == 0.0)
    slopes = DOFS_PER_NODE * np.arange(line.n_nodes) + WC + 1  # the contact wire's slope: no weight
    free = np.setdiff1d(np.arange(line.n_dof), np.concatenate([slopes, line.fixed]))
    assert line.f_static[free].sum() == pytest.approx(-d.gravity * carried, rel=1e-9)


def test_the_static_stitched_line_rests_on_its_supports_and_anchors(stitched):
    """Vertical equilibrium of the stitched line in its static state: supports, the contact wire's
    beam ends, the messenger's string ends and the anchored stitch wire's end carry its weight
    (stitch wires included), computed from the data."""
    line, d, w = stitched, stitched.data, stitched.w_static
    supports = np.asarray(line.support_nodes)
    reaction = -d.steady_arm_stiffness * w[DOFS_PER_NODE * supports + WC].sum()
    reaction -= d.messenger_support_stiffness * w[DOFS_PER_NODE * supports + WM].sum()
    last = line.n_nodes - 1
    for e, end in ((0, 0), (last - 1, 2)):
        ke, _ = beam_matrices(d.contact, line.h[e])
        dofs = [4 * e + WC, 4 * e + WC + 1, 4 * (e + 1) + WC, 4 * (e + 1) + WC + 1]
        reaction += (ke @ w[dofs] - gravity_load(d.contact, line.h[e], d.gravity))[end]
    ends = ((0, 0), (last - 1, 1))  # (element, its anchored end)
    strings = [(d.messenger, [4 * e + WM, 4 * (e + 1) + WM], e, end) for e, end in ends]
    for a, _, rho, tension in stitch_wires(line):
        if a == 0.0:  # anchored at node 0; its first element's far end is node 1's stitch height
            strings.append((WireData(rho, tension, 0.0), [WS, 4 + WS], 0, 0))
    for wire, dofs, e, end in strings:
        ks, _ = string_matrices(wire, line.h[e])
        reaction += (ks @ w[dofs])[end] + 0.5 * wire.rho * d.gravity * line.h[e]
    assert reaction == pytest.approx(stitched_weight(line), rel=1e-9)
