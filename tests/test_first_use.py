"""What a newcomer hit on first use, each pinned: waits that say what they wait for, one-line
errors instead of tracebacks, params files with ROS's semantics, a clean Ctrl-C of `simulate`,
the plant's line announced, and diagnostics that describe what is there."""

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import ROS2, one_line, ros2

from pac_bag.reader import BagError, read_bag
from pac_common.command_line import ParamsFile, UsageError, section_matches
from pac_rig.launcher import node_env

#: A folder nobody can create files in, root included (the tests run as root here).
READ_ONLY = Path("/proc")


def simulate(*args: str, env: dict[str, str], cwd=None) -> subprocess.CompletedProcess:
    return ros2("run", "pac_rig", "simulate", *args, env=env, cwd=cwd)


# -- 1. a waiting node says what it waits for, and gives up --------------------------------------------


def test_a_waiting_plant_names_what_is_missing_and_gives_up(domain_id):
    started = time.monotonic()
    proc = ros2(
        "run",
        "pac_plant",
        "plant_node",
        "--ros-args",
        "-p",
        "wait_for_recorder:=true",
        "-p",
        "start_timeout:=6.0",
        env=node_env(domain_id),
    )
    took = time.monotonic() - started
    assert proc.returncode == 1, proc.stderr
    assert "waiting 5 s for an observer and a recorder (wait_for_recorder) subscribed to measurement" in (
        proc.stderr
    )
    gave_up = [line for line in proc.stderr.splitlines() if "gave up after" in line]
    assert len(gave_up) == 1 and "a recorder subscribed to plant_truth" in gave_up[0], proc.stderr
    assert "a controller publishing command" in gave_up[0] and "start_timeout 6 s" in gave_up[0]
    print(f"\nplant gave up after {took:.1f} s (start_timeout 6 s, process start included)")


# -- 2. one-line errors instead of tracebacks ----------------------------------------------------------


@pytest.mark.offline
@pytest.mark.slow
def test_simulate_into_an_existing_or_read_only_folder_is_one_line(tmp_path):
    env = node_env()
    existing = tmp_path / "run"
    existing.mkdir()
    one_line(simulate(str(existing), env=env), 2, "'bag'", str(existing), "does not exist yet")
    one_line(simulate(str(READ_ONLY / "run"), env=env), 2, "'bag'", "writable folder")


@pytest.mark.offline
@pytest.mark.slow
def test_campaign_out_on_a_read_only_path_is_one_line(tmp_path):
    spec = tmp_path / "spec.yaml"
    spec.write_text("grid: {speed_kmh: [300.0]}\nfixed: {duration: 0.1}\nwindow: [0.0, 0.1]\n")
    proc = ros2(
        "run", "pac_experiments", "campaign", str(spec), "--out", str(READ_ONLY / "c"), env=node_env()
    )
    one_line(proc, 2, "'--out'", "writable")


@pytest.mark.offline
@pytest.mark.slow
def test_report_from_a_read_only_working_directory_is_one_line(tmp_path):
    env = node_env()
    bag = tmp_path / "bag"
    assert simulate(str(bag), "-p", "duration:=0.05", env=env).returncode == 0
    proc = ros2("run", "pac_analysis", "report", str(bag), env=env, cwd=READ_ONLY)
    one_line(proc, 2, "cannot write", "--out")


# -- 3 and 5. params files with ROS's semantics ---------------------------------------------------------


@pytest.mark.unit
def test_params_file_sections_follow_ros():
    assert section_matches("/**", "/controller_node")
    assert section_matches("controller_node", "/controller_node")
    assert section_matches("/**/controller_node", "/controller_node")
    assert section_matches("/rig/*", "/rig/controller_node")
    assert not section_matches("/observer_node", "/controller_node")
    assert not section_matches("/*", "/rig/controller_node")


