"""``make bench``: loop timing of the live rig and speed of the offline simulator.

Runs (1) a real-time rig for ``--realtime-seconds`` (default 30), (2) a lock-step rig
for ``--lockstep-seconds`` of simulated time, (3) the offline simulator for 10 s
with and without bag writing, (4) the compiled batch closed loop (``--batch-runs``
scenarios of 10 s, ``--batch-threads`` threads), (5) the start-up time of each loop node
(process start to its first published message), and prints one table.  Timing is
measured, never asserted: the machine is shared and noisy.  ``--offline-only`` skips
the live rigs (1, 2); ``--live-only`` runs only them and prints their tables.  Each live
configuration runs ``--live-repeats`` times, pac and its floor in turn, and every figure is
the median of its runs, so that a load that comes and goes falls on both.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import itertools
import json
import math
import os
import platform
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from pac_analysis.metrics import compute_metrics, loop_timing, timing_table
from pac_bag.reader import read_bag
from pac_common import markdown, messages
from pac_experiments.bench import report as bench_report
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


def median_timing(timings: list[Any]) -> Any:
    """One LoopTiming whose every figure is the median of ``timings`` (runs of one configuration)."""
    first = timings[0]
    values: dict[str, Any] = {}
    for f in dataclasses.fields(first):
        got = [getattr(t, f.name) for t in timings]
        if isinstance(got[0], dict):
            values[f.name] = {k: statistics.median(g[k] for g in got) for k in got[0]}
        else:
            values[f.name] = type(got[0])(statistics.median(got))
    return dataclasses.replace(first, **values)


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
    rows = []
    for key, label in FLOOR_RATIOS:
        cells = [getattr(runs[p], key) / getattr(runs[f], key) for p, f in pairs]
        rows.append([label, *(f"{c:.2f}" for c in cells)])
    for node in ("plant", "observer", "controller", "loop", "recorder"):
        cells = [cpus[p].get(node, math.nan) / cpus[f].get(node, math.nan) for p, f in pairs]
        rows.append([f"CPU {node}", *(number(c, "{:.2f}") for c in cells)])
    header = ["pac / floor", *(p for p, _ in pairs)]
    return markdown.table(header, rows, ["l"] + ["r"] * len(pairs)) + "\n"


def live_table(runs: dict, cpus: dict, quality: dict, pairs: list[tuple[str, str]]) -> str:
    """The live loop's timing table (every column) and the pac / floor table."""
    names = list(runs)
    extra = [
        [f"CPU {node} [%]", *(number(cpus[n].get(node, math.nan), "{:.0f}") for n in names)]
        for node in ("plant", "observer", "controller", "loop", "recorder")
    ]
    extra.append(
        [
            "contact-force std [N]",
            *(f"{quality[n].contact_force_std:.3g}" if quality[n] else "-" for n in names),
        ]
    )
    return (
        timing_table(runs, extra)
        + "\nFloor: the same nodes with cores that do no work (rclpy + Fast DDS only)\n\n"
        + floor_table(runs, cpus, pairs)
    )


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
    message with the rosbags serialiser (the offline simulator's path before the bulk one) for
    comparison; best of 3."""
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


def _note_first_arrival(first: dict[str, float], topic: str) -> Callable[[Any], None]:
    """A subscription callback: the monotonic time of ``topic``'s first message into ``first``."""

    def note(_msg: Any) -> None:
        first.setdefault(topic, time.monotonic())

    return note


#: The floor of a node's start-up: a bare rclpy node that publishes a measurement once its
#: reader is matched (no pac module, no numpy core, no numba), started as the launcher starts nodes.
STARTUP_FLOOR = """
import time, rclpy
from pac_common.discovery import loopback_only
from pac_common.qos import PUBLISH_QOS
from pac_interfaces.msg import FrameMeasurement
loopback_only()
rclpy.init()
node = rclpy.create_node("startup_floor")
pub = node.create_publisher(FrameMeasurement, "measurement", PUBLISH_QOS)
deadline = time.monotonic() + 60.0
while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
    time.sleep(0.001)
while time.monotonic() < deadline:  # re-sent, as the plant re-sends tick 0 until it is answered
    pub.publish(FrameMeasurement())
    time.sleep(0.005)
"""


#: The floor of a node that runs compiled code: the bare node above, which first loads one cached
#: njit function (numba's import, and its first load of compiled code: that fills numba's target
#: registries, which imports numpy's and scipy's linear algebra). Run from a file (numba caches
#: only functions defined in one), once beforehand to write the cache.
STARTUP_FLOOR_NUMBA = (
    """
import sys
import numba
import numpy as np

@numba.njit(cache=True)
def first_command(x):
    return 2.0 * x[0]

first_command(np.zeros(1))
if sys.argv[1:] == ["--write-cache"]:
    sys.exit(0)
"""
    + STARTUP_FLOOR
)


def _file_stem(name: str) -> str:
    """A node's or floor's name as part of a file name ("floor numba" -> "floor_numba")."""
    return name.replace(" ", "_")


def node_startup(workdir: Path, repeats: int) -> dict[str, list[float]]:
    """Seconds from ``Popen`` of each loop node to the first message it publishes.

    The bench process stands in for the node's peers: it offers the input the node needs
    (the plant only needs a command publisher to exist before it sends tick 0) and listens
    for the output.
    """
    import domain_coordinator

    from pac_common.node import LOOP_QOS, PUBLISH_QOS, loopback_only, rclpy
    from pac_interfaces import msg as pac_msg

    workdir.mkdir(parents=True, exist_ok=True)
    numba_floor = workdir / "startup_floor_numba.py"
    numba_floor.write_text(STARTUP_FLOOR_NUMBA)
    subprocess.run([sys.executable, str(numba_floor), "--write-cache"], check=True)
    # Each floor's interpreter arguments, by its name in the plan.
    floors = {"floor": ["-c", STARTUP_FLOOR], "floor numba": [str(numba_floor)]}
    plan = {**_STARTUP, **dict.fromkeys(floors, ("measurement", "command", None))}
    out: dict[str, list[float]] = {name: [] for name in plan}

    def start_floor(rig: Rig, name: str) -> Any:
        from pac_rig.launcher import Process, node_env

        log_path = workdir / f"startup_{_file_stem(name)}.log"
        log = log_path.open("wb")
        popen = subprocess.Popen(
            [sys.executable, *floors[name]],
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=node_env(rig.domain_id),
        )
        log.close()
        rig.processes[name] = proc = Process(name, popen, log_path)
        return proc

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
            node.create_subscription(cls, topic, _note_first_arrival(first, topic), LOOP_QOS)
            pubs[topic] = node.create_publisher(cls, topic, PUBLISH_QOS)
        try:
            for _ in range(repeats):
                for name, (answer, needs, input_type) in plan.items():
                    rig = Rig(
                        workdir / f"startup_{_file_stem(name)}",
                        duration=0.0,
                        timing_mode="lockstep",
                        domain_id=domain_id,
                        record=False,
                    )
                    try:
                        first.pop(answer, None)
                        proc = start_floor(rig, name) if name in floors else rig.start_node(name)
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


# -- the speed goals of the offline loop, campaigns and nodes (bench_report.GOALS) -----------------


def median(values: list[float]) -> float:
    return float(statistics.median(values)) if values else math.nan


def lumped_tick(repeats: int) -> tuple[float, float]:
    """(compiled, today's) CPU µs per tick of the default scenario, median of ``repeats``.

    Compiled: :func:`pac_rig.loop.run_block` over 10 s (no Python per tick); today's: the core
    objects stepped tick by tick (``closed_loop.run_cores``, what ``closed_loop.run`` did before
    the loop was compiled, and what the nodes still do), over 1 s.
    """
    from pac_rig.closed_loop import build_cores, run_cores
    from pac_rig.loop import TICK, compile_loop
    from pac_rig.simulate import scenario_from_flat

    compiled, today = [], []
    for _ in range(repeats):
        s = scenario_from_flat({"duration": 10.0})
        loop = compile_loop(*build_cores(s), s.loop.command_delay_ticks)
        if loop is None:
            raise RuntimeError("the default scenario has no compiled loop")
        out = np.empty(s.loop.ticks, TICK)
        noise = np.zeros((1, 2))
        loop.run(0, 10, noise, out)  # loads the compiled code
        start = time.process_time()
        loop.run(10, s.loop.ticks, noise, out[10:])
        compiled.append(1e6 * (time.process_time() - start) / (s.loop.ticks - 10))
        s = scenario_from_flat({"duration": 1.0})
        cores = build_cores(s)
        start = time.process_time()
        for _ in run_cores(s, *cores):
            pass
        today.append(1e6 * (time.process_time() - start) / s.loop.ticks)
    return median(compiled), median(today)


ALLOCATION_SCRIPT = "from pac_experiments.bench.rig import count_allocations; count_allocations()"


def count_allocations() -> None:
    """Print (JSON) numba's allocation counts of a 10-tick and a 9980-tick call of each law's loop,
    and of the default law's with a train's sensor suite on a moving roof (key ``law+sensors``).

    Run in a process started with NUMBA_NRT_STATS=1 (:func:`loop_allocations`).
    """
    from numba.core.runtime import rtsys

    from pac_controller.parameters import COMPILED_LAW_NAMES
    from pac_rig.closed_loop import build_cores
    from pac_rig.loop import TICK, compile_loop
    from pac_rig.simulate import scenario_from_flat

    counts = {}
    train = {"sensors": "train_load_cell", "roof_motion": "german_low"}
    cases = [(law, {"law": law}) for law in COMPILED_LAW_NAMES]
    cases.append((f"{COMPILED_LAW_NAMES[0]}+{train['sensors']}", {"law": COMPILED_LAW_NAMES[0], **train}))
    for law, case in cases:
        values = {**case, "duration": 10.0, "noise_std": (1e-6, 1e-6), "command_delay_ticks": 2}
        s = scenario_from_flat(values)
        plant, observer, controller = build_cores(s)
        loop = compile_loop(plant, observer, controller, 2)
        if loop is None:
            raise RuntimeError(f"law {law}: no compiled loop (not a kernel law?)")
        noise = plant.noise_rows(0, s.loop.ticks)
        out = np.empty(s.loop.ticks, TICK)
        loop.run(0, 10, noise, out)  # compiles or loads, outside the count
        stats = [rtsys.get_allocation_stats()]
        loop.run(10, 20, noise[10:], out[10:])
        stats.append(rtsys.get_allocation_stats())
        reached, code, _ = loop.run(20, s.loop.ticks, noise[20:], out[20:])
        stats.append(rtsys.get_allocation_stats())
        if reached != s.loop.ticks or code:
            raise RuntimeError(f"{law}: the run stopped at tick {reached} (code {code})")
        short, long = [[b.alloc - a.alloc, b.free - a.free] for a, b in itertools.pairwise(stats)]
        counts[law] = {"10 ticks": short, "9980 ticks": long}
    print(json.dumps(counts))


def loop_allocations() -> dict[str, dict[str, list[int]]]:
    """:func:`count_allocations` in a fresh process (NRT statistics are switched on at numba's start)."""
    env = {**os.environ, "NUMBA_NRT_STATS": "1"}
    done = subprocess.run(
        [sys.executable, "-c", ALLOCATION_SCRIPT],
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def allocations_per_tick(counts: dict[str, dict[str, list[int]]]) -> float:
    """Extra allocations per tick of the long call over the short one (the worst law)."""
    return max((c["9980 ticks"][0] - c["10 ticks"][0]) / 9970 for c in counts.values())


#: CPU seconds of the last :func:`whole_process` (the command and its children): the machine is shared.
LAST_PROCESS_CPU = [math.nan]


def whole_process(
    cmd: list[str], timeout: float = 900.0, env: dict[str, str] | None = None
) -> tuple[float, str]:
    """Wall seconds of a whole command (start-up included) and its stdout (``env``: its whole
    environment; None: this process's)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(
        cmd, capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL, env=env
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    LAST_PROCESS_CPU[0] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: exit {done.returncode}: {done.stderr.strip()[-500:]}")
    return wall, done.stdout


def simulate_process(workdir: Path, seconds: float = 100.0) -> float:
    """× real time of ``ros2 run pac_rig simulate BAG duration:=seconds`` as a whole process."""
    bag = workdir / "simulate_whole"
    shutil.rmtree(bag, ignore_errors=True)
    wall, _ = whole_process(["ros2", "run", "pac_rig", "simulate", str(bag), "-p", f"duration:={seconds}"])
    shutil.rmtree(bag, ignore_errors=True)
    return seconds / wall


#: Train time of the realistic run: as far as the line goes (2.95 km; 36 s, 3 km, would run past its
#: last span, which the plant refuses: it allows 35.48 s from the pantograph's start).
REALISTIC_SECONDS = 35.4
#: The realistic run the speed goal names: the 3 km drawn line at 300 km/h, its EN 50367 force.
REALISTIC_RUN = (
    "-p", "scenario:=realistic_electromechanical", "-p", "law:=passive", "-p", "speed_kmh:=300.0",
    "-p", "force_amplitude:=157.3", "-p", f"duration:={REALISTIC_SECONDS}",
)  # fmt: skip
#: The moving window the realistic speed goal is measured with (docs/catenary.md, "A moving window").
REALISTIC_WINDOW_SPANS = 16.0


def realistic_process(workdir: Path, window_spans: float, line_cache: Path | None) -> float:
    """× real time of the realistic ``simulate`` run as a whole process (0: the whole line).
    ``line_cache``: the directory of solved dropper lengths it may read (``PAC_LINE_CACHE``; None:
    none, the run solves its line's, as the first run of a line does)."""
    bag = workdir / "simulate_realistic"
    shutil.rmtree(bag, ignore_errors=True)
    cmd = ["ros2", "run", "pac_rig", "simulate", str(bag), *REALISTIC_RUN]
    cmd += ["-p", f"fe_window_spans:={window_spans}"]
    env = {**os.environ, "PAC_LINE_CACHE": "" if line_cache is None else str(line_cache)}
    wall, _ = whole_process(cmd, env=env)
    shutil.rmtree(bag, ignore_errors=True)
    return REALISTIC_SECONDS / wall


def simulate_today(workdir: Path, seconds: float = 10.0) -> float:
    """× real time of today's per-record path to a bag (in process, ``compiled=False``)."""
    from pac_rig.simulate import scenario_from_flat

    path = workdir / "simulate_today"
    start = time.perf_counter()
    simulate_to_bag(scenario_from_flat({"duration": seconds}), path, compiled=False)
    wall = time.perf_counter() - start
    shutil.rmtree(path, ignore_errors=True)
    return seconds / wall


#: Scenario-seconds per CPU-second (all threads) of the last :func:`batch_rates`, set-up included.
BATCH_CPU = [math.nan]
#: Repeats of the batch figure (median).
BATCH_REPEATS = 7


def batch_rates(threads: int) -> tuple[float, float]:
    """(compiled batch, today's tick by tick) scenario-s per wall-s: every law at four speeds, 10 s."""
    from pac_controller.parameters import COMPILED_LAW_NAMES
    from pac_rig.closed_loop import build_cores, run_cores
    from pac_rig.simulate import scenario_from_flat

    scenarios = [
        scenario_from_flat({"law": law, "speed_kmh": v, "duration": 10.0})
        for law in COMPILED_LAW_NAMES
        for v in (200.0, 260.0, 320.0, 380.0)
    ]
    run_batch(scenarios[:1])  # loads the compiled code
    # The whole batch takes ~0.2 s of wall time: one load spike moves a single sample by 2x on
    # this shared VM (561 against a median of 1215 minutes apart), so the median of BATCH_REPEATS.
    walls, cpus = [], []
    for _ in range(BATCH_REPEATS):
        cpu = time.process_time()
        result = run_batch(scenarios, threads=threads)
        cpus.append(result.simulated_seconds / (time.process_time() - cpu))
        walls.append(result.simulated_seconds / result.wall_seconds)
    BATCH_CPU[0] = float(np.median(cpus))
    compiled = float(np.median(walls))
    start = time.perf_counter()
    simulated = 0.0
    for law in COMPILED_LAW_NAMES:
        s = scenario_from_flat({"law": law, "duration": 1.0})
        for _ in run_cores(s, *build_cores(s)):
            pass
        simulated += s.loop.duration
    return compiled, simulated / (time.perf_counter() - start)


def campaign_rate(spec: Path, workdir: Path, env: dict[str, str] | None = None) -> tuple[float, float, float]:
    """(scenario-s per wall-s of the whole command, the campaign's own compute-phase rate, wall s)."""
    out = workdir / f"campaign_{spec.stem}"
    shutil.rmtree(out, ignore_errors=True)
    cmd = ["ros2", "run", "pac_experiments", "campaign", str(spec), "--out", str(out)]
    wall, stdout = whole_process(cmd, env=env)
    shutil.rmtree(out, ignore_errors=True)
    found = re.search(r"([0-9.]+) scenario-s in ([0-9.]+) s = ([0-9.]+) scenario-s per wall-s", stdout)
    if not found:
        raise RuntimeError(f"campaign {spec}: no throughput line in its output: {stdout[-300:]}")
    return float(found.group(1)) / wall, float(found.group(3)), wall


#: What any campaign's process cannot avoid: Python, numpy, numba, the batch's modules and its
#: compiled loop loaded from the cache (one scenario of one tick of the given line).
CAMPAIGN_FLOOR = (
    "from pac_rig.batch import run_batch; from pac_rig.simulate import scenario_from_flat; "
    "run_batch([scenario_from_flat({{'duration': 0.001, 'catenary_model': '{line}'}})])"
)


def campaign_floor(line: str) -> tuple[float, float]:
    """(wall s, CPU s) of :data:`CAMPAIGN_FLOOR` as a whole process, median of 3."""
    walls, cpus = [], []
    for _ in range(3):
        walls.append(whole_process([sys.executable, "-c", CAMPAIGN_FLOOR.format(line=line)])[0])
        cpus.append(LAST_PROCESS_CPU[0])
    return median(walls), median(cpus)


#: The campaign of drawn lines the realistic speed goal names ("in minutes, not hours"): the passive
#: pantograph on 20 lines at 250, 300 and 350 km/h and the ideal rig beside it, as committed.
REALISTIC_CAMPAIGN = "config/campaigns/realistic_passive.yaml"


FE_CAMPAIGN = """# bench: an FE-line campaign as config/campaigns/fe_laws.yaml runs them (passive and
# line_adaptive on the contact-force observer, EN 50318 statistics), 2 laws x 4 speeds x 10 s
grid:
  law: [passive, line_adaptive]
  observer: [contact_force]
  speed_kmh: [250.0, 290.0, 330.0, 360.0]
fixed:
  catenary_model: fe
  fe_datum: fixed
  span_length: 55.0
  shape: constant
  duration: 10.0
window: [5.0, 10.0]
statistics: en50318
force_target: en50367
"""


def load_average() -> str:
    return ", ".join(f"{v:.2f}" for v in os.getloadavg())


def goal_figures(args: argparse.Namespace, workdir: Path, runs: dict, startup: dict) -> dict:
    """Every figure of bench_report.GOALS (and today's path beside it): the results dictionary."""
    figures: dict[str, float | None] = {}
    today: dict[str, dict[str, Any]] = {}
    notes: list[str] = []
    print("bench: compiled tick ...", flush=True)
    compiled_us, today_us = lumped_tick(args.repeats)
    figures["lumped_tick_x"] = 1e3 / compiled_us
    today["lumped_tick_x"] = {"value": 1e3 / today_us, "what": "core objects tick by tick"}
    notes.append(f"compiled tick {compiled_us:.2f} µs CPU, core objects tick by tick {today_us:.1f} µs CPU")
    print("bench: allocations ...", flush=True)
    counts = loop_allocations()
    figures["lumped_tick_allocations"] = allocations_per_tick(counts)
    per_call = max(c["10 ticks"][0] for c in counts.values())
    notes.append(
        f"allocations: numba NRT counter (NUMBA_NRT_STATS=1), a 9980-tick call of each law allocates "
        f"what a 10-tick call does ({per_call}: the arrays handed over by Python, once per call)"
    )
    print("bench: simulate 100 s as a process ...", flush=True)
    speeds, cpus = [], []
    for _ in range(args.repeats):
        speeds.append(simulate_process(workdir))
        cpus.append(LAST_PROCESS_CPU[0])
    figures["simulate_100s_x"] = median(speeds)
    notes.append(
        f"100 s simulate as a process: {100.0 / median(speeds):.1f} s wall, {median(cpus):.1f} s CPU "
        f"({100.0 / median(cpus):.0f}× real time per CPU-second; start-up included)"
    )
    today["simulate_100s_x"] = {"value": simulate_today(workdir), "what": "per-record path, 10 s, in process"}
    print("bench: the realistic run as a process ...", flush=True)
    lines = workdir / "line_cache"  # the line's dropper lengths, solved by the first run below
    shutil.rmtree(lines, ignore_errors=True)
    first = realistic_process(workdir, REALISTIC_WINDOW_SPANS, lines)
    windowed = [realistic_process(workdir, REALISTIC_WINDOW_SPANS, lines) for _ in range(args.repeats)]
    cold = [realistic_process(workdir, REALISTIC_WINDOW_SPANS, None) for _ in range(args.repeats)]
    whole_line = [realistic_process(workdir, 0.0, lines) for _ in range(args.repeats)]
    shutil.rmtree(lines, ignore_errors=True)
    figures["realistic_simulate_x"] = median(windowed)
    today["realistic_simulate_x"] = {"value": median(whole_line), "what": "the whole line"}
    figures["realistic_simulate_cold_x"] = median(cold)
    notes.append(
        f"realistic {REALISTIC_SECONDS:g} s simulate as a process: "
        f"{REALISTIC_SECONDS / median(windowed):.2f} s wall with the {REALISTIC_WINDOW_SPANS:g}-span window "
        "and the line's dropper lengths solved by an earlier run "
        f"(the first, which solved them: {REALISTIC_SECONDS / first:.2f} s), "
        f"{REALISTIC_SECONDS / median(cold):.2f} s with no line cache (every run solves them), "
        f"{REALISTIC_SECONDS / median(whole_line):.1f} s on the whole line"
    )
    print("bench: batch ...", flush=True)
    batch, batch_today = batch_rates(args.batch_threads)
    figures["batch_rate"] = batch
    today["batch_rate"] = {"value": batch_today, "what": "core objects tick by tick, 1 thread"}
    notes.append(
        f"batch (median of {BATCH_REPEATS}): {BATCH_CPU[0]:.0f} scenario-s per CPU-second "
        "(both threads, packing included); "
        f"wall-clock rate {batch:.0f} on two cores shared with the load above"
    )
    if args.campaigns:
        print("bench: campaigns ...", flush=True)
        spec = Path(args.campaign_spec)
        whole, inner, wall = campaign_rate(spec, workdir)
        cpu = LAST_PROCESS_CPU[0]
        floor_wall, floor_cpu = campaign_floor("lumped")
        figures["campaign_lumped_rate"] = whole
        notes.append(
            f"campaign {spec.name}: {wall:.1f} s wall, {cpu:.1f} s CPU as a whole command; its runs alone "
            f"{inner:.0f} scenario-s per wall-s (the campaign's own figure: start-up and report excluded); "
            f"floor (a process that imports the batch and loads its compiled loop, one 1-tick run): "
            f"{floor_wall:.2f} s wall, {floor_cpu:.2f} s CPU"
        )
        fe_spec = workdir / "fe_bench.yaml"
        fe_spec.write_text(FE_CAMPAIGN)
        whole, inner, wall = campaign_rate(fe_spec, workdir)
        cpu = LAST_PROCESS_CPU[0]
        floor_wall, floor_cpu = campaign_floor("fe")
        figures["campaign_fe_rate"] = whole
        notes.append(
            f"FE campaign (passive and line_adaptive x 4 speeds x 10 s, EN 50318 statistics, the compiled "
            f"batch): {wall:.1f} s wall, {cpu:.1f} s CPU as a whole command, runs alone {inner:.1f} "
            f"scenario-s per wall-s; floor (as above, one 1-tick FE run: the line built once): "
            f"{floor_wall:.2f} s wall, {floor_cpu:.2f} s CPU"
        )
    if args.campaigns:
        print("bench: the realistic passive campaign ...", flush=True)
        spec = Path(REALISTIC_CAMPAIGN)
        lines = workdir / "campaign_line_cache"  # empty: the campaign solves its lines, as a first one does
        shutil.rmtree(lines, ignore_errors=True)
        _, _, wall = campaign_rate(spec, workdir, {**os.environ, "PAC_LINE_CACHE": str(lines)})
        shutil.rmtree(lines, ignore_errors=True)
        figures["realistic_campaign_min"] = wall / 60.0
        notes.append(
            f"realistic campaign {spec.name} (as `make realistic-passive` runs it): {wall / 60.0:.1f} min "
            f"wall, {LAST_PROCESS_CPU[0] / 60.0:.1f} min CPU as a whole command"
        )
    print("bench: FE tick ...", flush=True)
    from pac_experiments.bench.fe import (
        fe_tick_figures,  # the FE line's own timing (by part)
    )

    fe = fe_tick_figures()
    figures["fe_tick_x"] = fe["fe_plant_realtime_factor"]
    notes.append(
        f"FE plant tick {fe['fe_plant_tick_us']:.0f} µs CPU (advance + measurement + truth; compiled step "
        f"{fe['step_new_us']:.0f} µs): "
        "`python -m pac_experiments.bench.fe` for the parts"
    )
    if startup:
        medians = {name: median(times) for name, times in startup.items()}
        nodes = [startup[name] for name in _STARTUP]
        figures["startup_s"] = max(medians[name] for name in _STARTUP) if all(nodes) else None
        if startup.get("floor"):
            today["startup_s"] = {"value": medians["floor"], "what": "its floor: a bare rclpy node"}
        notes.append(
            "start-up medians: "
            + ", ".join(f"{n} {v:.2f} s" for n, v in medians.items() if n in _STARTUP)
            + f"; the floor (a bare rclpy node publishing one measurement, started the same way) "
            f"{medians.get('floor', math.nan):.2f} s; the same node that first loads one cached "
            f"njit function (a node that runs compiled code can start no sooner) "
            f"{medians.get('floor numba', math.nan):.2f} s"
        )
    if "realtime" in runs:
        for field in ("on_time_periods_percent", "commands_on_time_percent", "latency_p50_ms"):
            figures[f"realtime_{field}"] = getattr(runs["realtime"], field)
            if "realtime floor" in runs:
                floor = getattr(runs["realtime floor"], field)
                today[f"realtime_{field}"] = {"value": floor, "what": "its floor, rclpy + Fast DDS"}
    if "lockstep" in runs and "lockstep floor" in runs:
        figures["lockstep_floor_ratio"] = (
            runs["lockstep"].steps_per_second / runs["lockstep floor"].steps_per_second
        )
        notes.append(
            f"lock step {runs['lockstep'].steps_per_second:.0f} steps/s, its floor "
            f"{runs['lockstep floor'].steps_per_second:.0f}"
        )
    return {"figures": figures, "today": today, "notes": notes}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bench", description=__doc__)
    parser.add_argument(
        "--realtime-seconds", type=float, default=10.0, help="each real-time run (0: no real-time rigs)"
    )
    parser.add_argument("--lockstep-seconds", type=float, default=10.0, help="each lock-step run")
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
    parser.add_argument(
        "--live-only",
        action="store_true",
        help="only the live rigs, their tables printed (no reports/bench file written)",
    )
    parser.add_argument(
        "--live-repeats",
        type=int,
        default=3,
        help="each live configuration run this many times, pac and its floor in turn; every figure "
        "the median over the runs (a load that comes and goes falls on both)",
    )
    parser.add_argument("--batch-runs", type=int, default=16)
    parser.add_argument("--batch-threads", type=int, default=2)
    parser.add_argument("--startup-repeats", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3, help="repeats of each offline figure (median)")
    parser.add_argument(
        "--campaigns", action=argparse.BooleanOptionalAction, default=True, help="run the two campaigns"
    )
    parser.add_argument("--campaign-spec", default="config/campaigns/laws_speeds.yaml")
    parser.add_argument("--out-dir", type=Path, default=Path("reports/bench"), help="where latest.md/json go")
    parser.add_argument(
        "--readme",
        action="store_true",
        help=f"only regenerate {bench_report.RESULTS_PAGE}'s block from OUT_DIR/latest.json",
    )
    return parser


def _argument_error(args: argparse.Namespace) -> str | None:
    """The one line refusing ``args``, or None."""
    for name, value, low, high in (
        ("--batch-runs", args.batch_runs, 1, 100000),
        ("--batch-threads", args.batch_threads, 1, 64),
        ("--startup-repeats", args.startup_repeats, 0, 100),
        ("--repeats", args.repeats, 1, 100),
        ("--live-repeats", args.live_repeats, 1, 100),
    ):
        if not low <= value <= high:
            return f"bench: invalid {name} {value!r}: allowed {low}..{high}"
    if args.load < 0:
        return f"bench: invalid --load {args.load}: allowed an integer >= 0"
    return None


#: A live configuration: (column, timing mode, seconds, composed, busy loops).
LivePlan = list[tuple[str, str, float, bool, int]]


def live_plan(args: argparse.Namespace) -> LivePlan:
    """The live configurations ``args`` ask for; each is run as pac, then as its floor."""
    if args.offline_only:
        return []
    plan: LivePlan = []
    if args.realtime_seconds:
        plan.append(("realtime", "realtime", args.realtime_seconds, False, 0))
    if args.load and args.realtime_seconds:
        plan.append((f"realtime load {args.load}", "realtime", args.realtime_seconds, False, args.load))
    plan.append(("lockstep", "lockstep", args.lockstep_seconds, False, 0))
    if args.composed:
        if args.realtime_seconds:
            plan.append(("composed realtime", "realtime", args.realtime_seconds, True, 0))
        plan.append(("composed lockstep", "lockstep", args.lockstep_seconds, True, 0))
    return plan


def live_runs(
    args: argparse.Namespace, plan: LivePlan, workdir: Path
) -> tuple[dict[str, Any], dict[str, dict[str, float]], dict[str, Any]]:
    """Every live configuration of ``plan``, pac and its floor in turn, ``args.live_repeats``
    times: (timing, CPU per node, run quality) by column, each figure the median of its runs."""
    runs: dict[str, Any] = {}
    cpus: dict[str, dict[str, float]] = {}
    quality: dict[str, Any] = {}
    for name, mode, seconds, composed, load in plan:
        timings: dict[str, list] = {name: [], f"{name} floor": []}
        used: dict[str, list[dict[str, float]]] = {name: [], f"{name} floor": []}
        for repeat in range(args.live_repeats):
            for relay, column in ((False, name), (True, f"{name} floor")):
                turn = f"{repeat + 1}/{args.live_repeats}"
                print(f"bench: {column} rig, {seconds:g} s ({turn}) ...", flush=True)
                with busy_loops(load):
                    timing, cpu, quality[column] = live_run(
                        mode,
                        seconds,
                        workdir,
                        args.realtime_priority,
                        relay=relay,
                        composed=composed,
                        label=f"{column.replace(' ', '_')}_{repeat}",
                    )
                timings[column].append(timing)
                used[column].append(cpu)
        for column in timings:
            runs[column] = median_timing(timings[column])
            cpus[column] = {n: statistics.median(c[n] for c in used[column]) for n in used[column][0]}
    return runs, cpus, quality


@dataclasses.dataclass(frozen=True)
class OfflineFigures:
    """What the bench measures without a live rig."""

    speed_core: float  # x real time, cores only
    speed_bag: float  # x real time, with bag writing
    writing: list[tuple[str, float, float, int]]  # bag writing: name, wall and CPU ms per s, size
    speed_batch: float  # scenario-s per wall-s
    batch_wall: float  # s
    startup: dict[str, list[float]]  # node -> seconds to its first message


def offline_figures(args: argparse.Namespace, workdir: Path) -> OfflineFigures:
    """The offline simulator's speed, bag writing, the batch and node start-up."""
    print("bench: offline simulator ...", flush=True)
    speed_core, speed_bag = offline_speed(False, workdir), offline_speed(True, workdir)
    print("bench: bag writing ...", flush=True)
    writing = bag_writing(workdir)
    print("bench: batch ...", flush=True)
    run_batch([Scenario()])  # loads the compiled kernel: not part of the measurement
    speed_batch, batch_wall = batch_speed(args.batch_runs, args.batch_threads)
    print("bench: node start-up ...", flush=True)
    startup = node_startup(workdir, args.startup_repeats) if args.startup_repeats else {}
    return OfflineFigures(speed_core, speed_bag, writing, speed_batch, batch_wall, startup)


def print_offline(args: argparse.Namespace, f: OfflineFigures) -> None:
    print(
        f"\nOffline simulator, 10 s scenario: {f.speed_core:.1f}x real time (cores only), "
        f"{f.speed_bag:.1f}x with bag writing"
    )
    header = [
        "bag writing, 10 s offline run",
        "wall ms per simulated s",
        "CPU ms per simulated s",
        "bag size [MB]",
    ]
    cells = [[name, f"{wall:.1f}", f"{cpu:.1f}", f"{size / 1e6:.2f}"] for name, wall, cpu, size in f.writing]
    print("\n" + markdown.table(header, cells))
    print(
        f"\nBatch (compiled closed loop): {args.batch_runs} x 10 s scenarios in {f.batch_wall:.2f} s = "
        f"{f.speed_batch:.0f} scenario-s per wall-s ({args.batch_threads} threads)"
    )
    for name, times in f.startup.items():
        shown = ", ".join(f"{t:.2f}" for t in times) or "no message"
        print(f"Start-up {name}_node (process start -> first published message): {shown} s")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.readme:
        results = json.loads((args.out_dir / "latest.json").read_text())
        bench_report.update_readme(Path(bench_report.RESULTS_PAGE), results)
        page, source = bench_report.RESULTS_PAGE, args.out_dir / "latest.json"
        print(f"bench: {page} performance block regenerated from {source}")
        return 0
    error = _argument_error(args)
    if error:
        print(error, file=sys.stderr)
        return 2
    workdir = Path(tempfile.mkdtemp(prefix="pac_bench_"))
    load_before = load_average()
    try:
        plan = live_plan(args)
        pairs = [(name, f"{name} floor") for name, *_ in plan]  # (pac, its floor)
        runs, cpus, quality = live_runs(args, plan, workdir)
        if args.live_only:
            if runs:
                print(live_table(runs, cpus, quality, pairs), end="")
            return 0
        offline = offline_figures(args, workdir)
        results = goal_figures(args, workdir, runs, offline.startup)
        if runs:
            results["notes"].append(
                f"live loop: each configuration run {args.live_repeats} times, pac and its floor in turn "
                f"(real time {args.realtime_seconds:g} s, lock step {args.lockstep_seconds:g} s each); "
                "every figure the median of its runs"
            )
        live_tables = ""
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    print(
        f"\n## pac bench, {datetime.now():%Y-%m-%d %H:%M}, {platform.node()}, "
        f"{platform.machine()}, {__import__('os').cpu_count()} cores, realtime_priority "
        f"{'launcher default' if args.realtime_priority is None else args.realtime_priority}\n"
    )
    if runs:
        live_tables = live_table(runs, cpus, quality, pairs)
        print(live_tables, end="")
    print_offline(args, offline)
    results.update(
        date=f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC",
        machine=f"{platform.node()}, {platform.machine()}, {os.cpu_count()} cores",
        load_before=load_before,
        load_after=load_average(),
        repeats=args.repeats,
        loop_timing=live_tables,
    )
    print("\n" + bench_report.markdown(results))
    js, md = bench_report.write(results, args.out_dir)
    page = bench_report.RESULTS_PAGE
    print(f"wrote {js} and {md} ({page}'s block: ros2 run pac_experiments bench --readme)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
