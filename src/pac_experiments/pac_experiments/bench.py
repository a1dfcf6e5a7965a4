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
    return 0


if __name__ == "__main__":
    sys.exit(main())
