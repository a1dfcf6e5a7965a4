"""``ros2 run pac_analysis recover <bag> [--out DIR]``: make a crashed recording a closed, indexed bag.

Reads whatever the MCAP record stream of ``<bag>`` holds (a recorder killed with
SIGKILL leaves no summary, index or metadata.yaml) and writes it to a new bag
(default ``<bag>_recovered``); the original is left alone.  Exit status 1 when the
input was damaged (one line per problem; the recovered bag is still written), 0 when
it was intact, 2 when the output exists already.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pac_bag.reader import BagError, bag_files
from pac_bag.recovery import iter_records
from pac_bag.writer import BagWriter
from pac_common import messages


def recover(path: Path, out: Path) -> tuple[dict[str, int], list[str]]:
    bag_files(path)  # not a bag: the one line every tool gives
    warnings: list[str] = []
    records = list(iter_records(path, warnings))
    if not records:
        raise BagError(f"{path}: no readable message" + (f" ({'; '.join(warnings)})" if warnings else ""))
    topics = {t: ty for t, ty, _, _ in records if t in messages.WATCHED_TOPICS}
    for topic in sorted({t for t, _, _, _ in records} - set(topics)):
        warnings.append(f"topic '{topic}': not a pac topic, not recovered")
    with BagWriter(
        out, {"source": "recovered", "label": out.name, "recovered_from": str(path)}, topics
    ) as bag:
        for topic, _, log_time, data in records:
            if topic in topics:
                bag.write_raw(topic, data, log_time)
        counts = dict(bag.counts)
    return counts, warnings


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="recover", description=__doc__)
    parser.add_argument("bag", type=Path)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    out = args.out or args.bag.with_name(args.bag.name + "_recovered")
    if out.exists():
        print(f"recover: invalid --out {out}: allowed a path that does not exist yet", file=sys.stderr)
        return 2
    try:
        counts, warnings = recover(args.bag, out)
    except BagError as exc:
        print(f"recover: {exc}", file=sys.stderr)
        return 1
    for warning in warnings:
        print(f"recover: {args.bag}: {warning}", file=sys.stderr)
    print(f"recover: wrote {out} ({', '.join(f'{t}={n}' for t, n in counts.items())})")
    return 1 if warnings else 0


if __name__ == "__main__":
    sys.exit(main())
