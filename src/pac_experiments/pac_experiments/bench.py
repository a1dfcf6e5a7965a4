"""``make bench``: loop timing of the live rig and speed of the offline simulator.

Runs (1) a real-time rig for ``--realtime-seconds`` (default 30), (2) a lock-step rig
for ``--lockstep-seconds`` of simulated time, (3) the offline simulator for 10 s
with and without bag writing, (4) the compiled batch closed loop (``--batch-runs``
scenarios of 10 s, ``--batch-threads`` threads), (5) the start-up time of each loop node
(process start to its first published message), and prints one table.  Timing is
measured, never asserted: the machine is shared and noisy.  ``--offline-only`` skips
the live rigs (1, 2).
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
from pac_bag.reader import read_bag
from pac_common import messages
from pac_rig.batch import run_batch
from pac_rig.closed_loop import Scenario, run
from pac_rig.launcher import Rig
from pac_rig.simulate import simulate_to_bag

#: Node -> (topic it answers on, topic it needs an input on, input message type).
_STARTUP = {
    "plant": ("measurement", "command", None),
    "observer": ("estimate", "measurement", "FrameMeasurement"),
    "controller": ("command", "estimate", "ObserverEstimate"),
}


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


def bag_writing(workdir: Path, seconds: float = 10.0) -> list[tuple[str, float, float, int]]:
    """Cost of recording an offline run: (path, wall and CPU ms per simulated second, bag bytes).

    The run's ticks are collected first (the simulator's own field dictionaries), then written
    through the bulk path (columns -> CDR -> chunks) with each compression, and message by
    message with the rosbags serialiser (the path before #10) for comparison; best of 3."""
    from pac_bag.mcap_writer import COMPRESSIONS
    from pac_bag.writer import BagWriter
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


def batch_speed(runs: int, threads: int) -> tuple[float, float]:
    """(scenario-seconds per wall-second, wall seconds) of ``runs`` default 10 s scenarios in one batch."""
    result = run_batch([Scenario()] * runs, threads=threads)
    return result.simulated_seconds / result.wall_seconds, result.wall_seconds


def node_startup(workdir: Path, repeats: int) -> dict[str, list[float]]:
    """Seconds from ``Popen`` of each loop node to the first message it publishes.

    The bench process stands in for the node's peers: it offers the input the node needs
    (the plant only needs a command publisher to exist before it sends tick 0) and listens
    for the output.
    """
    import domain_coordinator

    from pac_common.node import LOOP_QOS, PUBLISH_QOS, loopback_only, rclpy
    from pac_interfaces import msg as pac_msg

    out: dict[str, list[float]] = {name: [] for name in _STARTUP}
    with domain_coordinator.domain_id() as domain_id:
        context = rclpy.Context()
        loopback_only()
        rclpy.init(context=context, domain_id=domain_id)
        node = rclpy.create_node("bench_startup", context=context)
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
        executor.add_node(node)
        first: dict[str, float] = {}
        types = {
            "measurement": "FrameMeasurement",
            "estimate": "ObserverEstimate",
            "command": "ActuatorCommand",
        }
        pubs = {}
        for topic, typename in types.items():
            cls = getattr(pac_msg, typename)
            node.create_subscription(
                cls, topic, lambda _m, t=topic: first.setdefault(t, time.monotonic()), LOOP_QOS
            )
            pubs[topic] = node.create_publisher(cls, topic, PUBLISH_QOS)
        try:
            for _ in range(repeats):
                for name, (answer, needs, input_type) in _STARTUP.items():
                    rig = Rig(
                        workdir / f"startup_{name}",
                        duration=0.0,
                        timing_mode="lockstep",
                        domain_id=domain_id,
                        record=False,
                    )
                    try:
                        first.pop(answer, None)
                        proc = rig.start_node(name)
                        deadline = proc.started + 120.0
                        while answer not in first and time.monotonic() < deadline and proc.poll() is None:
                            if input_type is not None:
                                pubs[needs].publish(getattr(pac_msg, input_type)())
                            executor.spin_once(timeout_sec=0.005)
                        if answer in first:
                            out[name].append(first[answer] - proc.started)
                    finally:
                        rig.stop(grace=5.0)
        finally:
            executor.shutdown()
            node.destroy_node()
            rclpy.shutdown(context=context)
    return out


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
    parser.add_argument("--offline-only", action="store_true", help="skip the live rigs")
    parser.add_argument("--batch-runs", type=int, default=16)
    parser.add_argument("--batch-threads", type=int, default=2)
    parser.add_argument("--startup-repeats", type=int, default=3)
    args = parser.parse_args(argv)
    for name, value, low, high in (
        ("--batch-runs", args.batch_runs, 1, 100000),
        ("--batch-threads", args.batch_threads, 1, 64),
        ("--startup-repeats", args.startup_repeats, 0, 100),
    ):
        if not low <= value <= high:
            print(f"bench: invalid {name} {value!r}: allowed {low}..{high}", file=sys.stderr)
            return 2
    if args.load < 0:
        print(f"bench: invalid --load {args.load}: allowed an integer >= 0", file=sys.stderr)
        return 2
    workdir = Path(tempfile.mkdtemp(prefix="pac_bench_"))
    try:
        runs, cpus, quality = {}, {}, {}
        # (column, timing mode, seconds, composed, busy loops): each is run as pac, then as its floor.
        plan = [("realtime", "realtime", args.realtime_seconds, False, 0)]
        if args.offline_only:
            plan = []
        elif args.load:
            plan.append((f"realtime load {args.load}", "realtime", args.realtime_seconds, False, args.load))
        if not args.offline_only:
            plan.append(("lockstep", "lockstep", args.lockstep_seconds, False, 0))
        if args.composed and not args.offline_only:
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
        print("bench: bag writing ...", flush=True)
        writing = bag_writing(workdir)
        print("bench: batch ...", flush=True)
        run_batch([Scenario()])  # loads the compiled kernel: not part of the measurement
        speed_batch, batch_wall = batch_speed(args.batch_runs, args.batch_threads)
        print("bench: node start-up ...", flush=True)
        startup = node_startup(workdir, args.startup_repeats) if args.startup_repeats else {}
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    print(
        f"\n## pac bench, {datetime.now():%Y-%m-%d %H:%M}, {platform.node()}, "
        f"{platform.machine()}, {__import__('os').cpu_count()} cores, realtime_priority "
        f"{'launcher default' if args.realtime_priority is None else args.realtime_priority}\n"
    )
    if runs:
        print(timing_table(runs), end="")
    names = list(runs)
    for node in ("plant", "observer", "controller", "loop", "recorder") if runs else ():
        print(
            f"| CPU {node} [%] | "
            + " | ".join(number(cpus[n].get(node, math.nan), "{:.0f}") for n in names)
            + " |"
        )
    if runs:
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
    print(
        "\n| bag writing, 10 s offline run | wall ms per simulated s | CPU ms per simulated s "
        "| bag size [MB] |\n|---|---|---|---|"
    )
    for name, wall, cpu, size in writing:
        print(f"| {name} | {wall:.1f} | {cpu:.1f} | {size / 1e6:.2f} |")
    print(
        f"Batch (compiled closed loop): {args.batch_runs} x 10 s scenarios in {batch_wall:.2f} s = "
        f"{speed_batch:.0f} scenario-s per wall-s ({args.batch_threads} threads)"
    )
    for name, times in startup.items():
        shown = ", ".join(f"{t:.2f}" for t in times) or "no message"
        print(f"Start-up {name}_node (process start -> first published message): {shown} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
