"""``ros2 run pac_experiments campaign SPEC.yaml --out DIR``: a grid of offline scenarios on Dask.

SPEC (YAML)::

    grid:                 # every combination of these lists (any simulate parameter, see
      c1: [20.0, 40.0]    #   ``ros2 run pac_rig simulate --list``)
      speed_kmh: [200.0, 300.0, 360.0]
    fixed:                # any simulate parameter, the same for every run
      duration: 6.0
    window: [3.0, 6.0]    # measures over this window of simulated time [s]

``grids:`` (a list of such mappings) instead of ``grid:`` runs the union of several grids;
each grid gives its own robustness map in the report. Every grid point is validated
with ``scenario_from_flat`` before anything runs; a bad SPEC stops with one line, exit 2.

By default the runs go to a Dask ``LocalCluster`` on this machine (one single-threaded
worker process per core, bound to 127.0.0.1, no dashboard); ``--scheduler tcp://HOST:PORT``
sends them to an existing Dask cluster instead, with identical results. Each finished
run is appended to ``DIR/runs.jsonl`` at once, keyed by a hash of the scenario's full
parameter set and the window, so re-running the same command skips what is done
(after Ctrl-C or a lost worker). ``DIR/results.csv`` (one row per grid point, grid
order) and ``DIR/report.md`` with its figures are written at the end.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import itertools
import json
import logging
import math
import os
import shutil
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from pac_analysis.metrics import Metrics, RunSeries, metrics_from_series
from pac_common.parameters import ParameterError, check_output_folder
from pac_rig.batch import BatchResult, batchable, run_batch
from pac_rig.closed_loop import DivergenceError, Scenario, TickRecord, run
from pac_rig.simulate import scenario_from_flat, scenario_to_flat, simulate_to_bag

#: The measures of a run, named as in ``pac_analysis.metrics.Metrics`` (and its reports).
METRIC_COLUMNS = tuple(
    f.name for f in dataclasses.fields(Metrics) if f.name not in ("window_from", "window_to")
)
#: EN 50367 quality criteria on the mean contact force Fm and its standard deviation sigma.
EN50367_COLUMNS = ("en50367_sigma_ok", "en50367_min_ok")
#: Always in results.csv, whether varied or not (``law`` empty while no such parameter exists).
ALWAYS = ("law", "speed_kmh")
STATUS_OK, STATUS_DIVERGED, STATUS_ERROR = "ok", "diverged", "error"

RUNS_FILE = "runs.jsonl"
RESULTS_FILE = "results.csv"


class SpecError(ValueError):
    """A campaign SPEC that cannot run; the message is one line."""


@dataclass(frozen=True)
class Spec:
    name: str
    grids: tuple[dict[str, list[Any]], ...]
    fixed: dict[str, Any]
    window: tuple[float, float]

    @property
    def axes(self) -> list[str]:
        """Every parameter a grid names (the campaign's varied ones), in order of first appearance."""
        out: list[str] = []
        for grid in self.grids:
            out += [name for name in grid if name not in out]
        return out


@dataclass(frozen=True)
class Point:
    """One run of the campaign: its values as the SPEC gives them, and its stable key."""

    key: str
    values: dict[str, Any]
    grid: int  # index of the grid it comes from


def load_spec(path: Path) -> Spec:
    """Read and check the SPEC's shape (not yet its values: see :func:`expand`)."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise SpecError(f"cannot read spec {path}: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise SpecError(f"spec {path} is not valid YAML ({first})") from None
    if not isinstance(data, dict):
        raise SpecError(f"spec {path} must be a mapping with 'grid' (or 'grids'), 'fixed', 'window'")
    unknown = sorted(set(data) - {"grid", "grids", "fixed", "window", "name"})
    if unknown:
        raise SpecError(
            f"spec {path}: unknown key '{unknown[0]}' (allowed: grid, grids, fixed, window, name)"
        )
    if ("grid" in data) == ("grids" in data):
        raise SpecError(
            f"spec {path}: give exactly one of 'grid' (a mapping) or 'grids' (a list of mappings)"
        )
    raw_grids = [data["grid"]] if "grid" in data else data["grids"]
    if not isinstance(raw_grids, list) or not raw_grids:
        raise SpecError(f"spec {path}: 'grids' must be a non-empty list of mappings")
    grids = []
    for i, grid in enumerate(raw_grids):
        where = "grid" if "grid" in data else f"grids[{i}]"
        if not isinstance(grid, dict) or not grid:
            raise SpecError(f"spec {path}: '{where}' is empty or not a mapping (parameter: [values, ...])")
        for name, values in grid.items():
            if not isinstance(values, list) or not values:
                raise SpecError(
                    f"spec {path}: {where}.{name} must be a non-empty list of values, got {values!r}"
                )
        grids.append({str(k): list(v) for k, v in grid.items()})
    fixed = data.get("fixed") or {}
    if not isinstance(fixed, dict):
        raise SpecError(f"spec {path}: 'fixed' must be a mapping of parameter: value")
    window = data.get("window", [3.0, None])
    if (
        not isinstance(window, list)
        or len(window) != 2
        or not all(w is None or (isinstance(w, int | float) and not isinstance(w, bool)) for w in window)
        or window[0] is None
    ):
        raise SpecError(f"spec {path}: 'window' must be [from, to] in seconds, got {window!r}")
    name = str(data.get("name") or Path(path).stem)
    return Spec(name, tuple(grids), dict(fixed), (float(window[0]), window[1]))


def point_key(scenario: Scenario, window: tuple[float, float]) -> str:
    """A stable hash of every parameter of the scenario (validated, normalised) and the window."""
    text = json.dumps(
        {"parameters": scenario_to_flat(scenario), "window": list(window)}, sort_keys=True, default=list
    )
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _grid_points(spec: Spec) -> Iterator[Point]:
    """Every point of every grid, validated, in grid order (a point two grids share comes twice)."""
    for gi, grid in enumerate(spec.grids):
        names = list(grid)
        for combo in itertools.product(*grid.values()):
            values = {**spec.fixed, **dict(zip(names, combo, strict=True))}
            try:
                scenario = scenario_from_flat(values)
            except ParameterError as exc:
                raise SpecError(str(exc)) from None
            except (TypeError, ValueError) as exc:
                raise SpecError(f"invalid point {values}: {exc}") from None
            duration = scenario.loop.duration
            w_from, w_to = spec.window[0], duration if spec.window[1] is None else float(spec.window[1])
            if duration <= 0.0:
                raise SpecError("invalid parameter 'duration' = 0.0: allowed (0, 86400] s offline")
            if not 0.0 <= w_from < w_to <= duration:
                raise SpecError(
                    f"invalid window [{w_from:g}, {w_to:g}] s: "
                    f"allowed 0 <= from < to <= duration ({duration:g} s)"
                )
            yield Point(point_key(scenario, (w_from, w_to)), values, gi)


def expand(spec: Spec) -> list[Point]:
    """Every grid point, validated, in grid order; a point several grids share runs once.

    Raises SpecError (one line) on the first invalid point, before anything runs.
    """
    points: list[Point] = []
    seen: set[str] = set()
    for point in _grid_points(spec):
        if point.key not in seen:
            seen.add(point.key)
            points.append(point)
    return points


def grid_keys(spec: Spec) -> list[set[str]]:
    """The keys of each grid's points (the rows a grid's figures show)."""
    keys: list[set[str]] = [set() for _ in spec.grids]
    for point in _grid_points(spec):
        keys[point.grid].add(point.key)
    return keys


def _series(records: list[TickRecord]) -> RunSeries:
    n = len(records)
    every = np.arange(n)
    time_ = np.array([r.truth.time for r in records])
    return RunSeries(
        tick=np.array([r.truth.tick for r in records], dtype=np.int64),
        time=time_,
        contact_force=np.array([r.truth.contact_force for r in records]),
        stiffness=np.array([r.truth.stiffness for r in records]),
        reference_index=every,
        force_reference=np.array([r.command.force_reference for r in records]),
        estimate_index=every,
        stiffness_hat=np.array([r.estimate.stiffness_hat for r in records]),
        u_time=time_,
        u=np.array([r.command.u for r in records]),
    )


def en50367(mean: float, std: float) -> tuple[bool, bool]:
    """EN 50367 criteria: sigma <= 0.3 Fm, and Fm - 3 sigma > 0 (the statistical minimum)."""
    return bool(std <= 0.3 * mean), bool(mean - 3.0 * std > 0.0)


def run_point(point: Point, window: tuple[float, float | None], bag_dir: str | None = None) -> dict[str, Any]:
    """Run one scenario; never raises: a divergence or an exception is the row's status and reason."""
    start = time.perf_counter()
    row: dict[str, Any] = {"key": point.key, "status": STATUS_OK, "reason": ""}
    records: list[TickRecord] = []
    rate = 0.0
    try:
        scenario = scenario_from_flat(point.values)
        rate = scenario.loop.rate_hz
        w_to = scenario.loop.duration if window[1] is None else float(window[1])
        row.update(scenario_to_flat(scenario))
        diverged = None
        if bag_dir is None:
            try:
                for rec in run(scenario):
                    records.append(rec)
            except DivergenceError as exc:
                diverged = str(exc)
        else:
            bag_path = Path(bag_dir) / point.key
            shutil.rmtree(bag_path, ignore_errors=True)  # a partial bag of an interrupted run
            diverged = simulate_to_bag(scenario, bag_path, point.key, on_record=records.append).diverged
        if diverged:
            row.update(status=STATUS_DIVERGED, reason=diverged.splitlines()[0])
        else:
            m = metrics_from_series(_series(records), window[0], w_to)
            row.update({k: getattr(m, k) for k in METRIC_COLUMNS})
            row.update(zip(EN50367_COLUMNS, en50367(m.contact_force_mean, m.contact_force_std), strict=True))
    except Exception as exc:  # noqa: BLE001 - any failure of one run is that run's row, not the campaign's end
        row.update(status=STATUS_ERROR, reason=f"{type(exc).__name__}: {exc}".splitlines()[0])
    row["ticks_run"] = len(records)
    row["simulated_seconds"] = len(records) / rate if rate else 0.0
    row["wall_seconds"] = time.perf_counter() - start
    return row


