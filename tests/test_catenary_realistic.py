"""A realistic line: droppers that carry tension only at rest, the contact-wire deviation drawn from
a spectrum, a whole line drawn by a layout rule. Each physics check compares with an independent
reference and is shown to fail on the wrong physics (a taut-only static solve, the rest load left
out of the dynamics, a wrong spectrum)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fe_step_oracle import NumpyStep
from scipy.signal import welch

from pac_plant.catenary.catenary_file import CatenaryFileError, load_catenary, parse_catenary
from pac_plant.catenary.data import CatenaryData
from pac_plant.catenary.deviation import DeviationModel, apply_deviation, spectral_density, vertical_deviation
from pac_plant.catenary.imperfections import apply_imperfections
from pac_plant.catenary.integrator import ContactSimulation
from pac_plant.catenary.layout_rule import reflect
from pac_plant.catenary.line import WC, WM, Line, beam_matrices, gravity_load
from pac_plant.catenary.pantographs import paper_pantograph

pytestmark = pytest.mark.offline

ROOT = Path(__file__).resolve().parents[1]
#: The deviation model of the realistic preset (its numbers are judgement: docs/catenary.md).
MODEL = DeviationModel(vertical_sigma=0.004, correlation_length=10.0, longitudinal_sigma=0.05)


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
    step = sim.step if compiled else NumpyStep(sim)
    for _ in range(200):
        step(0.0)
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


# -- 2. the deviation's spectrum --------------------------------------------------------------------
def sampled_spectral_density(kappa: np.ndarray, sigma: float, ell: float, step: float) -> np.ndarray:
    """One-sided spectral density of the process sampled every ``step`` [m]: the Fourier series of its
    autocorrelation sigma^2 rho^|k|, rho = exp(-step / ell) (the stated S(kappa) folded at 1/(2 step))."""
    rho = np.exp(-step / ell)
    return (
        2.0 * step * sigma**2 * (1.0 - rho**2) / (1.0 - 2.0 * rho * np.cos(2 * np.pi * kappa * step) + rho**2)
    )


def band_ratios(u: np.ndarray, step: float, sigma: float, ell: float) -> np.ndarray:
    """Welch estimate / reference spectrum, averaged over bands of 8 frequency bins (DC left out)."""
    kappa, estimate = welch(u, fs=1.0 / step, nperseg=256)
    reference = sampled_spectral_density(kappa, sigma, ell, step)
    ratio = estimate[1:-1] / reference[1:-1]
    return ratio[: len(ratio) // 8 * 8].reshape(-1, 8).mean(axis=1)


#: Welch over 2^17 samples, 256-sample Hann segments half overlapping: ~1000 segments, a bin's
#: relative standard error ~ 1/sqrt(1000 x 0.9) = 3.3 %, a band of 8 correlated bins ~2 %: 10 % is
#: 5 standard errors (a false failure ~1e-6), while a correlation length off by 1.5x misses by 25 % or more.
SPECTRUM_TOLERANCE = 0.10


def test_the_drawn_deviation_has_the_stated_spectrum() -> None:
    sigma, ell, step = 0.004, 10.0, 5.75
    x = step * np.arange(2**17)
    u = vertical_deviation(x, sigma, ell, np.random.default_rng(7))
    ratios = band_ratios(u, step, sigma, ell)
    assert np.max(np.abs(ratios - 1.0)) < SPECTRUM_TOLERANCE
    assert abs(np.std(u) / sigma - 1.0) < 0.02
    # The reference is the stated S(kappa) folded by the sampling at the droppers (aliasing):
    # sum over m of S(|kappa + m / step|), here summed term by term.
    kappa = np.linspace(0.0, 0.5 / step, 7)
    m = np.arange(-20000, 20001)[:, None]
    folded = spectral_density(np.abs(kappa[None, :] + m / step), sigma, ell).sum(axis=0)
    assert np.allclose(sampled_spectral_density(kappa, sigma, ell, step), folded, rtol=1e-3)
    # Mutations: a wrong correlation length, or white noise of the same variance, fails the check.
    assert np.max(np.abs(band_ratios(u, step, sigma, 1.5 * ell) - 1.0)) > 2 * SPECTRUM_TOLERANCE
    white = np.random.default_rng(7).normal(0.0, sigma, len(x))
    assert np.max(np.abs(band_ratios(white, step, sigma, ell) - 1.0)) > 2 * SPECTRUM_TOLERANCE


def test_the_deviation_is_seeded_different_in_every_span_and_within_its_amplitude() -> None:
    data = CatenaryData()

    def draw(seed: int) -> CatenaryData:
        return apply_deviation(data, MODEL, 60, np.random.default_rng(seed))

    a, b = draw(1), draw(2)
    assert draw(1) == a  # the same seed, the same line
    assert a != b
    sag = np.array([s.presag for s in a.spans]) - np.array(data.presag)
    assert not np.any(np.all(np.isclose(sag[1:], sag[0]), axis=1))  # no span repeats the first
    assert 0.005 < np.max(np.abs(sag)) < 0.02  # several mm, up to about +-10 mm (4 mm standard deviation)
    shift = np.array([s.dropper_positions for s in a.spans]) - np.array(data.dropper_positions)
    assert 0.03 < np.std(shift) < 0.07 and np.max(np.abs(shift)) <= 0.15 + 1e-12


# -- 3./4. the whole line and its file --------------------------------------------------------------
def test_the_realistic_preset_follows_its_layout_rule() -> None:
    f = load_catenary("realistic_3km")
    data = f.data
    assert data.whole_line and f.drawing is not None and f.drawing.layout is not None
    rule = f.drawing.layout
    lengths = np.array([s.length for s in data.spans])
    heights = np.array([s.encumbrance for s in data.spans])
    assert lengths.sum() >= 3000.0 and data.n_spans == len(data.spans)
    assert np.all((lengths >= rule.span_min) & (lengths <= rule.span_max))
    assert np.max(np.abs(np.diff(heights))) <= rule.max_height_step + 1e-12
    assert np.all((heights >= rule.height_min) & (heights <= rule.height_max))
    assert len(set(np.round(lengths, 6))) == len(lengths)  # drawn, not repeated
    assert f.line(2) != data and f.line(1) == data  # line_seed


@pytest.mark.parametrize("seed", [100, 117])
def test_the_line_as_designed_is_the_installed_line_without_its_deviation(seed: int) -> None:
    """realistic_3km_as_designed draws the layout of realistic_3km for the same seed (spans, system
    heights): the two differ only in the deviation, which moves droppers and pre-sag, never a span
    or a height; the deviation drawn on the designed line (its stream of the seed) is the installed one."""
    installed = load_catenary("realistic_3km")
    designed = load_catenary("realistic_3km_as_designed")
    assert designed.drawing is not None and designed.drawing.deviation is None
    assert installed.drawing is not None and installed.drawing.deviation is not None
    a, d = installed.line(seed), designed.line(seed)
    assert [(s.length, s.encumbrance) for s in a.spans] == [(s.length, s.encumbrance) for s in d.spans]
    assert a.spans != d.spans
    redrawn = apply_deviation(d, installed.drawing.deviation, d.n_spans, np.random.default_rng([seed, 1]))
    assert redrawn.spans == a.spans  # (name and source are the files')


def test_reflect_keeps_the_height_in_its_range() -> None:
    assert reflect(1.65, 1.1, 1.6) == pytest.approx(1.55)
    assert reflect(1.0, 1.1, 1.6) == pytest.approx(1.2)
    assert reflect(1.3, 1.1, 1.6) == 1.3


BASE = (ROOT / "config" / "catenaries" / "realistic_3km.yaml").read_text()


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("rule: uniform_spans", "rule: gaussian", "layout.rule"),
        ("max_height_step: 0.15", "max_height_step: -0.1", "layout.max_height_step"),
        ("span_max: 60.0", "span_max: 40.0", "layout.span_max"),
        ("droppers: 9 ", "droppers: 40 ", "layout.droppers"),
        ("model: exponential_psd", "model: white", "deviation.model"),
        ("vertical_sigma: 0.004", "vertical_sigma: 0.2", "deviation.vertical_sigma"),
        ("longitudinal_sigma: 0.05", "longitudinal_sigma: 0.9", "deviation.longitudinal_sigma"),
        ("line_seed: 1", "line_seed: -3", "line_seed"),
        ("layout:", "spans: [{length: 55.0}]\nlayout:", "spans"),
    ],
)
def test_a_bad_layout_or_deviation_is_refused_in_one_line(old: str, new: str, key: str) -> None:
    assert old in BASE
    with pytest.raises(CatenaryFileError) as err:
        parse_catenary(BASE.replace(old, new, 1), "bad.yaml")
    message = str(err.value)
    assert "\n" not in message and f"'{key}'" in message


WHOLE_SHORT = str(ROOT / "tests" / "data" / "catenary_whole_short.yaml")


def test_the_plant_runs_a_whole_line_once_from_its_first_support() -> None:
    from pac_model.parameters import PantographParameters, TrackParameters
    from pac_plant.fe_plant import FEPlant
    from pac_plant.parameters import PlantOptions

    def plant(seed: int) -> FEPlant:
        options = PlantOptions(catenary_model="fe", catenary=WHOLE_SHORT, line_seed=seed)
        return FEPlant(PantographParameters(), TrackParameters(speed_kmh=300.0), None, options, 1e-3)

    p = plant(-1)
    assert p.data == load_catenary(WHOLE_SHORT).data  # -1: the file's line_seed
    assert not p.sim.endless and p.line.n_spans == len(p.data.spans)  # the whole line, not a window
    assert p.sim.x == p.line.layout.support_x[1]
    assert np.array_equal(p.sim.slack, p.line.rest_slack) and p.truth().contact_force == 0.0
    for _ in range(2000):
        p.advance(120.0)
    assert p.truth().contact_position == pytest.approx(p.line.layout.support_x[1] + 2000 * 300.0 / 3.6e3)
    assert 0.0 < p.truth().contact_force < 400.0
    assert plant(2).data != p.data  # line_seed draws another line


def test_a_run_longer_than_the_whole_line_is_refused_before_it_starts() -> None:
    """The whole line ends: a duration that would take the pantograph past its end is refused in one
    line before any tick (it stopped mid-run with 'ran off the line'); one that ends on it runs."""
    from pac_common.parameters import ParameterError
    from pac_rig.closed_loop import build_cores, run
    from pac_rig.simulate import scenario_from_flat

    flat = {"catenary_model": "fe", "catenary": WHOLE_SHORT, "speed_kmh": 300.0, "law": "passive"}
    plant = build_cores(scenario_from_flat({**flat, "duration": 0.1}))[0]
    longest = plant.run_length / (300.0 / 3.6)
    assert 0.0 < longest < 60.0
    with pytest.raises(ParameterError) as info:
        build_cores(scenario_from_flat({**flat, "duration": longest + 0.01}))
    message = str(info.value)
    assert info.value.name == "duration" and "the line ends" in message and "\n" not in message
    # Two ticks short of the end runs to its last tick (the bound is where the step stops).
    scenario = scenario_from_flat({**flat, "duration": round(longest - 2e-3, 3)})
    assert sum(1 for _ in run(scenario)) == scenario.loop.ticks


def test_the_whole_lines_dropper_lengths_put_the_taut_wire_at_its_design_presag() -> None:
    """The dropper lengths of a whole line (solved by chord steps, one solve a pass): with every
    dropper taut, the static contact wire sits at each dropper's target (the design pre-sag plus
    the drawn deviation) within 1e-6 m, as the per-pass solve of a periodic line does (its passes
    stop when the lengths move less than 1e-9 m). One pass alone misses by ~85 mm."""
    f = load_catenary("realistic_3km")
    data = f.line(3)
    line = Line(data, f.numerics, n_spans=len(data.spans))
    dr = line.droppers
    taut = line.solve_static(line.f_static)
    assert len(dr.node) > 400  # a whole line's droppers, not a period's
    assert np.max(np.abs(taut[dr.wc] + dr.target_sag)) < 1e-6


def test_the_whole_lines_dropper_passes_stop_converged_or_say_they_did_not(monkeypatch) -> None:
    """The chord passes stop because the lengths moved less than their tolerance (1e-9 m), not at
    their cap: one more pass from the solved lengths moves them less than that. Without the
    steps' correction for the dropper stiffness the passes shrink the residual ~1.4x each and do
    not converge within 50; a solve that does not converge says so in one line. (No line cache:
    every solve here runs its passes.)"""
    monkeypatch.setenv("PAC_LINE_CACHE", "")
    f = load_catenary("realistic_3km")
    data = f.line(3)
    line = Line(data, f.numerics, n_spans=len(data.spans))
    dr = line.droppers
    solved = dr.length0.copy()
    line.solve_dropper_lengths(max_iterations=1)  # raises unless the one pass moves < 1e-9 m
    np.testing.assert_allclose(dr.length0, solved, rtol=0.0, atol=1e-9)
    dr.length0, dr.stiffness = dr.height.copy(), data.dropper_ea / dr.height
    with pytest.raises(ValueError) as info:
        line.solve_dropper_lengths(max_iterations=5)
    message = str(info.value)
    assert "did not converge in 5 passes" in message and "\n" not in message


def test_the_element_flexibility_is_the_inverse_stiffness_by_solves() -> None:
    """The 4x4 blocks of K^-1 on each element's contact DOFs, read off the band of K^-1 (the
    Takahashi recurrence on the line's own Cholesky factor), equal K^-1 by banded solves of unit
    loads (the reference: scipy's cholesky_banded and cho_solve_banded, LAPACK's, with the fixed
    DOFs' loads zeroed as solve_static does) within 1e-12 of the largest entry (rounding of two
    O(n kd) recurrences; measured 1.4e-15)."""
    from scipy.linalg import cho_solve_banded, cholesky_banded

    line = Line(CatenaryData(n_spans=6), n_spans=6)
    got = line.element_flexibility()
    lapack = cholesky_banded(line.K.ab, lower=True)
    for e in range(line.n_nodes - 1):
        dofs = line.contact_dofs(e)
        unit = np.zeros((line.n_dof, 4))
        unit[dofs, np.arange(4)] = 1.0
        unit[line.fixed] = 0.0
        want = cho_solve_banded((lapack, True), unit)[dofs, :]
        np.testing.assert_allclose(got[e], want, rtol=0.0, atol=1e-12 * np.max(np.abs(want)) + 1e-300)
    assert not np.any(got[0][:, 0]) and not np.any(got[0][0, :])  # the first node's wire is fixed
