"""realistic_laws_figures --also: the runs of two campaigns on the same lines joined by their key."""

from __future__ import annotations

import pytest

from pac_experiments.realistic.laws_figures import merge_runs

pytestmark = pytest.mark.unit


def _row(key: str, law: str, sigma: str) -> dict[str, str]:
    return {"law": law, "line_seed": "1", "status": "ok", "en50318_contact_force_std": sigma, "key": key}


def test_a_run_in_both_campaigns_counts_once_and_one_with_other_numbers_is_refused():
    laws = [_row("p1", "passive", "50.0"), _row("a1", "line_adaptive", "35.0")]
    baselines = [_row("p1", "passive", "50.0"), _row("q1", "pid", "54.0")]
    merged = merge_runs(laws, baselines)
    assert [r["key"] for r in merged] == ["p1", "a1", "q1"]
    with pytest.raises(ValueError, match="p1 is there with other numbers"):
        merge_runs(laws, [_row("p1", "passive", "50.1")])
    with pytest.raises(ValueError, match="without a key"):
        merge_runs(laws, [{"law": "pid"}])
