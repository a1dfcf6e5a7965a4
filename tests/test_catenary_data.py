"""The catenary as data: the file format and its refusals, today's line bit for bit from its file,
and per line (every preset + an unequal-span stitched test line) checks that fail on wrong physics:
static stiffness against an independent exact taut-string solution, pinned-wire frequencies
against the analytic tensioned beam, wave speed against the dispersive beam value, pre-sag
measured on a finer mesh than it was solved on, span periodicity, mutation checks."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import simulate_refusal
from scipy.linalg import eigh

from pac_plant.catenary.catenary_file import CatenaryFileError, load_catenary, parse_catenary, presets
from pac_plant.catenary.data import CatenaryData, NumericalOptions, SpanData
from pac_plant.catenary.integrator import ContactSimulation
from pac_plant.catenary.line import DOFS_PER_NODE, RC, RM, WC, WM, Line
from pac_plant.catenary.pantographs import paper_pantograph, three_mass_pantograph

pytestmark = pytest.mark.offline

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ("benchmark_55m", "stitched_hs_65m", "re200_like_65m")
TEST_LINE = str(ROOT / "tests" / "data" / "catenary_unequal_stitched.yaml")
LINES = (*PRESETS, TEST_LINE)

#: Static stiffness [N/m] of each preset's stated data as taut strings (``taut_string_stiffness``:
#: no bending, rigid droppers) at the middle support of its 10-span section and mid-span after it,
#: computed once and written here: a fixed value, so a file whose tension or stiffness moves fails.
TAUT_STRING = {
    "benchmark_55m": (7210.064364244068, 2588.726996526264),
    "stitched_hs_65m": (5409.001598503299, 2721.284342643094),
    "re200_like_65m": (4176.1567878363285, 1116.1003124212423),
}
#: FE (bending, elastic droppers) vs taut strings: what bending and the droppers' stretch may move.
STIFFNESS_TOLERANCE = 0.015


_LINES: dict[str, Line] = {}


def built(name: str) -> Line:
    """The line of a file, built once per test session (a 10-span line takes 1-10 s here)."""
    if name not in _LINES:
        f = load_catenary(name)
        _LINES[name] = Line(f.data, f.numerics)
    return _LINES[name]


# -- an independent reference: the line as taut strings ----------------------------------------------
def taut_string_stiffness(data: CatenaryData, n_spans: int, x_load: float) -> float:
    """Exact static point stiffness at x_load of the line as taut strings [N/m]: every wire straight
    between the points where something acts on it (supports, droppers, clamps, the load), so the
    solution of the string equation is exact; droppers rigid (contact wire and the wire above share
    one height there), no bending, support springs, both wires anchored at the two end supports; a
    stitch wire is clamped to the messenger half its length either side of its support (at an end
    support, anchored there). Built from the data alone, without the FE line's mesh or indices."""
    spans = data.spans
    starts = [0.0]
    for s in range(n_spans):
        starts.append(starts[-1] + spans[s % len(spans)].length)
    end = starts[-1]
    parent: dict[tuple[str, float], tuple[str, float]] = {}

    def root(p: tuple[str, float]) -> tuple[str, float]:
        while parent.setdefault(p, p) != p:
            p = parent[p]
        return p

    def tie(a: tuple[str, float], b: tuple[str, float]) -> None:
        parent[root(a)] = root(b)

    def at(wire: str, x: float) -> tuple[str, float]:
        return wire, round(x, 9)

    points: dict[str, set[float]] = {"c": {0.0, end, x_load}, "m": {0.0, end}}
    tension = {"c": data.contact.tension, "m": data.messenger.tension}
    anchored = [at("c", 0.0), at("m", 0.0), at("c", end), at("m", end)]
    for s in range(n_spans + 1):
        x0 = starts[s]
        points["c"].add(x0)
        points["m"].add(x0)
        if s < n_spans:
            for d in spans[s % len(spans)].dropper_positions:
                points["c"].add(x0 + d)
                points["m"].add(x0 + d)
                tie(at("c", x0 + d), at("m", x0 + d))
        st = spans[s % len(spans)].stitch
        if st is None:
            continue
        w = f"stitch{s}"
        tension[w] = st.tension
        a, b = max(0.0, x0 - st.length / 2), min(end, x0 + st.length / 2)
        points[w] = {a, b}
        for clamp, inside in ((a, s > 0), (b, s < n_spans)):
            if inside:
                points["m"].add(clamp)
                tie(at(w, clamp), at("m", clamp))
            else:
                anchored.append(at(w, clamp))
        for o in st.dropper_offsets:
            if 0.0 < x0 + o < end:
                points[w].add(x0 + o)
                points["c"].add(x0 + o)
                tie(at("c", x0 + o), at(w, x0 + o))
    index: dict[tuple[str, float], int] = {}

    def dof(wire: str, x: float) -> int:
        return index.setdefault(root(at(wire, x)), len(index))

    pairs = []
    for wire, xs in points.items():
        xs_sorted = sorted(xs)
        pairs += [
            (dof(wire, a), dof(wire, b), tension[wire] / (b - a))
            for a, b in zip(xs_sorted[:-1], xs_sorted[1:], strict=True)
        ]
    k = np.zeros((len(index), len(index)))
    for i, j, kk in pairs:
        k[[i, j], [i, j]] += kk
        k[i, j] -= kk
        k[j, i] -= kk
    for x0 in starts[1:-1]:
        k[dof("c", x0), dof("c", x0)] += data.steady_arm_stiffness
        k[dof("m", x0), dof("m", x0)] += data.messenger_support_stiffness
    fixed = {index[root(p)] for p in anchored}
    free = [i for i in range(len(index)) if i not in fixed]
    f = np.zeros(len(index))
    f[dof("c", x_load)] = 1.0
    w = np.linalg.solve(k[np.ix_(free, free)], f[free])
    return 1.0 / float(w[free.index(dof("c", x_load))])