def _batch_series(result: BatchResult, i: int) -> RunSeries:
    """The series of run ``i`` of a compiled batch: the same numbers as :func:`_series` (bit for bit)."""
    n = int(result.ticks[i])
    every = np.arange(n)
    time_ = every * float(result.sample_period[i])
    traces = {name: result.traces[name][i, :n] for name in result.traces}
    return RunSeries(
        tick=every.astype(np.int64),
        time=time_,
        contact_force=traces["contact_force"],
        stiffness=traces["stiffness"],
        reference_index=every,
        force_reference=traces["force_reference"],
        estimate_index=every,
        stiffness_hat=traces["stiffness_hat"],
        u_time=time_,
        u=traces["u"],
    )


def run_batched(points: list[Point], window: tuple[float, float | None]) -> dict[str, dict[str, Any]]:
    """Rows of the points the compiled batch runs (``pac_rig.batch.batchable``), by key.

    One compiled call for all of them (no per-tick Python); its traces equal
    ``closed_loop.run``'s bit for bit (tests/test_batch.py), so the rows equal
    :func:`run_point`'s. A run that diverges, or a point that does not validate, is left to
    :func:`run_point`, which gives its status and reason.
    """
    chosen: list[tuple[Point, Scenario]] = []
    for point in points:
        try:
            scenario = scenario_from_flat(point.values)
        except Exception:  # noqa: BLE001 - run_point reports it as the row's error
            continue
        if batchable(scenario):
            chosen.append((point, scenario))
    if not chosen:
        return {}
    start = time.perf_counter()
    result = run_batch([s for _, s in chosen])
    wall = (time.perf_counter() - start) / len(chosen)
    rows = {}
    for i, (point, scenario) in enumerate(chosen):
        if result.diverged[i] is not None:
            continue
        w_to = scenario.loop.duration if window[1] is None else float(window[1])
        m = metrics_from_series(_batch_series(result, i), window[0], w_to)
        row: dict[str, Any] = {"key": point.key, "status": STATUS_OK, "reason": ""}
        row.update(scenario_to_flat(scenario))
        row.update({k: getattr(m, k) for k in METRIC_COLUMNS})
        row.update(zip(EN50367_COLUMNS, en50367(m.contact_force_mean, m.contact_force_std), strict=True))
        row["ticks_run"] = int(result.ticks[i])
        row["simulated_seconds"] = int(result.ticks[i]) / scenario.loop.rate_hz
        row["wall_seconds"] = wall
        rows[point.key] = row
    return rows


