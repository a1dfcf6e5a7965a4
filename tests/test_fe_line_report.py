"""make catenary's write-up of the reference runs on every catenary preset (synthetic rows, no FE runs)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pac_experiments.catenary.line_report import lines_reference_section, reference_figure_name
from pac_experiments.catenary.line_runs import EN50318_BANDS, reference_lines
from pac_plant.catenary.catenary_file import DEFAULT, presets


def _row(name: str, speed: int, mean: float, stitched: bool, spans: list[float]) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(EN50318_BANDS, 1.0)
    row.update(
        catenary=name,
        speed_kmh=speed,
        span_lengths_m=spans,
        stitched=stitched,
        contact_tension_N=27000.0,
        messenger_tension_N=21000.0,
        contact_force_mean=mean,
        max_slack_droppers=3 if speed == 300 else 0,
    )
    return row


@pytest.mark.unit
def test_every_line_gets_its_band_table_with_distances():
    a_spans, b_spans = [55.0], [60.0, 65.0]
    refs = {
        "line_a": {
            250: _row("line_a", 250, 130.8, False, a_spans),
            300: _row("line_a", 300, 115.0, False, a_spans),
        },
        "line_b": {
            250: _row("line_b", 250, 100.0, True, b_spans),
            300: _row("line_b", 300, 121.5, True, b_spans),
        },
    }
    text = lines_reference_section(refs)
    assert "### line_a" in text and "### line_b" in text
    assert text.index("### line_a") < text.index("### line_b")
    a, b = text.split("### line_b")
    # The mean's row: ours, the 110-120 band and the distance to its nearest edge, per speed.
    assert "| contact_force_mean | 130.8 | 110–120 | +10.8 | 115.0 | 110–120 | +0.0 |" in a
    assert "| contact_force_mean | 100.0 | 110–120 | -10.0 | 121.5 | 110–120 | +1.5 |" in b
    assert "no stitch wire" in a and "stitch wire at the supports" in b
    assert "Spans 55 m" in a and "Spans 60/65 m" in b
    assert "250 km/h 0, 300 km/h 3" in b
    assert "(reference_runs_line_a.png)" in a and "(reference_runs_line_b.png)" in b
    assert "not its own" in text and "EN 50318:2002 reference model" in text


@pytest.mark.offline
def test_reference_runs_cover_every_preset_default_first():
    lines = reference_lines()
    assert lines[0] == DEFAULT
    assert reference_figure_name(DEFAULT) == "reference_runs.png"  # the default line's figure keeps its name
    assert sorted(lines) == sorted(presets()) and len(lines) == len(set(lines)) >= 3


@pytest.mark.unit
def test_docs_per_preset_table_is_the_committed_report():
    """docs/catenary.md's per-preset reference-run table is reports/catenary/metrics.json (written by
    `make catenary`) to the digits printed, one row per line and speed."""
    import json
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    runs = json.loads((root / "reports" / "catenary" / "metrics.json").read_text())["reference_runs_by_line"]
    section = (root / "docs" / "catenary.md").read_text().split("### Reference runs on every preset", 1)[1]
    rows = [r for r in section.split("\n\n", 3)[2].splitlines() if r.startswith("| ") and "km/h" not in r]
    keys = (
        "contact_force_mean",
        "contact_force_std",
        "statistical_max",
        "statistical_min",
        "contact_force_max",
        "contact_force_min",
        "support_uplift_mm",
        "contact_loss_percent",
    )
    seen = set()
    for row in rows:
        line, speed, *cells = (c.strip() for c in row.strip("|").split("|"))
        run = runs[line][speed]
        assert cells == [f"{run[k]:.1f}" for k in keys], (line, speed)
        seen.add((line, speed))
    assert seen == {(line, speed) for line, by_speed in runs.items() for speed in by_speed}


@pytest.mark.unit
def test_reference_figure_of_a_line_with_its_own_supports(tmp_path):
    """A line's figure is drawn over its own window (its supports, not the default line's 55 m)."""
    import matplotlib.image

    from pac_experiments.catenary.line_report import reference_figure

    x = np.linspace(0.0, 400.0, 4001)
    run = {
        "catenary": "line_b",
        "_x": x,
        "_f": 120.0 + 20.0 * np.sin(2 * np.pi * x / 65.0),
        "_uplift": 0.05 + 0.01 * np.cos(2 * np.pi * x / 65.0),
        "_window_supports": (260.0, 325.0, 390.0),
    }
    path = tmp_path / "reference_runs_line_b.png"
    reference_figure(path, {250: run, 300: run})
    image = matplotlib.image.imread(path)
    assert image.shape[0] > 500 and image.shape[1] > 1000 and image.std() > 0.01
