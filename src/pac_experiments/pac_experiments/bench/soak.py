"""``make soak``: the real-time rig for a long run (default 10 min), then one table.

Runs the rig as ``make demo`` does (launcher defaults, real-time priorities where the
machine allows them) and reports, per node, the resident memory (RSS) shortly after
the start and just before the end and the CPU it used; whether every tick is in the
bag; and the contact-force sigma per minute.  Not part of ``make test``: it is long,
and its figures are measured, never asserted.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

import numpy as np

from pac_analysis.metrics import loop_timing
from pac_bag.reader import read_bag
from pac_common import markdown
from pac_common.contact_statistics import statistics
from pac_common.parameters import LoopParameters
from pac_rig.launcher import Rig

#: /proc/<pid>/statm counts pages: their size is the machine's (4 KiB on x86-64, 16 or 64 KiB on
#: some ARM kernels).
PAGE = os.sysconf("SC_PAGE_SIZE")


def rss_mb(pid: int) -> float:
    """Resident set size of ``pid`` [MB] (Linux /proc), NaN once it has exited."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * PAGE / 1e6
    except (OSError, IndexError, ValueError):
        return float("nan")


def sigma_per_minute(bag, rate_hz: float) -> list[tuple[int, float, float]]:
    """(minute, mean, sigma) of the contact force over each whole or partial minute of the run."""
    truth = bag.topics["plant_truth"]
    ticks, first = np.unique(truth["tick"], return_index=True)
    force = truth["contact_force"][first]
    minute = (ticks / rate_hz // 60).astype(int)
    out = []
    for m in np.unique(minute):
        stats = statistics(force[minute == m])
        out.append((int(m), stats.contact_force_mean, stats.contact_force_std))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="soak", description=__doc__)
    parser.add_argument("--minutes", type=float, default=10.0, help="run length [min] (default 10)")
    parser.add_argument("--bag", type=Path, default=None, help="keep the bag here (default: a temporary one)")
    parser.add_argument("--sample-every", type=float, default=5.0, help="RSS sampling period [s]")
    args = parser.parse_args(argv)
    if not args.minutes > 0 or not args.sample_every > 0:
        print(
            f"soak: invalid --minutes {args.minutes} / --sample-every {args.sample_every}: allowed > 0",
            file=sys.stderr,
        )
        return 2
    import domain_coordinator

    seconds = 60.0 * args.minutes
    workdir = Path(tempfile.mkdtemp(prefix="pac_soak_"))
    bag_path = args.bag or workdir / "soak"
    started = datetime.now()
    with domain_coordinator.domain_id() as domain_id:
        rig = Rig(bag_path, duration=seconds, domain_id=domain_id)
        samples: dict[str, list[tuple[float, float]]] = {}
        try:
            rig.start()
            t0 = time.monotonic()
            print(f"soak: real-time rig, {args.minutes:g} min, bag {bag_path}", flush=True)
            plant = rig.processes["plant"]
            next_report = 60.0
            while plant.poll() is None and time.monotonic() - t0 < seconds + 120.0:
                now = time.monotonic() - t0
                for name, proc in rig.processes.items():
                    rss = rss_mb(proc.popen.pid) if proc.poll() is None else float("nan")
                    if rss == rss:
                        samples.setdefault(name, []).append((now, rss))
                if now >= next_report:
                    print(f"soak: {now / 60:.0f} min", flush=True)
                    next_report += 60.0
                time.sleep(args.sample_every)
            rig.wait_finished(timeout=60.0)
        finally:
            codes = rig.stop()
    if any(code != 0 for code in codes.values()):
        print(f"soak: exit codes {codes}; logs in {rig.log_dir}", file=sys.stderr)
        return 1
    bag = read_bag(bag_path)
    timing = loop_timing(bag)
    print(
        f"\n## pac soak, {started:%Y-%m-%d %H:%M} to {datetime.now():%H:%M}, {args.minutes:g} min real time\n"
    )
    usage = []
    for name, proc in rig.processes.items():
        series = samples.get(name, [])
        start = next((rss for t, rss in series if t >= 10.0), float("nan"))
        end = series[-1][1] if series else float("nan")
        cpu = (
            100.0 * proc.cpu_seconds / proc.wall_seconds
            if proc.cpu_seconds is not None and proc.wall_seconds
            else float("nan")
        )
        usage.append([name, f"{start:.1f}", f"{end:.1f}", f"{end - start:+.1f}", f"{cpu:.0f}"])
    header = ["node", "RSS after ~10 s [MB]", "RSS at the end [MB]", "growth [MB]", "CPU [%]"]
    print(markdown.table(header, usage, ["l", "r", "r", "r", "r"]))
    print(f"\nticks in the run: {timing.ticks}")
    for topic in ("measurement", "plant_truth"):
        print(f"ticks without {topic} in the bag: {timing.messages_lost[topic]}")
    # Real time: a node that falls behind skips to the newest sample; what it published is all
    # in the bag (the skipped ticks were never answered, they are not recording losses).
    for name, topic, pattern in (
        ("observer", "estimate", r"processed (\d+) measurements"),
        ("controller", "command", r"sent (\d+) commands"),
    ):
        match = re.search(pattern, rig.processes[name].log())
        published = int(match.group(1)) if match else -1
        in_bag = int(np.unique(bag.topics[topic]["tick"]).size)
        print(
            f"{topic}: {published} published by the {name}, {in_bag} ticks in the bag "
            f"({timing.messages_lost[topic]} ticks skipped under load, never published)"
        )
    print(
        f"periods <= 1.5 T: {timing.on_time_periods_percent:.2f} %, y -> u latency p50 / p99: "
        f"{timing.latency_p50_ms:.2f} / {timing.latency_p99_ms:.2f} ms, u applied one tick after y: "
        f"{timing.commands_on_time_percent:.1f} %\n"
    )
    print("Contact force per minute of simulated time (minute 1 holds the start: F_r filtered from 0)\n")
    minutes = [
        [minute + 1, f"{mean:.2f}", f"{std:.3f}"]
        for minute, mean, std in sigma_per_minute(bag, LoopParameters().rate_hz)
    ]
    print(markdown.table(["minute", "mean contact force [N]", "sigma [N]"], minutes, "r"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
