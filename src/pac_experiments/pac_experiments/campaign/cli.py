"""``ros2 run pac_experiments campaign SPEC.yaml --out DIR``: a grid of offline scenarios on Dask.

The SPEC (YAML) is described in ``campaign_spec``: ``grid`` (or ``grids``), ``fixed``,
``window`` (seconds) or ``window_spans`` (whole spans of the line), ``statistics``
(``raw`` | ``en50318``), ``force_target`` (``en50367``). Every grid point is validated
before anything runs; a bad SPEC stops with exit 2 and one line per error, all of them at once.

When every point is one the compiled batch runs (every law, both lines) and no bags are
asked for, the runs go through it in this process, one thread per core (``--workers``
threads): no cluster starts and the compiled code and an FE line are loaded once. Otherwise
(or with ``--cluster``) they go to a Dask ``LocalCluster`` on this machine (one
single-threaded worker process per core, bound to 127.0.0.1, no dashboard);
``--scheduler tcp://HOST:PORT`` sends them to an existing Dask cluster instead. The rows are
the same on every path. Each finished
run is appended to ``DIR/runs.jsonl`` at once, keyed by a hash of the scenario's full
parameter set and the window, so re-running the same command skips what is done
(after Ctrl-C or a lost worker). ``DIR/results.csv`` (one row per grid point, grid
order) and ``DIR/report.md`` with its figures are written at the end.

Modules by job: ``campaign_spec`` (SPEC, points, keys), ``campaign_run`` (one row per
point: tick by tick or the compiled batch), ``campaign_results`` (runs.jsonl, results.csv),
``campaign_dask`` (the cluster), ``campaign_report`` (report.md, figures), this CLI.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

from pac_common.files import FileInputError
from pac_common.parameters import ParameterError, check_output_folder
from pac_experiments.campaign.dask_runner import (
    Outcome,
    embedded_cluster,
    execute,
    execute_in_process,
    runs_in_process,
)
from pac_experiments.campaign.results import RESULTS_FILE, RUNS_FILE, read_done, write_results
from pac_experiments.campaign.spec import Point, Spec, SpecError, grid_size, load_points

INTERRUPTED = "campaign: interrupted; re-run the same command to resume"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="campaign", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("spec", type=Path, help="campaign SPEC (YAML)")
    parser.add_argument("--out", type=Path, required=True, help="output directory (re-using it resumes)")
    parser.add_argument(
        "--scheduler", help="address of an existing Dask scheduler, e.g. tcp://127.0.0.1:8786"
    )
    parser.add_argument(
        "--workers",
        type=int,
        help="worker processes of the embedded cluster, or threads of a run in process (default: cores)",
    )
    parser.add_argument(
        "--cluster",
        action="store_true",
        help="the embedded Dask cluster even when the runs could go through the batch in process",
    )
    parser.add_argument(
        "--chunk-size", type=int, help="runs per Dask task (default: about 4 tasks per worker)"
    )
    parser.add_argument("--bags", action="store_true", help="keep each run's bag in DIR/bags/<key>")
    parser.add_argument("--no-report", action="store_true", help="results.csv only")
    args = parser.parse_args(argv)
    try:
        return _run(args)
    except KeyboardInterrupt:  # Ctrl-C while the SPEC's points are checked, or in a cluster's start
        print(INTERRUPTED, file=sys.stderr)
        return 130
    except FileInputError as exc:  # the --out folder's runs.jsonl cannot be read
        print(f"campaign: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the disk filled up or the folder went read-only during the runs
        print(
            f"campaign: cannot write in {args.out}: {exc.strerror or exc}; the finished runs are in "
            f"{RUNS_FILE} (a torn last line is ignored): re-run the same command to resume",
            file=sys.stderr,
        )
        return 1


#: Grid points from which checking them takes long enough to say so first.
ANNOUNCE_POINTS = 100


def _announce(spec: Spec) -> None:
    """The campaign's size before its points are checked (a grid of thousands takes seconds)."""
    if grid_size(spec.grids) >= ANNOUNCE_POINTS:
        print(
            f"campaign {spec.name}: {grid_size(spec.grids)} grid points in {len(spec.grids)} grid(s); "
            "checking them",
            flush=True,
        )


def _run(args: argparse.Namespace) -> int:
    # Every error of the command line and the SPEC at once, one line each; nothing runs.
    errors = [
        f"invalid option '--{name.replace('_', '-')}' = {value}: allowed an integer >= 1"
        for name, value in (("workers", args.workers), ("chunk_size", args.chunk_size))
        if value is not None and value < 1
    ]
    try:
        check_output_folder("--out", args.out)
    except ParameterError as exc:
        errors.append(str(exc))
    try:
        spec, points = load_points(args.spec, _announce)
    except SpecError as exc:
        errors += exc.errors
    if errors:
        for line in errors:
            print(f"campaign: {line}", file=sys.stderr)
        return 2

    cluster = client = None
    setup_start = time.perf_counter()
    done = read_done(args.out)
    if all(p.key in done for p in points):  # all done: no cluster needed
        return _finish(args, spec, points, Outcome(len(points), len(points), 0, 0, 0, 0.0, 0.0), 0.0)
    todo = [p for p in points if p.key not in done]
    if not (args.scheduler or args.cluster) and runs_in_process(spec, todo, args.bags):
        threads = args.workers or os.cpu_count() or 1
        outcome = execute_in_process(spec, points, args.out, threads, args.chunk_size)
        return _finish(args, spec, points, outcome, None)
    from distributed import Client

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


def _finish(
    args: argparse.Namespace, spec: Spec, points: list[Point], outcome: Outcome, setup: float | None
) -> int:
    """``setup``: seconds the cluster took to start; None: the runs went through the batch in process."""
    rate = outcome.simulated_seconds / outcome.wall_seconds if outcome.wall_seconds > 0 else math.nan
    where = "in process, no cluster" if setup is None else f"+{setup:.1f} s cluster start"
    print(
        f"campaign {spec.name}: {outcome.total} runs, {outcome.skipped} already done, {outcome.ran} run "
        f"({outcome.failed} diverged or failed), {outcome.lost} lost; {outcome.simulated_seconds:.1f} "
        f"scenario-s in {outcome.wall_seconds:.1f} s = {rate:.1f} scenario-s per wall-s "
        f"({where})"
    )
    if outcome.batch_error:
        print(f"campaign: the compiled batch failed ({outcome.batch_error}); its runs ran tick by tick")
    if outcome.interrupted:
        print(INTERRUPTED, file=sys.stderr)
        return 130
    args.out.mkdir(parents=True, exist_ok=True)
    rows = write_results(spec, points, read_done(args.out), args.out)
    print(f"wrote {args.out / RESULTS_FILE}")
    if not args.no_report:
        from pac_experiments.campaign.report import write_report  # matplotlib: only when a report is written

        print(f"wrote {write_report(spec, rows, args.out)}")
    return 1 if outcome.lost else 0


if __name__ == "__main__":
    sys.exit(main())
