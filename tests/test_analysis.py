"""The analysis tools: report, info, replay, re-estimate, and bad bags — on bags the tests generate."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import one_line, ros2, stop
from mcap_ros2.reader import read_ros2_messages
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from pac_analysis.info import describe
from pac_analysis.re_estimate import re_estimate
from pac_analysis.recover import recover
from pac_analysis.report import report
from pac_bag.reader import BagError, read_bag
from pac_bag.typestore import interface_dir
from pac_bag.writer import BagWriter
from pac_common import messages
from pac_common.messages import RosbagsFactory
from pac_rig.launcher import node_env, ros_args
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.offline

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def offline_bags(tmp_path_factory):
    root = tmp_path_factory.mktemp("bags")
    simulate_to_bag(scenario_from_flat({"duration": 5.0}), root / "active")
    simulate_to_bag(scenario_from_flat({"duration": 5.0, "mode": "passive"}), root / "passive")
    return root


def independent_contact_force(bag_dir, t_from):
    """Contact force from the raw MCAP through the mcap library's own decoder."""
    (mcap_file,) = bag_dir.glob("*.mcap")
    forces = []
    for item in read_ros2_messages(str(mcap_file), topics=["/plant_truth"]):
        stamp = item.ros_msg.header.stamp.sec + 1e-9 * item.ros_msg.header.stamp.nanosec
        if stamp >= t_from - 1e-12:
            forces.append(item.ros_msg.contact_force)
    return np.array(forces)


@pytest.mark.slow
def test_report_agrees_with_an_independent_computation(offline_bags, tmp_path):
    out = tmp_path / "report"
    results, problems = report([offline_bags / "passive", offline_bags / "active"], out, 3.0, None)
    assert problems == []
    data = json.loads((out / "metrics.json").read_text())["runs"]
    for name in ("passive", "active"):
        force = independent_contact_force(offline_bags / name, 3.0)
        m = data[name]["metrics"]
        assert m["contact_force_mean"] == pytest.approx(force.mean(), rel=1e-12)
        assert m["contact_force_std"] == pytest.approx(force.std(), rel=1e-9)
        assert m["contact_force_min"] == force.min() and m["contact_force_max"] == force.max()
        assert m["contact_loss_percent"] == pytest.approx(100 * np.mean(force <= 0))
        assert m["statistical_min"] == pytest.approx(force.mean() - 3 * force.std(), rel=1e-9)
        assert (m["ticks_expected"], m["ticks_missing"]) == (5000, 0)
        png = (out / f"{name}.png").read_bytes()
        assert png.startswith(PNG) and len(png) > 20_000
    assert (out / "overlay.png").read_bytes().startswith(PNG)
    md = (out / "metrics.md").read_text()
    assert "passive" in md and "active" in md and "Fm, mean contact force" in md
    # The active loop is far better than the passive one: the report shows it.
    assert (
        data["active"]["metrics"]["contact_force_std"]
        < 0.01 * data["passive"]["metrics"]["contact_force_std"]
    )


@pytest.mark.slow
def test_report_window_options(offline_bags, tmp_path):
    report([offline_bags / "active"], tmp_path / "w", 1.0, 2.0)
    m = json.loads((tmp_path / "w" / "metrics.json").read_text())["runs"]["active"]["metrics"]
    force = independent_contact_force(offline_bags / "active", 1.0)[:1001]
    assert (m["window_from"], m["window_to"]) == (1.0, 2.0)
    assert m["contact_force_mean"] == pytest.approx(force.mean(), rel=1e-12)


@pytest.mark.slow
def test_info_shows_topics_counts_and_ticks(offline_bags):
    text, warnings = describe(offline_bags / "active")
    assert not warnings
    for topic in messages.TOPICS:
        assert topic in text
    assert text.count(" 5000 ") >= 4 and "0..4999" in text and "1000.0" in text


@pytest.mark.slow
def test_re_estimate_on_offline_bag_is_exact(offline_bags):
    result = re_estimate(offline_bags / "active", {})
    assert result["compared"] == 5000
    assert all(f["identical"] for f in result["fields"].values())


@pytest.mark.slow
def test_re_estimate_detects_different_tuning(offline_bags):
    result = re_estimate(offline_bags / "active", {"rho_theta": 10.0})
    assert not result["fields"]["theta_hat"]["identical"]
    assert result["fields"]["theta_hat"]["max_rel_diff"] > 1e-3


def recorder(bag: Path, topics: str, **parameters: float) -> list[str]:
    """The command line of a recorder of ``topics`` (comma-separated) into ``bag``."""
    return [
        "ros2",
        "run",
        "pac_rig",
        "recorder",
        *ros_args({"bag_path": bag, "topics": topics, **parameters}),
    ]


