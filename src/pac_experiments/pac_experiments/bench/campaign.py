"""``ros2 run pac_experiments campaign_bench``: Dask per-task overhead and campaign throughput (a table).

On the embedded cluster (one worker process per core): the wall time of empty tasks, then
the same grid of offline runs with one run per task and with the default chunking,
in scenario-seconds per wall-second. Nothing is asserted: timing on a shared machine is noisy.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from pac_common import markdown
from pac_experiments.campaign.dask_runner import auto_chunk_size, embedded_cluster, execute
from pac_experiments.campaign.run import run_chunk
from pac_experiments.campaign.spec import Spec, expand


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="campaign_bench", description=__doc__)
    parser.add_argument("--workers", type=int, help="worker processes (default: cores)")
    parser.add_argument("--runs", type=int, default=16, help="offline runs per throughput row")
    parser.add_argument("--duration", type=float, default=2.0, help="simulated seconds per run")
    parser.add_argument("--empty-tasks", type=int, default=400)
    args = parser.parse_args(argv)
    if args.runs < 1 or not 0.0 < args.duration <= 600.0 or args.empty_tasks < 1:
        print("campaign_bench: --runs >= 1, --duration in (0, 600] s, --empty-tasks >= 1", file=sys.stderr)
        return 2
    from distributed import Client, wait

    speeds = [160.0 + 240.0 * i / max(1, args.runs - 1) for i in range(args.runs)]
    spec = Spec("bench", ({"speed_kmh": speeds},), {"duration": args.duration}, (0.0, args.duration))
    points = expand(spec)
    cluster = embedded_cluster(args.workers)
    client = Client(cluster)
    rows = []
    try:
        workers = len(client.scheduler_info()["workers"])
        client.submit(run_chunk, [], pure=False).result()  # imports on a worker
        start = time.perf_counter()
        wait([client.submit(run_chunk, [], pure=False) for _ in range(args.empty_tasks)])
        per_task = (time.perf_counter() - start) / args.empty_tasks
        rows.append(("empty task", f"{args.empty_tasks} tasks", f"{1e3 * per_task:.2f} ms per task"))
        for label, size in (("1 run per task", 1), ("default chunks", auto_chunk_size(len(points), workers))):
            with tempfile.TemporaryDirectory() as tmp:
                outcome = execute(client, spec, points, Path(tmp), chunk_size=size, progress=False)
            rate = outcome.simulated_seconds / outcome.wall_seconds
            rows.append(
                (
                    label,
                    f"{len(points)} x {args.duration:g} s, chunk {size}",
                    f"{rate:.1f} scenario-s per wall-s",
                )
            )
    finally:
        client.close()
        cluster.close()
    print(f"Campaign engine on {workers} local Dask workers (1 thread each)\n")
    print(markdown.table(["measure", "what", "result"], rows, ["l", "l", "r"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
