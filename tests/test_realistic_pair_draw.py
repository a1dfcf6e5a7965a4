"""realistic_pair_draw: the passive pair's second draw against its first, and each configuration's
extra loss read against the draw's largest rise; the refusals before any run."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import pytest
from conftest import ROOT

from pac_experiments.realistic import DRAW_SEEDS, draw
from pac_experiments.realistic.pair_draw import against_passive, main, spread

unit = pytest.mark.unit
offline = pytest.mark.offline


def _row(
    seed: int, config: str, loss: tuple[float, float], sigma: tuple[float, float] = (30.0, 40.0)
) -> dict[str, Any]:
    return {
        "line_seed": seed,
        "config": config,
        "active": "",
        "speed_kmh": 300.0,
        "leading_sigma": sigma[0],
        "leading_mean": 155.0,
        "leading_loss_percent": loss[0],
        "trailing_sigma": sigma[1],
        "trailing_mean": 155.0,
        "trailing_loss_percent": loss[1],
    }


FIRST = [
    _row(1, "passive pair", (0.0, 1.0)),
    _row(2, "passive pair", (0.5, 2.0)),
    _row(3, "passive pair", (0.0, 3.0)),
    # the leader active: its follower loses 0.1, 0.5 and 0.05 points more
    _row(1, "active leading", (0.0, 1.1)),
    _row(2, "active leading", (0.2, 2.5)),
    _row(3, "active leading", (0.0, 3.05)),
]
SECOND = [
    _row(1, "passive pair", (0.0, 1.2), (33.0, 40.0)),  # trailing +0.2 points, leading sigma +10 %
    _row(2, "passive pair", (0.5, 1.9), (30.0, 38.0)),  # trailing -0.1, trailing sigma -5 %
    _row(3, "passive pair", (0.0, 3.0)),
    # the follower now loses 0.3 more, 0.1 less, and 0.3 more
    _row(1, "active leading", (0.0, 1.5), (30.0, 44.0)),
    _row(2, "active leading", (0.5, 1.8), (30.0, 38.0)),
    _row(3, "active leading", (0.0, 3.3), (30.0, 40.0)),
]


@offline
def test_a_draw_sets_parameters_a_run_knows():
    from pac_common.parameters import ParameterError
    from pac_rig.simulate import scenario_from_flat

    assert set(draw(3).values()) == {3} and len(draw(3)) == len(DRAW_SEEDS) == 3
    for name, value in draw(3).items():  # a misspelt name is refused by the run
        scenario_from_flat({"scenario": "realistic_electromechanical", name: value, "duration": 0.01})
    with pytest.raises(ParameterError):
        scenario_from_flat({"scenario": "realistic_electromechanical", "roof_sed": 3, "duration": 0.01})


@unit
def test_the_spread_counts_lines_that_lose_more_on_the_second_draw():
    s = spread(FIRST, SECOND)
    lead, trail = s[300.0, "leading"], s[300.0, "trailing"]
    assert (lead.lines, lead.more_loss, lead.largest_rise) == (3, 0, 0.0)
    assert lead.sigma_change == pytest.approx((0.0, 10.0))
    assert (trail.more_loss, trail.loss_change) == (1, pytest.approx((-0.1, 0.2)))
    assert trail.largest_rise == pytest.approx(0.2)
    assert trail.sigma_change == pytest.approx((-5.0, 0.0))


@unit
def test_extra_loss_counts_beyond_the_draw_only_above_its_largest_rise():
    by = against_passive(FIRST, SECOND, spread(FIRST, SECOND))
    assert {config for _, config, _ in by} == {"active leading"}
    follower = by[300.0, "active leading", "trailing"]
    # draw 0: 0.1, 0.5, 0.05 more; only 0.5 exceeds the draw's 0.2. Draw 1: 0.3, -0.1, 0.3.
    assert (follower.lines, follower.more_loss, follower.beyond) == (3, (3, 2), (1, 2))
    # both draws: 0.4, 0.4, 0.35 more on the sum
    assert follower.more_loss_both == 3
    # sigma: draw 0 unchanged; draw 1 +10 %, 0 % (38 against 38) and 0 %
    assert follower.sigma_change == pytest.approx((0.0, 10.0 / 3))
    # leader: line 2 loses less on draw 0, as much on draw 1; the draw's leading rise is 0
    leader = by[300.0, "active leading", "leading"]
    assert (leader.more_loss, leader.beyond, leader.more_loss_both) == ((0, 0), (0, 0), 0)


def _write(rows: list[dict[str, Any]], path: Path) -> Path:
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


@offline
def test_the_report_is_rebuilt_from_results_without_runs(tmp_path, capsys):
    against = _write(FIRST, tmp_path / "pair.csv")
    results = _write([{**r, "draw": 1} for r in SECOND], tmp_path / "draw.csv")
    out = tmp_path / "report"
    assert main(["--against", str(against), "--results", str(results), "--out", str(out)]) == 0
    text = (out / "draw.md").read_text()
    assert "| 300 | trailing | 1 of 3 | -0.10 … +0.20 |" in text
    assert "| 300 | active leading | trailing | 3 | +0.0 / +3.3 | 3 / 2 | 1 / 2 | 3 |" in text
    # the results it was rebuilt from, written back as they were read (the draw an integer)
    assert (out / "results.csv").read_bytes() == results.read_bytes()


@offline
def test_refusals_exit_2_with_one_line_before_any_run(tmp_path, capsys):
    against = _write(FIRST, tmp_path / "pair.csv")
    results = _write([{**r, "draw": 1} for r in SECOND], tmp_path / "draw.csv")
    cases = [
        (["--draw", "0"], "--draw 0"),
        (["--against", str(tmp_path / "missing.csv")], "cannot read"),
        (["--against", str(against), "--seeds", "7"], "no passive pair on line 7"),
        (["--against", str(against), "--results", str(results), "--draw", "2"], "not 2"),
        (["--configs", "active middle"], "'active middle' is no configuration"),
    ]
    for argv, words in cases:
        assert main([*argv, "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
    assert not (tmp_path / "out").exists()


@offline
@pytest.mark.slow
def test_one_line_of_the_passive_pair_on_draw_1_is_the_same_line_run_again(tmp_path):
    """The tool's own run: line 100 at 300 km/h, the passive pair on draw 1, against the pair
    report's draw 0 of it. The draw reached the run (sigma moved) and the rest of the run is the
    pair report's (it moved by the few percent a draw moves it: +-2 % over the report lines)."""
    from pac_experiments.realistic.pair import read_results
    from pac_experiments.realistic.pair_draw import AGAINST

    out, against = tmp_path / "report", ROOT / AGAINST
    argv = ["--against", str(against), "--seeds", "100", "--speeds", "300", "--configs", "passive pair"]
    assert main([*argv, "--out", str(out)]) == 0
    (row,) = read_results(out / "results.csv")
    (first,) = [
        r
        for r in read_results(against)
        if r["config"] == "passive pair" and r["line_seed"] == 100 and r["speed_kmh"] == 300.0
    ]
    assert row["draw"] == 1 and row["config"] == "passive pair"
    for name in ("leading", "trailing"):
        change = row[f"{name}_sigma"] / first[f"{name}_sigma"] - 1.0
        assert 0.0 < abs(change) < 0.05, (name, change)
    assert "| 300 | leading | " in (out / "draw.md").read_text()
