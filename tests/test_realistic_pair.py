"""realistic_pair's report: each pantograph of an active configuration against the same pantograph of
the passive pair on the same line (per line, not the change of the means)."""

from __future__ import annotations

import numpy as np
import pytest

from pac_experiments.realistic.pair import PAIR_EFFORT_WEIGHT, main, read_results, write_report

pytestmark = pytest.mark.unit


def test_each_pantograph_is_compared_with_the_passive_pair_on_its_own_line(tmp_path):
    rows = []
    for seed in range(4):
        base = {"line_seed": seed, "speed_kmh": 300.0, "leading_mean": 155.0, "trailing_mean": 155.0}
        rows.append(
            {
                **base,
                "config": "passive pair",
                "active": "",
                "leading_sigma": 50.0 + seed,
                "trailing_sigma": 70.0,
                "leading_loss_percent": 0.0,
                "trailing_loss_percent": 6.0,
            }
        )
        rows.append(
            {
                **base,
                "config": "active leading",
                "active": "leading",
                "leading_sigma": 30.0 + seed,
                "trailing_sigma": 77.0,
                "leading_loss_percent": 0.0,
                "trailing_loss_percent": 8.0 if seed else 6.0,
            }
        )
        rows.append(
            {
                **base,
                "config": f"active leading, mu {PAIR_EFFORT_WEIGHT:g}",
                "active": "leading",
                "leading_sigma": 40.0,
                "trailing_sigma": 70.0,
                "leading_loss_percent": 0.0,
                "trailing_loss_percent": 6.0,
            }
        )
        rows.append(
            {
                **base,
                "config": "active trailing",
                "active": "trailing",
                "leading_sigma": 50.0 + seed,
                "trailing_sigma": 63.0,
                "leading_loss_percent": 0.0,
                "trailing_loss_percent": 6.0,
            }
        )
        rows.append(
            {
                **base,
                "config": "both active",
                "active": "both",
                "leading_sigma": 35.0 + seed,
                "trailing_sigma": 70.0,
                "leading_loss_percent": 0.0,
                "trailing_loss_percent": 6.0,
            }
        )
    text = write_report(rows, tmp_path)
    expected = np.mean([100.0 * ((30.0 + s) / (50.0 + s) - 1.0) for s in range(4)])
    line = next(
        row for row in text.splitlines() if row.startswith("| 300 | active leading | leading (active)")
    )
    assert f"{expected:+.1f} [" in line
    trailing = next(row for row in text.splitlines() if row.startswith("| 300 | active leading | trailing |"))
    assert "+10.0 [" in trailing and trailing.rstrip(" |").endswith("3")  # 3 lines lose more contact
    spared = [
        row
        for row in text.splitlines()
        if row.startswith(f"| 300 | active leading, mu {PAIR_EFFORT_WEIGHT:g} |")
    ]
    assert [row.split(" | ")[2] for row in spared] == ["leading (active)", "trailing"]
    assert " | +0.0 [" in spared[1] and spared[1].rstrip(" |").endswith("0")
    active = [row.split(" | ")[2] for row in text.splitlines() if row.startswith("| 300 | active trailing |")]
    assert active == ["leading", "trailing (active)"]
    both = [row.split(" | ")[2] for row in text.splitlines() if row.startswith("| 300 | both active |")]
    assert both == ["leading (active)", "trailing (active)"]
    assert (tmp_path / "results.csv").read_text().count("\n") == 21


def _pair_rows(speed: float, passive_sigma: float, active_sigma: float) -> list[dict]:
    rows = []
    for seed in range(3):
        base = {"line_seed": seed, "speed_kmh": speed, "leading_mean": 155.0, "trailing_mean": 155.0}
        for config, active, sigma in (
            ("passive pair", "", passive_sigma),
            ("active leading", "leading", active_sigma),
        ):
            rows.append(
                {
                    **base,
                    "config": config,
                    "active": active,
                    "leading_sigma": sigma + seed,
                    "trailing_sigma": 70.0,
                    "leading_loss_percent": 0.0,
                    "trailing_loss_percent": 5.0,
                }
            )
    return rows


