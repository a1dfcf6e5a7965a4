"""A user's own observer from a Python file (``observer:=path/to/my_observer.py``): the example,
examples/my_observer.py, run from its file in simulate, a campaign and observer_node, each checked
against the observer's formula recomputed here on the recorded inputs; a law on it composed as on a
registered observer; the one-line refusals (pac_observer.user_observer)."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
import yaml
from conftest import (
    ROOT,
    assert_imported_once_and_an_edit_refused,
    assert_simulate_refuses_the_file,
    first_per_tick,
    lockstep_run_equals_offline,
)

from pac_bag.reader import read_bag
from pac_experiments.campaign import run as campaign_run
from pac_experiments.campaign import spec as campaign_spec
from pac_observer import user_observer
from pac_observer.user_observer import load_observer_file
from pac_rig import composition, simulate
from pac_rig.batch import batchable
from pac_rig.composition import CompositionError
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.offline

EXAMPLE = ROOT / "examples" / "my_observer.py"
#: The example's time constant [s] (its parameter; the formula is written again in ``expected``).
TAU = 0.5


def expected(ticks: np.ndarray, actuator_force: np.ndarray, dt: float) -> np.ndarray:
    """The example's F_hat on recorded inputs: a first-order low-pass of the actuator's force, started
    at its first sample, over the time between samples."""
    out = np.empty(actuator_force.size)
    out[0] = actuator_force[0]
    for k in range(1, out.size):
        gap = (ticks[k] - ticks[k - 1]) * dt
        out[k] = out[k - 1] + (1.0 - math.exp(-gap / TAU)) * (actuator_force[k] - out[k - 1])
    return out


def assert_bag_ran_the_observer(bag_path, values: dict) -> None:
    """Every estimate is the example's F_hat of the recorded actuator forces. Tolerance: the run and
    this loop do the same two double operations a tick in the same order; 1e-9 N is far below any
    physical effect and far above a rounding step."""
    topics = read_bag(bag_path).topics
    measurement, estimate = topics["measurement"], topics["estimate"]
    (tm, im), (te, ie) = first_per_tick(measurement), first_per_tick(estimate)
    np.testing.assert_array_equal(tm, te)
    dt = scenario_from_flat(values).loop.sample_period
    want = expected(tm, np.asarray(measurement["actuator_force"])[im], dt)
    np.testing.assert_allclose(np.asarray(estimate["contact_force_hat"])[ie], want, rtol=0.0, atol=1e-9)
    assert np.ptp(want) > 1.0  # the law moved the force: the check saw the low-pass work


#: A law that feeds F_hat back, so the estimate changes the run (pid reads the observer's own F_hat).
RUN = {"law": "pid", "duration": 2.0}


def test_the_example_runs_in_simulate_from_its_file(tmp_path):
    values = {"observer": str(EXAMPLE), **RUN}
    derived, notes = composition.derive(values)
    assert derived["force_estimate"] == "contact_force_hat", (
        notes
    )  # what the file gives, as a registry line's
    scenario = scenario_from_flat(derived)
    assert not batchable(scenario)  # a Python observer: the loop steps the cores tick by tick
    result = simulate_to_bag(scenario, tmp_path / "bag")
    assert result.ticks == 2000 and result.diverged is None
    assert_bag_ran_the_observer(tmp_path / "bag", derived)


def test_simulate_takes_the_path_as_typed(tmp_path, monkeypatch, capsys):
    """``-p observer:=examples/my_observer.py`` from the repository's root, as docs/laws.md shows it."""
    monkeypatch.chdir(ROOT)
    bag = tmp_path / "bag"
    args = ["-p", "observer:=examples/my_observer.py", "-p", "law:=pid", "-p", "duration:=0.5"]
    code = simulate.main([str(bag), *args])
    assert code == 0, capsys.readouterr().err
    assert read_bag(bag).topics["estimate"]["contact_force_hat"].size == 500


