"""A user's own law from a Python file (``law:=path/to/my_law.py``): the example, examples/my_law.py,
run from its file in simulate, a campaign and controller_node, each checked against the law's
formula recomputed here on the recorded inputs and passed through the safety chain's limits; the
compiled form of the same file; the chain's answer to a non-finite demand; the one-line refusals."""

from __future__ import annotations

import csv
import math
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import (
    ROOT,
    ROS2,
    assert_imported_once_and_an_edit_refused,
    assert_simulate_refuses_the_file,
    first_per_tick,
    lockstep_run_equals_offline,
    stop,
)

from pac_analysis.metrics import compute_metrics
from pac_bag.reader import read_bag
from pac_common import messages
from pac_controller import user_law
from pac_controller.controller import Controller
from pac_controller.laws import make_controller
from pac_controller.parameters import ControllerParameters, ReferenceParameters
from pac_controller.user_law import load_law_file
from pac_experiments.campaign import run as campaign_run
from pac_experiments.campaign import spec as campaign_spec
from pac_model.parameters import PantographParameters, TrackParameters
from pac_rig import simulate
from pac_rig.closed_loop import build_cores, run, run_cores
from pac_rig.launcher import node_env
from pac_rig.loop import compile_loop
from pac_rig.simulate import scenario_from_flat, simulate_to_bag

pytestmark = pytest.mark.offline

EXAMPLE = ROOT / "examples" / "my_law.py"
#: Limits tight enough that the run has demands cut by the slew limit (the demand moves up to
#: ~0.9 N a tick here) and by the saturation (the formula check below then covers the chain too),
#: with room for the default reference's 100 N.
LIMITS = {"u_max": 125.0, "slew_rate_max": 500.0}
#: The example's gains (its parameters; the formula itself is written again in ``expected``).
KP, KI = 0.5, 2.0


def compiled_copy(folder: Path, source: Path = EXAMPLE) -> Path:
    """The example with ``COMPILED = True``: the same law, numba-compiled into the chain."""
    path = folder / "my_compiled_law.py"
    text = source.read_text()
    assert "COMPILED = False" in text
    path.write_text(text.replace("COMPILED = False", "COMPILED = True"))
    return path


def expected(f_r, f_hat, u_law, u, dt: float, u_min: float, u_max: float, slew: float):
    """The example's law on recorded inputs (docs/laws.md, "Your own law"): its demand each tick and
    the command the chain makes of it (slew limit from the previous command, then saturation).
    The integral grows only on ticks whose recorded command is the recorded demand."""
    demand, command = np.empty(f_r.size), np.empty(f_r.size)
    integral = 0.0
    for k in range(f_r.size):
        error = f_r[k] - f_hat[k]
        demand[k] = f_r[k] + KP * error + integral
        limited = demand[k] if k == 0 else min(max(demand[k], u[k - 1] - slew * dt), u[k - 1] + slew * dt)
        command[k] = min(max(limited, u_min), u_max)
        if u[k] == u_law[k]:
            integral += dt * KI * error
    return demand, command


