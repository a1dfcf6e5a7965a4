"""realistic_pair_bound: the quadratic model of each pantograph's sigma, the choice of the weights, the
basis, and the open-loop feedforward law it runs (zero: the passive pair to the bit)."""

from __future__ import annotations

import numpy as np
import pytest

from pac_common.parameters import ParameterError
from pac_experiments.realistic import feedforward_law
from pac_experiments.realistic.pair_bound import (
    LAW_FILE,
    band_edges,
    basis,
    best_weights,
    sigma_quadratics,
)

unit = pytest.mark.unit


@unit
def test_the_quadratic_is_the_sigma_of_the_superposed_force():
    rng = np.random.default_rng(3)
    passive = 150.0 + 40.0 * rng.standard_normal(500)
    responses = rng.standard_normal((500, 4)) * [5.0, 10.0, 20.0, 1.0]
    q = sigma_quadratics(passive, responses)
    for _ in range(5):
        x = rng.standard_normal(4)
        assert q.sigma(x) == pytest.approx(np.std(passive + responses @ x), rel=1e-12)


@unit
def test_a_follower_untouched_by_the_basis_leaves_the_leader_its_least_squares_best():
    rng = np.random.default_rng(4)
    responses = rng.standard_normal((400, 3))
    leading = 2.0 * responses @ np.array([1.0, -0.5, 0.25]) + rng.standard_normal(400)
    trailing = 60.0 * rng.standard_normal(400)
    lead_q = sigma_quadratics(leading, responses)
    trail_q = sigma_quadratics(trailing, np.zeros((400, 3)))
    lam, x = best_weights(lead_q, trail_q, margin=1.0)
    assert lam == 0.0
    design = np.column_stack([responses, np.ones(400)])
    fit, *_ = np.linalg.lstsq(design, -leading, rcond=None)  # the residual's sigma, independently
    assert lead_q.sigma(x) == pytest.approx(np.std(leading + design @ fit), rel=1e-6)
    assert x == pytest.approx(fit[:3], rel=1e-6)


@unit
def test_a_leader_whose_every_gain_costs_its_follower_gets_none_from_the_bound():
    """One direction g: the leader's force is -g (plus its own), the follower's +0.5 g: whatever
    lowers the leader raises the follower; held to the follower's margin, the leader gains nothing."""
    rng = np.random.default_rng(5)
    g = 10.0 * np.sin(np.linspace(0.0, 60.0, 600))
    leading = -g + rng.standard_normal(600)
    trailing = 0.5 * g + rng.standard_normal(600)
    responses = g[:, None]
    lead_q, trail_q = sigma_quadratics(leading, responses), sigma_quadratics(trailing, responses)
    lam, x = best_weights(lead_q, trail_q, margin=0.99)
    assert lam > 0.0 and x[0] < 0.0
    assert trail_q.sigma(x) <= 0.99 * np.std(trailing)
    assert lead_q.sigma(x) > np.std(leading)
    assert best_weights(lead_q, trail_q, margin=0.01) is None  # no weight brings it that low


@unit
def test_bands_hold_each_learned_harmonic_and_the_first_at_least():
    f1 = 83.333 / 54.94  # 300 km/h over the realistic line's mean span
    edges = band_edges(f1, 4.0)
    assert len(edges) == 3  # harmonics 1 and 2 (3 f1 = 4.55 Hz is above the law's band)
    for h in (1, 2):
        assert edges[h - 1] < h * f1 < edges[h]
    assert len(band_edges(f1, 1.0)) == 2  # below f1: the first harmonic still


@unit
def test_each_basis_part_has_its_twin_a_quarter_period_behind_and_the_stretches_sum_to_it():
    dt, f = 0.001, 1.5
    t = np.arange(0.0, 20.0, dt)
    pattern = 10.0 * np.sin(2 * np.pi * f * t)
    parts = basis(pattern, dt, [0.6, 2.3], segments=3)
    assert len(parts) == 6
    inner = slice(4000, 16000)  # away from the filter's ends
    band, twin = parts[0] + parts[2] + parts[4], parts[1] + parts[3] + parts[5]
    # within 2 % of the amplitude: the band filter's gain at f and the Hilbert transform of a
    # finite record (it leaks from the ends) are not exact
    assert np.max(np.abs(band - pattern)[inner]) < 0.2
    assert np.max(np.abs(twin + 10.0 * np.cos(2 * np.pi * f * t))[inner]) < 0.2
    assert np.max(np.abs(twin - 10.0 * np.cos(2 * np.pi * f * t))[inner]) > 19.0  # not ahead