def test_a_law_that_needs_what_the_file_does_not_give_is_refused_in_one_line(capsys):
    with pytest.raises(CompositionError) as info:
        composition.check_pair("adaptive_backstepping", str(EXAMPLE))
    message = str(info.value)
    assert "\n" not in message and "theta_hat" in message and f"observer '{EXAMPLE}'" in message
    code = simulate.main(["unused_bag", "-p", f"observer:={EXAMPLE}", "-p", "law:=adaptive_backstepping"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "theta_hat" in lines[0], lines


def test_a_file_that_reads_a_head_accelerometer_is_refused_on_sensors_without_one(tmp_path):
    reads = tmp_path / "reads.py"
    reads.write_text(EXAMPLE.read_text() + "\nREADS = ('head_acceleration',)\n")
    composition.check_pair("passive", str(reads), None, "train")
    with pytest.raises(CompositionError) as info:
        composition.check_pair("passive", str(reads), None, "ground")
    assert f"observer '{reads}' reads a head accelerometer, which sensors 'ground' do not have" in str(
        info.value
    )


def test_a_campaign_point_key_holds_the_observer_file_text(tmp_path, monkeypatch):
    """A point of an observer file keys on its text: the same text keeps its results, an edit does
    not (in a new process), and a point run after its file was edited is an error row."""
    observer = tmp_path / "observer.py"
    observer.write_text(EXAMPLE.read_text())
    spec = campaign_spec.Spec(
        "t", ({"observer": [str(observer), "contact_force"]},), {"law": "pid", "duration": 0.05}, (0.0, 0.05)
    )
    points = campaign_spec.expand(spec)
    first = [p.key for p in points]
    assert len(set(first)) == 2
    assert [p.key for p in campaign_spec.expand(spec)] == first
    observer.write_text(EXAMPLE.read_text().replace("TAU = 0.5", "TAU = 0.4"))
    monkeypatch.setattr(user_observer, "_LOADED", {})  # a worker in a new process
    row = campaign_run.run_point(points[0])
    assert row["status"] == "error" and f"the observer file {observer} changed" in row["reason"], row
    second = [p.key for p in campaign_spec.expand(spec)]
    assert second[0] != first[0] and second[1] == first[1]


@pytest.mark.slow
def test_the_example_runs_in_a_campaign_from_its_file(tmp_path, capsys):
    """A campaign of the example and the contact-force filter: the example's row holds the measures
    of the example's own run (simulate's bag)."""
    from pac_analysis.metrics import compute_metrics
    from pac_experiments.campaign.cli import main

    window = [0.5, 1.5]
    spec = tmp_path / "spec.yaml"
    fixed = {"law": "pid", "duration": 1.5}
    grid = {"observer": [str(EXAMPLE), "contact_force"]}
    spec.write_text(yaml.safe_dump({"grid": grid, "fixed": fixed, "window": window}))
    out = tmp_path / "out"
    code = main([str(spec), "--out", str(out), "--workers", "1", "--no-report"])
    assert code == 0, capsys.readouterr().err
    with (out / "results.csv").open() as f:
        rows = {row["observer"]: row for row in csv.DictReader(f)}
    assert set(rows) == {str(EXAMPLE), "contact_force"} and {r["status"] for r in rows.values()} == {"ok"}
    values, _ = composition.derive({"observer": str(EXAMPLE), **fixed})
    simulate_to_bag(scenario_from_flat(values), tmp_path / "bag")
    assert_bag_ran_the_observer(tmp_path / "bag", values)
    metrics = compute_metrics(read_bag(tmp_path / "bag"), *window)
    for name in ("contact_force_mean", "contact_force_std", "u_max_abs"):
        assert float(rows[str(EXAMPLE)][name]) == pytest.approx(getattr(metrics, name), rel=1e-12), name
        assert rows[str(EXAMPLE)][name] != rows["contact_force"][name], name


@pytest.mark.live
def test_the_example_runs_in_observer_node_from_its_file(rigs, tmp_path):
    """Lock step with observer_node running the example: the same run as simulate's, bit for bit,
    and every estimate the example's formula."""
    values, _ = composition.derive({"observer": str(EXAMPLE), "law": "pid", "duration": 1.0})
    params = {"observer": {"observer": str(EXAMPLE)}, "controller": {"law": "pid"}}
    bag = lockstep_run_equals_offline(rigs, "own_observer", params, values, tmp_path / "offline")
    assert_bag_ran_the_observer(bag, values)


# -- refusals: one line, naming the file and what is wrong --------------------------------------
BAD_FILES = [
    (None, "no such file"),
    ("GIVES = (\n", "importing it raised SyntaxError"),
    ("GIVES = ()\nx = 1 / 0\n", "importing it raised ZeroDivisionError: division by zero (line 2)"),
    ("class Observer:\n    pass\n", "it does not define GIVES"),
    ("GIVES = 'contact_force_hat'\n", "is not a collection of names"),
    ("GIVES = ('speed',)\n", "GIVES names speed; it may name theta_hat, contact_force_hat"),
    ("GIVES = ()\nREADS = ('head_force',)\n", "READS names head_force; it may name head_acceleration"),
    ("GIVES = ()\n", "it does not define Observer"),
    ("GIVES = ()\nObserver = 3\n", "Observer is not a class"),
    ("GIVES = ()\nclass Observer:\n    def update(self):\n        pass\n", "Observer has no method reset"),
    (
        "GIVES = ()\nclass Observer:\n    def __init__(self, *a):\n        raise ValueError('no')\n"
        "    def update(self):\n        pass\n    def reset(self):\n        pass\n",
        "building Observer raised ValueError: no (line 4)",
    ),
]


@pytest.mark.parametrize(("text", "expected_text"), BAD_FILES)
def test_simulate_refuses_a_bad_observer_file_in_one_line(tmp_path, capsys, text, expected_text):
    assert_simulate_refuses_the_file(tmp_path, capsys, "observer", text, expected_text, "-p", "law:=passive")


def test_a_file_is_imported_once_and_an_edit_after_is_refused(tmp_path):
    assert_imported_once_and_an_edit_refused(
        tmp_path / "observer.py", EXAMPLE.read_text(), load_observer_file
    )
