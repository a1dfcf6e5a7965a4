"""``make bench``: loop timing of the live rig and speed of the offline simulator.

Runs (1) a real-time rig for ``--realtime-seconds`` (default 30), (2) a lock-step rig
for ``--lockstep-seconds`` of simulated time, (3) the offline simulator for 10 s
with and without bag writing, and prints one table.  Timing is measured, never
asserted: the machine is shared and noisy.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path

from pac_analysis.metrics import compute_metrics, loop_timing, timing_table
from pac_rig.bag import read_bag
from pac_rig.closed_loop import Scenario, run
from pac_rig.launcher import Rig
from pac_rig.simulate import simulate_to_bag


def live_run(
    mode: str,
    seconds: float,
    workdir: Path,
    priority: int | None,
    *,
    relay: bool = False,
    composed: bool = False,
    label: str | None = None,
) -> tuple:
    """One live rig (``relay``: the floor); ``priority`` None: the launcher's default priorities,
    0: normal scheduling, else SCHED_FIFO ``priority`` on the loop nodes (the recorder at normal)."""
    import domain_coordinator

    bag_path = workdir / (label or mode)
    with domain_coordinator.domain_id() as domain_id:
        rig = Rig(
            bag_path,
            duration=seconds,
            timing_mode=mode,
            domain_id=domain_id,
            params={} if priority is None else {"all": {"realtime_priority": priority}},
            relay=relay,
            composed=composed,
            priorities=None if priority is None else {},
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
    # The floor's physics is meaningless (no plant): only its timing is read.
    quality = None if relay else compute_metrics(bag, min(3.0, seconds / 2))
    return loop_timing(bag), cpu, quality


@contextlib.contextmanager
def busy_loops(n: int) -> Iterator[list[subprocess.Popen]]:
    """``n`` processes spinning at normal priority (the load), killed by PID on exit."""
    procs = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)
        for _ in range(n)
    ]
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()


#: The measures whose pac/floor ratio the floor table prints (higher is worse for all but steps/s).
FLOOR_RATIOS = (
    ("steps_per_second", "steps/s"),
    ("period_p99_ms", "period p99"),
    ("latency_p50_ms", "y -> u latency p50"),
    ("latency_p99_ms", "y -> u latency p99"),
)


def number(value: float, fmt: str) -> str:
    """A table cell; "-" where the column has no such process (composed: one ``loop``)."""
    return "-" if math.isnan(value) else fmt.format(value)


def floor_table(runs: dict, cpus: dict, pairs: list[tuple[str, str]]) -> str:
    """pac / floor for each (pac column, floor column) measured in the same bench run."""
    lines = [
        "| pac / floor | " + " | ".join(p for p, _ in pairs) + " |",
        "|---|" + "---:|" * len(pairs),
    ]
    for key, label in FLOOR_RATIOS:
        cells = [getattr(runs[p], key) / getattr(runs[f], key) for p, f in pairs]
        lines.append(f"| {label} | " + " | ".join(f"{c:.2f}" for c in cells) + " |")
    for node in ("plant", "observer", "controller", "loop", "recorder"):
        cells = [cpus[p].get(node, math.nan) / cpus[f].get(node, math.nan) for p, f in pairs]
        lines.append(f"| CPU {node} | " + " | ".join(number(c, "{:.2f}") for c in cells) + " |")
    return "\n".join(lines) + "\n"


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
        "--realtime-priority",
        type=int,
        default=None,
        help="SCHED_FIFO priority for the loop nodes, recorder at normal (0: all normal; "
        "default: the launcher's, loop 60 above recorder 50)",
    )
    parser.add_argument(
        "--load", type=int, default=0, help="also run the real-time pac and floor rigs under N busy loops"
    )
    parser.add_argument(
        "--composed",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also run the loop composed in one process (ros2 run pac_rig composed), pac and floor",
    )
    args = parser.parse_args(argv)
    if args.load < 0:
        print(f"bench: invalid --load {args.load}: allowed an integer >= 0", file=sys.stderr)
        return 2
    workdir = Path(tempfile.mkdtemp(prefix="pac_bench_"))
    try:
        runs, cpus, quality = {}, {}, {}
        # (column, timing mode, seconds, composed, busy loops): each is run as pac, then as its floor.
        plan = [("realtime", "realtime", args.realtime_seconds, False, 0)]
        if args.load:
            plan.append((f"realtime load {args.load}", "realtime", args.realtime_seconds, False, args.load))
        plan.append(("lockstep", "lockstep", args.lockstep_seconds, False, 0))
        if args.composed:
            plan += [
                ("composed realtime", "realtime", args.realtime_seconds, True, 0),
                ("composed lockstep", "lockstep", args.lockstep_seconds, True, 0),
            ]
        pairs = [(name, f"{name} floor") for name, *_ in plan]  # (pac, its floor)
        for name, mode, seconds, composed, load in plan:
            for relay, column in ((False, name), (True, f"{name} floor")):
                print(f"bench: {column} rig, {seconds:g} s ...", flush=True)
                with busy_loops(load):
                    runs[column], cpus[column], quality[column] = live_run(
                        mode,
                        seconds,
                        workdir,
                        args.realtime_priority,
                        relay=relay,
                        composed=composed,
                        label=column.replace(" ", "_"),
                    )
        print("bench: offline simulator ...", flush=True)
        speed_core, speed_bag = offline_speed(False, workdir), offline_speed(True, workdir)
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    print(
        f"\n## pac bench, {datetime.now():%Y-%m-%d %H:%M}, {platform.node()}, "
        f"{platform.machine()}, {__import__('os').cpu_count()} cores, realtime_priority "
        f"{'launcher default' if args.realtime_priority is None else args.realtime_priority}\n"
    )
    print(timing_table(runs), end="")
    names = list(runs)
    for node in ("plant", "observer", "controller", "loop", "recorder"):
        print(
            f"| CPU {node} [%] | "
            + " | ".join(number(cpus[n].get(node, math.nan), "{:.0f}") for n in names)
            + " |"
        )
    print(
        "| contact-force std [N] | "
        + " | ".join(f"{quality[n].contact_force_std:.3g}" if quality[n] else "-" for n in names)
        + " |"
    )
    print("\nFloor: the same nodes with cores that do no work (rclpy + Fast DDS only)\n")
    print(floor_table(runs, cpus, pairs), end="")
    print(
        f"\nOffline simulator, 10 s scenario: {speed_core:.1f}x real time (cores only), "
        f"{speed_bag:.1f}x with bag writing"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
