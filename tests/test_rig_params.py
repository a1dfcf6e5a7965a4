"""``rig_params``: one parameter file for the rig's nodes started one by one, composed as the
launcher and ``simulate`` compose a run (a scenario file's values, what the parts derive).

Checked against ``simulate``'s own composition (``composition.derive`` of the expanded values,
each node given the values it has), by the one-line refusals, and by a run of the four nodes
started by hand with the file, in lock step, bit for bit equal to the offline loop of the
values ``simulate`` derives.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest
import yaml
from conftest import assert_lockstep_equals_offline

from pac_rig import composition, scenario_file
from pac_rig.configs import parameter_sets
from pac_rig.launcher import node_env
from pac_rig.nodes import LOOP_NODES, NODES

#: The realistic scenario with the learning law: the run whose parts derive the most (the law's
#: observer, the actuator's range and static force, the line's map and the law's design for it).
VALUES = {"scenario": "realistic_electromechanical", "law": "line_adaptive", "speed_kmh": 300.0}


ROS_RUN = ("ros2", "run")


def run_rig_params(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pac_rig.rig_params", *args], capture_output=True, text=True, timeout=120
    )


@pytest.mark.offline
def test_each_node_gets_the_values_simulate_composes_for_it(tmp_path):
    out = tmp_path / "rig.yaml"
    run = run_rig_params(*(a for k, v in VALUES.items() for a in ("-p", f"{k}:={v}")), "-o", str(out))
    assert run.returncode == 0, run.stderr
    sections = yaml.safe_load(out.read_text())
    assert set(sections) == {NODES[role].executable for role in LOOP_NODES}
    expanded, _ = scenario_file.expand(VALUES)
    derived, _ = composition.derive(expanded)
    for role in LOOP_NODES:
        given = sections[NODES[role].executable]["ros__parameters"]
        assert "scenario" not in given
        names = {spec.name for cls in parameter_sets(role) for spec in cls.specs()}
        # The plant runs the line and the train as the scenario states them (what observer and
        # controller derive from them, such as the span they assume, is theirs), and the static
        # force its actuator works about.
        source = {**expanded, "actuator_static_force": derived["actuator_static_force"]}
        want = {
            k: list(v) if isinstance(v, tuple) else v
            for k, v in (source if role == "plant" else derived).items()
            if k in names
        }
        assert {k: given.get(k) for k in want} == want, role
    controller = sections["controller_node"]["ros__parameters"]
    plant = sections["plant_node"]["ros__parameters"]
    # What only the composition knows reached the node that needs it.
    assert controller["u_max"] - controller["u_min"] == pytest.approx(200.0)
    assert plant["actuator_static_force"] == pytest.approx(0.5 * (controller["u_min"] + controller["u_max"]))
    assert sections["observer_node"]["ros__parameters"]["observer"] == derived["observer"]


@pytest.mark.offline
@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["-p", "scenario:=no_such_scenario"], "'scenario' = 'no_such_scenario'"),
        (["-p", "law:=adaptive_backstepping", "-p", "observer:=contact_force"], "needs theta_hat"),
        (["-p", "no_such_parameter:=1"], "unknown parameter 'no_such_parameter'"),
    ],
)
def test_what_cannot_be_composed_is_refused_in_one_line_and_no_file_is_written(tmp_path, args, says):
    out = tmp_path / "rig.yaml"
    run = run_rig_params(*args, "-o", str(out))
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1, run.stderr
    assert says in lines[0]
    assert not out.exists()


def test_a_node_given_a_scenario_itself_names_the_command_that_composes_it(domain_id):
    run = subprocess.run(
        [*ROS_RUN, "pac_controller", "controller_node", "--ros-args", "-p", "scenario:=realistic_pneumatic"],
        capture_output=True,
        text=True,
        timeout=60,
        env=node_env(domain_id),
    )
    lines = [line for line in run.stderr.splitlines() if line.strip()]
    assert run.returncode == 2 and len(lines) == 1, run.stderr
    assert "unknown parameter 'scenario'" in lines[0] and "ros2 run pac_rig rig_params" in lines[0]


def test_the_nodes_started_by_hand_with_the_file_run_the_scenario_as_simulate_does(domain_id, tmp_path):
    """Recorder, plant, observer and controller, each its own `ros2 run` with the one file, in
    lock step: the bag equals the offline loop of simulate's composition, tick for tick."""
    duration = 0.5
    values = {**VALUES, "duration": duration, "timing_mode": "lockstep"}
    params = tmp_path / "rig.yaml"
    run = run_rig_params(
        *(a for k, v in values.items() for a in ("-p", f"{k}:={v}")), "--record", "-o", str(params)
    )
    assert run.returncode == 0, run.stderr
    bag = tmp_path / "bag"
    recorder = ["--ros-args", "-p", f"bag_path:={bag}", "-p", "stop_after_run:=true"]
    rig = ["--ros-args", "--params-file", str(params)]
    commands = [
        [*ROS_RUN, "pac_rig", "recorder", *recorder],
        *([*ROS_RUN, NODES[role].package, NODES[role].executable, *rig] for role in LOOP_NODES),
    ]
    procs: list[subprocess.Popen] = []
    logs = [tmp_path / f"{i}.log" for i in range(len(commands))]
    try:
        for command, log in zip(commands, logs, strict=True):
            with open(log, "wb") as out:
                procs.append(
                    subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, env=node_env(domain_id))
                )
        deadline = time.monotonic() + 240
        while any(p.poll() is None for p in procs) and time.monotonic() < deadline:
            time.sleep(0.2)
        codes = [p.poll() for p in procs]
        tails = {log.name: log.read_text()[-800:] for log in logs}
        assert codes == [0] * len(procs), (codes, tails)
    finally:
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    expanded, _ = scenario_file.expand({k: v for k, v in values.items() if k != "timing_mode"})
    derived, _ = composition.derive(expanded)
    columns = {"plant_truth": ["contact_force"], "estimate": ["contact_force_hat"], "command": ["u", "mode"]}
    assert_lockstep_equals_offline(bag, derived, tmp_path / "offline", columns)
