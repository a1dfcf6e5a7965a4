"""The ros2 stand-in's daily verbs against a live rig (called by path, not via PATH).

The rig (plant in real time at 200 Hz, observer, controller) runs in its own ROS domain for the
module; every process it starts is stopped at teardown, pass or fail.
"""

import concurrent.futures
import fcntl
import os
import pty
import re
import signal
import struct
import subprocess
import termios
import time

import numpy as np
import pytest
import yaml
from conftest import ROS2

from pac_bag.reader import read_bag
from pac_bag.typestore import interface_dir
from pac_rig.configs import defaults_yaml
from pac_rig.launcher import Rig, node_env
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.offline

RATE_HZ = 200.0
TYPES = {
    "/measurement": "pac_interfaces/msg/FrameMeasurement",
    "/plant_truth": "pac_interfaces/msg/PlantTruth",
    "/estimate": "pac_interfaces/msg/ObserverEstimate",
    "/command": "pac_interfaces/msg/ActuatorCommand",
}


def ros2(env, *args, timeout=60):
    return subprocess.run([ROS2, *args], capture_output=True, text=True, env=env, timeout=timeout)


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    """(env, rig): a rig running until stopped, in a domain reserved for this module (its users
    are live tests: conftest.LIVE_FIXTURES)."""
    import domain_coordinator

    tmp = tmp_path_factory.mktemp("cli")
    with domain_coordinator.domain_id() as did:
        rig = Rig(
            tmp / "unused_bag",
            duration=0.0,  # runs until stopped
            domain_id=did,
            log_dir=tmp / "logs",
            record=False,
            params={"all": {"rate_hz": RATE_HZ}},
        )
        try:
            rig.start()
            deadline = time.monotonic() + 60
            while "real-time loop running" not in rig.processes["plant"].log():
                assert time.monotonic() < deadline, rig.processes["plant"].log()
                assert all(p.poll() is None for p in rig.processes.values())
                time.sleep(0.05)
            yield node_env(did), rig
        finally:
            rig.stop(grace=5.0)
            assert all(p.poll() is not None for p in rig.processes.values())


def test_topic_list_and_info(live):
    env, _ = live
    listed = ros2(env, "topic", "list", "-t")
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.splitlines()
    for topic, typename in TYPES.items():
        assert f"{topic} [{typename}]" in lines
    plain = ros2(env, "topic", "list").stdout.splitlines()
    assert set(TYPES) <= set(plain) and all(" " not in line for line in plain)

    info = ros2(env, "topic", "info", "measurement")  # relative names resolve against /
    assert info.returncode == 0, info.stderr
    assert info.stdout.splitlines() == [
        "Type: pac_interfaces/msg/FrameMeasurement",
        "Publisher count: 1",
        "Subscription count: 1",
    ]
    verbose = ros2(env, "topic", "info", "/estimate", "-v").stdout
    assert "Node name: observer_node" in verbose and "Node name: controller_node" in verbose
    assert "Reliability: RELIABLE" in verbose and "Reliability: BEST_EFFORT" in verbose

    missing = ros2(env, "topic", "info", "/no_such_topic")
    assert missing.returncode == 1 and len(missing.stderr.strip().splitlines()) == 1


def test_node_list_and_info(live):
    env, _ = live
    nodes = ros2(env, "node", "list")
    assert nodes.returncode == 0, nodes.stderr
    assert nodes.stdout.splitlines() == ["/controller_node", "/observer_node", "/plant_node"]
    info = ros2(env, "node", "info", "/plant_node")
    assert info.returncode == 0, info.stderr
    text = info.stdout
    assert text.startswith("/plant_node\n  Subscribers:\n    /command: pac_interfaces/msg/ActuatorCommand\n")
    publishers = text.split("  Publishers:\n")[1].split("  Service Servers:")[0]
    assert "    /measurement: pac_interfaces/msg/FrameMeasurement\n" in publishers
    assert "    /plant_truth: pac_interfaces/msg/PlantTruth\n" in publishers
    assert "/plant_node/set_parameters: rcl_interfaces/srv/SetParameters" in text