@unit
def test_the_law_refuses_a_run_without_its_pattern(monkeypatch, tmp_path):
    monkeypatch.delenv(feedforward_law.TABLE_VARIABLE, raising=False)
    with pytest.raises(ParameterError, match=feedforward_law.TABLE_VARIABLE):
        feedforward_law.design(None)
    monkeypatch.setenv(feedforward_law.TABLE_VARIABLE, str(tmp_path / "missing.npy"))
    with pytest.raises(ParameterError, match="readable"):
        feedforward_law.design(None)
    bad = tmp_path / "bad.npy"
    np.save(bad, np.array([1.0, np.nan]))
    monkeypatch.setenv(feedforward_law.TABLE_VARIABLE, str(bad))
    with pytest.raises(ParameterError, match="finite"):
        feedforward_law.design(None)


@pytest.mark.offline
@pytest.mark.slow
def test_the_feedforward_law_presses_its_pattern_and_at_zero_is_the_passive_pair(monkeypatch, tmp_path):
    from pac_experiments.realistic.pair import simulate

    spans = (0, 1)
    passive, first, last, dt = simulate(0, ("passive", 0, {}), 300.0, spans=spans)
    n = len(passive)
    table = tmp_path / "pattern.npy"
    np.save(table, np.zeros(n))
    monkeypatch.setenv(feedforward_law.TABLE_VARIABLE, str(table))
    zero, *_ = simulate(0, (str(LAW_FILE), 0, {}), 300.0, spans=spans)
    forces = slice(0, 2)  # the record holds room for four pantographs (NaN past the two)
    assert np.array_equal(
        zero["pantograph_contact_force"][:, forces], passive["pantograph_contact_force"][:, forces]
    )
    pattern = 5.0 * np.sin(2 * np.pi * 1.5 * dt * np.arange(n))
    np.save(table, pattern)
    pressed, *_ = simulate(0, (str(LAW_FILE), 0, {}), 300.0, spans=spans)
    ticks = np.rint(pressed["time"] / dt).astype(int)
    # the law's demand (the start's ramp of F_r holds the command at u_min, after the limits)
    assert np.allclose(pressed["u_unsaturated"] - pressed["force_reference"], pattern[ticks], atol=1e-9)
    assert not np.array_equal(
        pressed["pantograph_contact_force"][:, 1], passive["pantograph_contact_force"][:, 1]
    )


@unit
def test_the_report_pairs_each_run_with_its_own_passive_pair_and_counts_the_followers_extra_loss(tmp_path):
    from pac_experiments.realistic.pair_bound import write_report

    rows = []
    for seed in range(4):
        rows.append(
            {
                "line_seed": seed,
                "speed_kmh": 300.0,
                "segments": 1,
                "basis": 4,
                "passive_leading_sigma": 50.0 + seed,
                "passive_leading_loss_percent": 0.0,
                "adaptive_leading_sigma": 30.0 + seed,
                "adaptive_leading_loss_percent": 0.0,
                "passive_trailing_sigma": 70.0,
                "passive_trailing_loss_percent": 6.0,
                "adaptive_trailing_sigma": 77.0,
                "adaptive_trailing_loss_percent": 8.0,
                "lambda": 2.0,
                "predicted_leading_sigma": 45.0,
                "predicted_trailing_sigma": 69.0,
                "bound_leading_sigma": 46.0,
                "bound_leading_loss_percent": 0.0,
                "bound_trailing_sigma": 70.0,
                "bound_trailing_loss_percent": 6.5 if seed < 3 else 5.0,
            }
        )
    text = write_report(rows, tmp_path)
    line = next(row for row in text.splitlines() if row.startswith("| 300 | 4 of 4 |"))
    cells = line.strip("| ").split(" | ")
    expected = np.mean([100.0 * ((30.0 + s) / (50.0 + s) - 1.0) for s in range(4)])
    assert cells[3].startswith(f"{expected:+.1f} [")
    assert cells[4].startswith("+10.0 [") and cells[5] == "8.00 %, 4 of 4"
    assert cells[9].startswith("+0.0 [") and cells[10] == "6.12 %, 3 of 4"
    assert (tmp_path / "results.csv").read_text().count("\n") == 5
