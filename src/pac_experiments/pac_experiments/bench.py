"""``make bench``: loop timing of the live rig and speed of the offline simulator.

Runs (1) a real-time rig for ``--realtime-seconds`` (default 30), (2) a lock-step rig
for ``--lockstep-seconds`` of simulated time, (3) the offline simulator for 10 s
with and without bag writing, and prints one table.  Timing is measured, never
asserted: the machine is shared and noisy.
"""

from __future__ import annotations

import argparse
import platform
import shutil
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

from pac_analysis.metrics import compute_metrics, loop_timing, timing_table
from pac_common import messages
from pac_rig.bag import read_bag
from pac_rig.closed_loop import Scenario, run
from pac_rig.launcher import Rig
from pac_rig.simulate import simulate_to_bag


def live_run(mode: str, seconds: float, workdir: Path, priority: int) -> tuple:
    import domain_coordinator

    bag_path = workdir / mode
    with domain_coordinator.domain_id() as domain_id:
        rig = Rig(
            bag_path,
            duration=seconds,
            timing_mode=mode,
            domain_id=domain_id,
            params={"all": {"realtime_priority": priority}},
        )
        try:
            rig.start()
            rig.wait_finished(timeout=120.0 + 10.0 * seconds)
        finally:
            codes = rig.stop()
    if any(code != 0 for code in codes.values()):
        raise RuntimeError(f"{mode} run: exit codes {codes}; logs in {rig.log_dir}")
    bag = read_bag(bag_path)
    cpu = {
        n: 100.0 * p.cpu_seconds / p.wall_seconds
        for n, p in rig.processes.items()
        if p.cpu_seconds is not None and p.wall_seconds
    }
    return loop_timing(bag), cpu, compute_metrics(bag, min(3.0, seconds / 2))


def offline_speed(with_bag: bool, workdir: Path) -> float:
    scenario = Scenario()
    start = time.perf_counter()
    if with_bag:
        simulate_to_bag(scenario, workdir / "offline")
    else:
        for _ in run(scenario):
            pass
    return scenario.loop.duration / (time.perf_counter() - start)


def bag_writing(workdir: Path, seconds: float = 10.0) -> list[tuple[str, float, float, int]]:
    """Cost of recording an offline run: (path, wall and CPU ms per simulated second, bag bytes).

    The run's ticks are collected first (the simulator's own field dictionaries), then written
    through the bulk path (columns -> CDR -> chunks) with each compression, and message by
    message with the rosbags serialiser (the path before #10) for comparison; best of 3."""
    from pac_rig.bag import BagWriter
    from pac_rig.mcap_writer import COMPRESSIONS
    from pac_rig.simulate import scenario_from_flat, tick_fields, write_ticks

    scenario = scenario_from_flat({"duration": seconds})
    rows: dict[str, list] = {}
    stamps = []
    for rec in run(scenario):
        for topic, fields in tick_fields(rec, scenario).items():
            rows.setdefault(topic, []).append(fields)
        stamps.append(messages.tick_stamp_ns(rec.measurement.tick, scenario.loop.rate_hz))

    def timed(name: str, write) -> tuple[str, float, float, int]:
        wall = cpu = float("inf")
        for attempt in range(3):
            path = workdir / f"bag_{attempt}"
            start, start_cpu = time.perf_counter(), time.process_time()
            write(path)
            wall = min(wall, time.perf_counter() - start)
            cpu = min(cpu, time.process_time() - start_cpu)
            size = sum(f.stat().st_size for f in path.iterdir())
            shutil.rmtree(path)
        return name, 1e3 * wall / seconds, 1e3 * cpu / seconds, size

    def bulk(compression: str):
        def write(path: Path) -> None:
            with BagWriter(path, compression=compression) as bag:
                write_ticks(bag, rows, stamps)

        return write

    def one_by_one(path: Path) -> None:
        with BagWriter(path, compression="none") as bag:
            for topic, block in rows.items():
                for fields, stamp in zip(block, stamps, strict=True):
                    bag.write(topic, fields, stamp)

    results = [timed(f"bulk, {c}", bulk(c)) for c in COMPRESSIONS]
    results.append(timed("message by message (rosbags CDR), none", one_by_one))
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench", description=__doc__)
    parser.add_argument("--realtime-seconds", type=float, default=30.0)
    parser.add_argument("--lockstep-seconds", type=float, default=10.0)
    parser.add_argument(
        "--realtime-priority", type=int, default=0, help="SCHED_FIFO priority for the loop nodes (0: off)"
    )
    args = parser.parse_args(argv)
    workdir = Path(tempfile.mkdtemp(prefix="pac_bench_"))
    try:
        runs, cpus, quality = {}, {}, {}
        for mode, seconds in (("realtime", args.realtime_seconds), ("lockstep", args.lockstep_seconds)):
            print(f"bench: {mode} rig, {seconds:g} s ...", flush=True)
            runs[mode], cpus[mode], quality[mode] = live_run(mode, seconds, workdir, args.realtime_priority)
        print("bench: offline simulator ...", flush=True)
        speed_core, speed_bag = offline_speed(False, workdir), offline_speed(True, workdir)
        print("bench: bag writing ...", flush=True)
        writing = bag_writing(workdir)
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    print(
        f"\n## pac bench, {datetime.now():%Y-%m-%d %H:%M}, {platform.node()}, "
        f"{platform.machine()}, {__import__('os').cpu_count()} cores, realtime_priority "
        f"{args.realtime_priority}\n"
    )
    print(timing_table(runs), end="")
    names = list(runs)
    for node in ("plant", "observer", "controller", "recorder"):
        print(
            f"| CPU {node} [%] | "
            + " | ".join(f"{cpus[n].get(node, float('nan')):.0f}" for n in names)
            + " |"
        )
    print(
        "| contact-force std [N] | " + " | ".join(f"{quality[n].contact_force_std:.3g}" for n in names) + " |"
    )
    print(
        f"\nOffline simulator, 10 s scenario: {speed_core:.1f}x real time (cores only), "
        f"{speed_bag:.1f}x with bag writing"
    )
    print(
        "\n| bag writing, 10 s offline run | wall ms per simulated s | CPU ms per simulated s "
        "| bag size [MB] |\n|---|---|---|---|"
    )
    for name, wall, cpu, size in writing:
        print(f"| {name} | {wall:.1f} | {cpu:.1f} | {size / 1e6:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