def test_replay_into_a_live_observer_reproduces_the_estimates(offline_bags, tmp_path, domain_id, processes):
    """Replay measurement in lock step into observer_node; record what it sees and says.

    Every sample is processed whatever the load (each is published once the observer answered the
    one before), so the live observer's estimates equal the original run's bit for bit, and the
    observer core fed with exactly the samples it processed (re_estimate on the new bag).  A timed
    replay lost up to 13 % of them on a loaded 2-core machine (keep-last-1)."""
    env = node_env(domain_id)
    rec_bag = tmp_path / "new_estimates"
    for cmd in (
        recorder(rec_bag, "measurement,estimate", stop_after_tick=4999, idle_timeout=3.0),
        ["ros2", "run", "pac_observer", "observer_node"],
    ):
        with open(tmp_path / f"{cmd[3]}.log", "wb") as log:  # the process keeps its own handle
            processes.append(subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT))
    replay = subprocess.run(
        [
            "ros2",
            "run",
            "pac_rig",
            "replay",
            str(offline_bags / "active"),
            "--topics",
            "measurement",
            "--lockstep",
            "--wait-for",
            "2",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert replay.returncode == 0, replay.stderr
    assert "published 5000 messages" in replay.stderr, replay.stderr
    print(f"\n{replay.stderr.strip().splitlines()[-1]}")
    assert processes[0].wait(timeout=60) == 0, (tmp_path / "recorder.log").read_text()
    stop(processes[1])
    same_samples = re_estimate(rec_bag, {})
    assert same_samples["compared"] == 5000
    assert all(f["identical"] for f in same_samples["fields"].values())
    new = read_bag(rec_bag).topics["estimate"]
    old = read_bag(offline_bags / "active").topics["estimate"]
    ticks, idx = np.unique(new["tick"], return_index=True)
    np.testing.assert_array_equal(ticks, np.arange(5000))
    for field in ("theta_hat", "z_hat", "stiffness_hat"):
        np.testing.assert_array_equal(new[field][idx], old[field], err_msg=field)


def test_lockstep_replay_refuses_what_no_loop_node_answers_and_gives_up_without_an_answer(
    offline_bags, domain_id, processes
):
    """--lockstep replays one answered topic; with nobody answering it stops with one line."""
    env = node_env(domain_id)
    bag = str(offline_bags / "active")
    for topics in (["command"], ["measurement", "estimate"]):
        proc = ros2("run", "pac_rig", "replay", bag, "--topics", *topics, "--lockstep", env=env)
        one_line(proc, 2, "--lockstep replays one topic that a loop node answers")
    proc = ros2("run", "pac_rig", "replay", bag, "--lockstep", "--resend-timeout", "0", env=env)
    one_line(proc, 2, "invalid --resend-timeout 0")
    # a subscriber that never answers: the recorder
    processes.append(
        subprocess.Popen(
            recorder(offline_bags.parent / f"unanswered_{domain_id}", "measurement"),
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    )
    proc = ros2("run", "pac_rig", "replay", bag, "--lockstep", "--timeout", "2", env=env)
    one_line(proc, 1, "--lockstep: no estimate for tick 0 within 2 s")


# -- bad bags ---------------------------------------------------------------------------------


@pytest.mark.slow
def test_truncated_mcap_without_metadata_gives_partial_results(offline_bags, tmp_path):
    crashed = tmp_path / "crashed"
    shutil.copytree(offline_bags / "active", crashed)
    (crashed / "metadata.yaml").unlink()
    (mcap_file,) = crashed.glob("*.mcap")
    data = mcap_file.read_bytes()
    mcap_file.write_bytes(data[: int(len(data) * 0.6)])
    bag = read_bag(crashed)
    assert any("metadata.yaml" in w for w in bag.warnings)
    assert any("truncated" in w for w in bag.warnings)
    n = len(bag.topics["plant_truth"])
    assert 1000 < n < 5000
    results, problems = report([crashed], tmp_path / "r", 1.0, None)
    assert problems and all("\n" not in p for p in problems)
    assert results["crashed"]["metrics"]["ticks_recorded"] == n
    # and recover makes it a closed bag again
    counts, _ = recover(crashed, tmp_path / "recovered")
    assert counts["plant_truth"] == n
    assert read_bag(tmp_path / "recovered").warnings == []


@pytest.mark.slow
def test_missing_topics_are_named_and_the_rest_is_reported(offline_bags, tmp_path):
    partial = tmp_path / "partial"
    full = read_bag(offline_bags / "active")
    # the source is complete (so what is missing below is missing only from the rebuilt bag)
    assert full.warnings == [] and {t: len(d) for t, d in full.topics.items()} == {
        **dict.fromkeys(messages.LOOP_TOPICS, 5000),
        "run_status": 2,
    }
    # rebuild a bag with two topics, one of them empty:
    with BagWriter(partial, topics={t: messages.TOPICS[t] for t in ("measurement", "command")}) as bag:
        src = read_bag(offline_bags / "active", topics=["command"]).topics["command"]
        for i in range(len(src)):
            fields = {
                "header": messages.header(
                    int(src["header.stamp.sec"][i] * 1e9 + src["header.stamp.nanosec"][i])
                ),
                "tick": int(src["tick"][i]),
                "u": float(src["u"][i]),
                "u_unsaturated": float(src["u_unsaturated"][i]),
                "force_reference": float(src["force_reference"][i]),
                "tracking_error": src["tracking_error"][i],
                "saturated": bool(src["saturated"][i]),
                "mode": int(src["mode"][i]),
                "estimate_age_ticks": 0,
            }
            bag.write("command", fields, int(src.log_time_ns[i]))
    results, problems = report([partial], tmp_path / "r", 3.0, None)
    assert any("no 'plant_truth' messages" in p for p in problems)
    m = results["partial"]["metrics"]
    assert np.isnan(m["contact_force_mean"])
    assert m["u_max_abs"] == pytest.approx(np.max(np.abs(src["u"][src["header.stamp.sec"] >= 3])))


def _foreign_bag(path, with_pac_topic):
    """A bag written by rosbags with a type pac does not know (and, if asked, a pac topic)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg("float64 x", "other_pkg/msg/Thing"))
    store.register(get_types_from_msg((interface_dir() / "RunStatus.msg").read_text(), messages.RUN_STATUS))
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    thing = writer.add_connection("thing", "other_pkg/msg/Thing", typestore=store)
    cls = store.types["other_pkg/msg/Thing"]
    for i in range(10):
        writer.write(thing, i, store.serialize_cdr(cls(x=float(i)), "other_pkg/msg/Thing"))
    if with_pac_topic:
        status = writer.add_connection("/run_status", messages.RUN_STATUS, typestore=store)
        msg = RosbagsFactory(store).make(
            messages.RUN_STATUS, messages.run_status_fields(7, messages.RUN_ENDED, 1.0, 0)
        )
        writer.write(status, 20, store.serialize_cdr(msg, messages.RUN_STATUS))
    writer.close()
    return path


def test_unknown_type_is_skipped_with_a_warning(tmp_path):
    bag = read_bag(_foreign_bag(tmp_path / "mixed", with_pac_topic=True))
    assert list(bag.topics) == ["run_status"] and list(bag.topics["run_status"]["tick"]) == [7]
    assert bag.warnings == [
        "topic 'thing': unknown message type other_pkg/msg/Thing, skipped",
        "topic 'thing': 0 of 10 messages readable (per metadata.yaml)",
    ]


def test_a_bag_of_unknown_types_only_is_refused_naming_the_type(tmp_path):
    with pytest.raises(BagError, match="no readable message.*unknown message type other_pkg/msg/Thing"):
        read_bag(_foreign_bag(tmp_path / "foreign", with_pac_topic=False))


@pytest.mark.slow
def test_empty_bag_and_no_bag(tmp_path):
    empty = tmp_path / "empty"
    BagWriter(empty).close()
    with pytest.raises(BagError, match="no readable message"):
        read_bag(empty)
    with pytest.raises(BagError, match="no such bag"):
        read_bag(tmp_path / "nothing")
    proc = subprocess.run(
        ["ros2", "run", "pac_analysis", "report", str(empty), "--out", str(tmp_path / "r")],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [f"report: {empty}: no readable message"]


def _live_bag(rate_hz, wall_periods_s):
    """BagData with only the plant_truth of a live run at rate_hz, woken up after wall_periods_s."""
    from pac_bag.reader import BagData, TopicData

    n = len(wall_periods_s) + 2  # tick 0 (the start-up handshake) and the first period's start
    ticks = np.arange(n)
    stamp_ns = ticks * int(round(1e9 / rate_hz))
    wall_ns = (1_000_000_000 + 1e9 * np.concatenate([[0.0, 0.5], 0.5 + np.cumsum(wall_periods_s)])).astype(
        np.int64
    )
    columns = {
        "tick": ticks,
        "header.stamp.sec": stamp_ns // 1_000_000_000,
        "header.stamp.nanosec": stamp_ns % 1_000_000_000,
        "wall_stamp.sec": wall_ns // 1_000_000_000,
        "wall_stamp.nanosec": wall_ns % 1_000_000_000,
        "round_trip_latency": np.full(n, 1e-3),
        "command_age_ticks": np.full(n, 2),
        "applied_command_tick": ticks - 1,
    }
    truth = TopicData(messages.PLANT_TRUTH, stamp_ns, columns)
    return BagData(Path("synthetic"), {"plant_truth": truth}, {}, [])


@pytest.mark.parametrize("rate_hz", [1000.0, 500.0, 200.0])
def test_late_periods_are_counted_against_the_runs_own_period(rate_hz):
    """A period is late beyond 1.5 nominal periods, whatever rate_hz is (not a fixed 1.5 ms)."""
    from pac_analysis.metrics import loop_timing

    t = 1.0 / rate_hz
    periods = [t] * 96 + [1.4 * t, 1.6 * t, 2.0 * t, 1.49 * t]  # two late, two on time
    timing = loop_timing(_live_bag(rate_hz, periods))
    assert timing.nominal_period_ms == pytest.approx(1e3 * t)
    assert timing.late_periods == 2
    assert timing.on_time_periods_percent == pytest.approx(98.0)
