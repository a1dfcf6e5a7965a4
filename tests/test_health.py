"""Node health on /diagnostics, end-of-run counters (pac-stats) and managed (lifecycle) start-up.

Unit tests of the pure status rules, then live nodes in this test's own ROS domain: the
controller goes WARN with the fallback when the observer is killed and OK when it is back;
the recorder goes ERROR below its free-disk floor; a lifecycle run, configured and activated
by a manager, records the same run as the offline simulator bit for bit (lock step).
"""

import json
import math
import signal
import subprocess
import time

import numpy as np
import pytest
import rclpy
from conftest import node_stats
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from pac_analysis.info import describe
from pac_bag.reader import read_bag
from pac_common import diagnostics
from pac_common.diagnostics import ERROR, OK, WARN, LoopTiming
from pac_rig.launcher import NODES, node_env
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

# The pure rules are unit tests; every test below that starts nodes uses domain_id: live.
pytestmark = pytest.mark.unit

# -- the pure rules --------------------------------------------------------------------------------


def test_loop_timing_percentiles_match_numpy_over_the_last_window():
    rng = np.random.default_rng(3)
    timing = LoopTiming(size=256)
    starts = np.cumsum(rng.integers(900_000, 1_100_000, size=700))
    latencies = rng.uniform(1e-4, 2e-3, size=700)
    for start, latency in zip(starts, latencies, strict=True):
        timing.record(int(start), float(latency))
    summary = timing.summary()
    window_periods = np.diff(starts[-256:]) * 1e-6
    window_latencies = latencies[-256:] * 1e3
    assert summary["period_p50_ms"] == pytest.approx(np.percentile(window_periods, 50), rel=1e-12)
    assert summary["period_p99_ms"] == pytest.approx(np.percentile(window_periods, 99), rel=1e-12)
    assert summary["period_max_ms"] == pytest.approx(window_periods.max(), rel=1e-12)
    assert summary["latency_p99_ms"] == pytest.approx(np.percentile(window_latencies, 99), rel=1e-12)
    assert timing.last_ns == starts[-1]
    assert math.isnan(LoopTiming().summary()["latency_p50_ms"])  # nothing recorded yet


def test_controller_status_warns_while_the_fallback_is_active_and_not_after():
    running = {
        "state": "running",
        "last_tick": 10,
        "fallback_active": False,
        "refused": 0,
        "input_age_s": 0.001,
    }
    assert diagnostics.controller_status("controller_node", running, None).level == OK
    fallback = {**running, "fallback_active": True, "estimate_age_ticks": 60, "fallback_force": 120.0}
    status = diagnostics.controller_status("controller_node", fallback, running)
    assert status.level == WARN and "fallback active" in status.message and "60 ticks" in status.message
    assert status.name == "controller_node: control"
    assert ("fallback_active", "true") in status.values
    assert diagnostics.controller_status("controller_node", running, fallback).level == OK


def test_events_warn_for_one_report_conditions_for_as_long_as_they_last():
    before = {"state": "running", "refused": 3, "reinitialisations": 0, "input_age_s": 0.001}
    now = {**before, "refused": 5}
    status = diagnostics.observer_status("observer_node", now, before)
    assert status.level == WARN and "2 measurement(s) refused" in status.message
    assert diagnostics.observer_status("observer_node", now, now).level == OK
    stale = {**now, "input_age_s": 2.0}
    assert "no measurement for 2.0 s" in diagnostics.observer_status("observer_node", stale, now).message
    assert diagnostics.observer_status("observer_node", {**stale, "state": "ended"}, now).level == OK
    timed_out = {"state": "running", "command_timed_out": True, "command_age_ticks": 51, "schedule_slips": 0}
    assert diagnostics.plant_status("plant_node", timed_out, timed_out).level == WARN


