"""campaign_summary: groups by every axis but the one summarised over, the mean with its 95 %
confidence interval (against scipy's t interval), extremes, and runs that failed left out."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from scipy import stats

from pac_experiments.campaign.summary import Interval, main, summarise

pytestmark = pytest.mark.unit


def rows() -> list[dict[str, str]]:
    out = []
    for law, base in (("passive", 50.0), ("pid", 40.0)):
        for seed in range(5):
            out.append(
                {
                    "law": law,
                    "line_seed": str(seed),
                    "force_amplitude": "157.3",
                    "status": "ok",
                    "en50318_contact_force_std": str(base + seed),
                    "en50318_contact_force_mean": "157.0",
                }
            )
    out.append({**out[0], "status": "diverged", "en50318_contact_force_std": "1e9"})
    out.append({**out[0], "law": "ideal", "line_seed": "-1"})  # a group of one run: no interval
    return out


def test_the_interval_is_students_t_on_the_runs():
    values = [50.0, 51.0, 52.0, 53.0, 54.0]
    got = Interval.of(values)
    low, high = stats.t.interval(0.95, len(values) - 1, loc=np.mean(values), scale=stats.sem(values))
    assert (
        got.mean == pytest.approx(52.0) and got.low == pytest.approx(low) and got.high == pytest.approx(high)
    )
    assert (got.smallest, got.largest, got.n) == (50.0, 54.0, 5)
    one = Interval.of([3.0])
    assert one.n == 1 and one.mean == 3.0 and np.isnan(one.low)


def test_groups_are_every_other_axis_and_failed_runs_are_left_out(tmp_path):
    groups = summarise(rows(), "line_seed")
    assert [g for g, _ in groups] == [{"law": "passive"}, {"law": "pid"}, {"law": "ideal"}]
    passive = groups[0][1]["en50318_contact_force_std"]
    assert passive.n == 5 and passive.largest == 54.0  # the diverged run's 1e9 is not in it
    data = rows()
    with (tmp_path / "results.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(data[0]))
        writer.writeheader()
        writer.writerows(data)
    assert main([str(tmp_path)]) == 0
    text = (tmp_path / "summary.md").read_text()
    assert "| passive | 5 |" in text and "52 [" in text
    import json

    def refuse(token: str) -> float:
        raise AssertionError(f"not strict JSON: {token}")

    json.loads((tmp_path / "summary.json").read_text(), parse_constant=refuse)
    assert main([str(tmp_path / "none")]) == 2


def test_against_pairs_each_run_with_the_reference_run_of_its_line():
    """pid's runs are 10 N below passive's on the same seed (50+s against 40+s): the change is
    -10/(50+s) per pair, not the change of the means; a run without its passive run is counted as
    unpaired; more contact loss than its own passive run is counted."""
    from pac_experiments.campaign.summary import compare

    data = [dict(r, en50318_contact_loss_percent="0") for r in rows() if r["law"] != "ideal"]
    data[5 + 2]["en50318_contact_loss_percent"] = "0.1"  # pid on seed 2 loses contact, passive not
    data.append({**data[5], "line_seed": "9"})  # a pid run whose passive run is missing
    (pid,) = compare(data, "line_seed", "passive")
    assert pid.group == {"law": "pid"} and pid.unpaired == 1 and pid.more_loss == 1
    expected = [100.0 * ((40.0 + s) / (50.0 + s) - 1.0) for s in range(5)]
    assert pid.sigma_change.n == 5
    assert pid.sigma_change.mean == pytest.approx(np.mean(expected))
    assert pid.sigma_change.largest == pytest.approx(max(expected))


def test_against_an_axis_value_pairs_the_runs_that_differ_only_there(tmp_path):
    """``--against catenary=as_designed``: each law's run on the installed line against the same law's
    run on the designed one of the same seed (pid against pid, passive against passive, never
    across laws); an axis the results do not have is refused in one line (exit 2)."""
    from pac_experiments.campaign.summary import compare

    data = []
    for catenary, shift in (("as_designed", 0.0), ("installed", 2.0)):
        for r in rows()[:10]:
            data.append({"catenary": catenary, **r, "en50318_contact_loss_percent": "0"})
            data[-1]["en50318_contact_force_std"] = str(float(r["en50318_contact_force_std"]) + shift)
    got = {c.group["law"]: c for c in compare(data, "line_seed", "catenary=as_designed")}
    assert set(got) == {"passive", "pid"} and all(c.group["catenary"] == "installed" for c in got.values())
    for law, base in (("passive", 50.0), ("pid", 40.0)):
        expected = [100.0 * 2.0 / (base + s) for s in range(5)]
        assert got[law].pairs == 5 and got[law].unpaired == 0
        assert got[law].sigma_change.mean == pytest.approx(np.mean(expected))
    with (tmp_path / "results.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(data[0]))
        writer.writeheader()
        writer.writerows(data)
    assert main([str(tmp_path), "--against", "catenary=as_designed"]) == 0
    assert "# Against `catenary=as_designed`" in (tmp_path / "against.md").read_text()
    assert main([str(tmp_path), "--against", "track=flat"]) == 2


def test_draws_within_a_line_are_averaged_before_the_interval_over_the_lines(tmp_path):
    """With draws (``--draws roof_seed``) the interval is Student's t over the lines' means, not over
    the runs (two runs on one line are not independent draws of the line); the worst change, the
    extremes and the runs with more contact loss are over every run; a draw is never a group."""
    from pac_experiments.campaign.summary import compare

    data = []
    for seed in range(4):
        for draw in range(2):
            for law, sigma in (("passive", 50.0 + seed), ("pid", 40.0 + seed + 5.0 * draw)):
                data.append(
                    {
                        "law": law,
                        "line_seed": str(seed),
                        "roof_seed": str(draw),
                        "status": "ok",
                        "en50318_contact_force_std": str(sigma),
                        "en50318_contact_loss_percent": "0.1" if (law, seed, draw) == ("pid", 3, 1) else "0",
                    }
                )
    (pid,) = compare(data, "line_seed", "passive", ("roof_seed",))
    changes = {(s, d): 100.0 * ((40.0 + s + 5.0 * d) / (50.0 + s) - 1.0) for s in range(4) for d in range(2)}
    per_line = [np.mean([changes[(s, 0)], changes[(s, 1)]]) for s in range(4)]
    low, high = stats.t.interval(0.95, 3, loc=np.mean(per_line), scale=stats.sem(per_line))
    change = pid.sigma_change
    assert pid.group == {"law": "pid"} and pid.pairs == 8 and change.n == 4 and pid.more_loss == 1
    assert change.mean == pytest.approx(np.mean(per_line))
    assert (change.low, change.high) == (pytest.approx(low), pytest.approx(high))
    assert change.largest == pytest.approx(max(changes.values()))
    assert change.smallest == pytest.approx(min(changes.values()))
    groups = summarise(data, "line_seed", ("roof_seed",))
    assert [g for g, _ in groups] == [{"law": "passive"}, {"law": "pid"}]
    assert groups[1][1]["en50318_contact_force_std"].n == 4
    with (tmp_path / "results.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(data[0]))
        writer.writeheader()
        writer.writerows(data)
    assert main([str(tmp_path), "--against", "passive", "--draws", "roof_seed"]) == 0
    against = (tmp_path / "against.md").read_text()
    assert "| pid | 8 | 4 |" in against and "averaged per line_seed first" in against
