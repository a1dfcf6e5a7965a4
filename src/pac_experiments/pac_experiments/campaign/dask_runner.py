"""Running a campaign's points on Dask: the embedded local cluster or an existing scheduler.

Each finished run is appended to ``DIR/runs.jsonl`` at once (so re-running the same
command skips what is done, after Ctrl-C or a lost worker); ``results.csv`` is rewritten
at the end.
"""

from __future__ import annotations

import logging
import math
import os
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pac_experiments.campaign.results import RUNS_FILE, read_done, runs_line, write_results
from pac_experiments.campaign.run import STATUS_OK, run_chunk
from pac_experiments.campaign.spec import Point, Spec


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
    batch_error: str = ""  # the first failure of the compiled batch (its runs then ran tick by tick)


def _chunks(points: list[Point], size: int) -> list[list[Point]]:
    return [points[i : i + size] for i in range(0, len(points), size)]


def auto_chunk_size(n_points: int, workers: int) -> int:
    """About 4 tasks per worker (load balance, little lost on Ctrl-C), at most 16 runs per task."""
    return max(1, min(16, math.ceil(n_points / max(1, 4 * workers))))


class _RowLog:
    """``DIR/runs.jsonl`` opened for appending, and what a finished task's rows change: the file
    (a row flushed at once), the rows done, the outcome's counts and the progress bar."""

    def __init__(self, out: Path, done: dict, outcome: Outcome, bar: Any, on_row) -> None:
        self.done, self.outcome, self.bar, self.on_row = done, outcome, bar, on_row
        self.log = (out / RUNS_FILE).open("a+")
        if self.log.tell() > 0:
            self.log.seek(self.log.tell() - 1)
            if self.log.read(1) != "\n":
                self.log.write("\n")  # after a torn last line (a kill mid-write) start a fresh one

    def rows(self, rows: list[dict]) -> None:
        outcome = self.outcome
        for row in rows:
            if row.get("batch_error") and not outcome.batch_error:
                outcome.batch_error = row["batch_error"]
                self.bar.write(
                    f"campaign: the compiled batch failed ({row['batch_error']}); its runs ran tick by tick"
                )
            self.log.write(runs_line(row))
            self.done[row["key"]] = row
            outcome.ran += 1
            outcome.failed += row["status"] != STATUS_OK
            outcome.simulated_seconds += row["simulated_seconds"]
            if self.on_row is not None:
                self.on_row(row)
        self.log.flush()
        self.bar.update(len(rows))
        self.bar.set_postfix(failed=outcome.failed, refresh=False)

    def close(self) -> None:
        self.log.close()


def _start(
    spec: Spec, points: list[Point], out: Path, progress: bool | None
) -> tuple[dict, list[Point], Outcome, Any]:
    """(rows done, points to do, the outcome so far, the progress bar) of a campaign in ``out``."""
    from tqdm import tqdm

    out.mkdir(parents=True, exist_ok=True)
    done = read_done(out)
    todo = [p for p in points if p.key not in done]
    outcome = Outcome(len(points), len(points) - len(todo), 0, 0, 0, 0.0, 0.0)
    bar = tqdm(
        total=len(todo),
        unit="run",
        disable=(not sys.stdout.isatty()) if progress is None else not progress,
        desc=spec.name,
        file=sys.stdout,
    )
    return done, todo, outcome, bar


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

    done, todo, outcome, bar = _start(spec, points, out, progress)
    workers = max(1, len(client.scheduler_info().get("workers", {})))
    size = chunk_size or auto_chunk_size(len(todo), workers)
    bag_dir = str((out / "bags").resolve()) if bags else None
    start = time.perf_counter()
    run_id = uuid.uuid4().hex[
        :8
    ]  # task keys unique per invocation (a shared scheduler may remember old ones)
    futures = [
        client.submit(run_chunk, chunk, bag_dir, pure=False, key=f"campaign-{run_id}-{i}")
        for i, chunk in enumerate(_chunks(todo, size))
    ]
    sizes = {f.key: len(c) for f, c in zip(futures, _chunks(todo, size), strict=True)}
    # Ctrl-C sets a flag that the loop below polls (every 50 ms) rather than raising inside
    # Dask's client code; the rows written so far stay, the rest is cancelled.
    stop = threading.Event()
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, lambda *_: stop.set()) if in_main else None
    log = _RowLog(out, done, outcome, bar, on_row)
    try:
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
                    bar.write(f"campaign: {sizes[future.key]} runs not done ({type(exc).__name__}: {exc})")
                    bar.update(sizes[future.key])
                    continue
                log.rows(rows)
    except KeyboardInterrupt:  # defensive: any other interrupt in here stops the same way
        stop.set()
    finally:
        log.close()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        if stop.is_set():
            outcome.interrupted = True
            client.cancel(futures)
        bar.close()
        outcome.wall_seconds = time.perf_counter() - start
        write_results(spec, points, done, out)
    return outcome


def in_process_chunk_size(n_points: int, threads: int) -> int:
    """Runs per compiled batch in process: 8 per thread (threads kept busy to the end of a chunk,
    and a finished chunk's rows written before the next starts, for a resume after Ctrl-C)."""
    return max(1, min(n_points, 8 * threads))


def runs_in_process(spec: Spec, points: list[Point], bags: bool) -> bool:
    """Whether ``campaign`` runs the points here rather than on a cluster: each is one the compiled
    batch runs (its threads use every core, no worker process starts, no second process loads
    the compiled code or builds an FE line again), and no bags are asked for."""
    from pac_rig.batch import batchable

    if bags:
        return False
    try:
        return all(batchable(p.built()) for p in points)
    except Exception:  # noqa: BLE001 - a point that does not build: the cluster path reports it per row
        return False


def execute_in_process(
    spec: Spec,
    points: list[Point],
    out: Path,
    threads: int,
    chunk_size: int | None = None,
    progress: bool | None = None,
    on_row: Callable[[dict], None] | None = None,
) -> Outcome:
    """:func:`execute` without Dask: the points not yet in ``out`` through the compiled batch in this
    process, ``threads`` threads, a chunk at a time (each chunk's rows appended when it is done).
    Ctrl-C stops after the running chunk (compiled code is not interrupted); what was written stays.
    The handler is set here, as :func:`execute` does: a process started with SIGINT ignored (a
    background job of a script) would otherwise never see it."""
    done, todo, outcome, bar = _start(spec, points, out, progress)
    size = chunk_size or in_process_chunk_size(len(todo), threads)
    start = time.perf_counter()
    stop = threading.Event()
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, lambda *_: stop.set()) if in_main else None
    log = _RowLog(out, done, outcome, bar, on_row)
    try:
        for chunk in _chunks(todo, size):
            if stop.is_set():
                break
            log.rows(run_chunk(chunk, None, threads))
    except KeyboardInterrupt:  # defensive, as in execute
        stop.set()
    finally:
        log.close()
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        outcome.interrupted = stop.is_set() and outcome.ran < len(todo)
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
