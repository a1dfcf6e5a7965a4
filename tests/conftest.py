"""Shared fixtures and helpers of the tests, and their kinds.

Every test that touches DDS gets its own ROS domain and cleans up its processes.  Every test
has a kind (pytest.ini): ``unit``, ``offline`` or ``live``, set per module with
``pytestmark = pytest.mark.<kind>`` (or on a test); a test that uses a fixture that starts ROS
processes (``domain_id``, ``rigs``, test_cli's ``live``: LIVE_FIXTURES) is ``live`` whatever its
module says.  ``slow`` (beside the kind) marks a unit or offline test that takes seconds: a tool
started as a process, a Dask cluster, a long simulation.  ``make test-fast`` runs
``unit or offline`` without ``live`` and without ``slow`` (under a minute); ``make test`` runs
them all.
"""

import atexit
import contextlib
import os
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # also for anything imported below
# Whole lines' dropper lengths (pac_plant.catenary.line_cache) in this test process's own directory:
# no test reads what other runs left there; each line is solved once per test process.
_LINE_CACHE = tempfile.mkdtemp(prefix="pac-line-cache-")
os.environ["PAC_LINE_CACHE"] = _LINE_CACHE
atexit.register(shutil.rmtree, _LINE_CACHE, True)


def node_stats(log: str, node: str) -> dict:
    """A node's end-of-run counters: its ``pac-stats {json}`` line in ``log`` (the process's output).

    Tests read the counters from this line, never from the nodes' prose (which may be reworded)."""
    from pac_common.diagnostics import parse_stats

    stats = parse_stats(log)
    assert node in stats, f"no pac-stats line of {node} in:\n{log[-2000:]}"
    return stats[node]


@pytest.fixture
def domain_id():
    """A ROS_DOMAIN_ID no other test (or test run) on this machine holds."""
    import domain_coordinator

    with domain_coordinator.domain_id() as did:
        yield did


@pytest.fixture
def rigs(domain_id, tmp_path):
    """Factory of rigs in this test's domain; every process is stopped at teardown, pass or fail."""
    from pac_rig.launcher import Rig

    made = []

    def make(name="run", **kwargs):
        rig = Rig(tmp_path / name, domain_id=domain_id, log_dir=tmp_path / f"{name}_logs", **kwargs)
        made.append(rig)
        return rig

    yield make
    for rig in made:
        rig.stop(grace=5.0)
        assert all(p.poll() is not None for p in rig.processes.values())


# -- test kinds --------------------------------------------------------------------------------
KINDS = ("unit", "offline", "live")
#: Fixtures that start ROS processes over DDS: a test that uses one is live.
LIVE_FIXTURES = ("domain_id", "rigs", "live")


@pytest.hookimpl(tryfirst=True)  # before -m selects on the markers
def pytest_collection_modifyitems(config, items):
    unmarked = []
    for item in items:
        kinds = {m.name for m in item.iter_markers() if m.name in KINDS}
        if set(LIVE_FIXTURES) & set(getattr(item, "fixturenames", ())) and "live" not in kinds:
            item.add_marker(pytest.mark.live)
            kinds.add("live")
        if not kinds:
            unmarked.append(item.nodeid)
    if unmarked:
        raise pytest.UsageError(
            "tests without a kind (add `pytestmark = pytest.mark.unit|offline|live` to the module, "
            "see pytest.ini): " + ", ".join(unmarked)
        )


# -- helpers shared by several test modules ------------------------------------------------------
#: The repository's root (the tests' parent folder).
ROOT = Path(__file__).resolve().parents[1]


#: The project's ``ros2`` (the workspace's environment set up, as the README runs it).
ROS2 = str(ROOT / "scripts" / "bin" / "ros2")


