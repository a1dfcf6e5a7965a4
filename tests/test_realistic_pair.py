"""realistic_pair's report: each pantograph of an active configuration against the same pantograph of
the passive pair on the same line (per line, not the change of the means)."""

from __future__ import annotations

import numpy as np
import pytest

from pac_experiments.realistic.pair import PAIR_EFFORT_WEIGHT, write_report

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
    text = write_report(rows, tmp_path)
    expected = np.mean([100.0 * ((30.0 + s) / (50.0 + s) - 1.0) for s in range(4)])
    line = next(row for row in text.splitlines() if row.startswith("| active leading | leading (active)"))
    assert f"{expected:+.1f} [" in line
    trailing = next(row for row in text.splitlines() if row.startswith("| active leading | trailing |"))
    assert "+10.0 [" in trailing and trailing.rstrip(" |").endswith("3")  # 3 lines lose more contact
    spared = [
        row for row in text.splitlines() if row.startswith(f"| active leading, mu {PAIR_EFFORT_WEIGHT:g} |")
    ]
    assert [row.split(" | ")[1] for row in spared] == ["leading (active)", "trailing"]
    assert " | +0.0 [" in spared[1] and spared[1].rstrip(" |").endswith("0")
    active = [row.split(" | ")[1] for row in text.splitlines() if row.startswith("| active trailing |")]
    assert active == ["leading", "trailing (active)"]
    assert (tmp_path / "results.csv").read_text().count("\n") == 17