def run_chunk(
    points: list[Point], window: tuple[float, float | None], bag_dir: str | None = None
) -> list[dict]:
    """The Dask task: several runs in one task, so the per-task overhead is paid once per chunk.

    Without bags, the points the compiled batch can run go through it in one call; the rest
    (other laws, the FE line, divergences) run tick by tick.
    """
    batched = {}
    if bag_dir is None:
        try:
            batched = run_batched(points, window)
        except Exception:  # noqa: BLE001 - every point then runs tick by tick and reports for itself
            batched = {}
    return [batched.get(p.key) or run_point(p, window, bag_dir) for p in points]


def read_done(out: Path) -> dict[str, dict[str, Any]]:
    """Rows already in ``DIR/runs.jsonl`` by key (a torn last line, from a kill, is ignored)."""
    done: dict[str, dict[str, Any]] = {}
    path = out / RUNS_FILE
    if not path.exists():
        return done
    for line in path.read_text().splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(row, dict) and "key" in row:
            done[row["key"]] = row
    return done


def _cell(value: Any) -> Any:
    if isinstance(value, list | tuple):
        return json.dumps(list(value))
    return value


def result_columns(spec: Spec) -> list[str]:
    axes = spec.axes
    return (
        [*axes, *(a for a in ALWAYS if a not in axes), "status", "reason"]
        + list(METRIC_COLUMNS)
        + list(EN50367_COLUMNS)
        + ["ticks_run", "simulated_seconds", "key"]
    )


