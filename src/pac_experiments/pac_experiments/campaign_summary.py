"""A campaign's results summarised over one axis (the line seeds): mean, 95 % confidence interval,
worst and best per group of the other axes.

``ros2 run pac_experiments campaign_summary DIR --over line_seed`` reads ``DIR/results.csv`` (a
campaign's output) and writes ``DIR/summary.md`` and ``DIR/summary.json``: for each combination of
the other axes, over the runs that are ``ok``, the number of runs and, per measure, the mean with
its 95 % confidence interval (Student's t on the runs' standard error: the runs are independent
draws of the line), the smallest and the largest value. A group of one run (the ideal rig, whose
line has no seed) gets its value, no interval.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path

from scipy import stats

from pac_common import jsonio, markdown

#: The measures summarised, as results.csv names them, and their headings.
MEASURES = {
    "en50318_contact_force_mean": "Fm [N]",
    "en50318_contact_force_std": "sigma [N]",
    "en50318_statistical_min": "Fm-3sigma [N]",
    "en50318_contact_force_max": "max F [N]",
    "en50318_contact_loss_percent": "loss [%]",
    "uplift_max_mm": "max uplift [mm]",
}
#: Columns before ``status`` in results.csv that are not axes (what a SPEC derives).
NOT_AXES = {"force_amplitude"}


@dataclass(frozen=True)
class Interval:
    """The mean of ``n`` values with its 95 % confidence interval, and their extremes."""

    n: int
    mean: float
    low: float
    high: float
    smallest: float
    largest: float

    @staticmethod
    def of(values: list[float]) -> Interval:
        n = len(values)
        mean = statistics.fmean(values)
        if n < 2:
            return Interval(n, mean, math.nan, math.nan, mean, mean)
        half = stats.t.ppf(0.975, n - 1) * statistics.stdev(values) / math.sqrt(n)
        return Interval(n, mean, mean - half, mean + half, min(values), max(values))

    def text(self) -> str:
        if self.n < 2:
            return f"{self.mean:.4g}"
        return f"{self.mean:.4g} [{self.low:.4g}, {self.high:.4g}] ({self.smallest:.4g}..{self.largest:.4g})"


def summarise(rows: list[dict[str, str]], over: str) -> list[tuple[dict[str, str], dict[str, Interval]]]:
    """Groups of ``rows`` (status ok) by every axis but ``over`` and the measures, in first-seen
    order, each with its measures' intervals."""
    if not rows:
        return []
    columns = list(rows[0])
    # The campaign writes its axes first, then what it derives and the status, then the measures.
    head = columns[: columns.index("status")] if "status" in columns else columns
    axes = [c for c in head if c not in NOT_AXES and c != over]
    groups: dict[tuple[str, ...], list[dict[str, str]]] = {}
    for row in rows:
        if row.get("status") != "ok":
            continue
        groups.setdefault(tuple(row[a] for a in axes), []).append(row)
    out = []
    for key, members in groups.items():
        measures = {}
        for name in MEASURES:
            values = [float(r[name]) for r in members if r.get(name) not in (None, "", "nan")]
            if values:
                measures[name] = Interval.of(values)
        out.append((dict(zip(axes, key, strict=True)), measures))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="campaign_summary", description=__doc__)
    parser.add_argument("out", type=Path, help="a campaign's output directory (with results.csv)")
    parser.add_argument("--over", default="line_seed", help="the axis summarised over (default line_seed)")
    args = parser.parse_args(argv)
    path = args.out / "results.csv"
    try:
        with path.open(newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as exc:
        print(f"campaign_summary: cannot read {path}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    groups = summarise(rows, args.over)
    if not groups:
        print(f"campaign_summary: no run in {path}", file=sys.stderr)
        return 2
    axes = list(groups[0][0])
    header = [*axes, "runs", *MEASURES.values()]
    table = [
        [*group.values(), str(next(iter(m.values())).n), *(m[k].text() if k in m else "" for k in MEASURES)]
        for group, m in groups
    ]
    text = (
        f"# Summary over `{args.over}` of {args.out.name}\n\n"
        "Per measure: mean [95 % confidence interval] (smallest..largest) over the runs of each group.\n\n"
        + markdown.table(header, table)
        + "\n"
    )
    (args.out / "summary.md").write_text(text)
    data = [{"group": group, "measures": {k: vars(v) for k, v in m.items()}} for group, m in groups]
    jsonio.write(args.out / "summary.json", data)  # strict JSON: a NaN (no interval) as null
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
