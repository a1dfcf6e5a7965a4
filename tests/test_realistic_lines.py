"""The realistic scenario's line seeds: design, report and held-out lines kept apart, so a
reported number never comes from a line the law was chosen on (docs/realistic_scenario.md)."""

from __future__ import annotations

import pytest
from conftest import ROOT

from pac_experiments.campaign.spec import load_spec
from pac_experiments.realistic import DESIGN_LINES, HELD_OUT_FROM, REPORT_LINES, pair, pair_bound, passes

pytestmark = pytest.mark.unit

CAMPAIGNS = ROOT / "config" / "campaigns"


def lines_of(name: str) -> set[int]:
    """Every line seed a campaign file's grids name."""
    spec = load_spec(str(CAMPAIGNS / f"{name}.yaml"))
    return {int(seed) for grid in spec.grids for seed in grid.get("line_seed", [])}


def test_the_three_sets_are_apart() -> None:
    assert not set(DESIGN_LINES) & set(REPORT_LINES)
    assert max(DESIGN_LINES) < HELD_OUT_FROM and max(REPORT_LINES) < HELD_OUT_FROM


def test_held_out_lines_are_neither_design_nor_report_lines() -> None:
    held_out = lines_of("realistic_held_out")
    assert len(held_out) >= 20
    assert min(held_out) >= HELD_OUT_FROM


def test_design_campaign_runs_on_design_lines() -> None:
    design = lines_of("realistic_design")
    assert design and design <= set(DESIGN_LINES)


#: Every realistic campaign file but the design and held-out ones reports: on the report lines.
REPORT_CAMPAIGNS = sorted(
    p.stem
    for p in CAMPAIGNS.glob("realistic_*.yaml")
    if p.stem not in ("realistic_design", "realistic_held_out")
)


def test_report_campaigns_are_found() -> None:
    assert "realistic_laws" in REPORT_CAMPAIGNS and len(REPORT_CAMPAIGNS) >= 9


@pytest.mark.parametrize("name", REPORT_CAMPAIGNS)
def test_report_campaigns_run_on_the_report_lines(name: str) -> None:
    assert lines_of(name) == set(REPORT_LINES)


def test_experiments_default_to_the_report_lines() -> None:
    for module in (pair, pair_bound, passes):
        assert tuple(module.SEEDS) == REPORT_LINES, module.__name__
