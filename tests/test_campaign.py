"""Campaigns on Dask: failing runs are rows, resume skips done rows, bad SPECs stop before any run,
and a separate Dask cluster (scheduler + workers as processes) gives the embedded run's results."""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from pac_analysis.metrics import compute_metrics
from pac_bag.reader import read_bag
from pac_controller.parameters import COMPILED_LAW_NAMES
from pac_experiments.campaign import dask_runner as campaign_dask
from pac_experiments.campaign import results as campaign_results
from pac_experiments.campaign import run as campaign_run
from pac_experiments.campaign import spec as campaign_spec
from pac_rig import closed_loop
from pac_rig.closed_loop import build_cores
from pac_rig.simulate import scenario_from_flat

pytestmark = pytest.mark.offline

WINDOW = [0.25, 0.5]
#: The paper's gains with an ideal actuator (as reproduce's paper_gains run): diverge in ~0.23 s.
PAPER_GAINS = {
    "c1": [400.0],
    "c2": [400.0],
    "c3": [50.0],
    "u_min": [-1e7],
    "u_max": [1e7],
    "slew_rate_max": [1e12],
    "shape": ["constant"],
}


def write_spec(path: Path, spec: dict) -> Path:
    path.write_text(yaml.safe_dump(spec))
    return path


def read_rows(out: Path) -> list[dict[str, str]]:
    with (out / "results.csv").open() as f:
        return list(csv.DictReader(f))


