"""A ROS 2 user's habits on the nodes: one-line refusals, --help, and runs that end."""

import subprocess
import time

import numpy as np
import pytest
from conftest import ROS2, stop
from mcap_ros2.reader import read_ros2_messages

from pac_common.node import MAX_DOMAIN_ID
from pac_rig.configs import parameter_sets
from pac_rig.launcher import NODES, node_env

pytestmark = pytest.mark.live


def run_node(
    node: str, *args: str, env: dict[str, str], timeout: float = 60.0
) -> subprocess.CompletedProcess:
    pkg, exe = NODES[node].package, NODES[node].executable
    return subprocess.run(
        [ROS2, "run", pkg, exe, *args], capture_output=True, text=True, timeout=timeout, env=env
    )


def one_line_refusal(proc: subprocess.CompletedProcess, *needles: str) -> str:
    """Exit 2, exactly one line on stderr (no traceback), naming every needle."""
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.mark.parametrize("node", list(NODES))
def test_help_lists_every_parameter_and_exits_0(domain_id, node):
    proc = run_node(node, "--help", env=node_env(domain_id))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"usage: {NODES[node].executable}")
    for cls in parameter_sets(node):
        for spec in cls.specs():
            assert f"{spec.name} (default" in proc.stdout, spec.name


def test_a_typo_in_a_parameter_name_is_refused(domain_id, tmp_path):
    env = node_env(domain_id)
    one_line_refusal(run_node("controller", "--ros-args", "-p", "c11:=3", env=env), "'c11'", "unknown")
    params = tmp_path / "typo.yaml"
    params.write_text("/**:\n  ros__parameters:\n    rho_zz: 40.0\n")
    one_line_refusal(run_node("observer", "--ros-args", "--params-file", str(params), env=env), "'rho_zz'")
    # ROS parameters outside --ros-args would be ignored by rclpy: refused instead
    one_line_refusal(run_node("controller", "-p", "c1:=3", env=env), "'-p'", "--ros-args")


def test_bad_command_lines_give_one_line_and_exit_2(domain_id, tmp_path):
    env = node_env(domain_id)
    missing = tmp_path / "nope.yaml"
    one_line_refusal(
        run_node("controller", "--ros-args", "--params-file", str(missing), env=env), str(missing)
    )
    malformed = tmp_path / "bad.yaml"
    malformed.write_text("a: [b\n")
    one_line_refusal(
        run_node("controller", "--ros-args", "--params-file", str(malformed), env=env), str(malformed), "YAML"
    )
    one_line_refusal(run_node("controller", "--ros-args", "-p", "c1:=", env=env), "c1:=")
    out_of_range = dict(env, ROS_DOMAIN_ID=str(MAX_DOMAIN_ID + 1))
    one_line_refusal(run_node("plant", env=out_of_range), f"ROS_DOMAIN_ID='{MAX_DOMAIN_ID + 1}'", "[0, 232]")
    unwritable = "/proc/nope/bag"
    one_line_refusal(
        run_node("recorder", "--ros-args", "-p", f"bag_path:={unwritable}", env=env), "'bag_path'", unwritable
    )


def test_an_unknown_parameter_is_refused_by_name_at_run_time(domain_id):
    env = node_env(domain_id)
    node = subprocess.Popen(
        [ROS2, "run", "pac_controller", "controller_node"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while (
            "controller_node"
            not in subprocess.run(
                [ROS2, "node", "list"], capture_output=True, text=True, timeout=60, env=env
            ).stdout
        ):
            assert time.monotonic() < deadline and node.poll() is None, "controller_node never appeared"
        proc = subprocess.run(
            [ROS2, "param", "set", "controller_node", "c11", "3.0"],
            capture_output=True,
            text=True,
            timeout=60,
            env=env,
        )
        assert proc.returncode != 0 and "c11" in proc.stdout + proc.stderr, (proc.stdout, proc.stderr)
        assert "no such parameter" in proc.stdout + proc.stderr
    finally:
        stop(node, timeout=10)


def test_the_by_hand_recipe_ends_by_itself(domain_id, tmp_path):
    """docs/usage.md's recipe: four `ros2 run`, plant 3 s in real time, the others asked to stop
    after the run.

    Everything exits 0 by itself, and the bag's last command answers the plant's last tick
    (no fallback tail after the run: the controller went idle)."""
    env = node_env(domain_id)
    bag = tmp_path / "by_hand"
    follow = ["-p", "stop_after_run:=true"]
    commands = {
        "recorder": ["--ros-args", "-p", f"bag_path:={bag}", *follow],
        "observer": ["--ros-args", *follow],
        "controller": ["--ros-args", *follow],
        "plant": ["--ros-args", "-p", "duration:=3.0", "-p", "wait_for_recorder:=true"],
    }
    procs = {}
    try:
        for name, args in commands.items():
            pkg, exe = NODES[name].package, NODES[name].executable
            procs[name] = subprocess.Popen(
                [ROS2, "run", pkg, exe, *args],
                env=env,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
            )
        codes = {name: proc.wait(timeout=90) for name, proc in procs.items()}
        logs = {name: proc.stdout.read() for name, proc in procs.items()}
        assert codes == dict.fromkeys(commands, 0), logs
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    plant_rate = next(s for c in parameter_sets("plant") for s in c.specs() if s.name == "rate_hz").default
    last_tick = int(round(3.0 * plant_rate)) - 1
    (mcap_file,) = bag.glob("*.mcap")
    ticks = {}
    for item in read_ros2_messages(str(mcap_file)):
        if hasattr(item.ros_msg, "tick"):  # the loop's topics and run_status; not /diagnostics
            ticks.setdefault(item.channel.topic.lstrip("/"), []).append(int(item.ros_msg.tick))
    assert max(ticks["measurement"]) == last_tick
    assert max(ticks["command"]) == last_tick, "the run's last command answers the plant's last tick"
    assert np.unique(ticks["plant_truth"]).size == last_tick + 1