def assert_the_law_ran(f_r, f_hat, u_law, u, mode, values: dict) -> None:
    """Every command is the example's demand through the chain's limits; the run met both limits.
    Tolerance: the run and this loop do the same few double operations per tick, in another
    order at most (1e-9 N is far below any physical effect and far above a rounding step)."""
    scenario = scenario_from_flat(values)
    s, dt = scenario.controller, scenario.loop.sample_period
    demand, command = expected(f_r, f_hat, u_law, u, dt, s.u_min, s.u_max, s.slew_rate_max)
    assert np.all(mode == messages.MODES["active"])
    np.testing.assert_allclose(u_law, demand, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(u, command, rtol=0.0, atol=1e-9)
    slewed = (u != u_law) & (s.u_min < u) & (u < s.u_max)  # limited, but not by the saturation
    assert np.any(u == s.u_max) and np.any(slewed) and np.any(u == u_law)


def assert_bag_ran_the_law(bag_path: Path, values: dict) -> None:
    topics = read_bag(bag_path).topics
    command, estimate = topics["command"], topics["estimate"]
    (_, ic), (_, ie) = first_per_tick(command), first_per_tick(estimate)
    assert_the_law_ran(
        command["force_reference"][ic],
        estimate["contact_force_hat"][ie],
        command["u_unsaturated"][ic],
        command["u"][ic],
        command["mode"][ic],
        values,
    )


def test_the_example_runs_in_simulate_from_its_file(tmp_path):
    values = {"law": str(EXAMPLE), "duration": 2.0, **LIMITS}
    result = simulate_to_bag(scenario_from_flat(values), tmp_path / "bag")
    assert result.ticks == 2000 and result.diverged is None
    assert_bag_ran_the_law(tmp_path / "bag", values)


def test_simulate_takes_the_path_as_typed(tmp_path, monkeypatch, capsys):
    """``-p law:=examples/my_law.py`` from the repository's root, as docs/laws.md shows it."""
    monkeypatch.chdir(ROOT)
    bag = tmp_path / "bag"
    code = simulate.main([str(bag), "-p", "law:=examples/my_law.py", "-p", "duration:=0.5"])
    assert code == 0, capsys.readouterr().err
    assert read_bag(bag).topics["command"]["u"].size == 500


@pytest.mark.slow  # the compiled copy compiles its chain and loop: 15-45 s
def test_a_plain_python_law_runs_tick_by_tick_and_the_compiled_copy_in_the_compiled_loop(tmp_path):
    """The Python file has no compiled loop (the cores step it); its copy with njit functions has,
    and both give the same run as the core objects stepped tick by tick (the nodes' calls)."""
    values = {"law": str(EXAMPLE), "duration": 1.0, **LIMITS}
    assert compile_loop(*build_cores(scenario_from_flat(values)), 1) is None
    compiled = {**values, "law": str(compiled_copy(tmp_path))}
    loop = compile_loop(*build_cores(scenario_from_flat(compiled)), 1)
    assert loop is not None and loop.block is not None
    python = list(run(scenario_from_flat(values)))
    fast = list(run(scenario_from_flat(compiled)))
    stepped = list(run_cores(scenario_from_flat(compiled), *build_cores(scenario_from_flat(compiled))))
    for name in ("u", "u_unsaturated", "force_reference", "mode"):
        a, b, c = ([getattr(r.command, name) for r in records] for records in (python, fast, stepped))
        assert a == b == c, name
    assert [r.truth.contact_force for r in python] == [r.truth.contact_force for r in fast]


NAN_LAW = """
import math
NEEDS = ()
STATE_SIZE = 2  # the force a restart continues from; 1 until the first commit after a restart


def restart(consts, state, has_u, u_applied):
    state[0], state[1] = u_applied, 1.0 if has_u else 0.0


def output(consts, state, t, f_r, z_hat, theta_hat, f_hat):
    if 0.5 <= t < 0.6:
        return math.nan
    return state[0] if state[1] == 1.0 else f_r[0] + 10.0


def commit(consts, state, u_applied):
    state[1] = 0.0
"""


@pytest.mark.parametrize(
    "compiled", [False, pytest.param(True, marks=pytest.mark.slow)], ids=["python", "compiled"]
)
def test_a_non_finite_demand_is_answered_by_the_fallback_and_the_law_restarts(tmp_path, compiled):
    """NaN for 0.1 s: the fallback force (within the slew limit) instead, then the law restarts from
    the force the actuator holds (bumpless) and goes on."""
    path = tmp_path / "nan_law.py"
    path.write_text(
        "from numba import njit\n" + NAN_LAW.replace("\ndef ", "\n@njit\ndef ") if compiled else NAN_LAW
    )
    values = {"law": str(path), "duration": 1.0, "fallback_force": 90.0}
    assert (compile_loop(*build_cores(scenario_from_flat(values)), 1) is not None) == compiled
    records = list(run(scenario_from_flat(values)))
    u = np.array([r.command.u for r in records])
    f_r = np.array([r.command.force_reference for r in records])
    mode = [r.command.mode for r in records]
    assert np.all(np.isfinite(u))
    assert set(mode[500:600]) == {"fallback"} and set(mode[:500] + mode[600:]) == {"active"}
    assert np.all(np.abs(np.diff(u)) <= 1e5 * 1e-3 * (1 + 1e-12))  # the default slew limit, always
    assert u[599] == 90.0 and u[600] == u[599]  # the fallback force, then the law from it
    np.testing.assert_allclose(u[:500], f_r[:500] + 10.0, rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(u[601:], f_r[601:] + 10.0, rtol=0.0, atol=1e-9)


def test_the_estimate_a_law_reads_is_checked_for_it():
    """The example reads F_hat only: a non-finite F_hat is refused, a non-finite theta_hat is not."""
    controller = make_controller(
        PantographParameters(),
        TrackParameters(),
        ControllerParameters(law=str(EXAMPLE)),
        ReferenceParameters(),
        1e-3,
    )
    assert isinstance(controller, Controller) and controller.name == str(EXAMPLE)
    assert controller.compute(0, np.zeros(4), np.full(3, math.nan), 0.0).mode == "active"
    assert controller.compute(1, np.zeros(4), np.zeros(3), math.nan).mode == "fallback"


def test_a_campaign_point_key_holds_the_law_file_text(tmp_path, monkeypatch):
    """A point of a law file keys on its text: the same text keeps its results, an edit does not
    (in a new process: one process refuses a file edited after it imported it, and so does a run
    of a point checked with the old text)."""
    law = tmp_path / "law.py"
    law.write_text(EXAMPLE.read_text())
    spec = campaign_spec.Spec("t", ({"law": [str(law), "passive"]},), {"duration": 0.05}, (0.0, 0.05))
    points = campaign_spec.expand(spec)
    first = [p.key for p in points]
    assert len(set(first)) == 2
    assert [p.key for p in campaign_spec.expand(spec)] == first
    law.write_text(EXAMPLE.read_text().replace("KP = 0.5", "KP = 0.4"))
    row = campaign_run.run_point(points[0])
    assert (
        row["status"] == "error"
        and f"the law file {law} changed since the campaign was checked" in row["reason"]
    )
    with pytest.raises(campaign_spec.SpecError, match="its text changed since this process imported it"):
        campaign_spec.expand(spec)
    monkeypatch.setattr(user_law, "_LOADED", {})  # a new process
    second = [p.key for p in campaign_spec.expand(spec)]
    assert second[0] != first[0] and second[1] == first[1]


@pytest.mark.slow
def test_the_example_runs_in_a_campaign_from_its_file(tmp_path, capsys):
    """A campaign of the example and passive (Dask: a law file is not the batch's): the example's row
    holds the measures of the example's own run (simulate's bag, its report)."""
    from pac_experiments.campaign.cli import main

    window = [0.5, 1.5]
    spec = tmp_path / "spec.yaml"
    fixed = {"duration": 1.5, **LIMITS}
    spec.write_text(
        yaml.safe_dump({"grid": {"law": [str(EXAMPLE), "passive"]}, "fixed": fixed, "window": window})
    )
    out = tmp_path / "out"
    code = main([str(spec), "--out", str(out), "--workers", "1", "--no-report"])
    assert code == 0, capsys.readouterr().err
    with (out / "results.csv").open() as f:
        rows = {row["law"]: row for row in csv.DictReader(f)}
    assert set(rows) == {str(EXAMPLE), "passive"} and {r["status"] for r in rows.values()} == {"ok"}
    values = {"law": str(EXAMPLE), **fixed}
    simulate_to_bag(scenario_from_flat(values), tmp_path / "bag")
    metrics = compute_metrics(read_bag(tmp_path / "bag"), *window)
    for name in ("contact_force_mean", "contact_force_std", "u_max_abs"):
        assert float(rows[str(EXAMPLE)][name]) == pytest.approx(getattr(metrics, name), rel=1e-12), name
        assert rows[str(EXAMPLE)][name] != rows["passive"][name], name


@pytest.mark.live
@pytest.mark.parametrize("compiled", [False, True], ids=["python", "compiled"])
def test_the_example_runs_in_controller_node_from_its_file(rigs, tmp_path, compiled):
    """Lock step with controller_node running the example (and its compiled copy): the same run as
    simulate's, bit for bit, and every command the law's formula through the chain."""
    law = str(compiled_copy(tmp_path) if compiled else EXAMPLE)
    values = {"law": law, "duration": 1.0, **LIMITS}
    controller = {"law": law, **LIMITS}
    bag = lockstep_run_equals_offline(
        rigs, "own_law", {"controller": controller}, values, tmp_path / "offline"
    )
    assert_bag_ran_the_law(bag, values)


# -- refusals: one line, naming the file and what is wrong --------------------------------------
BAD_FILES = [
    (None, "no such file"),
    ("NEEDS = (\n", "importing it raised SyntaxError"),
    ("NEEDS = ()\nx = 1 / 0\n", "importing it raised ZeroDivisionError: division by zero (line 2)"),
    ("def output(*a):\n    return 0.0\n", "it does not define NEEDS"),
    ("NEEDS = 'z_hat'\n", "is not a collection of names"),
    ("NEEDS = ('speed',)\n", "NEEDS names speed; it may name z_hat, theta_hat, contact_force_hat"),
    ("NEEDS = ()\n", "it does not define output"),
    ("NEEDS = ()\noutput = 3\n", "output is not a function"),
    ("NEEDS = ()\nSTATE_SIZE = -1\ndef output(*a):\n    return 0.0\n", "STATE_SIZE = -1"),
    (
        "NEEDS = ()\ndef design(setup):\n    return setup.no_such\ndef output(*a):\n    return 0.0\n",
        "design raised AttributeError",
    ),
    (
        "NEEDS = ()\ndef design(setup):\n    return 'gains'\ndef output(*a):\n    return 0.0\n",
        "design raised ValueError: could not convert string to float",
    ),
    (
        "from numba import njit\nNEEDS = ()\n@njit\ndef output(c, s, t, f_r, z, th, f):\n    return z.no\n",
        "its njit functions do not compile",
    ),
]


@pytest.mark.parametrize(("text", "expected"), BAD_FILES)
def test_simulate_refuses_a_bad_law_file_in_one_line(tmp_path, capsys, text, expected):
    assert_simulate_refuses_the_file(tmp_path, capsys, "law", text, expected)


def test_a_law_on_an_observer_without_what_it_needs_is_refused(tmp_path, capsys):
    law = tmp_path / "law.py"
    law.write_text("NEEDS = ('theta_hat',)\ndef output(*a):\n    return 0.0\n")
    code = simulate.main([str(tmp_path / "bag"), "-p", f"law:={law}", "-p", "observer:=contact_force"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert f"law '{law}' needs theta_hat, which observer 'contact_force' does not give" in lines[0]


def test_a_law_that_is_neither_a_name_nor_a_python_file_is_refused(tmp_path, capsys):
    code = simulate.main([str(tmp_path / "bag"), "-p", "law:=my_law"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert "'law' = 'my_law': allowed one of adaptive_backstepping," in lines[0]
    assert lines[0].endswith("or the path of a .py file")


def test_a_campaign_refuses_a_bad_law_file_before_any_run(tmp_path, capsys):
    from pac_experiments.campaign.cli import main

    spec = tmp_path / "spec.yaml"
    missing = tmp_path / "missing.py"
    spec.write_text(yaml.safe_dump({"grid": {"law": [str(missing)]}, "fixed": {"duration": 0.5}}))
    code = main([str(spec), "--out", str(tmp_path / "out")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "no such file" in lines[0] and str(missing) in lines[0], lines
    assert not (tmp_path / "out").exists()


@pytest.mark.live
def test_controller_node_refuses_a_bad_law_file_in_one_line(domain_id, tmp_path):
    law = tmp_path / "law.py"
    law.write_text("NEEDS = ()\n")
    proc = subprocess.run(
        ["ros2", "run", "pac_controller", "controller_node", "--ros-args", "-p", f"law:={law}"],
        capture_output=True,
        text=True,
        timeout=60,
        env=node_env(domain_id),
    )
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and f"'law' = '{law}'" in lines[0] and "it does not define output" in lines[0], (
        lines
    )


def test_a_file_is_imported_once_and_an_edit_after_is_refused(tmp_path, monkeypatch):
    """A law is fixed for a run: a process that imported a file does not take up an edit of it
    (a node's retune builds the law again from the file)."""
    monkeypatch.setattr(user_law, "_LOADED", {})
    assert_imported_once_and_an_edit_refused(tmp_path / "law.py", EXAMPLE.read_text(), load_law_file)


@pytest.mark.live
def test_a_retune_after_the_law_file_was_edited_is_refused_and_the_node_runs_on(domain_id, tmp_path):
    """A node builds its law again on a retune: from a file edited since its start it refuses the
    change in one line (the law is fixed for a run) instead of running the new text or dying."""
    law = tmp_path / "law.py"
    law.write_text(EXAMPLE.read_text())
    env = node_env(domain_id)

    def ros2(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([ROS2, *args], capture_output=True, text=True, env=env, timeout=60)

    node = subprocess.Popen(
        [ROS2, "run", "pac_controller", "controller_node", "--ros-args", "-p", f"law:={law}"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while "/controller_node" not in ros2("node", "list").stdout.splitlines():
            assert time.monotonic() < deadline and node.poll() is None
        assert ros2("param", "set", "controller_node", "u_max", "300.0").returncode == 0
        law.write_text(EXAMPLE.read_text().replace("KP = 0.5", "KP = 0.4"))
        refused = ros2("param", "set", "controller_node", "u_max", "200.0")
        assert refused.returncode == 1 and "its text changed since this process imported it" in refused.stderr
        assert ros2("param", "get", "controller_node", "u_max").stdout.strip() == "300.0"
        assert node.poll() is None
    finally:
        stop(node)
    assert node.returncode == 0