@pytest.fixture
def client():
    """An in-process Dask cluster (threads): the test's monkeypatches reach its tasks."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=False,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
    )
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.mark.slow
def test_diverging_and_raising_runs_are_rows_and_the_campaign_finishes(tmp_path, client, monkeypatch):
    spec_path = write_spec(
        tmp_path / "spec.yaml",
        {
            "grids": [
                {"speed_kmh": [300.0, 360.0]},
                PAPER_GAINS,  # diverge with one tick of delay
            ],
            "fixed": {"duration": 0.5},
            "window": WINDOW,
        },
    )
    real_run = campaign_run.run_traces

    def run_or_raise(scenario):
        if scenario.track.speed_kmh == 300.0:
            raise RuntimeError("injected failure")
        return real_run(scenario)

    monkeypatch.setattr(campaign_run, "run_traces", run_or_raise)
    monkeypatch.setattr(campaign_run, "batchable", lambda scenario: False)  # every run tick by tick
    spec = campaign_spec.load_spec(spec_path)
    points = campaign_spec.expand(spec)
    outcome = campaign_dask.execute(client, spec, points, tmp_path / "out", progress=False)
    assert (outcome.total, outcome.ran, outcome.failed, outcome.lost) == (3, 3, 2, 0)
    rows = {(r["speed_kmh"], r["c1"]): r for r in read_rows(tmp_path / "out")}
    raised = rows[("300.0", "40.0")]
    assert raised["status"] == "error" and raised["reason"] == "RuntimeError: injected failure"
    assert raised["contact_force_std"] == ""
    diverged = rows[("360.0", "400.0")]
    assert diverged["status"] == "diverged" and diverged["reason"].startswith("closed loop diverged at tick")
    ok = rows[("360.0", "40.0")]
    assert ok["status"] == "ok" and ok["reason"] == ""
    assert float(ok["contact_force_std"]) > 0.0 and float(ok["ticks_run"]) == 500
    from pac_experiments.campaign.report import write_report

    report = write_report(
        spec,
        campaign_results.write_results(
            spec, points, campaign_results.read_done(tmp_path / "out"), tmp_path / "out"
        ),
        tmp_path / "out",
    ).read_text()
    assert (
        "diverged: closed loop diverged at tick" in report
        and "error: RuntimeError: injected failure" in report
    )


def test_resume_runs_only_what_is_not_done(tmp_path, client, monkeypatch):
    spec = {
        "grid": {"speed_kmh": [300.0, 360.0], "c3": [40.0, 50.0]},
        "fixed": {"duration": 0.3},
        "window": [0.1, 0.3],
    }
    executed: list[str] = []
    real = campaign_run.run_point

    def counting(point, bag_dir=None):
        executed.append(point.key)
        return real(point, bag_dir)

    monkeypatch.setattr(campaign_run, "run_point", counting)
    monkeypatch.setattr(campaign_run, "batchable", lambda scenario: False)  # every run counted here
    out = tmp_path / "out"

    def go(s: dict) -> campaign_dask.Outcome:
        loaded = campaign_spec.load_spec(write_spec(tmp_path / "spec.yaml", s))
        return campaign_dask.execute(
            client, loaded, campaign_spec.expand(loaded), out, chunk_size=1, progress=False
        )

    assert go(spec).ran == 4 and len(executed) == 4
    first = (out / "results.csv").read_text()
    assert go(spec).ran == 0 and len(executed) == 4  # the same command again: nothing runs
    assert (out / "results.csv").read_text() == first
    # A campaign killed mid-write: two rows lost, the last line torn.
    lines = (out / "runs.jsonl").read_text().splitlines()
    (out / "runs.jsonl").write_text("\n".join(lines[:2]) + "\n" + lines[2][:40])
    executed.clear()
    outcome = go(spec)
    assert (outcome.skipped, outcome.ran) == (2, 2) and len(executed) == 2
    assert (out / "results.csv").read_text() == first
    # A grown grid runs only the new points.
    executed.clear()
    spec["grid"]["speed_kmh"].append(200.0)
    assert go(spec).ran == 2 and len(executed) == 2
    assert len(read_rows(out)) == 6


@pytest.mark.unit
def test_runs_jsonl_is_strict_json_and_a_nan_measure_reads_back_as_nan(tmp_path):
    row = {"key": "k1", "status": "ok", "reason": "", "law": "passive", "du_dt_max_abs": float("nan")}
    row["contact_force_std"] = 3.5
    line = campaign_results.runs_line(row)
    assert line.endswith("\n") and line.count("\n") == 1

    def refuse(constant: str) -> None:
        raise AssertionError(f"not strict JSON: {constant}")

    assert json.loads(line, parse_constant=refuse)["du_dt_max_abs"] is None
    (tmp_path / campaign_results.RUNS_FILE).write_text(line)
    back = campaign_results.read_done(tmp_path)["k1"]
    assert np.isnan(back["du_dt_max_abs"]) and back["contact_force_std"] == 3.5
    assert {k: v for k, v in back.items() if k != "du_dt_max_abs"} == {
        k: v for k, v in row.items() if k != "du_dt_max_abs"
    }


@pytest.mark.slow
@pytest.mark.parametrize("statistics", ["raw", "en50318"])
def test_batched_rows_equal_the_tick_by_tick_rows(monkeypatch, statistics):
    """The compiled batch serves every run (every law, both lines and observers); every row equals the
    row of the same point stepped tick by tick through the core objects (no compiled loop at all)."""
    spec = campaign_spec.Spec(
        "t",
        (
            {"law": list(COMPILED_LAW_NAMES), "plant_mass_scale": [0.85, 1.0]},
            {"noise_std": [[1e-5, 1e-5]], "command_delay_ticks": [0, 3]},
            {"law": ["pid", "lqr"], "speed_kmh": [300.0]},
            {"catenary_model": ["fe"], "law": ["passive", "line_adaptive"], "observer": ["contact_force"]},
            PAPER_GAINS,  # diverges: left to run_point for its reason
        ),
        {"duration": 0.5},
        (0.25, 0.5),
        statistics=statistics,
    )
    points = campaign_spec.expand(spec)
    batched = campaign_run.run_batched(points)
    assert len(batched) == len(points)  # the divergence too: its row from the batch's tick and reason
    assert sum(r["status"] == "diverged" for r in batched.values()) == 1
    chunk = campaign_run.run_chunk(points, None, 2)  # two threads, as a campaign in process runs it
    with monkeypatch.context() as m:
        m.setattr(closed_loop, "compile_loop", lambda *args: None)  # closed_loop.run: core objects
        reference_rows = [campaign_run.run_point(point) for point in points]
    for point, row, reference in zip(points, chunk, reference_rows, strict=True):
        for name, value in reference.items():
            if name != "wall_seconds":
                assert row[name] == value or (value != value and row[name] != row[name]), (point.values, name)
    # A failure of the batch itself costs nothing: every point then runs tick by tick.
    monkeypatch.setattr(campaign_run, "run_batch", lambda scenarios, threads=1: 1 / 0)
    again = campaign_run.run_chunk(points)
    assert [r["status"] for r in again] == [r["status"] for r in chunk]
    assert {r["batch_error"] for r in again} == {"ZeroDivisionError: division by zero"}  # and says why


def test_measures_in_memory_equal_the_bag_reports(tmp_path):
    """One formula: the campaign's row (in memory) and the report of the bag it keeps agree exactly."""
    spec = campaign_spec.Spec("t", ({"speed_kmh": [250.0]},), {"duration": 0.5}, (0.25, 0.5))
    (point,) = campaign_spec.expand(spec)
    in_memory = campaign_run.run_point(point)
    with_bag = campaign_run.run_point(point, str(tmp_path))
    from_bag = compute_metrics(read_bag(tmp_path / point.key), 0.25, 0.5)
    for name in campaign_run.METRIC_COLUMNS:
        assert in_memory[name] == with_bag[name] == getattr(from_bag, name), name