def test_topic_echo(live):
    env, _ = live
    once = ros2(env, "topic", "echo", "/estimate", "--once", "--timeout", "20")
    assert once.returncode == 0, once.stderr
    assert once.stdout.endswith("---\n") and once.stdout.count("---\n") == 1
    msg = yaml.safe_load(once.stdout.removesuffix("---\n"))
    assert list(msg) == [
        "header", "tick", "z_hat", "theta_hat", "stiffness_hat", "contact_force_hat",
        "innovation", "status", "rejected_measurements", "reinitialisations", "actuator_force",
    ]  # fmt: skip
    assert len(msg["z_hat"]) == 4 and len(msg["theta_hat"]) == 3
    assert set(msg["header"]["stamp"]) == {"sec", "nanosec"}
    assert np.isfinite(msg["stiffness_hat"]) and msg["stiffness_hat"] > 0

    csv = ros2(env, "topic", "echo", "command", "--csv", "-n", "3", "--timeout", "20")
    assert csv.returncode == 0, csv.stderr
    rows = [line.split(",") for line in csv.stdout.splitlines()]
    # sec, nanosec, frame_id, tick, u, u_unsaturated, F_r, e1, e2, e3, saturated, mode, estimate age
    assert len(rows) == 3 and all(len(r) == 13 for r in rows)
    ticks = [int(r[3]) for r in rows]
    assert ticks == sorted(ticks) and len(set(ticks)) == 3

    field = ros2(env, "topic", "echo", "/command", "--field", "u", "-n", "2", "--timeout", "20")
    assert field.returncode == 0, field.stderr
    values = [float(v) for v in field.stdout.split("---\n") if v.strip()]
    assert len(values) == 2 and all(np.isfinite(values))
    bad = ros2(env, "topic", "echo", "/command", "--field", "no_such_field", "--once", "--timeout", "20")
    assert bad.returncode == 2 and "no_such_field" in bad.stderr

    nobody = ros2(
        env, "topic", "echo", "/nobody", "pac_interfaces/msg/FrameMeasurement", "--once", "--timeout", "1"
    )
    assert nobody.returncode == 1 and len(nobody.stderr.strip().splitlines()) == 1


def test_topic_hz(live):
    env, _ = live
    hz = ros2(env, "topic", "hz", "/measurement", "--duration", "3.5")
    assert hz.returncode == 0, hz.stderr
    reports = re.findall(
        r"average rate: ([\d.]+)\n\tmin: [\d.]+s max: [\d.]+s std dev: [\d.]+s window: (\d+)\n", hz.stdout
    )
    assert len(reports) >= 2, hz.stdout
    windows = [int(w) for _, w in reports]
    assert windows == sorted(windows)  # the window grows up to --window
    rate = float(reports[-1][0])
    print(f"\nros2 topic hz /measurement: {rate:.1f} Hz (plant at {RATE_HZ:g} Hz)")
    assert 0.8 * RATE_HZ < rate < 1.2 * RATE_HZ  # what is measured is the publisher's rate


def test_param_dump_and_a_node_that_is_not_there(live):
    env, rig = live
    dump = ros2(env, "param", "dump", "/controller_node")
    assert dump.returncode == 0, dump.stderr
    dumped = yaml.safe_load(dump.stdout)["/controller_node"]["ros__parameters"]
    declared = yaml.safe_load(defaults_yaml("controller"))["/**"]["ros__parameters"]
    expected = {**declared, **rig.params["controller"]}
    for name, value in expected.items():
        assert dumped[name] == pytest.approx(value), name

    start = time.monotonic()
    absent = ros2(env, "param", "set", "/not_running", "c1", "30.0")
    elapsed = time.monotonic() - start
    print(f"\nros2 param set on an absent node answered in {elapsed:.2f} s")
    assert absent.returncode == 1
    assert absent.stderr.strip().splitlines() == [absent.stderr.strip()] and "not found" in absent.stderr


def test_interface_show():
    env = node_env()
    shown = ros2(env, "interface", "show", "pac_interfaces/msg/ObserverEstimate")
    assert shown.returncode == 0, shown.stderr
    lines = shown.stdout.splitlines()
    top = [line for line in lines if not line.startswith("\t")]
    assert top == (interface_dir() / "ObserverEstimate.msg").read_text().splitlines()
    header = lines.index("std_msgs/Header header")
    assert lines[header + 1 : header + 5] == [
        "\tbuiltin_interfaces/Time stamp",
        "\t\tint32 sec",
        "\t\tuint32 nanosec",
        "\tstring frame_id",
    ]
    short = ros2(env, "interface", "show", "pac_interfaces/ObserverEstimate", "--no-comments")
    assert short.returncode == 0 and "#" not in short.stdout and "float64[3] theta_hat" in short.stdout
    assert "pac_interfaces/msg/PlantTruth" in ros2(env, "interface", "package", "pac_interfaces").stdout
    unknown = ros2(env, "interface", "show", "pac_interfaces/msg/Nothing")
    assert unknown.returncode == 1 and len(unknown.stderr.strip().splitlines()) == 1