def middle_points(line: Line) -> tuple[float, float]:
    """The middle support of the line's section and the mid-span after it [m]."""
    s = line.layout.support_x
    i = len(s) // 2
    return float(s[i]), float(0.5 * (s[i] + s[i + 1]))


# -- the file: today's line, presets, refusals ----------------------------------------------------------
@pytest.mark.unit
def test_the_benchmark_file_states_the_line_of_catenary_data_defaults():
    f = load_catenary("benchmark_55m")
    assert dataclasses.replace(f.data, source=CatenaryData().source) == CatenaryData()
    assert f.numerics == NumericalOptions()
    assert set(PRESETS) <= set(presets())
    for name in PRESETS:  # every preset names its sources
        assert len(load_catenary(name).data.source) > 100


def _fingerprint(a: np.ndarray) -> tuple[float, float]:
    """(w . a, sum |w_i a_i|) with fixed pseudo-random weights w: one number that moves when any
    entry of ``a`` moves, and the scale its rounding is judged against (PCG64 normal draws are the
    same on every machine)."""
    flat = np.ascontiguousarray(a, dtype=float).ravel()
    w = np.random.default_rng(20260).standard_normal(flat.size)
    return float(w @ flat), float(np.abs(w) @ np.abs(flat))


#: Fingerprints of the line hard-coded before the catenary file existed (commit c49f3bf's
#: pac_plant.catenary, recorded where that line's arrays were hashed: the same arrays bit for bit).
TODAYS_LINE = {
    "K": 12681182.483668739,
    "M": 4.757082349923141,
    "w_static": 2.9700874575684124,
    "length0": 8.168534578393235,
}
#: Relative to the fingerprint's scale. K and M are sums of a few element contributions per entry:
#: rounding of ~1e-16 of the scale (measured 4e-17 and 1e-17 with numpy's AVX-512 and AVX2 loops
#: disabled and OpenBLAS on its Haswell kernels). The static state and the droppers' lengths come
#: out of banded solves whose forward error is the condition number times eps; measured 2e-15 and
#: 3e-17 under the same change. The bounds leave three or more orders of margin; a line that is
#: wrong moves them by far more (the contact wire's clamps 1 % heavier: 1e-6 to 4e-5 of the scale).
FINGERPRINT_REL = {"K": 1e-13, "M": 1e-13, "w_static": 1e-11, "length0": 1e-11}