def ros2(*args: str, env: dict[str, str], timeout: float = 120.0, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([ROS2, *args], capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd)


def one_line(proc: subprocess.CompletedProcess, code: int, *needles: str) -> str:
    """Exit ``code``, exactly one line on stderr (no traceback), naming every needle."""
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == code and len(lines) == 1 and "Traceback" not in proc.stderr, (
        proc.returncode,
        proc.stderr,
    )
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def stop(proc: subprocess.Popen, timeout: float = 30.0) -> int:
    """Stop a process this test started, by its PID: SIGINT, then SIGKILL after ``timeout``."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
    return proc.wait()


@pytest.fixture
def processes():
    """Popen objects started by the test; each is stopped (:func:`stop`) by PID, pass or fail."""
    started: list[subprocess.Popen] = []
    yield started
    for proc in started:
        stop(proc)


def repository_files(*patterns: str) -> list[Path]:
    """The repository's files matching git pathspecs ``patterns``, tracked or new, not ignored
    (build outputs and bags are not the project's text)."""
    out = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", *patterns],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return [ROOT / f for f in out if (ROOT / f).is_file()]


#: The physics fields of each loop topic (what a lock-step run and the offline simulator share).
PHYSICS = {
    "measurement": ["z1", "z2", "actuator_force"],
    "plant_truth": ["z", "stiffness", "contact_force", "in_contact", "u_applied", "applied_command_tick"],
    "estimate": ["z_hat", "theta_hat", "stiffness_hat", "contact_force_hat", "innovation"],
    "command": ["u", "u_unsaturated", "force_reference", "tracking_error", "saturated", "mode"],
}


def first_per_tick(topic):
    """(ticks, index of each tick's first message) of a topic read from a bag."""
    ticks, idx = np.unique(topic["tick"], return_index=True)
    return ticks, idx


def assert_bag_holds_every_message_published(bag, logs: dict[str, str]) -> tuple[dict, dict]:
    """Every estimate and command the observer and the controller published is in the bag (their
    ``pac-stats`` counters from ``logs``: role -> process output), each answered tick once:

    - their answers, and their answers again to a re-sent sample (the plant re-sends tick 0 until
      the loop answers: a CI run had tick 0's command twice);
    - the controller's fallback commands: its watchdog's (no fresh estimate in time, which a
      starved host gives: a loaded CI host had 1411 commands for 1405 answers) and those answering
      a refused estimate.

    Returns the two nodes' counters."""
    from pac_common import messages

    observer = node_stats(logs["observer"], "observer_node")
    controller = node_stats(logs["controller"], "controller_node")
    estimates = bag.topics["estimate"]["tick"]
    assert estimates.size == observer["processed"] + observer["answered_again"], observer
    assert np.unique(estimates).size == observer["processed"], observer
    command = bag.topics["command"]
    fallback = command["mode"] == messages.MODES["fallback"]
    assert np.count_nonzero(fallback) == controller["fallback_commands"] + controller["refused"], controller
    assert np.count_nonzero(~fallback) == controller["sent"] + controller["answered_again"], controller
    assert np.unique(command["tick"][~fallback]).size == controller["sent"], controller
    return observer, controller


def assert_lockstep_equals_offline(
    bag_path: Path, values: dict, offline_path: Path, columns: dict[str, list[str]] = PHYSICS
) -> dict:
    """A lock-step run's bag equals the offline simulator's run of the same scenario (``values``)
    bit for bit: every tick of the run, in order, on each topic of ``columns`` (a re-sent sample
    is recorded twice: its first copy counts). Returns the offline bag's topics."""
    from pac_bag.reader import read_bag
    from pac_rig.simulate import scenario_from_flat, simulate_to_bag

    scenario = scenario_from_flat(values)
    simulate_to_bag(scenario, offline_path)
    live, offline = read_bag(bag_path).topics, read_bag(offline_path).topics
    for topic, names in columns.items():
        ticks, idx = first_per_tick(live[topic])
        np.testing.assert_array_equal(ticks, np.arange(scenario.loop.ticks), err_msg=topic)
        for column in names:
            np.testing.assert_array_equal(
                np.asarray(live[topic][column])[idx], offline[topic][column], err_msg=f"{topic}.{column}"
            )
    return offline


def lockstep_run_equals_offline(rigs, name: str, params: dict, values: dict, offline_path: Path) -> Path:
    """Run the four processes in lock step for ``values['duration']`` with the nodes' ``params``;
    every process must exit 0 and the bag equal the offline simulator's run of ``values`` bit for
    bit (:func:`assert_lockstep_equals_offline`). Returns the bag's path."""
    from pac_rig.launcher import NODES

    rig = rigs(name, duration=values["duration"], timing_mode="lockstep", params=params)
    rig.start()
    rig.wait_finished(timeout=120)
    assert rig.exit_codes() == dict.fromkeys(NODES, 0), {n: p.log()[-500:] for n, p in rig.processes.items()}
    assert_lockstep_equals_offline(rig.bag_path, values, offline_path)
    return rig.bag_path


def assert_simulate_refuses_the_file(
    tmp_path: Path, capsys, parameter: str, text: str | None, expected: str, *args: str
) -> None:
    """``simulate -p PARAMETER:=FILE ARGS`` with FILE holding ``text`` (None: no such file) exits 2 with
    one line naming the parameter and the file and saying ``expected``, and writes no bag."""
    from pac_rig import simulate

    path = tmp_path / f"{parameter}.py"
    if text is not None:
        path.write_text(text)
    code = simulate.main([str(tmp_path / "bag"), "-p", f"{parameter}:={path}", *args])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"simulate: invalid parameter '{parameter}' = '{path}'"), lines
    assert expected in lines[0], lines
    assert not (tmp_path / "bag").exists()


def assert_imported_once_and_an_edit_refused(path: Path, text: str, load) -> None:
    """A user's file (``text`` written to ``path``) is imported once per process by ``load``, and an
    edit after that is refused (what it defines is fixed for a run; pac_common.user_file)."""
    from pac_common.parameters import ParameterError

    path.write_text(text)
    first = load(str(path))
    assert load(str(path)) is first
    path.write_text(text + "\n# edited\n")
    with pytest.raises(ParameterError, match="its text changed since this process imported it"):
        load(str(path))


def assert_starts_and_stops_cleanly(
    cmd: list[str], ready_text: str, env: dict[str, str], log: Path, stop: int = signal.SIGINT
) -> str:
    """Start ``cmd``, wait until its log shows ``ready_text``, send it ``stop``: it must exit 0.
    Its log, which a failure shows.

    The process is killed on any failure, so nothing outlives the test.
    """
    with open(log, "wb") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=env)
    try:
        deadline = time.monotonic() + 30
        while ready_text not in log.read_text() and time.monotonic() < deadline:
            assert proc.poll() is None, log.read_text()
            time.sleep(0.05)
        assert ready_text in log.read_text()
        proc.send_signal(stop)
        assert proc.wait(timeout=20) == 0, log.read_text()
        return log.read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@contextlib.contextmanager
