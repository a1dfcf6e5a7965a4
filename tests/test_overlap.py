"""Tension sections joined by an overlap: the pantograph handed from one contact wire to the next.

The physics check compares a slow run over an overlap with an independent reference: the static
two-spring contact of the head with each wire, built from each section solved alone as a line
of its own (its static height plus the overlap's lift, its point flexibility N^T K^-1 N plus the
penalty's). A lift left out of the contact, or a second wire the head does not feel, fails it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pac_plant.catenary.catenary_file import CatenaryFileError, load_catenary, parse_catenary
from pac_plant.catenary.data import CatenaryData, SpanData
from pac_plant.catenary.integrator import ContactSimulation
from pac_plant.catenary.layout_rule import LayoutRule, draw_sections
from pac_plant.catenary.line import Line
from pac_plant.catenary.pantographs import paper_pantograph
from pac_plant.catenary.sections import SectionedLine

pytestmark = pytest.mark.offline

ROOT = Path(__file__).resolve().parents[1]
SPAN = 55.0
#: Two sections of 7 benchmark-like spans sharing a three-span overlap (spans 4-6): the outgoing
#: wire level over the overlap's first three supports and 0.5 m up at its anchor, the incoming
#: one the mirror. Supports O_0 .. O_3 of the overlap at 220, 275, 330, 385 m.
LIFT = (0.0, 0.0, 0.0, 0.5)
SPANS = (SpanData(),) * 11
DATA = CatenaryData(
    spans=SPANS, n_spans=11, whole_line=True, sections=((0, SPANS[:7]), (4, SPANS[4:])), overlap_lift=LIFT
)
UPLIFT = 150.0  # N
SPEED = 5.0  # m/s: slow against the waves (128 m/s) and the head's modes, so the contact is near static


def two_spring_reference(xs: np.ndarray, kp: float) -> np.ndarray:
    """(force on the outgoing wire, on the incoming wire) [N] at each x of a head pressed up with
    UPLIFT against every wire over it, statically: wire i at height h_i(x) (its section's static
    height, solved as a line alone, plus its lift) through the compliance c_i = N^T K_i^-1 N + 1/kp,
    F_i = max(y - h_i, 0) / c_i with y such that the forces add up to UPLIFT (bisection)."""
    parts = [
        Line(dataclasses.replace(DATA, spans=spans, n_spans=len(spans), sections=(), overlap_lift=()))
        for _, spans in DATA.sections
    ]
    lifts = [np.array(LIFT), np.array(LIFT[::-1])]
    out = np.zeros((len(xs), 2))
    for j, x in enumerate(xs):
        heights, compliances, which = [], [], []
        for s, (first, spans) in enumerate(DATA.sections):
            x0 = first * SPAN
            if not x0 <= x <= x0 + len(spans) * SPAN:
                continue
            local = x - x0
            dofs, n = parts[s].contact_interpolation(local)
            f = np.zeros(parts[s].n_dof)
            f[dofs] = n
            overlap = (len(spans) - 3) * SPAN if s == 0 else 0.0  # the overlap's first support, locally
            lift = float(np.interp(local, overlap + SPAN * np.arange(4), lifts[s], left=0.0, right=0.0))
            heights.append(parts[s].static_height(local) + lift)
            compliances.append(float(n @ parts[s].solve_static(f)[dofs]) + 1.0 / kp)
            which.append(s)
        h, c = np.array(heights), np.array(compliances)
        lo, hi = float(h.min()), float(h.min()) + 2.0 * UPLIFT * float(c.max())
        for _ in range(60):
            y = 0.5 * (lo + hi)
            lo, hi = (lo, y) if np.sum(np.maximum(y - h, 0.0) / c) > UPLIFT else (y, hi)
        out[j, which] = np.maximum(y - h, 0.0) / c
    return out


@pytest.fixture(scope="module")
def slow_run() -> tuple[np.ndarray, np.ndarray, float]:
    """(x, contact force on each wire [N] per step, kp) of the paper's pantograph pressed up with
    UPLIFT at SPEED from the second support to past the overlap, started in static equilibrium."""
    line = SectionedLine(DATA)
    sim = ContactSimulation(line, paper_pantograph(), 1e-3, SPEED, 2 * SPAN)
    sim.start_static(UPLIFT)
    n = int(6.7 * SPAN / SPEED / 1e-3)
    x, force, reported = np.empty(n), np.empty((n, 2)), np.empty((n, 2))
    for k in range(n):
        sim.step(UPLIFT)
        x[k] = sim.x
        for wire in (0, 1):  # contact 1 is the pantograph's on the second wire set (step.StepConstants)
            force[k, wire] = sim.kp * sim.state.deltas[wire] if sim.state.touching[wire] else 0.0
        reported[k] = sim.contact_forces[0], sim.contact_force
    # What the plant reports as the pantograph's contact force is the sum over the wires it touches.
    np.testing.assert_allclose(reported, np.c_[force.sum(axis=1), force.sum(axis=1)], rtol=1e-12, atol=1e-9)
    return x, force, sim.kp


def test_the_overlap_hands_the_head_over_where_the_static_contact_says(slow_run) -> None:
    """The incoming wire takes the head where, statically, it comes down to it, and the outgoing
    one lets go where it rises away: both positions within 0.5 m of the two-spring reference's
    (measured 0.01 and 0.05 m at 5 m/s). Without the lift the incoming wire, anchored level with
    the supports, would take the head at 220 m and the outgoing one would hold it to 385 m."""
    x, force, kp = slow_run
    grid = np.arange(4.5 * SPAN, 6.5 * SPAN, 0.05)
    ref = two_spring_reference(grid, kp)
    touch_on, lift_off = x[np.argmax(force[:, 1] > 0.0)], x[len(x) - 1 - np.argmax(force[::-1, 0] > 0.0)]
    ref_on, ref_off = grid[np.argmax(ref[:, 1] > 0.0)], grid[len(grid) - 1 - np.argmax(ref[::-1, 0] > 0.0)]
    assert abs(ref_on - 5 * SPAN) < 5.0 and abs(ref_off - 6 * SPAN) < 5.0  # near O_1 and O_2
    assert abs(touch_on - ref_on) < 0.5
    assert abs(lift_off - ref_off) < 0.5


def test_both_wires_share_the_head_as_two_static_springs_and_the_total_does_not_jump(slow_run) -> None:
    """Over the overlap, each wire's force (mean over +-1 m, the reference averaged alike) is the
    two-spring reference's within 5 % of the uplift (measured 2.8 %: what is left is the head
    rocking between two contact springs at 5 m/s), and the total force within 3 % of the uplift
    (measured 1.7 %; 0.9 % on the single wire before it): the hand-over makes no jump."""
    x, force, kp = slow_run
    fine = np.arange(4.5 * SPAN - 1.0, 6.6 * SPAN + 1.0, 0.1)
    ref = two_spring_reference(fine, kp)
    for centre in np.arange(4.5 * SPAN, 6.6 * SPAN, 1.0):
        m = np.abs(x - centre) <= 1.0
        r = ref[np.abs(fine - centre) <= 1.0 + 1e-9].mean(axis=0)
        got = force[m].mean(axis=0)
        assert np.all(np.abs(got - r) <= 0.05 * UPLIFT), (centre, got, r)
        assert abs(got.sum() - UPLIFT) <= 0.03 * UPLIFT, (centre, got.sum())
    middle = (x > 5.2 * SPAN) & (x < 5.8 * SPAN)  # the middle span: both wires level, both touched
    assert np.all(force[middle] > 0.0)


# -- the line of tension sections as data ------------------------------------------------------------
SMALL_FILE = (ROOT / "config/catenaries/realistic_3km_sections.yaml").read_text()


def small_sectioned_file(tmp_path: Path) -> Path:
    """realistic_3km_sections cut to 11 spans of 55 m in two sections of 7 (the overlap at 220-385 m)."""
    text = (
        SMALL_FILE.replace("length: 3000.0", "length: 605.0")
        .replace("span_min: 50.0 ", "span_min: 55.0 ")
        .replace("span_max: 60.0", "span_max: 55.0")
        .replace("spans_min: 20 ", "spans_min: 7 ")
        .replace("spans_max: 30", "spans_max: 7")
    )
    path = tmp_path / "small_sections.yaml"
    path.write_text(text)
    return path


def test_a_line_in_sections_is_the_same_line_but_for_the_overlaps_second_wire() -> None:
    """realistic_3km_sections draws, for a seed, realistic_3km's masts and wires; its sections hold
    20-30 spans and share 3; the incoming wire over an overlap has a deviation of its own."""
    plain, cut = load_catenary("realistic_3km"), load_catenary("realistic_3km_sections")
    for seed in (1, 7):
        a, b = plain.line(seed), cut.line(seed)
        assert a.spans == b.spans and not a.sections and len(b.sections) >= 2
        for s, (first, spans) in enumerate(b.sections):
            assert 20 <= len(spans) or s == len(b.sections) - 1  # (a short line's last one: the rest)
            own = spans[3:] if s > 0 else spans
            assert own == b.spans[first + len(spans) - len(own) : first + len(spans)]
            if s > 0:
                assert b.sections[s - 1][0] + len(b.sections[s - 1][1]) - 3 == first
                assert [x.length for x in spans[:3]] == [x.length for x in b.spans[first : first + 3]]
                assert spans[:3] != b.spans[first : first + 3]  # the second wire is not a copy
        assert b.sections[-1][0] + len(b.sections[-1][1]) == len(b.spans)


def test_sections_are_drawn_within_the_rule() -> None:
    rule = LayoutRule(3000.0, 50.0, 60.0, 1.1, 1.6, 0.15, 9, 4.5, 0.001, section_spans_min=20,
                      section_spans_max=30, overlap_lift=LIFT)  # fmt: skip
    for n_spans in (40, 45, 55, 60, 61, 100, 250):
        for seed in range(20):
            split = draw_sections(n_spans, rule, np.random.default_rng(seed))
            counts = [c for _, c in split]
            assert split[0][0] == 0 and split[-1][0] + split[-1][1] == n_spans
            assert all(b[0] == a[0] + a[1] - 3 for a, b in zip(split, split[1:], strict=False))
            assert all(20 <= c for c in counts)
            assert all(c <= 30 for c in counts) or len(split) == 1 or counts[-1] > 30 or n_spans < 60


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("overlap_lift: [0.0, 0.0, 0.0, 0.5]", "overlap_lift: [0.1, 0.0, 0.0, 0.5]", "overlap_lift"),
        ("overlap_lift: [0.0, 0.0, 0.0, 0.5]", "overlap_lift: [0.0, 0.0, 0.0, 0.0]", "overlap_lift"),
        ("spans_min: 20 ", "spans_min: 6 ", "spans_min"),
        ("spans_max: 30", "spans_max: 19", "spans_max"),
        ("spans_max: 30", "spans_max: 30\n    overlap: 3", "overlap"),
    ],
)
def test_a_bad_section_rule_is_one_line(old: str, new: str, key: str) -> None:
    assert old in SMALL_FILE
    with pytest.raises(CatenaryFileError) as err:
        parse_catenary(SMALL_FILE.replace(old, new), "bad.yaml")
    message = str(err.value)
    assert "\n" not in message and key in message and "layout.sections" in message


def test_the_compiled_loop_runs_the_overlap_as_the_core_objects(tmp_path: Path) -> None:
    """simulate's compiled loop and the core objects stepped tick by tick write the same bag, byte
    for byte, over an overlap: two pantographs 20 m apart start at the first support (55 m) and
    run 300 m at 300 km/h, through the whole overlap (220-385 m) but its last span."""
    from test_loop import messages_of

    from pac_rig.simulate import scenario_from_flat, simulate_to_bag

    values = {
        "catenary_model": "fe",
        "catenary": str(small_sectioned_file(tmp_path)),
        "speed_kmh": 300.0,
        "pantograph": "three_mass",
        "passive_pantograph": "three_mass",
        "pantographs": (0.0, 20.0),
        "law": "passive",
        "duration": 3.6,
    }
    s = scenario_from_flat(values)
    fast = simulate_to_bag(s, tmp_path / "fast")
    slow = simulate_to_bag(s, tmp_path / "slow", compiled=False)
    assert (fast.ticks, fast.diverged) == (slow.ticks, slow.diverged) == (3600, None)
    got, want = messages_of(tmp_path / "fast"), messages_of(tmp_path / "slow")
    assert got == want