def test_recorder_status_is_error_below_the_free_disk_floor_or_after_a_failed_write():
    ok = {
        "state": "recording",
        "messages": 10,
        "bag_bytes": 4096,
        "free_disk_mb": 500.0,
        "min_free_disk_mb": 50.0,
    }
    assert diagnostics.recorder_status("recorder", ok, None).level == OK
    low = {**ok, "free_disk_mb": 20.0}
    status = diagnostics.recorder_status("recorder", low, ok)
    assert status.level == ERROR and "below min_free_disk_mb 50" in status.message
    failed = {**ok, "failed": True, "failure": "No space left on device"}
    assert (
        diagnostics.recorder_status("recorder", failed, ok).message
        == "recording stopped: No space left on device"
    )


def test_stats_line_is_one_strict_json_line_the_tests_parse():
    line = diagnostics.stats_line(
        "plant_node", {"resends": 3, "latency_p50_ms": math.nan, "timed_out": False}
    )
    assert "\n" not in line and line.startswith("pac-stats {")
    assert json.loads(line[len("pac-stats ") :]) == {
        "node": "plant_node",
        "resends": 3,
        "latency_p50_ms": None,
        "timed_out": False,
    }
    log = f"[INFO] some prose\n{line}\nrecorder: closed\n"
    assert node_stats(log, "plant_node")["resends"] == 3


def test_a_diagnostic_array_echoes_as_ros2cli_prints_it():
    """What `ros2 topic echo /diagnostics` prints: the stand-in decodes the type, a level is a number."""
    from pac_common.health import to_message
    from pac_ros2cli.common import plain

    status = diagnostics.controller_status(
        "controller_node", {"state": "running", "last_tick": 7, "fallback_active": False, "refused": 0}, None
    )
    data = plain(to_message([status], 1_500_000_000))
    assert data["header"]["stamp"] == {"sec": 1, "nanosec": 500_000_000}
    (entry,) = data["status"]
    assert entry["level"] == OK and entry["name"] == "controller_node: control"
    assert entry["message"] == "running, tick 7" and entry["hardware_id"] == "pac"
    assert {"key": "last_tick", "value": "7"} in entry["values"]


# -- live nodes ------------------------------------------------------------------------------------


class Monitor:
    """A /diagnostics subscriber in the test's domain (what rqt_robot_monitor or Foxglove does)."""

    def __init__(self, domain_id: int) -> None:
        from diagnostic_msgs.msg import DiagnosticArray

        from pac_common.health import DIAGNOSTICS_QOS

        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node("monitor", context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.seen: list[tuple[float, str, int, str]] = []
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_array, DIAGNOSTICS_QOS)

    def _on_array(self, msg) -> None:
        for status in msg.status:
            self.seen.append((time.monotonic(), status.name, status.level[0], status.message))

    def wait_for(self, name: str, level: int, text: str = "", timeout: float = 60.0, procs=None):
        """The first status of ``name`` at ``level`` (message containing ``text``) from now on."""
        start = len(self.seen)
        deadline = time.monotonic() + timeout
        while True:
            for entry in self.seen[start:]:
                if entry[1] == name and entry[2] == level and text in entry[3]:
                    return entry
            start = len(self.seen)
            last = [e for e in self.seen if e[1] == name][-1:] or "none yet"
            assert time.monotonic() < deadline, (
                f"{name}: no {diagnostics.level_name(level)} '{text}'; last {last}"
            )
            for proc in procs or ():
                assert proc.poll() is None, proc.log()[-2000:]
            self.executor.spin_once(timeout_sec=0.1)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def monitor(domain_id):
    mon = Monitor(domain_id)
    yield mon
    mon.close()