def test_plant_mass_mismatch_scales_only_the_plant():
    plant, observer, controller = build_cores(scenario_from_flat({"plant_mass_scale": 1.3}))
    assert (plant.pantograph.m1, plant.pantograph.m2) == pytest.approx((8.0 * 1.3, 12.0 * 1.3))
    assert (observer.pantograph.m1, controller.law.pantograph.m1) == (8.0, 8.0)
    assert (observer.pantograph.m2, controller.law.pantograph.m2) == (12.0, 12.0)
    nominal, *_ = build_cores(scenario_from_flat({}))
    assert (nominal.pantograph.m1, nominal.pantograph.m2) == (8.0, 12.0)


def _cli(*args: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pac_experiments.campaign.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def _main(capsys, *args: str) -> tuple[int, str, str]:
    """campaign's ``main`` in this process (what ``python -m pac_experiments.campaign.cli`` runs, without
    a new interpreter): (exit status, stdout, stderr)."""
    from pac_experiments.campaign.cli import main

    code = main(list(args))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


GOOD = {"grid": {"speed_kmh": [300.0]}, "fixed": {"duration": 0.5}, "window": WINDOW}


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (yaml.safe_dump({**GOOD, "grid": {"no_such_gain": [1.0]}}), "invalid parameter 'no_such_gain'"),
        (yaml.safe_dump({**GOOD, "grid": {"speed_kmh": [300.0, 900.0]}}), "'speed_kmh' = 900.0: allowed"),
        (yaml.safe_dump({**GOOD, "fixed": {"duration": 0.5, "c1": -1.0}}), "invalid parameter 'c1' = -1.0"),
        (yaml.safe_dump({**GOOD, "grid": {}}), "'grid' is empty"),
        (yaml.safe_dump({**GOOD, "grid": {"speed_kmh": []}}), "grid.speed_kmh must be a non-empty list"),
        (yaml.safe_dump({**GOOD, "window": [0.25, 2.0]}), "invalid window [0.25, 2] s"),
        (
            yaml.safe_dump({**GOOD, "fixed": {"duration": 0.5, "speed_kmh": 250.0}}),
            "parameter 'speed_kmh' is both in 'fixed' and in 'grid'",
        ),
        (
            yaml.safe_dump({"grid": GOOD["grid"], "window_spans": [2, 1]}),
            "'window_spans' must be [from, to] spans",
        ),
        ("grid: {speed_kmh: [300.0\nfixed: [", "line 2, column 6: is not valid YAML"),
        (None, "cannot be read (No such file or directory)"),
    ],
    ids=[
        "unknown",
        "out-of-range",
        "out-of-range-fixed",
        "empty-grid",
        "empty-axis",
        "window",
        "grid-and-fixed",
        "window-spans",
        "yaml",
        "missing",
    ],
)
def test_bad_spec_fails_before_any_run_with_one_line(tmp_path, capsys, text, expected):
    spec = tmp_path / "spec.yaml"
    if text is not None:
        spec.write_text(text)
    out = tmp_path / "out"
    code, stdout, stderr = _main(capsys, str(spec), "--out", str(out))
    assert code == 2, stderr
    assert stdout == ""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("campaign: ") and expected in lines[0], stderr
    assert not out.exists()  # nothing ran, nothing was written