def write_results(spec: Spec, points: list[Point], done: dict[str, dict], out: Path) -> list[dict]:
    """``results.csv``: one row per grid point that has run, in grid order (no wall times: reproducible)."""
    columns = result_columns(spec)
    rows = [done[p.key] for p in points if p.key in done]
    tmp = out / (RESULTS_FILE + ".tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_cell(row.get(c, "")) for c in columns])
    tmp.replace(out / RESULTS_FILE)
    return rows


@dataclass
class Outcome:
    total: int
    skipped: int
    ran: int
    failed: int  # diverged or raised
    lost: int  # tasks the cluster could not run (not written: a re-run retries them)
    wall_seconds: float
    simulated_seconds: float
    interrupted: bool = False


def _chunks(points: list[Point], size: int) -> list[list[Point]]:
    return [points[i : i + size] for i in range(0, len(points), size)]


def auto_chunk_size(n_points: int, workers: int) -> int:
    """About 4 tasks per worker (load balance, little lost on Ctrl-C), at most 16 runs per task."""
    return max(1, min(16, math.ceil(n_points / max(1, 4 * workers))))


def execute(
    client: Any,
    spec: Spec,
    points: list[Point],
    out: Path,
    chunk_size: int | None = None,
    bags: bool = False,
    progress: bool | None = None,
    on_row: Callable[[dict], None] | None = None,
) -> Outcome:
    """Run the points not yet in ``out`` on the Dask ``client``; append each finished row at once."""
    from distributed import as_completed
    from tqdm import tqdm

    out.mkdir(parents=True, exist_ok=True)
    done = read_done(out)
    todo = [p for p in points if p.key not in done]
    workers = max(1, len(client.scheduler_info().get("workers", {})))
    size = chunk_size or auto_chunk_size(len(todo), workers)
    bag_dir = str((out / "bags").resolve()) if bags else None
    outcome = Outcome(len(points), len(points) - len(todo), 0, 0, 0, 0.0, 0.0)
    start = time.perf_counter()
    bar = tqdm(
        total=len(todo),
        unit="run",
        disable=(not sys.stdout.isatty()) if progress is None else not progress,
        desc=spec.name,
        file=sys.stdout,
    )
    run_id = uuid.uuid4().hex[
        :8
    ]  # task keys unique per invocation (a shared scheduler may remember old ones)
    futures = [
        client.submit(run_chunk, chunk, spec.window, bag_dir, pure=False, key=f"campaign-{run_id}-{i}")
        for i, chunk in enumerate(_chunks(todo, size))
    ]
    sizes = {f.key: len(c) for f, c in zip(futures, _chunks(todo, size), strict=True)}
    # Ctrl-C sets a flag that the loop below polls (every 50 ms) rather than raising inside
    # Dask's client code; the rows written so far stay, the rest is cancelled.
    stop = threading.Event()
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, lambda *_: stop.set()) if in_main else None
    try:
        with (out / RUNS_FILE).open("a+") as log:
            if log.tell() > 0:
                log.seek(log.tell() - 1)
                if log.read(1) != "\n":
                    log.write("\n")  # after a torn last line (a kill mid-write) start a fresh one
            pending = as_completed(futures)
            while not stop.is_set() and not pending.is_empty():
                batch = pending.next_batch(block=False)
                if not batch:
                    stop.wait(0.05)
                for future in batch:
                    try:
                        rows = future.result()
                    except Exception as exc:  # noqa: BLE001 - a lost worker or task: its runs stay to do
                        outcome.lost += sizes[future.key]
                        bar.write(
                            f"campaign: {sizes[future.key]} runs not done ({type(exc).__name__}: {exc})"
                        )
                        bar.update(sizes[future.key])
                        continue
                    for row in rows:
                        log.write(json.dumps(row) + "\n")
                        done[row["key"]] = row
                        outcome.ran += 1
                        outcome.failed += row["status"] != STATUS_OK
                        outcome.simulated_seconds += row["simulated_seconds"]
                        if on_row is not None:
                            on_row(row)
                    log.flush()
                    bar.update(len(rows))
                    bar.set_postfix(failed=outcome.failed, refresh=False)
    except KeyboardInterrupt:  # defensive: any other interrupt in here stops the same way
        stop.set()
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        if stop.is_set():
            outcome.interrupted = True
            client.cancel(futures)
        bar.close()
        outcome.wall_seconds = time.perf_counter() - start
        write_results(spec, points, done, out)
    return outcome


