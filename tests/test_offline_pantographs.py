"""Several pantographs offline: ``simulate``'s bag carries every pantograph's truth on
``pantograph_truth`` as the live plant publishes it (read back with an independent MCAP reader),
the compiled loop's per-pantograph record equals the plant's own ``pantograph_truths()`` bit for
bit, the analysis reports every pantograph of an offline bag, and its statistics equal those of
the two-pantograph experiment's own simulation of the same run (``ContactSimulation`` stepped
directly, another code path); one pantograph: no ``pantograph_truth``, as live."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.reader import read_ros2_messages

from pac_analysis.metrics import pantograph_statistics
from pac_analysis.report import report
from pac_bag.reader import read_bag
from pac_common.contact_statistics import contact_statistics, target_mean_force
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.offline

SPACING = 200.0  # m
SPEED = 300.0  # km/h
FE = {"catenary_model": "fe", "speed_kmh": SPEED, "span_length": 55.0}
#: Two passive benchmark-like 3-mass pantographs pressed by the EN 50367 target at SPEED (the
#: controlled one by law passive, whose reference rises to it; the other by its file's uplift, the
#: target), as the two-pantograph experiment runs them; the observer that needs no F = k z1.
PASSIVE_PAIR = {
    **FE,
    "pantographs": (0.0, SPACING),
    "pantograph": "three_mass",
    "passive_pantograph": "three_mass",
    "law": "passive",
    "force_amplitude": target_mean_force(SPEED),
    "observer": "contact_force",
}


def by_topic(bag: Path) -> dict[str, dict[int, object]]:
    """Every message of the bag by topic and tick, decoded by mcap-ros2 (not the project's reader)."""
    (path,) = bag.glob("*.mcap")
    out: dict[str, dict[int, object]] = {}
    for m in read_ros2_messages(str(path)):
        out.setdefault(m.channel.topic, {})[int(m.ros_msg.tick)] = m.ros_msg
    return out


def channels(bag: Path) -> set[str]:
    (path,) = bag.glob("*.mcap")
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {c.topic for c in summary.channels.values()}


@pytest.mark.parametrize("controlled", [0, 1])
def test_an_offline_bag_has_every_pantograph_each_tick(tmp_path, controlled):
    """pantograph_truth at every tick of plant_truth, both pantographs in the order of
    ``pantographs``; the controlled one's entry is PlantTruth's contact, bit for bit (the plant's
    truth() and pantograph_truths() read the same contact), the other one lies SPACING ahead or
    behind and presses on the wire (its uplift: 157 N at 300 km/h)."""
    duration = 0.4
    flat = {**FE, "pantographs": (0.0, SPACING), "controlled_pantograph": controlled}
    result = simulate_to_bag(scenario_from_flat({**flat, "duration": duration}), tmp_path / "two")
    assert result.diverged is None and result.ticks == round(duration * 1000)
    topics = by_topic(tmp_path / "two")
    ticks = sorted(topics["/plant_truth"])
    assert ticks == list(range(result.ticks)) and sorted(topics["/pantograph_truth"]) == ticks
    other = 1 - controlled
    for k in ticks:
        one, every = topics["/plant_truth"][k], topics["/pantograph_truth"][k]
        stamp = (every.header.stamp.sec, every.header.stamp.nanosec)
        assert stamp == (one.header.stamp.sec, one.header.stamp.nanosec)
        assert every.controlled == controlled and list(every.spacing) == [0.0, SPACING]
        assert len(every.contact_force) == len(every.support_uplift) == 2
        assert every.contact_force[controlled] == one.contact_force
        assert every.contact_position[controlled] == one.contact_position
        assert every.contact_uplift[controlled] == one.contact_uplift
        assert every.support_uplift[controlled] == one.support_uplift
        assert every.contact_position[0] - every.contact_position[1] == pytest.approx(SPACING, abs=1e-9)
    passive = np.array([topics["/pantograph_truth"][k].contact_force[other] for k in ticks])
    assert passive.max() > 100.0 and np.all(np.isfinite(passive))


@pytest.mark.slow
def test_the_compiled_loop_records_every_pantograph_as_the_plant_reports_it(tmp_path):
    """The compiled loop's pantograph fields (simulate's fast path) == ``FEPlant.pantograph_truths``
    of the core objects stepped tick by tick (``compiled=False``, the plant node's own calls):
    every message of every topic, byte for byte, the trailing pantograph controlled by
    line_adaptive (its passive leader and it both move)."""
    from test_loop import messages_of

    flat = {
        **FE,
        "duration": 0.3,
        "pantographs": (0.0, SPACING),
        "controlled_pantograph": 1,
        "law": "line_adaptive",
        "observer": "contact_force",
    }
    s = scenario_from_flat(flat)
    fast = simulate_to_bag(s, tmp_path / "fast")
    slow = simulate_to_bag(s, tmp_path / "slow", compiled=False)
    assert (fast.ticks, fast.diverged) == (slow.ticks, slow.diverged) == (300, None)
    got, want = messages_of(tmp_path / "fast"), messages_of(tmp_path / "slow")
    assert len(got) == 5 * fast.ticks + 2
    assert sum(topic == "/pantograph_truth" for topic, _, _ in got) == fast.ticks
    assert got == want


def test_one_pantograph_has_no_pantograph_truth_as_live(tmp_path):
    """One pantograph (the FE line, or the lumped one): the bag has the loop's topics only, as the
    plant node publishes no pantograph_truth then."""
    simulate_to_bag(scenario_from_flat({**FE, "duration": 0.05}), tmp_path / "fe")
    simulate_to_bag(scenario_from_flat({"duration": 0.05}), tmp_path / "lumped")
    loop = {"/measurement", "/plant_truth", "/estimate", "/command", "/run_status"}
    assert channels(tmp_path / "fe") == channels(tmp_path / "lumped") == loop


def experiment_series(applied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contact forces and positions (ticks x 2, leading first) of the two-pantograph experiment's
    simulation of the run (``ContactSimulation`` stepped directly on its endless window, both 3-mass
    pantographs relaxed under ``target_mean_force``), the trailing one pressed by ``applied`` (the
    force the rig's plant applied at each tick), the leading one by the target; tick 0 the initial
    state, as a bag starts."""
    from pac_experiments.catenary.two_pantographs import DT, _Runs
    from pac_plant.catenary.integrator import ContactSimulation, PassivePantograph
    from pac_plant.catenary.pantographs import three_mass_pantograph

    runs = _Runs("benchmark_55m", SPACING)
    force = target_mean_force(SPEED)
    leading = PassivePantograph(three_mass_pantograph(), 0.0, force)
    sim = ContactSimulation(
        runs.line,
        three_mass_pantograph(),
        DT,
        SPEED / 3.6,
        runs.x0,
        endless=True,
        lag=SPACING,
        passive=(leading,),
    )
    sim.relax_roof_springs(force)
    ticks = len(applied)
    forces, positions = np.empty((ticks, 2)), np.empty((ticks, 2))
    for k in range(ticks):
        forces[k], positions[k] = sim.contact_forces[::-1], sim.contact_positions[::-1]
        sim.step(float(applied[k]))
    return forces, positions


@pytest.mark.slow
def test_the_analysis_of_an_offline_bag_equals_the_two_pantograph_experiment(tmp_path):
    """Two passive 3-mass pantographs, the trailing one the rig's controlled one (u = 0): the
    report's per-pantograph EN 50318 statistics of the offline bag equal those computed from the
    two-pantograph experiment's own simulation of the same run over the same whole spans (another
    path: no plant, no compiled loop, no bag; its DOFs in another order, so equal to rounding)."""
    duration = 2.0  # s: 167 m at 300 km/h, whole spans for both pantographs after 1 s
    scenario = scenario_from_flat({**PASSIVE_PAIR, "duration": duration, "controlled_pantograph": 1})
    result = simulate_to_bag(scenario, tmp_path / "pair")
    assert result.diverged is None
    results, problems = report([tmp_path / "pair"], tmp_path / "report", 1.0, None)
    rows = results["pair"]["pantographs"]
    assert rows == pantograph_statistics(read_bag(tmp_path / "pair"), window_from=1.0)
    assert [r["controlled"] for r in rows] == [False, True] and [r["spacing"] for r in rows] == [0.0, SPACING]
    assert "## Every pantograph: pair" in (tmp_path / "report" / "metrics.md").read_text()
    truth = by_topic(tmp_path / "pair")["/plant_truth"]
    # PlantTruth at tick k + 1 carries the force applied over [t_k, t_k+1].
    applied = np.array([truth[k + 1].u_applied for k in range(result.ticks - 1)] + [0.0])
    forces, positions = experiment_series(applied)
    bag = by_topic(tmp_path / "pair")["/pantograph_truth"]
    recorded = np.array([bag[k].contact_position for k in range(result.ticks)])
    np.testing.assert_allclose(recorded, positions, rtol=0.0, atol=1e-9)  # the same contact points
    for k, row in enumerate(rows):
        assert row["x_to"] - row["x_from"] >= 55.0
        want = contact_statistics(forces[:, k], positions[:, k], 1e-3, row["x_from"], row["x_to"]).as_dict()
        for name, value in want.items():
            assert row[name] == pytest.approx(value, rel=1e-6, abs=1e-6), (k, name)
    lead, trail = rows
    assert lead["contact_force_mean"] == pytest.approx(target_mean_force(SPEED), rel=0.1)
    assert trail["contact_force_std"] != pytest.approx(lead["contact_force_std"], rel=1e-3)
