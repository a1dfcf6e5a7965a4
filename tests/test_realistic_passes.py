"""realistic_passes' report: each run of pass B against pass B's passive run on the same line, and a
map run against the first pass B on the same line (per line, not the change of the means)."""

from __future__ import annotations

import numpy as np
import pytest

from pac_experiments.realistic.passes import RUNS, main, read_results, write_report

pytestmark = pytest.mark.unit

SIGMA = {
    "passive B": 50.0,
    "first pass B": 35.0,
    "map, position 1 m off": 40.0,
    "map, position as pass A": 30.0,
}


def test_each_run_is_compared_with_its_own_lines_passive_and_first_pass(tmp_path):
    rows = []
    for seed in range(4):
        for name, *_ in RUNS:
            sigma = SIGMA.get(name, 33.0) + (seed if name == "passive B" else 0.0)
            lost = name == "map, position 1 m off" and seed > 0
            rows.append(
                {
                    "scenario": "realistic_electromechanical", "speed_kmh": 300.0, "line_seed": seed,
                    "run": name, "sigma": sigma, "mean": 155.0, "loss_percent": 0.1 if lost else 0.0,
                    "u_max_abs": 100.0, "trip": "harm" if name.startswith("map") and seed == 3 else "",
                    "map_scale": "",
                }
            )  # fmt: skip
    text = write_report(rows, tmp_path)
    lines = {row.split(" | ")[2]: row for row in text.splitlines() if row.startswith("| realistic")}
    against_passive = np.mean([100.0 * (30.0 / (50.0 + s) - 1.0) for s in range(4)])
    aligned = lines["map, position as pass A"]
    assert f"| {against_passive:+.1f} [" in aligned
    assert aligned.rstrip(" |").endswith(f"{100.0 * (30.0 / 35.0 - 1.0):+.1f} [-14.3, -14.3]")
    off = lines["map, position 1 m off"].split(" | ")
    assert off[7:9] == ["3", "1"]  # 3 lines lose more contact than passive B; the guard fell back on 1
    assert "first pass A" not in lines  # pass A's own result is the realistic experiment's row
    assert (tmp_path / "results.csv").read_text().count("\n") == 1 + 4 * len(RUNS)


def _rows(seeds: range) -> list[dict]:
    return [
        {
            "scenario": "realistic_electromechanical",
            "speed_kmh": 300.0,
            "line_seed": seed,
            "run": name,
            "sigma": SIGMA.get(name, 33.0),
            "mean": 155.0,
            "loss_percent": 0.0,
            "u_max_abs": 100.0,
            "trip": "",
            "map_scale": 1.0 if name.startswith("map") else "",
        }  # fmt: skip
        for seed in seeds
        for name, *_ in RUNS
    ]


def test_a_report_read_back_is_the_same_report(tmp_path):
    """read_results gives write_report's rows back with their numbers as numbers: the report written
    from them again is the same, to the byte (what --add-to builds on)."""
    text = write_report(_rows(range(3)), tmp_path / "a")
    rows = read_results(tmp_path / "a" / "results.csv")
    assert isinstance(rows[0]["sigma"], float) and isinstance(rows[0]["line_seed"], int)
    assert write_report(rows, tmp_path / "b") == text
    assert (tmp_path / "b" / "results.csv").read_text() == (tmp_path / "a" / "results.csv").read_text()


def test_adding_a_line_the_results_already_hold_is_refused_in_one_line(tmp_path, capsys):
    write_report(_rows(range(2)), tmp_path)
    argv = ["--out", str(tmp_path / "out"), "--scenarios", "realistic_electromechanical", "--speeds", "300"]
    code = main([*argv, "--seeds", "1", "2", "--add-to", str(tmp_path / "results.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    csv_path = tmp_path / "results.csv"
    assert code == 2
    assert err == [f"realistic_passes: {csv_path} has realistic_electromechanical line 1 at 300 km/h already"]
    assert not (tmp_path / "out").exists()  # refused before any run


def test_settings_given_are_named_in_the_report_and_a_wrong_name_is_refused_in_one_line(tmp_path, capsys):
    """``-p NAME:=VALUE``: the report says line_adaptive ran with it (and no longer that pass A is
    the realistic experiment's row); a name that is no parameter of the laws is refused in one line,
    exit 2, before any run."""
    text = write_report(_rows(range(2)), tmp_path / "a", settings={"line_guard_loss_spans": 0})
    assert "`line_adaptive` with line_guard_loss_spans:=0 (every run of it)" in text
    assert "realistic experiment's row" not in text
    assert "realistic experiment's row" in write_report(_rows(range(2)), tmp_path / "b")
    code = main(["-p", "nope:=1", "--seeds", "1", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("realistic_passes: -p nope:")
    assert not (tmp_path / "out").exists()