def embedded_cluster(workers: int | None = None) -> Any:
    """One single-threaded worker process per core, on loopback, without a dashboard.

    (Dask still serves its health/metrics routes over HTTP: on a free loopback port.)
    """
    from distributed import LocalCluster

    # The worker processes start with SIGINT ignored (a new interpreter keeps an inherited
    # SIG_IGN): Ctrl-C stops the campaign, which then closes its workers cleanly.
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        return LocalCluster(
            n_workers=workers or os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
            silence_logs=logging.CRITICAL,  # task errors reach us through their futures
        )
    finally:
        signal.signal(signal.SIGINT, previous)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="campaign", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("spec", type=Path, help="campaign SPEC (YAML)")
    parser.add_argument("--out", type=Path, required=True, help="output directory (re-using it resumes)")
    parser.add_argument(
        "--scheduler", help="address of an existing Dask scheduler, e.g. tcp://127.0.0.1:8786"
    )
    parser.add_argument("--workers", type=int, help="embedded cluster: worker processes (default: cores)")
    parser.add_argument(
        "--chunk-size", type=int, help="runs per Dask task (default: about 4 tasks per worker)"
    )
    parser.add_argument("--bags", action="store_true", help="keep each run's bag in DIR/bags/<key>")
    parser.add_argument("--no-report", action="store_true", help="results.csv only")
    args = parser.parse_args(argv)
    try:
        for name in ("workers", "chunk_size"):
            value = getattr(args, name)
            if value is not None and value < 1:
                raise SpecError(
                    f"invalid option '--{name.replace('_', '-')}' = {value}: allowed an integer >= 1"
                )
        check_output_folder("--out", args.out)
        spec = load_spec(args.spec)
        points = expand(spec)
    except (SpecError, ParameterError) as exc:
        print(f"campaign: {exc}", file=sys.stderr)
        return 2

    from distributed import Client

    cluster = client = None
    setup_start = time.perf_counter()
    done = read_done(args.out)
    if all(p.key in done for p in points):  # all done: no cluster needed
        return _finish(args, spec, points, Outcome(len(points), len(points), 0, 0, 0, 0.0, 0.0), 0.0)
    try:
        if args.scheduler:
            client = Client(args.scheduler, timeout="20s")
            client.wait_for_workers(1, timeout=60)  # chunking and progress need to know the workers
        else:
            cluster = embedded_cluster(args.workers)
            client = Client(cluster)
    except (OSError, TimeoutError, ValueError) as exc:
        where = f"Dask scheduler {args.scheduler} (or no worker)" if args.scheduler else "local Dask cluster"
        print(f"campaign: cannot start on the {where}: {exc}", file=sys.stderr)
        for thing in (client, cluster):
            if thing is not None:
                thing.close()
        return 1
    setup = time.perf_counter() - setup_start
    try:
        outcome = execute(client, spec, points, args.out, args.chunk_size, args.bags)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return _finish(args, spec, points, outcome, setup)


def _finish(args: argparse.Namespace, spec: Spec, points: list[Point], outcome: Outcome, setup: float) -> int:
    rate = outcome.simulated_seconds / outcome.wall_seconds if outcome.wall_seconds > 0 else math.nan
    print(
        f"campaign {spec.name}: {outcome.total} runs, {outcome.skipped} already done, {outcome.ran} run "
        f"({outcome.failed} diverged or failed), {outcome.lost} lost; {outcome.simulated_seconds:.1f} "
        f"scenario-s in {outcome.wall_seconds:.1f} s = {rate:.1f} scenario-s per wall-s "
        f"(+{setup:.1f} s cluster start)"
    )
    if outcome.interrupted:
        print("campaign: interrupted; re-run the same command to resume", file=sys.stderr)
        return 130
    args.out.mkdir(parents=True, exist_ok=True)
    rows = write_results(spec, points, read_done(args.out), args.out)
    print(f"wrote {args.out / RESULTS_FILE}")
    if not args.no_report:
        from .campaign_report import write_report

        print(f"wrote {write_report(spec, rows, args.out)}")
    return 1 if outcome.lost else 0


if __name__ == "__main__":
    sys.exit(main())