def parameter_tester(domain_id: int, procs: dict[str, subprocess.Popen]):
    """A test node in its own rclpy context in ``domain_id`` and ``call(future)``, which spins it
    until the future is done (10 s) and returns the result. On exit, pass or fail: the node and
    its context are gone and every process of ``procs`` is stopped (SIGINT, killed after 15 s).

    The nodes must outlive the calls: a plant ends its process when its run ends (10 s by
    default), so start it with ``duration:=0`` (until stopped)."""
    import rclpy
    import rclpy.executors

    try:
        context = rclpy.Context()
        rclpy.init(context=context, domain_id=domain_id)
        node = rclpy.create_node("tester", context=context)
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        executor.add_node(node)

        def call(future):
            executor.spin_until_future_complete(future, timeout_sec=10)
            ended = {name: p.returncode for name, p in procs.items() if p.poll() is not None}
            assert future.done(), f"no answer within 10 s; processes ended (exit status): {ended}"
            return future.result()

        try:
            yield node, call
        finally:
            node.destroy_node()
            rclpy.shutdown(context=context)
    finally:
        for p in procs.values():
            p.send_signal(signal.SIGINT)
        for p in procs.values():
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def simulate_refusal(bag: Path, *overrides: str) -> str:
    """``simulate`` run with ``-p`` overrides that it must refuse: exit status 2, one line on stderr,
    no bag written; returns that line."""
    import sys

    args = [arg for override in overrides for arg in ("-p", override)]
    run = subprocess.run(
        [sys.executable, "-m", "pac_rig.simulate", str(bag), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    assert not bag.exists()
    return lines[0]