def test_the_benchmark_file_gives_todays_line_and_run():
    """Matrices, static state and a short run from the file = those of the hard-coded line before
    the file existed, on any machine: fingerprints at the rounding the numerics allow (not hashes
    of floats, which a machine with other SIMD loops or BLAS kernels does not reproduce)."""
    f = load_catenary("benchmark_55m")
    line = Line(f.data, f.numerics)
    arrays = {"K": line.K.ab, "M": line.M.ab, "w_static": line.w_static, "length0": line.droppers.length0}
    for name, a in arrays.items():
        value, scale = _fingerprint(a)
        assert abs(value - TODAYS_LINE[name]) <= FINGERPRINT_REL[name] * scale, name
    short = Line(f.data, f.numerics, n_spans=4)
    assert float(short.K.ab.sum()) == pytest.approx(74078406.94446956, rel=1e-13)
    assert float(np.abs(short.M.ab).sum()) == pytest.approx(500.44923982262753, rel=1e-13)
    sim = ContactSimulation(short, three_mass_pantograph(), 1e-3, 300 / 3.6, 55.0)
    sim.start_static(157.3)
    forces = []
    for _ in range(300):
        sim.step(157.3)
        forces.append(sim.contact_force)
    # 300 implicit steps of a stiff line: rounding grows with the step count and the compiled step may
    # fuse multiply-adds or not by CPU (docs/numerics.md); measured 4e-13 relative with numpy's and
    # OpenBLAS's SIMD narrowed; the contact wire's clamps 1 % heavier move these forces by 2e-5 or more.
    expected = (153.71739081121606, 132.72307449347176, 140.1721358313002)
    assert [forces[i] for i in (99, 199, 299)] == pytest.approx(expected, rel=1e-10)


GOOD = (ROOT / "config" / "catenaries" / "benchmark_55m.yaml").read_text()
NO_SPANS = GOOD.split("\nspans:")[0] + "\nspans: []\ndamping:" + GOOD.split("\ndamping:")[1]
STITCHED = (ROOT / "config" / "catenaries" / "stitched_hs_65m.yaml").read_text()

