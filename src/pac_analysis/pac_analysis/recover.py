"""``ros2 run pac_analysis recover <bag> [--out DIR]``: make a crashed recording a closed, indexed bag.

Reads whatever the MCAP record stream of ``<bag>`` holds (a recorder killed with
SIGKILL leaves no summary, index or metadata.yaml) and writes it to a new bag
(default ``<bag>_recovered``); the original is left alone.  A damaged chunk loses its own
messages only (they are counted); messages on a topic that are not of pac's type for it, or
on a topic that is not pac's, are counted and not written.  The new bag is written under a
temporary name and renamed when complete.  Exit status 1 when the input was damaged (one
line per problem; the recovered bag is still written), 0 when it was intact, 2 when the
output exists already or cannot be written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pac_bag.reader import BagError, bag_files
from pac_bag.recovery import iter_records
from pac_bag.writer import BagWriter, atomic_bag
from pac_common import messages


def recover(path: Path, out: Path) -> tuple[dict[str, int], list[str]]:
    """Write every intact message of ``path`` to the new bag ``out``: (messages per topic written,
    one line per problem, including each message not written and why)."""
    bag_files(path)  # not a bag: the one line every tool gives
    warnings: list[str] = []
    records = list(iter_records(path, warnings))
    if not records:
        raise BagError(f"{path}: no readable message" + (f" ({'; '.join(warnings)})" if warnings else ""))
    # A topic goes in with pac's type for it; messages of another type on it are not written.
    topics = {t: messages.WATCHED_TOPICS[t] for t, _, _, _ in records if t in messages.WATCHED_TOPICS}
    skipped: dict[tuple[str, str], int] = {}
    for topic, typename, _, _ in records:
        if topics.get(topic) != typename:
            skipped[topic, typename] = skipped.get((topic, typename), 0) + 1
    for (topic, typename), count in sorted(skipped.items()):
        why = "not a pac topic" if topic not in topics else f"not {topics[topic]}"
        warnings.append(f"topic '{topic}': {count} messages of {typename} not recovered ({why})")
    with (
        atomic_bag(out) as partial,
        BagWriter(
            partial,
            {"source": "recovered", "label": out.name, "recovered_from": str(path)},
            topics,
            name=out.name,
        ) as bag,
    ):
        for topic, typename, log_time, data in records:
            if topics.get(topic) == typename:
                bag.write_raw(topic, data, log_time)
        counts = dict(bag.counts)
    return counts, warnings


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="recover", description=__doc__)
    parser.add_argument("bag", type=Path)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    bag = args.bag if args.bag.name else args.bag.resolve()  # `recover .` names its output too
    out = args.out or bag.with_name(bag.name + "_recovered")
    if out.exists():
        print(f"recover: invalid --out {out}: allowed a path that does not exist yet", file=sys.stderr)
        return 2
    try:
        counts, warnings = recover(args.bag, out)
    except BagError as exc:
        print(f"recover: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"recover: cannot write {out}: {exc.strerror or exc} (nothing written)", file=sys.stderr)
        return 2
    for warning in warnings:
        print(f"recover: {args.bag}: {warning}", file=sys.stderr)
    print(f"recover: wrote {out} ({', '.join(f'{t}={n}' for t, n in counts.items())})")
    return 1 if warnings else 0


if __name__ == "__main__":
    sys.exit(main())