def test_each_speed_is_compared_with_the_passive_pair_at_that_speed_and_a_report_adds_to_its_csv(tmp_path):
    """Two speeds: each run against the passive pair on its line at its own speed (not the other
    speed's); read_results gives write_report's rows back as numbers, so a run at another speed can
    be added to an earlier report (``--add-to``); a line and speed already there is refused in one
    line, exit 2, as is a file that cannot be read."""
    first = _pair_rows(250.0, 30.0, 24.0)
    write_report(first, tmp_path / "a")
    earlier = read_results(tmp_path / "a" / "results.csv")
    assert earlier == first
    text = write_report(earlier + _pair_rows(300.0, 50.0, 35.0), tmp_path / "b")
    at = {
        row.split(" | ")[0].lstrip("| "): row
        for row in text.splitlines()
        if " | active leading | leading (active) |" in row
    }
    for speed, passive, active in (("250", 30.0, 24.0), ("300", 50.0, 35.0)):
        expected = np.mean([100.0 * ((active + s) / (passive + s) - 1.0) for s in range(3)])
        assert f"{expected:+.1f} [" in at[speed]
    assert "250, 300 km/h" in text
    assert main(["--add-to", str(tmp_path / "a" / "results.csv"), "--speeds", "250", "--seeds", "1"]) == 2
    assert main(["--add-to", str(tmp_path / "none.csv"), "--speeds", "300", "--seeds", "1"]) == 2


def test_a_configuration_run_again_replaces_its_earlier_rows_and_an_unknown_one_is_refused(tmp_path, capsys):
    """``--configs`` with ``--add-to``: the configurations run again replace their earlier rows on the
    lines and speeds run, every other row stays (the passive pair they are compared with among them);
    a name that is no configuration is refused in one line, exit 2, before any run."""
    from pac_experiments.realistic.pair import replaced

    rows = _pair_rows(250.0, 30.0, 24.0) + _pair_rows(300.0, 50.0, 35.0)
    kept = replaced(rows, {"active leading"}, {(1, 250.0)})
    assert [r for r in rows if r not in kept] == [
        r for r in rows if r["config"] == "active leading" and r["line_seed"] == 1 and r["speed_kmh"] == 250.0
    ]
    assert len(kept) == len(rows) - 1 and replaced(rows, {"active leading"}, set()) == rows
    capsys.readouterr()
    out = tmp_path / "out"
    assert main(["--configs", "active middle", "--seeds", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'active middle' is no configuration" in err[0] and "active trailing" in err[0]
    assert not out.exists()


def test_the_line_and_the_stretch_are_named_in_the_report_and_an_empty_stretch_is_refused(tmp_path, capsys):
    """``--catenary`` and ``--spans`` (the pair over tension sections): the report says which line and
    which supports its statistics cover; a stretch that ends where it starts is refused in one line,
    exit 2, before any run."""
    text = write_report(
        _pair_rows(300.0, 50.0, 35.0), tmp_path, catenary="realistic_3km_sections", spans=(10, 40)
    )
    assert "realistic_electromechanical on realistic_3km_sections with each" in text
    assert "over supports 10-40 of the leading one's start" in text
    assert "supports 10-30" in write_report(_pair_rows(300.0, 50.0, 35.0), tmp_path / "default")
    capsys.readouterr()
    assert main(["--spans", "12", "12", "--seeds", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--spans 12 12" in err[0]


def test_settings_given_reach_every_active_run_and_the_report_and_a_wrong_name_is_refused(tmp_path, capsys):
    """``-p NAME:=VALUE`` (the Makefile's way to run the pair without line_adaptive's design for a
    fast actuator): every line_adaptive configuration runs with it, the spared leader keeps its own
    effort weight on top, the passive pair gets nothing; the report's header names it; a name that
    is no parameter of the laws is refused in one line, exit 2, before any run."""
    from pac_experiments.realistic.pair import configurations

    settings = {"line_support_before": 0, "line_effort_weight": 0.2}
    configs = configurations((1.5,), settings)
    assert configs["passive pair"][2] == {}
    assert configs["active leading"][2] == configs["active trailing"][2] == settings
    assert configs["both active"][2] == settings
    assert configs["active leading, mu 1.5"][2] == {"line_support_before": 0, "line_effort_weight": 1.5}
    text = write_report(_pair_rows(300.0, 50.0, 35.0), tmp_path, settings={"line_support_before": 0})
    assert "line_adaptive with line_support_before:=0." in text
    assert "line_adaptive with" not in write_report(_pair_rows(300.0, 50.0, 35.0), tmp_path / "none")
    capsys.readouterr()
    assert main(["-p", "line_zone:=0", "--seeds", "1", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "-p line_zone" in err[0] and "not a parameter of the laws" in err[0]
    assert not (tmp_path / "out").exists()
