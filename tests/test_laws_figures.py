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
    with pytest.raises(ValueError, match="p1 is there with other numbers"):
        merge_runs(laws, [_row("p1", "passive", "50.0001")])  # 2e-6 of it: more than rounding
    with pytest.raises(ValueError, match="p1 is there with other numbers"):
        merge_runs(laws, [{**_row("p1", "passive", "50.0"), "status": "failed"}])
    # The same run computed again: equal to rounding (2.5e-7 N; 7.6e-7 N near zero), one run.
    again = merge_runs(laws, [_row("p1", "passive", "50.00000025")])
    assert [r["en50318_contact_force_std"] for r in again] == ["50.0", "35.0"]
    near_zero = [{**_row("p2", "passive", "50.0"), "contact_force_min": "0.0416622"}]
    assert len(merge_runs(near_zero, [{**near_zero[0], "contact_force_min": "0.0416615"}])) == 1
    with pytest.raises(ValueError, match="p2 is there with other numbers"):
        merge_runs(near_zero, [{**near_zero[0], "contact_force_min": "0.0417"}])
    with pytest.raises(ValueError, match="without a key"):
        merge_runs(laws, [{"law": "pid"}])
