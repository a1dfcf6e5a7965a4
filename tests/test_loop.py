"""The compiled loop's other fronts: simulate's bag from whole blocks, the bench's one results file."""

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from pac_experiments.bench import report as bench_report
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.offline

ROOT = Path(__file__).resolve().parents[1]


def messages_of(bag: Path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, CDR bytes) of every message, read with the independent mcap reader."""
    (path,) = bag.glob("*.mcap")
    with path.open("rb") as f:
        return [
            (c.topic, m.log_time, bytes(m.data))
            for _, c, m in make_reader(f).iter_messages(log_time_order=True)
        ]


@pytest.mark.parametrize(
    "values",
    [
        {"duration": 0.5, "noise_std": (1e-5, 1e-5), "command_delay_ticks": 2, "law": "pid"},
        {"duration": 5.0, "shape": "square", "period": 1.0},  # more than one block of ticks
        {"duration": 1.0, "c1": 400.0, "c2": 400.0, "u_min": -1e7, "u_max": 1e7, "slew_rate_max": 1e12},
        {
            "duration": 1.0,
            "actuator": "electromechanical",
            "command_delay_ticks": 2,
            "shape": "square",
            "period": 0.4,
        },
        {"duration": 1.0, "sensors": "train_load_cell", "roof_motion": "german_high", "law": "pid"},
        {
            "duration": 0.3,
            "catenary_model": "fe",
            "pantograph": "three_mass",
            "roof_motion": "german_low",
            "sensors": "train",
            "law": "line_adaptive",
            "observer": "contact_force",
        },
    ],
    ids=["noisy-pid", "blocks", "diverges", "actuator", "train-load-cell", "fe-train"],
)
@pytest.mark.slow
def test_compiled_bag_equals_the_per_record_bag(tmp_path, values):
    """Every message of every topic, byte for byte: columns from TICK blocks == one dict per message."""
    s = scenario_from_flat(values)
    fast = simulate_to_bag(s, tmp_path / "fast")
    slow = simulate_to_bag(s, tmp_path / "slow", compiled=False)
    assert (fast.ticks, fast.diverged) == (slow.ticks, slow.diverged)
    got, want = messages_of(tmp_path / "fast"), messages_of(tmp_path / "slow")
    assert len(got) == len(want) == 4 * fast.ticks + 2
    assert got == want


def test_the_performance_block_is_the_bench_file():
    """docs/results.md's generated block says exactly what reports/bench/latest.json says."""
    results = json.loads((ROOT / "reports/bench/latest.json").read_text())
    assert bench_report.readme_section(results) in (ROOT / bench_report.RESULTS_PAGE).read_text()
    for goal in bench_report.GOALS:
        assert goal.key in results["figures"], goal.key


def test_goal_marks():
    g = bench_report.GOALS[0]
    assert g.met(g.goal) is True and g.met(g.goal * 0.99) is False and g.met(None) is None
    assert g.met(float("nan")) is None
    low = next(goal for goal in bench_report.GOALS if not goal.at_least)
    assert low.met(low.goal) is True and low.met(low.goal + 1.0) is False


def test_blocks_computed_ahead_come_in_order_and_the_error_after_them():
    """computed_ahead gives every block in order, each computed in its worker thread (the next one
    while the caller holds this one), then raises the loop's error where the loop raised it."""
    import threading

    import numpy as np

    from pac_rig.closed_loop import DivergenceError, computed_ahead

    made_in: list[str] = []
    second_made = threading.Event()

    def blocks():
        for k in range(3):
            made_in.append(threading.current_thread().name)
            if k == 1:
                second_made.set()
            yield np.full(2, k)
        raise DivergenceError(6, "test: the run diverged")

    got = []
    with pytest.raises(DivergenceError, match="test: the run diverged"):
        for block in computed_ahead(blocks()):
            if not got:  # holding the first block, the second is made meanwhile, not on asking
                assert second_made.wait(timeout=10.0)
            got.append(int(block[0]))
    assert got == [0, 1, 2]
    assert len(made_in) == 3 and all(name.startswith("pac-loop") for name in made_in)