def test_a_spec_with_several_errors_names_each_once_before_any_run(tmp_path, capsys):
    """Every error in one go, one line each (key, value, what is allowed): an unknown key, a bad
    'statistics', a fixed value out of range (refused at every point: said once) and a grid value
    out of range in a point that has the fixed error too."""
    spec = tmp_path / "spec.yaml"
    spec.write_text(
        yaml.safe_dump(
            {
                **GOOD,
                "grid": {"speed_kmh": [300.0, 900.0]},
                "fixed": {"duration": 0.5, "c1": -1.0},
                "statistics": "median",
                "colour": "red",
            }
        )
    )
    out = tmp_path / "out"
    code, stdout, stderr = _main(capsys, str(spec), "--out", str(out), "--workers", "0")
    assert code == 2, stderr
    assert stdout == ""
    lines = stderr.strip().splitlines()
    expected = [
        "invalid option '--workers' = 0: allowed an integer >= 1",
        "unknown key 'colour' = 'red' (allowed: ",
        "'statistics' = 'median': allowed raw, en50318",
        "invalid parameter 'c1' = -1.0: allowed",
        "invalid parameter 'speed_kmh' = 900.0: allowed",
    ]
    assert len(lines) == len(expected), stderr
    assert all(line.startswith("campaign: ") for line in lines), stderr
    for text in expected:
        assert sum(text in line for line in lines) == 1, (text, stderr)
    assert not out.exists()  # nothing ran, nothing was written


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def dask_cluster(tmp_path):
    """``dask scheduler`` + two ``dask worker`` processes on loopback: (address, worker processes).

    Every process is stopped by its PID (its process group) at teardown, pass or fail."""
    dask = str(Path(sys.executable).parent / "dask")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs: list[subprocess.Popen] = []
    logs = []

    def start(*args: str) -> None:
        log = (tmp_path / f"dask_{len(procs)}.log").open("w")
        logs.append(log)
        # Own session: the worker's nanny has a child, stopped with it through the group.
        procs.append(
            subprocess.Popen([dask, *args], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        )

    try:
        start("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard")
        for i in range(2):
            start(
                "worker",
                address,
                "--host",
                "127.0.0.1",
                "--nthreads",
                "1",
                "--nworkers",
                "1",
                "--no-dashboard",
                "--name",
                f"w{i}",
            )
        from distributed import Client

        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=60)
        yield address, procs[1:]
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
        deadline = time.monotonic() + 10.0
        for p in procs:
            try:
                p.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=5.0)
        for log in logs:
            log.close()
        assert all(p.poll() is not None for p in procs)


@pytest.mark.slow
def test_scheduler_cluster_gives_the_embedded_results(tmp_path, dask_cluster):
    address, _ = dask_cluster
    spec = write_spec(
        tmp_path / "spec.yaml",
        {
            "grids": [
                {"speed_kmh": [250.0, 360.0], "plant_mass_scale": [0.8, 1.2]},
                PAPER_GAINS,
            ],
            "fixed": {"duration": 0.5},
            "window": WINDOW,
        },
    )
    remote = _cli(str(spec), "--out", str(tmp_path / "remote"), "--scheduler", address)
    assert remote.returncode == 0, remote.stderr
    embedded = _cli(str(spec), "--out", str(tmp_path / "embedded"), "--workers", "2")
    assert embedded.returncode == 0, embedded.stderr
    assert "(in process, no cluster)" in embedded.stdout  # every point batchable: no cluster started
    local = _cli(str(spec), "--out", str(tmp_path / "local"), "--workers", "2", "--cluster")
    assert local.returncode == 0, local.stderr
    assert "s cluster start)" in local.stdout
    rows = read_rows(tmp_path / "remote")
    assert len(rows) == 5 and sorted(r["status"] for r in rows) == ["diverged", "ok", "ok", "ok", "ok"]
    for other in ("embedded", "local"):
        assert (tmp_path / "remote" / "results.csv").read_bytes() == (
            tmp_path / other / "results.csv"
        ).read_bytes()
    assert (tmp_path / "remote" / "report.md").exists() and list((tmp_path / "remote").glob("fig_*.png"))
    assert "5 run (1 diverged or failed), 0 lost" in remote.stdout


