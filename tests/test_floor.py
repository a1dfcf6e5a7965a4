"""The floor rig (relay nodes), real-time priorities and their refusal. No timing asserted."""

import os
import re
import shutil
import subprocess
import time

import numpy as np
import pytest
from conftest import assert_bag_holds_every_message_published

from pac_bag.reader import read_bag
from pac_common import messages
from pac_controller.parameters import ControllerParameters
from pac_rig.launcher import NODES, REALTIME_PRIORITIES

pytestmark = pytest.mark.live

NO_SYS_NICE = "setpriv --bounding-set=-sys_nice"


def ticks_of(bag, topic):
    return np.unique(bag.topics[topic]["tick"])


def logs(rig):
    return {n: p.log()[-800:] for n, p in rig.processes.items()}


def can_use_fifo() -> bool:
    """SCHED_FIFO allowed here (tested in a child, so this process keeps its policy)."""
    code = "import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))"
    return subprocess.run(["python3", "-c", code], capture_output=True).returncode == 0


def thread_policies(pid: int) -> set[int]:
    out = set()
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            out.add(os.sched_getscheduler(int(tid)))
        except OSError:
            pass  # a thread that just ended
    return out


def test_floor_rig_runs_and_records_every_tick(rigs):
    """The relay nodes keep the real nodes' wiring: the run ends by itself, every plant tick and
    every answer the relays published is in the bag; with the launcher's priorities where the
    machine allows them, every thread of every node is SCHED_FIFO (Fast DDS's included)."""
    duration = 3.0
    rig = rigs("floor", duration=duration, relay=True)
    rig.start()
    fifo = can_use_fifo()
    if fifo:
        for name, proc in rig.processes.items():
            line = f"SCHED_FIFO priority {REALTIME_PRIORITIES[name]}"
            deadline = time.monotonic() + 60.0
            while line not in proc.log() and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            if proc.poll() is None:  # the plant may be done already on a fast machine
                assert thread_policies(proc.popen.pid) == {os.SCHED_FIFO}, name
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == dict.fromkeys(NODES, 0), logs(rig)
    for name, proc in rig.processes.items():
        line = f"SCHED_FIFO priority {REALTIME_PRIORITIES[name]}" if fifo else "refused"
        assert line in proc.log(), (name, proc.log()[-800:])
    bag = read_bag(rig.bag_path)
    n = int(duration * 1000)
    for topic in ("measurement", "plant_truth"):
        np.testing.assert_array_equal(ticks_of(bag, topic), np.arange(n), err_msg=topic)
    assert_bag_holds_every_message_published(bag, {n: p.log() for n, p in rig.processes.items()})
    assert ticks_of(bag, "command")[-1] == n - 1  # the run's last command is in the bag
    # A relay's physics is nothing: zero estimates, zero answers (it is not the real core); a
    # watchdog fallback command carries the fallback force, as the real controller's does.
    assert not np.any(bag.topics["estimate"]["theta_hat"])
    command = bag.topics["command"]
    fallback = command["mode"] == messages.MODES["fallback"]
    assert not np.any(command["u"][~fallback])
    assert np.all(command["u"][fallback] == ControllerParameters().fallback_force)


def test_floor_lockstep_answers_every_tick(rigs):
    rig = rigs("floor_lockstep", duration=1.0, timing_mode="lockstep", relay=True)
    rig.start()
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == dict.fromkeys(NODES, 0), logs(rig)
    bag = read_bag(rig.bag_path)
    for topic in ("measurement", "plant_truth", "estimate", "command"):
        np.testing.assert_array_equal(ticks_of(bag, topic), np.arange(1000), err_msg=topic)
    # Lock step runs flat out: the launcher asks for no real-time priority (it would starve the recorder).
    for name, proc in rig.processes.items():
        log = proc.log()
        assert "SCHED_FIFO" not in log and not re.search(r"realtime_priority \d+ refused", log), name


@pytest.mark.skipif(shutil.which("setpriv") is None, reason="needs setpriv (util-linux)")
def test_refused_realtime_priority_warns_once_and_runs(rigs):
    """Without CAP_SYS_NICE the launcher's SCHED_FIFO request is refused: one warning line per
    node, which runs with normal scheduling; the run and its bag are complete."""
    if subprocess.run([*NO_SYS_NICE.split(), "true"], capture_output=True).returncode != 0:
        pytest.skip("setpriv cannot drop CAP_SYS_NICE here")
    duration = 2.0
    rig = rigs("refused", duration=duration, prefix=NO_SYS_NICE)
    rig.start()
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == dict.fromkeys(NODES, 0), logs(rig)
    for name, proc in rig.processes.items():
        log = proc.log()
        warnings = [line for line in log.splitlines() if re.search(r"realtime_priority \d+ refused", line)]
        assert len(warnings) == 1, (name, log[-800:])
        assert f"realtime_priority {REALTIME_PRIORITIES[name]} refused" in warnings[0]
        assert "normal scheduling" in warnings[0]
        assert "SCHED_FIFO priority" not in log
    bag = read_bag(rig.bag_path)
    for topic in ("measurement", "plant_truth"):
        np.testing.assert_array_equal(ticks_of(bag, topic), np.arange(int(duration * 1000)), err_msg=topic)


def test_composed_lockstep_equals_offline_simulation_bit_for_bit(rigs, tmp_path):
    """The three loop nodes in one process (one executor) are the same nodes: a lock-step run
    equals the offline simulator bit for bit, every tick on every topic."""
    from conftest import assert_lockstep_equals_offline

    duration = 2.0
    rig = rigs("composed", duration=duration, timing_mode="lockstep", composed=True)
    rig.start()
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == {"recorder": 0, "loop": 0}, logs(rig)
    assert_lockstep_equals_offline(rig.bag_path, {"duration": duration}, tmp_path / "offline")


def test_composed_realtime_records_every_tick(rigs):
    duration = 2.0
    rig = rigs("composed_rt", duration=duration, composed=True)
    rig.start()
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == {"recorder": 0, "loop": 0}, logs(rig)
    bag = read_bag(rig.bag_path)
    for topic in ("measurement", "plant_truth"):
        np.testing.assert_array_equal(ticks_of(bag, topic), np.arange(int(duration * 1000)), err_msg=topic)
    assert ticks_of(bag, "command")[-1] == duration * 1000 - 1
