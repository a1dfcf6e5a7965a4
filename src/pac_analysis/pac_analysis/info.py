"""``ros2 run pac_analysis info <bag>``: what ``ros2 bag info`` shows, plus pac's tick check.

A bag with ``/diagnostics`` also gets each node's health: its worst level over the bag and
every change of level (log time from the bag's start, with the status message).

A damaged bag (truncated, unreadable index, messages missing against metadata.yaml, unknown
types) gives the table of what is readable, one line per problem on stderr and exit status 1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from pac_bag.reader import BagError, TopicData, read_bag
from pac_common import messages
from pac_common.diagnostics import level_name

#: Level changes listed per status; the rest are counted.
MAX_CHANGES = 8


def level_changes(data: TopicData) -> dict[str, list[tuple[int, int, str]]]:
    """Per status name (``<node>: <what>``): (log time [ns], level, message) at each change of level."""
    changes: dict[str, list[tuple[int, int, str]]] = {}
    for log_time, statuses in zip(data.log_time_ns, data["status"], strict=True):
        for status in statuses:
            seen = changes.setdefault(status.name, [])
            if not seen or seen[-1][1] != int(status.level):
                seen.append((int(log_time), int(status.level), status.message))
    return changes


def diagnostics_lines(data: TopicData, start_ns: int) -> list[str]:
    """The health summary: worst level per status, then its level changes."""
    lines = ["diagnostics: worst level per node, and each change of level (s from the bag's start)"]
    for name, changes in sorted(level_changes(data).items()):
        worst = max(level for _, level, _ in changes)
        lines.append(f"  {name:28s} worst {level_name(worst)}")
        for log_time, level, message in changes[:MAX_CHANGES]:
            lines.append(f"    {(log_time - start_ns) * 1e-9:9.3f} s  {level_name(level):5s} {message}")
        if len(changes) > MAX_CHANGES:
            lines.append(f"    ... {len(changes) - MAX_CHANGES} more changes")
    return lines


def describe(path: Path) -> tuple[str, list[str]]:
    bag = read_bag(path)
    lines = [f"bag: {path}"]
    if bag.metadata:
        lines.append(f"source: {bag.metadata.get('source', '?')}  label: {bag.metadata.get('label', '')}")
    starts = [int(t.log_time_ns.min()) for t in bag.topics.values() if len(t)]
    ends = [int(t.log_time_ns.max()) for t in bag.topics.values() if len(t)]
    lines.append(f"duration: {(max(ends) - min(starts)) * 1e-9:.3f} s (log time)")
    lines.append(
        f"{'topic':14s} {'type':36s} {'count':>7s} {'rate Hz':>8s} {'ticks':>13s} "
        f"{'missing':>7s} {'dup':>5s} {'max gap':>9s}"
    )
    for topic, data in sorted(bag.topics.items()):
        n = len(data)
        dur = (data.log_time_ns.max() - data.log_time_ns.min()) * 1e-9 if n > 1 else 0.0
        rate = (n - 1) / dur if dur > 0 else float("nan")
        gap = float(np.max(np.diff(data.log_time_ns)) * 1e-6) if n > 1 else float("nan")
        if "tick" in data.columns and topic in messages.LOOP_TOPICS:  # one message per tick
            ticks = data["tick"]
            unique = np.unique(ticks)
            span = f"{int(ticks.min())}..{int(ticks.max())}"
            missing = int(ticks.max() - ticks.min() + 1 - unique.size)
            dup = n - unique.size
        else:
            span, missing, dup = "-", 0, 0
        lines.append(
            f"{topic:14s} {data.typename:36s} {n:7d} {rate:8.1f} {span:>13s} {missing:7d} {dup:5d} "
            f"{gap:7.2f}ms"
        )
    diagnostics = bag.topics.get("diagnostics")
    if diagnostics is not None and len(diagnostics):
        lines += diagnostics_lines(diagnostics, min(starts))
    return "\n".join(lines), bag.warnings


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="info", description=__doc__)
    parser.add_argument("bag", type=Path)
    args = parser.parse_args(argv)
    try:
        text, warnings = describe(args.bag)
    except BagError as exc:
        print(f"info: {exc}", file=sys.stderr)
        return 1
    print(text)
    for warning in warnings:
        print(f"info: {args.bag}: {warning}", file=sys.stderr)
    return 1 if warnings else 0


if __name__ == "__main__":
    sys.exit(main())