@pytest.mark.slow
def test_embedded_cluster_listens_on_loopback_only():
    import psutil

    cluster = campaign_dask.embedded_cluster(1)
    try:
        me = psutil.Process()
        pids = {me.pid} | {p.pid for p in me.children(recursive=True)}
        listening = [
            c for c in psutil.net_connections("inet") if c.status == psutil.CONN_LISTEN and c.pid in pids
        ]
        assert listening and all(c.laddr.ip == "127.0.0.1" for c in listening), listening
    finally:
        cluster.close()


@contextlib.contextmanager
def campaign_running(spec: Path, out: Path, *extra: str):
    """``campaign SPEC --out OUT --chunk-size 1 EXTRA`` in its own process group, given once two
    runs are in runs.jsonl (or it ended, or 120 s passed); killed with its group on exit if still
    running, pass or fail."""
    args = [
        sys.executable,
        "-m",
        "pac_experiments.campaign.cli",
        str(spec),
        "--out",
        str(out),
        "--chunk-size",
        "1",
    ]
    proc = subprocess.Popen(
        [*args, *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and proc.poll() is None:
            runs = out / "runs.jsonl"
            if runs.exists() and len(runs.read_text().splitlines()) >= 2:
                break
            time.sleep(0.05)
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("where", "duration"), [("--cluster", 0.3), ("", 30.0)], ids=["cluster", "in_process"]
)
def test_ctrl_c_keeps_finished_runs_and_the_same_command_resumes(tmp_path, where, duration):
    """SIGINT to the whole process group (a terminal's Ctrl-C, workers included), on the embedded
    cluster and in process (the compiled batch, one run per chunk).

    48 runs: many more than finish before the interrupt, even with much faster cores (in process,
    48 x 30 s take seconds of compiled work)."""
    spec = write_spec(
        tmp_path / "spec.yaml",
        {
            "grid": {
                "speed_kmh": [160.0, 200.0, 240.0, 280.0, 320.0, 360.0, 380.0, 400.0],
                "c1": [30.0, 35.0, 40.0, 45.0, 50.0, 55.0],
            },
            "fixed": {"duration": duration},
            "window": [0.1, 0.3],
        },
    )
    out = tmp_path / "out"
    with campaign_running(spec, out, *([where] if where else [])) as proc:
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "interrupted; re-run the same command to resume" in stderr
    kept = len((out / "runs.jsonl").read_text().splitlines())
    assert 2 <= kept < 48
    assert len(read_rows(out)) == kept  # results.csv holds what finished
    again = _cli(str(spec), "--out", str(out), "--no-report")
    assert again.returncode == 0, again.stderr
    assert f"48 runs, {kept} already done, {48 - kept} run" in again.stdout
    assert len(read_rows(out)) == 48


@pytest.mark.slow
def test_a_lost_worker_loses_no_run(tmp_path, dask_cluster):
    """One of the two workers is killed (SIGKILL, with its nanny) mid-campaign: Dask re-runs its
    tasks on the other one; every row is there once and equals a run on an intact cluster."""
    address, workers = dask_cluster
    spec = write_spec(
        tmp_path / "spec.yaml",
        {
            "grid": {"speed_kmh": [160.0, 200.0, 240.0, 280.0, 320.0, 360.0], "c1": [35.0, 40.0]},
            "fixed": {"duration": 0.5},
            "window": WINDOW,
        },
    )
    out = tmp_path / "out"
    with campaign_running(spec, out, "--scheduler", address, "--no-report") as proc:
        os.killpg(workers[0].pid, signal.SIGKILL)
        stdout, stderr = proc.communicate(timeout=180)
    assert proc.returncode == 0, stderr
    assert "12 runs, 0 already done, 12 run (0 diverged or failed), 0 lost" in stdout
    keys = [json.loads(line)["key"] for line in (out / "runs.jsonl").read_text().splitlines()]
    assert len(keys) == len(set(keys)) == 12
    intact = _cli(str(spec), "--out", str(tmp_path / "intact"), "--workers", "2", "--no-report")
    assert intact.returncode == 0, intact.stderr
    assert (out / "results.csv").read_bytes() == (tmp_path / "intact" / "results.csv").read_bytes()


def test_a_whole_span_window_holds_whole_periods_of_the_span(tmp_path):
    """``window_spans``: the window is spans a..b at each point's speed, the run b + 1/2 spans; over
    whole spans a span-periodic force has its true mean and sigma, over 7.5 spans it has not."""
    spec_path = write_spec(
        tmp_path / "spec.yaml",
        {
            "grid": {"speed_kmh": [200.0, 300.0]},
            "fixed": {"span_length": 55.0},
            "window_spans": [2, 10],
            "statistics": "en50318",
            "force_target": "en50367",
        },
    )
    spec = campaign_spec.load_spec(spec_path)
    points = campaign_spec.expand(spec)
    for point, v in zip(points, (200.0, 300.0), strict=True):
        span_time = 55.0 / (v / 3.6)
        assert point.window == pytest.approx((2 * span_time, 10 * span_time), rel=1e-12)
        assert point.values["duration"] == pytest.approx(10.5 * span_time, abs=1e-3)
        assert point.values["force_amplitude"] == pytest.approx(0.00097 * v**2 + 70.0)
    # A span-periodic force (the span and its 9 dropper harmonics) at 300 km/h, sampled at 1 kHz.
    dt, span_time = 1e-3, 55.0 / (300.0 / 3.6)
    t = np.arange(0.0, 10.5 * span_time, dt)
    phase = 2 * np.pi * t / span_time
    force = 150.0 + 40.0 * np.sin(phase) + 10.0 * np.sin(9 * phase)
    zeros = np.zeros_like(t)
    whole = campaign_run.en50318_measures(t, force, zeros, force, zeros, points[1].window, dt)
    assert whole["en50318_contact_force_mean"] == pytest.approx(150.0, abs=0.05)
    assert whole["en50318_contact_force_std"] == pytest.approx(np.sqrt((40.0**2 + 10.0**2) / 2), rel=5e-3)
    part = campaign_run.en50318_measures(t, force, zeros, force, zeros, (2 * span_time, 9.5 * span_time), dt)
    assert abs(part["en50318_contact_force_mean"] - 150.0) > 0.5  # the half span biases the mean by ~1 %
    assert whole["force_hat_error_percent"] == 0.0 and whole["du_dt_max_abs"] == 0.0


CAMPAIGN_SPECS = Path(__file__).resolve().parents[1] / "config" / "campaigns"


@pytest.mark.unit
@pytest.mark.parametrize("spec", sorted(p.name for p in CAMPAIGN_SPECS.glob("*.yaml")))
def test_every_committed_campaign_spec_expands(spec):
    """A committed SPEC that no longer passes validation is found here, not when a user runs it."""
    path = CAMPAIGN_SPECS / spec
    assert campaign_spec.expand(campaign_spec.load_spec(path))


@pytest.mark.unit
def test_the_saturation_share_counts_the_chains_limits_and_the_actuators_rate():
    """Of 100 ticks: 5 the safety chain changed, 10 more on which the actuator's mean force moved by
    its rate limit r h (5 kN/s x 1 ms = 5 N), 10 that moved by 0.999 r h (not at the limit): 15 %.
    On the lumped line (no contact position) the spans are v t from a support."""
    from pac_rig.simulate import scenario_from_flat

    s = scenario_from_flat({"actuator": "electromechanical", "speed_kmh": 234.0})  # a 65 m span in 1 s
    n, dt = 3000, s.loop.sample_period
    applied = np.full(n, 100.0)
    applied[1010:1020] = 100.0 + 5.0 * np.arange(1, 11)  # ramps at r h
    applied[1020:1030] = applied[1019] + 0.999 * 5.0 * np.arange(1, 11)
    applied[1030:] = applied[1029]
    saturated = np.zeros(n, bool)
    saturated[1050:1055] = True
    force = np.full(n, 120.0)
    force[2500:2510] = 0.0  # 10 of span 2's 1000 ticks, in the window
    traces = {"contact_force": force, "contact_position": np.full(n, np.nan), "u_applied": applied,
              "saturated": saturated}  # fmt: skip
    win = np.zeros(n, bool)
    win[1000:1100] = True
    got = campaign_run.limit_measures(s, traces, win, dt)
    assert got["saturation_percent"] == pytest.approx(15.0)
    assert math.isnan(got["worst_span_loss_percent"])  # no whole span in 100 ticks
    win[1000:] = True  # spans 1 and 2 whole
    assert campaign_run.limit_measures(s, traces, win, dt)["worst_span_loss_percent"] == pytest.approx(1.0)