def test_controller_goes_warn_with_the_fallback_when_the_observer_dies_and_ok_when_it_is_back(rigs, monitor):
    # A restarted observer's first estimate can come > 10 s after the last one on a loaded machine
    # (process start): the controller's tick-jump check allows for the wall time passed since.
    rig = rigs("observer_dies", duration=0.0)
    rig.params["recorder"]["stop_after_tick"] = -1
    rig.start()
    controller = "controller_node: control"
    monitor.wait_for(controller, OK, "running", procs=rig.processes.values())
    monitor.wait_for("plant_node: loop", OK, "running")
    monitor.wait_for("observer_node: estimation", OK, "running")
    monitor.wait_for("recorder: recording", OK, "recording")
    rig.kill("observer")
    warned = monitor.wait_for(controller, WARN, "fallback active", timeout=30.0)
    rig.restart("observer")
    back = monitor.wait_for(controller, OK, "running", timeout=120.0)
    print(f"\ncontroller: WARN '{warned[3]}', OK again {back[0] - warned[0]:.1f} s later")
    assert rig.stop() == {"recorder": 0, "observer": 0, "controller": 0, "plant": 0}
    stats = node_stats(rig.processes["controller"].log(), "controller_node")
    assert stats["fallback_episodes"] >= 1 and stats["fallback_commands"] > 0
    assert stats["period_p50_ms"] is not None and stats["latency_p99_ms"] is not None
    # Recorded with the run (the recorder records /diagnostics by default), and summarised by info.
    bag = read_bag(rig.bag_path)
    levels = {(s.name, int(s.level)) for statuses in bag.topics["diagnostics"]["status"] for s in statuses}
    assert (controller, WARN) in levels and (controller, OK) in levels
    text, _ = describe(rig.bag_path)
    summary = text[text.index("diagnostics:") :]
    line = next(x for x in summary.splitlines() if x.strip().startswith(controller))
    assert "worst WARN" in line
    assert "fallback active" in summary


def test_recorder_goes_error_below_its_free_disk_floor_and_ok_when_the_floor_is_lowered(
    domain_id, tmp_path, monitor
):
    env = node_env(domain_id)
    log = tmp_path / "recorder.log"
    args = ["--ros-args", "-p", f"bag_path:={tmp_path / 'bag'}", "-p", "min_free_disk_mb:=1e12"]
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            ["ros2", "run", "pac_rig", "recorder", *args], stdout=out, stderr=subprocess.STDOUT, env=env
        )
    try:
        error = monitor.wait_for("recorder: recording", ERROR, "below min_free_disk_mb", timeout=60.0)
        print(f"\n{error[3]}")
        client = AsyncParameterClient(monitor.node, "recorder")
        assert client.wait_for_services(timeout_sec=30)
        future = client.set_parameters([Parameter("min_free_disk_mb", value=0.0)])
        monitor.executor.spin_until_future_complete(future, timeout_sec=10)
        assert future.result().results[0].successful
        monitor.wait_for("recorder: recording", OK, timeout=30.0)
    finally:
        proc.send_signal(signal.SIGINT)
        code = proc.wait(30)
    assert code == 0, log.read_text()[-2000:]
    stats = node_stats(log.read_text(), "recorder")
    assert stats["min_free_disk_mb"] == 0.0 and stats["free_disk_mb"] > 0 and not stats["failed"]


