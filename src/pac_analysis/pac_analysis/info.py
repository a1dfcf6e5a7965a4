"""``ros2 run pac_analysis info <bag>``: what ``ros2 bag info`` shows, plus pac's tick check.

A damaged bag (truncated, unreadable index, messages missing against metadata.yaml, unknown
types) gives the table of what is readable, one line per problem on stderr and exit status 1.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from pac_bag.reader import BagError, read_bag
from pac_common import messages


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