def test_bag_info_play_and_record(tmp_path, domain_id):
    env = node_env(domain_id)
    original = tmp_path / "original"
    simulate_to_bag(scenario_from_flat({"duration": 0.5}), original)
    info = ros2(env, "bag", "info", str(original))
    assert info.returncode == 0, info.stderr
    assert re.search(r"measurement\s+pac_interfaces/msg/FrameMeasurement\s+500\b", info.stdout), info.stdout

    copy = tmp_path / "copy"
    log = tmp_path / "record.log"
    with open(log, "wb") as out:
        recorder = subprocess.Popen(
            [ROS2, "bag", "record", "-o", str(copy), "/measurement", "/command"],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
        )
    try:
        play = ros2(
            env,
            "bag",
            "play",
            str(original),
            "--topics",
            "measurement",
            "command",
            "--wait-for",
            "1",
            "-r",
            "1",
        )
        assert play.returncode == 0, play.stderr
        assert "published 1000 messages" in play.stderr
        time.sleep(2.0)  # let the last samples arrive: this is delivery time, not synchronisation
        recorder.send_signal(signal.SIGINT)
        assert recorder.wait(timeout=20) == 0, log.read_text()
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait()
    source, copied = read_bag(original), read_bag(copy)
    assert sorted(copied.topics) == ["command", "measurement"]
    for topic, field in (("measurement", "z1"), ("command", "u")):
        np.testing.assert_array_equal(copied.topics[topic]["tick"], source.topics[topic]["tick"])
        np.testing.assert_array_equal(copied.topics[topic][field], source.topics[topic][field])

    nothing = ros2(env, "bag", "record", "-o", str(tmp_path / "x"))
    assert nothing.returncode == 2 and len(nothing.stderr.strip().splitlines()) == 1


def test_unknown_verbs_and_subcommands_say_so_in_one_line():
    env = node_env()
    for args in (["frobnicate"], ["topic", "pub", "/x"], ["node", "kill"], ["bag", "convert"]):
        out = ros2(env, *args)
        assert out.returncode == 2, args
        assert len(out.stderr.strip().splitlines()) == 1 and out.stdout == "", (args, out.stderr)


#: Executables that are ROS nodes (run_node): their --help belongs to the node base class.
NODE_EXECUTABLES = {"plant_node", "observer_node", "controller_node", "recorder", "live_view"}


@pytest.mark.slow
def test_every_pac_tool_answers_help_with_its_usage():
    env = node_env()
    listed = ros2(env, "pkg", "executables").stdout.split("\n")
    tools = [line.split() for line in listed if line.startswith("pac_")]
    tools = [(pkg, exe) for pkg, exe in tools if exe not in NODE_EXECUTABLES]
    assert {"simulate", "replay", "info", "report", "demo", "sweep", "reproduce"} <= {e for _, e in tools}
    # One process per tool, as many at once as there are cores (each spends its time importing).
    with concurrent.futures.ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        answers = pool.map(lambda tool: ros2(env, "run", *tool, "--help"), tools)
        for (pkg, exe), out in zip(tools, answers, strict=True):
            answered = out.returncode == 0 and out.stdout.startswith(f"usage: {exe}")
            assert answered, (pkg, exe, out.stderr[-300:])


@pytest.mark.slow
def test_simulate_shows_progress_on_a_terminal_only(tmp_path):
    env = node_env()
    cmd = [ROS2, "run", "pac_rig", "simulate", "-p", "duration:=1.0"]
    piped = subprocess.run(
        [*cmd[:4], str(tmp_path / "piped"), *cmd[4:]], capture_output=True, text=True, env=env
    )
    assert piped.returncode == 0, piped.stderr
    assert "%|" not in piped.stderr and "tick" not in piped.stderr  # quiet in logs and pipes

    master, slave = pty.openpty()
    # A new pty is 0 columns wide, and tqdm draws nothing in no width: give it a terminal's size.
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    proc = subprocess.Popen(
        [*cmd[:4], str(tmp_path / "tty"), *cmd[4:]], stdout=subprocess.DEVNULL, stderr=slave, env=env
    )
    os.close(slave)
    chunks = []
    try:
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:  # EIO: the child closed its terminal
                break
            if not data:
                break
            chunks.append(data)
        assert proc.wait(timeout=120) == 0
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    shown = b"".join(chunks).decode(errors="replace")
    assert "%|" in shown and "tick" in shown, shown