def test_a_managed_lockstep_run_configured_and_activated_by_a_manager_equals_the_offline_run(
    rigs, domain_id, tmp_path, monitor
):
    from pac_common.lifecycle import bring_up, get_state, managed_nodes

    duration = 1.5
    rig = rigs(
        "managed",
        duration=duration,
        timing_mode="lockstep",
        params={"all": {"lifecycle": True}, "recorder": {"lifecycle": True}},
    )
    rig.start()
    expected = ["/controller_node", "/observer_node", "/plant_node", "/recorder"]
    deadline = time.monotonic() + 60
    while managed_nodes(monitor.node) != expected:
        assert time.monotonic() < deadline, managed_nodes(monitor.node)
        for proc in rig.processes.values():
            assert proc.poll() is None, proc.log()[-2000:]
        monitor.executor.spin_once(timeout_sec=0.1)
    # The stand-in's verbs see them, unconfigured: nothing runs before the manager says so.
    env = node_env(domain_id)
    # A listing is what one process discovers in its bounded wait: as a user would, ask again.
    for _ in range(3):
        listed = subprocess.run(
            ["ros2", "lifecycle", "nodes"], capture_output=True, text=True, env=env, timeout=60
        )
        if listed.stdout.split() == expected:
            break
    assert listed.stdout.split() == expected, listed.stderr
    state = subprocess.run(
        ["ros2", "lifecycle", "get", "/plant_node"], capture_output=True, text=True, env=env, timeout=60
    )
    assert state.stdout.strip() == "unconfigured", state.stderr
    assert not rig.bag_path.exists()  # the recorder creates its bag when configured
    bring_up(monitor.node, monitor.executor, expected)
    assert {get_state(monitor.node, monitor.executor, n) for n in ("/plant_node", "/recorder")} <= {"active"}
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == dict.fromkeys(NODES, 0), {n: p.log()[-800:] for n, p in rig.processes.items()}
    simulate_to_bag(scenario_from_flat({"duration": duration}), tmp_path / "offline")
    live, offline = read_bag(rig.bag_path).topics, read_bag(tmp_path / "offline").topics
    n = int(duration * 1000)
    for topic in ("measurement", "plant_truth", "estimate", "command"):
        ticks, idx = np.unique(live[topic]["tick"], return_index=True)
        np.testing.assert_array_equal(ticks, np.arange(n), err_msg=topic)
        for column in offline[topic].columns:
            # Bookkeeping of the live transport, not of the run: wall times, round trips, and
            # tick 0's command source (the start-up handshake applies no command: PASSIVE).
            if column.startswith(("header", "wall_stamp")) or column in (
                "round_trip_latency",
                "command_source",
            ):
                continue
            np.testing.assert_array_equal(
                live[topic][column][idx], offline[topic][column], err_msg=f"{topic}.{column}"
            )
    assert node_stats(rig.processes["plant"].log(), "plant_node")["last_tick"] == n - 1


def test_a_managed_recorder_deactivates_cleans_up_its_bag_and_shuts_down(domain_id, tmp_path, monitor):
    from pac_common.lifecycle import change_state, get_state, managed_nodes

    bag = tmp_path / "bag"
    log = tmp_path / "recorder.log"
    args = ["--ros-args", "-p", f"bag_path:={bag}", "-p", "lifecycle:=true"]
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            ["ros2", "run", "pac_rig", "recorder", *args],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=node_env(domain_id),
        )
    try:
        deadline = time.monotonic() + 60
        while "/recorder" not in managed_nodes(monitor.node):
            assert time.monotonic() < deadline and proc.poll() is None, log.read_text()[-2000:]
            monitor.executor.spin_once(timeout_sec=0.1)
        node, executor = monitor.node, monitor.executor
        assert get_state(node, executor, "/recorder") == "unconfigured" and not bag.exists()
        monitor.wait_for("recorder: recording", OK, "lifecycle state unconfigured", timeout=30.0)
        assert change_state(node, executor, "/recorder", "configure") == "inactive" and bag.is_dir()
        assert change_state(node, executor, "/recorder", "activate") == "active"
        monitor.wait_for("recorder: recording", OK, "recording", timeout=30.0)  # it records its own status
        assert change_state(node, executor, "/recorder", "deactivate") == "inactive"
        assert change_state(node, executor, "/recorder", "cleanup") == "unconfigured"
        assert (bag / "metadata.yaml").is_file()  # closed: complete and indexed
        assert len(read_bag(bag).topics["diagnostics"]) >= 1
        change_state(node, executor, "/recorder", "shutdown")
        assert proc.wait(30) == 0, log.read_text()[-2000:]
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            proc.wait(30)


def test_lifecycle_verbs_refuse_a_node_that_is_not_managed(domain_id):
    env = node_env(domain_id)
    out = subprocess.run(
        ["ros2", "lifecycle", "get", "/nobody"], capture_output=True, text=True, env=env, timeout=60
    )
    assert out.returncode == 1 and "not a managed node" in out.stderr
    bad = subprocess.run(["ros2", "lifecycle", "set"], capture_output=True, text=True, env=env, timeout=60)
    assert bad.returncode == 2