BAD = [
    # (text, replaced by, key named in the message, what the message says is allowed)
    (GOOD, ("tension: 22000.0", "tension: -22000.0"), "'contact_wire.tension' = -22000.0", "(0, 1e+06] N"),
    (GOOD, ("rho: 1.08,", "rho: .nan,"), "'messenger_wire.rho' = nan", "a finite number"),
    (GOOD, ("ei: 195.0", "ei: .inf"), "'contact_wire.ei' = inf", "a finite number"),
    (GOOD, ("ei: 195.0", "ei: stiff"), "'contact_wire.ei' = 'stiff'", "a finite number"),
    (GOOD, ("ea: 200000.0", "ea: true"), "'droppers.ea' = True", "a finite number"),
    (
        GOOD,
        ("steady_arm_stiffness: 2673.58", "steady_arm_stiffness: 0"),
        "'supports.steady_arm_stiffness' = 0",
        "(0,",
    ),
    (
        GOOD,
        ("  messenger_support_stiffness: 500000.0  # N/m\n", ""),
        "'supports.messenger_support_stiffness' = None",
        "missing",
    ),
    (GOOD, ("gravity: 9.81", "gravity: 98.1"), "'gravity' = 98.1", "[9.7, 9.9]"),
    (GOOD, ("section_spans: 10", "section_spans: 1"), "'section_spans' = 1", "an integer in [2, 1000]"),
    (GOOD, ("section_spans: 10", "section_spans: 2.5"), "'section_spans' = 2.5", "an integer"),
    (GOOD, ("length: 55.0", "length: 0.0"), "'spans[0].length' = 0.0", "(5, 200] m"),
    (GOOD, ("encumbrance: 1.2", "encumbrance: -1.2"), "'spans[0].encumbrance' = -1.2", "(0.2, 5] m"),
    (GOOD, ("[4.5, 10.25,", "[10.25, 4.5,"), "'spans[0].droppers[1]' = 4.5", "ascending"),
    (GOOD, ("44.75, 50.5]", "44.75, 55.0]"), "'spans[0].droppers[8]' = 55.0", "(0, 55) m"),
    (GOOD, ("presag: [0.0, 0.024,", "presag: [0.024,"), "'spans[0].presag' = [", "a list of 9"),
    (GOOD, ("0.052, 0.055, 0.052", "0.052, 0.9, 0.052"), "'spans[0].presag[4]' = 0.9", "[-0.6, 0.6] m"),
    (
        GOOD,
        ("contact_stiffness: 50000.0", "contact_stiffness: 5.0"),
        "'contact_stiffness' = 5.0",
        "(1000, 1e+07] N/m",
    ),
    (GOOD, ("rayleigh_beta: 1.0e-4", "rayleigh_beta: 0.1"), "'damping.rayleigh_beta' = 0.1", "[0, 0.01] s"),
    (
        GOOD,
        ("rayleigh_beta: 1.0e-4", "rayleigh_bta: 1.0e-4"),
        "'damping.rayleigh_bta' = 0.0001",
        "one of the keys rayleigh_alpha, rayleigh_beta",
    ),
    (
        GOOD,
        ("contact_stiffness: 50000.0", "numerics: {element_size: 0.5}\ncontact_stiffness: 50000.0"),
        "'numerics' =",
        "one of the keys",
    ),
    (GOOD, ("gravity: 9.81", "gravity: 9.81\ngravity: 9.81"), "'gravity' = 'given twice'", "each key once"),
    (GOOD, ("damping: {", "dampin: {"), "'dampin' =", "one of the keys"),
    (NO_SPANS, ("spans: []", "spans: []"), "'spans' = []", "a non-empty list of spans"),
    (GOOD, ("44.75, 50.5]", "44.75, 50.5, 60.0]"), "'spans[0].droppers[9]' = 60.0", "(0, 55) m"),
    (GOOD, ("name: benchmark_55m", "name: [a"), "'(YAML)'", "valid YAML"),
    (GOOD, ("name: benchmark_55m", "name: ''"), "'name' = ''", "a non-empty string"),
    (
        GOOD,
        ("contact_wire:   {rho", "contact_wire:   {rh0"),
        "'contact_wire.rh0' = 1.35",
        "one of the keys rho, tension, ei",
    ),
    (STITCHED, ("length: 18.0", "length: 140.0"), "'spans[0].stitch.length' = 140.0", "(1, 100] m"),
    (
        STITCHED,
        ("length: 18.0", "length: 90.0"),
        "'spans[0].stitch.length' = 90.0",
        "less than the shorter neighbouring span (65 m)",
    ),
    (
        STITCHED,
        ("droppers: [-4.5, 4.5]", "droppers: [-4.5, 0.0]"),
        "'spans[0].stitch.droppers[1]' = 0.0",
        "an offset",
    ),
    (
        STITCHED,
        ("droppers: [-4.5, 4.5]", "droppers: [-4.5, 11.5]"),
        "'spans[0].stitch.droppers[1]' = 11.5",
        "(-9, 0) or (0, 9) m",
    ),
    (
        STITCHED,
        ("tension: 3500.0", "tension: -3500.0"),
        "'spans[0].stitch.tension' = -3500.0",
        "(0, 100000] N",
    ),
    (
        STITCHED,
        ("presag: [0.0, 0.0]\n", "presag: [0.0]\n"),
        "'spans[0].stitch.presag' = [0.0]",
        "a list of 2",
    ),
]


@pytest.mark.unit
@pytest.mark.parametrize(
    "text,change,key,allowed", BAD, ids=[b[2].split("'")[1] + ":" + str(i) for i, b in enumerate(BAD)]
)
def test_a_bad_catenary_file_is_refused_in_one_line_naming_key_value_and_what_is_allowed(
    text, change, key, allowed
):
    assert change[0] in text
    with pytest.raises(CatenaryFileError) as err:
        parse_catenary(text.replace(change[0], change[1], 1), "line.yaml")
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith("invalid catenary file 'line.yaml'")
    assert key in message and "allowed" in message and allowed in message
    if "YAML" not in key:
        assert ", line " in message and ", column " in message


@pytest.mark.unit
def test_a_missing_file_or_preset_is_refused_by_name():
    from pac_common.parameters import ParameterError

    with pytest.raises(ParameterError, match=r"'catenary' = 'no_such_line': allowed .*benchmark_55m"):
        load_catenary("no_such_line")
    with pytest.raises(ParameterError, match="readable catenary file"):
        load_catenary("/nonexistent/line.yaml")