@pytest.mark.unit
def test_a_params_file_splits_shared_and_own_sections(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text(
        "/**:\n  ros__parameters:\n    rate_hz: 500.0\n"
        "controller_node:\n  ros__parameters:\n    c1: 30.0\n    gains: {a: 1}\n"
        "/observer_node:\n  ros__parameters:\n    rho_z: 40.0\n"
    )
    shared, own = ParamsFile.read(str(path)).for_node("/controller_node")
    assert shared == {"rate_hz": 500.0} and own == {"c1": 30.0, "gains.a": 1}
    path.write_text("- just a list\n")
    with pytest.raises(UsageError, match="not a ROS 2 parameter file"):
        ParamsFile.read(str(path))


def test_a_dump_loads_with_params_file_and_shared_files_follow_ros(domain_id, tmp_path):
    """`ros2 param dump` of a live node starts a node (and simulate); a shared /** file with other
    nodes' keys is accepted; a file that gives a node nothing is said."""
    env = node_env(domain_id)
    node = subprocess.Popen(
        [ROS2, "run", "pac_controller", "controller_node", "--ros-args", "-p", "c1:=33.0"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        dump = ros2("param", "dump", "/controller_node", env=env)
        while dump.returncode != 0:
            assert time.monotonic() < deadline and node.poll() is None, dump.stderr
            dump = ros2("param", "dump", "/controller_node", env=env)
    finally:
        node.send_signal(signal.SIGINT)
        assert node.wait(timeout=20) == 0
    mine = tmp_path / "my.yaml"
    mine.write_text(dump.stdout)
    assert "start_type_description_service" in dump.stdout and "c1: 33.0" in dump.stdout

    def start(node_name: str, pkg: str, *params: str) -> subprocess.CompletedProcess:
        # start_timeout:=1: the node starts, waits 1 s for peers that never come, and exits 1
        return ros2("run", pkg, node_name, "--ros-args", *params, "-p", "start_timeout:=1.0", env=env)

    loaded = start("controller_node", "pac_controller", "--params-file", str(mine))
    assert loaded.returncode == 1 and "gave up after" in loaded.stderr, loaded.stderr
    assert "unknown parameter" not in loaded.stderr
    shared = tmp_path / "shared.yaml"
    shared.write_text("/**:\n  ros__parameters:\n    c1: 30.0\n    rho_z: 40.0\n    stop_after_run: true\n")
    observer = start("observer_node", "pac_observer", "--params-file", str(shared))
    assert observer.returncode == 1 and "gave up after" in observer.stderr, observer.stderr
    # the observer is given only the controller's section: it says so, and starts with its defaults
    empty = start("observer_node", "pac_observer", "--params-file", str(mine))
    assert empty.returncode == 1, empty.stderr
    assert (
        f"params file {mine} gives /observer_node nothing (its sections: '/controller_node'" in empty.stderr
    )
    # simulate takes a node's dump and --ros-args as a node does
    sim = simulate(
        str(tmp_path / "sim"), "--ros-args", "--params-file", str(mine), "-p", "duration:=0.05", env=env
    )
    assert sim.returncode == 0, sim.stderr
    assert "ignoring the nodes' own parameters" in sim.stderr and "start_timeout" in sim.stderr
    bag = read_bag(tmp_path / "sim")
    assert bag.metadata["parameters"]["c1"] == 33.0


# -- 4. Ctrl-C during simulate -----------------------------------------------------------------------


@pytest.mark.offline
@pytest.mark.slow
def test_ctrl_c_during_simulate_closes_the_bag_with_what_was_simulated(tmp_path):
    bag = tmp_path / "long"
    proc = subprocess.Popen(
        [ROS2, "run", "pac_rig", "simulate", str(bag), "-p", "duration:=3600.0"],
        env=node_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        # Interrupt once the first blocks of ticks are in the file: the compiled loop simulates
        # ~10^5 ticks/s, and every tick left in the bag costs this test's full read of it.
        deadline = time.monotonic() + 120
        while sum(f.stat().st_size for f in bag.glob("*.mcap")) < 200_000:
            assert time.monotonic() < deadline and proc.poll() is None
            time.sleep(0.01)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted (Ctrl-C) after" in err
    data = read_bag(bag)  # closed: metadata.yaml and an index, read by rosbags
    assert not data.warnings and (bag / "metadata.yaml").is_file()
    ticks = len(data.topics["measurement"])
    assert ticks > 100 and f"after {ticks} of 3600000 ticks" in err
    status = data.topics["run_status"]
    assert list(status["state"]) == [0, 1] and int(status["tick"][-1]) == ticks - 1
    print(f"\nsimulate interrupted: the bag holds {ticks} ticks")


# -- 8. the plant's line, and a diverged offline run ---------------------------------------------------


@pytest.mark.offline
@pytest.mark.slow
def test_simulate_announces_the_line_warns_on_a_span_mismatch_and_a_diverged_run_fails(tmp_path):
    env = node_env()
    # No span named: the FE line's is derived and said; a span named that differs: a warning.
    fe = simulate(str(tmp_path / "fe"), "-p", "catenary_model:=fe", "-p", "duration:=0.02", env=env)
    assert fe.returncode == 0, fe.stderr
    assert "simulate: span_length:=55 (the mean span of the FE line benchmark_55m)" in fe.stderr
    assert "warning" not in fe.stderr
    status = read_bag(tmp_path / "fe").topics["run_status"]
    assert set(status["catenary_model"]) == {"fe"} and set(status["span_length"]) == {55.0}
    told = ("-p", "catenary_model:=fe", "-p", "span_length:=65.0", "-p", "duration:=0.02")
    fe65 = simulate(str(tmp_path / "fe65"), *told, env=env)
    assert fe65.returncode == 0, fe65.stderr
    assert (
        "the plant runs the fe line with 55 m spans but observer and controller assume span_length 65 m"
        in fe65.stderr
    )
    paper_gains = ["c1:=400.0", "c2:=400.0", "c3:=50.0", "u_min:=-1.0e+7", "u_max:=1.0e+7"]
    paper_gains.append("slew_rate_max:=1.0e+12")  # reproduce's paper_gains: diverges at 0.234 s
    args = [a for p in [*paper_gains, "theta_hat0:=[3000.0, 0.0, 0.0]", "duration:=1.0"] for a in ("-p", p)]
    diverged = simulate(str(tmp_path / "diverged"), *args, env=env)
    assert diverged.returncode == 1 and "simulate: run stopped: closed loop diverged" in diverged.stderr


def test_observer_and_controller_warn_when_the_plants_span_differs(rigs):
    """A live rig whose plant runs 55 m spans while observer and controller assume 65 m."""
    rig = rigs("span", duration=0.5, timing_mode="lockstep", params={"plant": {"span_length": 55.0}})
    rig.start()
    rig.wait_finished(timeout=120)
    rig.stop()
    for name in ("observer", "controller"):
        log = rig.processes[name].log_path.read_text()
        assert "the plant runs the lumped line with 55 m spans but this node assumes span_length 65 m" in log


# -- 9. an out-of-range domain id ------------------------------------------------------------------------


@pytest.mark.offline
def test_ros2_node_list_in_an_impossible_domain_is_one_line():
    env = {**node_env(), "ROS_DOMAIN_ID": "300"}
    one_line(ros2("node", "list", env=env), 2, "ROS_DOMAIN_ID='300' is out of range")


@pytest.mark.unit
def test_make_demo_uses_an_exported_domain_id(monkeypatch):
    from pac_experiments.demo import free_domain

    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    with free_domain() as domain_id:
        assert domain_id == 42
    monkeypatch.setenv("ROS_DOMAIN_ID", "300")
    with pytest.raises(UsageError, match="out of range"):
        free_domain()
    monkeypatch.delenv("ROS_DOMAIN_ID")
    with free_domain() as domain_id:  # none exported: a free one, reserved
        assert 0 <= domain_id <= 232


# -- 10. diagnostics that describe what is there ---------------------------------------------------------


@pytest.mark.offline
@pytest.mark.slow
def test_tools_describe_a_directory_that_is_not_a_bag_the_same_way(tmp_path):
    env = node_env()
    folder = tmp_path / "notabag"
    folder.mkdir()
    (folder / "notes.txt").write_text("hello\n")
    text = tmp_path / "notes.mcap"
    text.write_text("not an mcap file\n")
    with pytest.raises(BagError, match="not an MCAP file"):
        read_bag(text)
    lines = set()
    for tool in (["pac_analysis", "info"], ["pac_analysis", "recover"], ["pac_rig", "replay"]):
        proc = ros2(
            "run", *tool, str(folder), *(["--out", str(tmp_path / "r")] if "recover" in tool else []), env=env
        )
        line = one_line(proc, 1, "not a bag (no .mcap file)")
        lines.add(line.split(": ", 1)[1])
    report = ros2("run", "pac_analysis", "report", str(folder), "--out", str(tmp_path / "rep"), env=env)
    lines.add(one_line(report, 1, "not a bag").split(": ", 1)[1])
    assert len(lines) == 1, lines
    one_line(ros2("run", "pac_analysis", "info", str(text), env=env), 1, "notes.mcap is not an MCAP file")


@pytest.mark.offline
@pytest.mark.slow
def test_bag_info_counts_missing_ticks_only_on_per_tick_topics(tmp_path):
    env = node_env()
    bag = tmp_path / "bag"
    assert simulate(str(bag), "-p", "duration:=0.2", env=env).returncode == 0
    info = ros2("bag", "info", str(bag), env=env)
    assert info.returncode == 0, info.stderr
    row = next(line.split() for line in info.stdout.splitlines() if line.startswith("run_status"))
    assert row[4] == "-" and row[5] == "0", row  # ticks column "-", missing 0


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