@pytest.mark.slow
def test_simulate_refuses_a_bad_catenary_file_with_one_line_exit_2_and_runs_nothing(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(GOOD.replace("tension: 16000.0", "tension: 0.0"))
    line = simulate_refusal(tmp_path / "bag", "catenary_model:=fe", f"catenary:={bad}", "duration:=0.01")
    assert "'messenger_wire.tension' = 0.0: allowed a finite number in (0, 1e+06] N" in line
    assert "line 14, column" in line


# -- physics, per line ------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", PRESETS)
@pytest.mark.slow
def test_static_stiffness_at_a_support_and_mid_span_is_the_taut_string_value_of_the_stated_data(name):
    line = built(name)
    support, mid = middle_points(line)
    fe = line.static_stiffness(np.array([support, mid]))
    fixed = TAUT_STRING[name]
    # The fixed values are the independent reference of the data as stated ...
    reference = [taut_string_stiffness(line.data, line.n_spans, x) for x in (support, mid)]
    assert reference == pytest.approx(fixed, rel=1e-9)
    # ... and the FE line (bending, elastic droppers) stays within 1.5 % of them.
    assert np.abs(fe / np.array(fixed) - 1.0).max() < STIFFNESS_TOLERANCE, (fe, fixed)
    assert fe[0] > 1.5 * fe[1]  # stiffer at the support than mid-span


def test_static_stiffness_of_the_unequal_stitched_line_is_the_taut_string_value():
    """Three unequal spans (60, 48, 55 m), three encumbrances, a stitch wire at one support in
    three: at every support of the middle period, mid-span of each span and at the stitch droppers."""
    line = built(TEST_LINE)
    s = line.layout.support_x
    xs = [*s[3:7], *(0.5 * (s[3:6] + s[4:7])), s[3] + 3.5, s[6] - 3.5]
    fe = line.static_stiffness(np.array(xs))
    ref = np.array([taut_string_stiffness(line.data, line.n_spans, x) for x in xs])
    assert np.abs(fe / ref - 1.0).max() < STIFFNESS_TOLERANCE, (fe, ref)


@pytest.mark.parametrize(
    "change",
    [
        ("contact", "tension"),
        ("messenger", "tension"),
        ("steady_arm_stiffness", None),
        ("stitch", None),
    ],
)
@pytest.mark.slow
def test_mutation_a_tension_or_a_stiffness_off_by_10_percent_fails_the_stiffness_check(change):
    """The check above must catch a wrong line: each value x 1.1 in the FE line (what a misread file
    or a wrong assembly would do) moves a support or mid-span stiffness out of the 1.5 % band; so
    does a stitched line without its stitch wires. (A stitch wire's tension x 1.1 moves the
    stiffness at its dropper by 1.2 % only: inside the band, not caught by this check.)"""
    name = "stitched_hs_65m" if change[0] == "stitch" else "benchmark_55m"
    f = load_catenary(name)
    data = f.data
    if change[0] in ("contact", "messenger"):
        wire = getattr(data, change[0])
        data = dataclasses.replace(data, **{change[0]: dataclasses.replace(wire, tension=1.1 * wire.tension)})
    elif change[0] == "stitch":  # the stitch wire (and its droppers) left out
        span = data.spans[0]
        offsets = span.stitch.dropper_offsets
        droppers = (*(span.length + o for o in offsets if o < 0), *span.dropper_positions)
        unstitched = dataclasses.replace(
            span,
            stitch=None,
            dropper_positions=tuple(sorted((*(o for o in offsets if o > 0), *droppers))),
            presag=(0.0,) * (len(span.dropper_positions) + len(offsets)),
        )
        data = dataclasses.replace(data, spans=(unstitched,))
    else:
        data = dataclasses.replace(data, steady_arm_stiffness=1.1 * data.steady_arm_stiffness)
    line = Line(data, f.numerics)
    support, mid = middle_points(line)
    fe = line.static_stiffness(np.array([support, mid]))
    assert np.abs(fe / np.array(TAUT_STRING[name]) - 1.0).max() > STIFFNESS_TOLERANCE


def _pinned_frequencies(line: Line, slots: tuple[int, int], count: int) -> np.ndarray:
    """The lowest natural frequencies [Hz] of the wire on DOF slots ``slots`` of a bare line."""
    free = np.setdiff1d(
        DOFS_PER_NODE * np.arange(line.n_nodes)[:, None] + np.array(slots), line.fixed
    ).ravel()
    k, m = line.K.dense()[np.ix_(free, free)], line.M.dense()[np.ix_(free, free)]
    return np.sqrt(eigh(k, m, eigvals_only=True, subset_by_index=(0, count - 1))) / (2 * math.pi)


@pytest.mark.parametrize("name", LINES)
def test_pinned_bare_wire_frequencies_are_the_tensioned_beam_values(name):
    """f_n = n / (2L) sqrt(T / rho) sqrt(1 + EI (n pi / L)^2 / T) of a pinned-pinned tensioned beam,
    first 10 modes, for the contact wire (a Hermite beam) and, on a line without stitch wires, the
    messenger (a beam too; a stitched line's messenger is a string and carries its stitch wires)."""
    f = load_catenary(name)
    line = Line(f.data, f.numerics, n_spans=1, droppers=False, supports=False)
    length = line.length
    wires = [(f.data.contact, (WC, RC))]
    if not f.data.stitched:
        wires.append((f.data.messenger, (WM, RM)))
    for wire, slots in wires:
        n = np.arange(1, 11)
        k = n * math.pi / length
        analytic = n / (2 * length) * wire.wave_speed * np.sqrt(1 + wire.ei * k**2 / wire.tension)
        assert _pinned_frequencies(line, slots, 10) == pytest.approx(analytic, rel=1e-7)


@pytest.mark.parametrize("name", LINES)
def test_a_pulse_on_the_bare_contact_wire_travels_at_the_dispersive_beam_speed(name):
    """A wide Gaussian pulse (width 6 m) on the bare contact wire of 3 spans, integrated by the FE
    step: its right-going half's centroid moves at the beam's group velocity (T + 2 EI k^2) /
    (rho c_p(k)) at the pulse's mean wavenumber, within 0.5 %."""
    f = load_catenary(name)
    line = Line(f.data, f.numerics, n_spans=3, droppers=False, supports=False)
    sim = ContactSimulation(line, paper_pantograph(), 5e-4, 0.0, 1.0, damping=False)
    x = line.x
    x0, s = 0.3 * line.length, 6.0
    wc = DOFS_PER_NODE * np.arange(line.n_nodes) + WC
    d = np.zeros(line.n_dof)
    d[wc] = 0.01 * np.exp(-(((x - x0) / s) ** 2))
    d[wc + 1] = -2 * (x - x0) / s**2 * d[wc]
    sim.set_line_state(d, np.zeros(line.n_dof))
    times, centroids = [], []
    for k in range(1, 601):
        sim.step(0.0)
        if k >= 350 and k % 50 == 0:
            w = sim.d[wc]
            right = x > x0  # the right-going half only (the halves are > 3 widths apart by now)
            centroids.append(float(np.sum(x[right] * w[right]) / np.sum(w[right])))
            times.append(sim.time)
    speed = np.polyfit(times, centroids, 1)[0]
    wire = f.data.contact
    k = 1.0 / (s * math.sqrt(2.0))  # mean |k| of the pulse's spectrum exp(-(k s / 2)^2) ~ its rms
    phase = math.sqrt((wire.tension + wire.ei * k**2) / wire.rho)
    group = (wire.tension + 2 * wire.ei * k**2) / (wire.rho * phase)
    assert abs(speed / group - 1.0) < 0.005, (speed, group)


@pytest.mark.parametrize("name", LINES)
@pytest.mark.slow
def test_the_presag_solved_on_one_mesh_is_there_on_a_finer_mesh(name):
    """Dropper lengths solved on the file's mesh (0.5 m), then used as they are on a mesh of half
    the element size: the contact-wire height measured at each dropper is the design pre-sag."""
    coarse = built(name)
    f = load_catenary(name)
    fine = Line(f.data, dataclasses.replace(f.numerics, element_size=0.5 * f.numerics.element_size))
    assert np.array_equal(fine.droppers.x, coarse.droppers.x)
    fine.set_dropper_lengths(coarse.droppers.length0)
    measured = np.array([-fine.static_height(float(x)) for x in coarse.droppers.x])
    # 1 mm: measured 0.41 mm on benchmark_55m, whose messenger is a beam (bending length
    # sqrt(EI/T) = 9 cm, not resolved by 0.5 m elements under the dropper forces); 0.01-0.02 mm
    # on the stitched lines, whose messenger is a string.
    assert np.abs(measured - coarse.droppers.target_sag).max() < 1e-3
    assert np.all(fine.droppers.static_tension > 0.0)


@pytest.mark.parametrize("name", PRESETS)
def test_equal_spans_give_a_span_periodic_stiffness(name):
    line = built(name)
    support, _ = middle_points(line)
    span = line.data.span
    xs = support + np.linspace(0.0, span, 45, endpoint=False)
    k, k_before = line.static_stiffness(xs), line.static_stiffness(xs - span)
    assert np.abs(k / k_before - 1.0).max() < 0.005


@pytest.mark.slow
def test_the_endless_window_on_unequal_stitched_spans_equals_a_long_fixed_line():
    """The plant's window shifts by whole periods (three unequal spans here, stitch droppers among
    them): over two shifts the contact force equals that of a fixed line long enough, within 1 mN."""
    f = load_catenary(TEST_LINE)
    period = f.data.period
    forces = {}
    for endless, n_spans in ((True, 9), (False, 15)):
        line = Line(f.data, f.numerics, n_spans=n_spans)
        sim = ContactSimulation(line, three_mass_pantograph(), 1e-3, 350 / 3.6, period, endless=endless)
        sim.start_static(120.0)
        out = []
        while sim.position < 3.2 * period:
            sim.step(120.0)
            out.append(sim.contact_force)
        forces[endless] = np.array(out)
        if endless:
            assert sim.offset == pytest.approx(2 * period)  # two shifts
    assert np.abs(forces[True] - forces[False]).max() < 1e-3
    assert forces[False].std() > 5.0  # the run does see the line


@pytest.mark.slow
def test_the_plant_runs_on_a_catenary_file():
    """FEPlant from ``catenary:=FILE``: the line of the file (period, stitch droppers), a finite
    contact force once the uplift acts, truth at the contact point."""
    from pac_model.parameters import PantographParameters, TrackParameters
    from pac_plant.fe_plant import FEPlant
    from pac_plant.parameters import PlantOptions

    options = PlantOptions(catenary_model="fe", catenary=TEST_LINE)
    plant = FEPlant(PantographParameters(), TrackParameters(speed_kmh=300.0), None, options, 1e-3)
    assert plant.data.name == "unequal_stitched"
    assert plant.line.n_spans == 12 and plant.sim.x == pytest.approx(plant.data.period)  # 4 periods
    for _ in range(300):
        plant.advance(120.0)
    truth = plant.truth()
    assert math.isfinite(truth.contact_force) and truth.contact_force > 0.0
    assert truth.contact_position == pytest.approx(plant.data.period + 0.3 * 300 / 3.6, rel=1e-9)


def test_span_data_defaults_are_the_benchmark_span():
    span = SpanData()
    assert span.length == 55.0 and len(span.dropper_positions) == len(span.presag) == 9


@pytest.mark.unit
def test_a_campaign_may_vary_the_line_and_keeps_its_old_keys_on_the_default_line(tmp_path):
    """Each point on the FE line is told its file's span (whole-span windows per line), and points on
    the default line keep the keys they had before the line became a parameter."""
    from pac_experiments.campaign.spec import expand, load_spec

    spec_path = tmp_path / "lines.yaml"
    spec_path.write_text(
        "grid:\n  catenary: [benchmark_55m, stitched_hs_65m]\n"
        "fixed:\n  catenary_model: fe\n  speed_kmh: 300.0\nwindow_spans: [4, 6]\n"
    )
    points = expand(load_spec(spec_path))
    assert [p.values["span_length"] for p in points] == [55.0, 65.0]
    for p, span in zip(points, (55.0, 65.0), strict=True):
        assert p.window == pytest.approx((4 * span / (300 / 3.6), 6 * span / (300 / 3.6)))
    assert len({p.key for p in points}) == 2
    # The committed campaigns' results were run before ``catenary`` and the imperfections existed:
    # their SPECs still expand to the keys of those rows (a rerun resumes instead of starting over).
    import csv

    for spec, results in (
        ("config/campaigns/laws_speeds.yaml", "reports/campaigns/laws_speeds/results.csv"),
        ("config/campaigns/fe_laws.yaml", "reports/catenary/laws/results.csv"),
        ("config/campaigns/lines_speeds.yaml", "reports/campaigns/lines_speeds/results.csv"),
    ):
        keys = {p.key for p in expand(load_spec(ROOT / spec))}
        with (ROOT / results).open() as rows:
            assert {row["key"] for row in csv.DictReader(rows)} <= keys, spec


# -- imperfections (off by default) -----------------------------------------------------------------------
@pytest.mark.unit
def test_imperfections_are_off_by_default_and_seeded():
    from pac_plant.catenary.imperfections import apply_imperfections

    data = load_catenary("stitched_hs_65m").data
    assert apply_imperfections(data, 0.0, 0.0, 7) is data
    a, b = apply_imperfections(data, 0.01, 0.0, 1), apply_imperfections(data, 0.01, 0.0, 1)
    assert a == b and a != apply_imperfections(data, 0.01, 0.0, 2)
    assert len(a.spans) == 10  # drawn over 10 spans (the period of one span repeated)
    errors = np.array([e - d for s in a.spans for e, d in zip(s.presag, data.spans[0].presag, strict=True)])
    assert abs(errors.mean()) < 0.004 and 0.007 < errors.std() < 0.013  # 70 draws of N(0, 10 mm)
    worn = apply_imperfections(data, 0.0, 0.2, 0)
    assert worn.contact.rho == pytest.approx(0.8 * data.contact.rho)
    assert worn.contact.ei == pytest.approx(0.64 * data.contact.ei)
    assert worn.contact.tension == data.contact.tension and worn.spans == data.spans


def test_height_errors_are_where_the_wire_hangs_measured_on_a_finer_mesh():
    """The dropper lengths solved for design pre-sag + errors, used on a mesh of half the element
    size: the contact-wire height at each dropper is the erroneous one (1 mm standard deviation:
    every dropper still hangs in tension) within 0.5 mm, and differs from the design by what was
    drawn."""
    from pac_plant.catenary.imperfections import apply_imperfections

    f = load_catenary("benchmark_55m")
    data = apply_imperfections(f.data, 0.001, 0.0, 3)
    coarse = Line(data, f.numerics, n_spans=10)
    fine = Line(data, dataclasses.replace(f.numerics, element_size=0.25), n_spans=10)
    fine.set_dropper_lengths(coarse.droppers.length0)
    measured = np.array([-fine.static_height(float(x)) for x in coarse.droppers.x])
    assert np.all(coarse.droppers.static_tension > 0.0)
    assert np.abs(measured - coarse.droppers.target_sag).max() < 5e-4
    design = np.tile(f.data.presag, 10)
    assert 0.0007 < np.std(measured - design) < 0.0013


def test_a_worn_contact_wire_has_the_tensioned_beam_frequencies_of_its_reduced_section():
    from pac_plant.catenary.imperfections import apply_imperfections

    f = load_catenary("benchmark_55m")
    wear = 0.2
    line = Line(
        apply_imperfections(f.data, 0.0, wear, 0), f.numerics, n_spans=1, droppers=False, supports=False
    )
    c = f.data.contact
    rho, ei = c.rho * (1 - wear), c.ei * (1 - wear) ** 2  # the stated rule, from the new wire's data
    n = np.arange(1, 11)
    k = n * math.pi / line.length
    analytic = n / (2 * line.length) * math.sqrt(c.tension / rho) * np.sqrt(1 + ei * k**2 / c.tension)
    assert _pinned_frequencies(line, (WC, RC), 10) == pytest.approx(analytic, rel=1e-7)


@pytest.mark.slow
def test_the_plant_runs_on_a_line_with_height_errors():
    from pac_model.parameters import PantographParameters, TrackParameters
    from pac_plant.fe_plant import FEPlant
    from pac_plant.parameters import PlantOptions

    options = PlantOptions(catenary_model="fe", fe_height_error=0.001, fe_imperfection_seed=4, fe_wear=0.1)
    plant = FEPlant(PantographParameters(), TrackParameters(speed_kmh=250.0), None, options, 1e-3)
    assert len(plant.data.spans) == 10 and plant.line.n_spans == 30  # 3 periods of 10 spans
    assert plant.data.contact.rho == pytest.approx(0.9 * 1.35)
    for _ in range(100):
        plant.advance(120.0)
    assert math.isfinite(plant.truth().contact_force)
    # Errors large enough that a dropper would have to push leave it hanging slack at rest (the
    # static state has droppers that carry tension only): 5 mm on this line slackens some of them,
    # the plant starts from that rest state and runs.
    slack = FEPlant(
        PantographParameters(),
        TrackParameters(),
        None,
        PlantOptions(catenary_model="fe", fe_height_error=0.005, fe_imperfection_seed=4),
        1e-3,
    )
    assert len(slack.line.rest_slack) > 0
    assert np.array_equal(slack.sim.slack, slack.line.rest_slack) and slack.truth().contact_force == 0.0
    for _ in range(100):
        slack.advance(120.0)
    assert math.isfinite(slack.truth().contact_force)
