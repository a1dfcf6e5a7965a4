"""A campaign's results summarised over one axis (the line seeds): mean, 95 % confidence interval,
worst and best per group of the other axes.

``ros2 run pac_experiments campaign_summary DIR --over line_seed`` reads ``DIR/results.csv`` (a
campaign's output) and writes ``DIR/summary.md`` and ``DIR/summary.json``: for each combination of
the other axes, over the runs that are ``ok``, the number of runs and, per measure, the mean with
its 95 % confidence interval (Student's t on the runs' standard error: the runs are independent
draws of the line), the smallest and the largest value. A group of one run (the ideal rig, whose
line has no seed) gets its value, no interval.

``--against passive`` compares every other law with that one, run by run: each run is paired with
the reference law's run that has the same value on every other axis (the same line seed, speed,
scenario; the observer may differ), and ``DIR/against.md`` / ``against.json`` give per group the
change of sigma [%] (mean with its 95 % interval over the pairs, and the worst: the largest), the
runs with more contact loss than their reference run, and the paired runs' Fm, Fm - 3 sigma, largest
|u| and F_hat error. A run without its reference run is left out (and counted).
``--against AXIS=VALUE`` does the same for any axis of the grid: ``--against
catenary=realistic_3km_as_designed`` compares each other catenary with that one, run by run.

``--draws AXIS[,AXIS...]`` names axes that are draws *within* a line (the car body's track, the
turbulence, the noise: another run of the same train on the same line): they are not groups. Each
line's runs are averaged over its draws first, and the interval is over the lines (the lines are the
independent draws; two runs on one line are not); the extremes, the worst change and the runs with
more contact loss are over every run.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
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
    "worst_span_loss_percent": "worst span's loss [%]",
    "saturation_percent": "saturated [%]",
}
#: Of MEASURES and AGAINST_MEASURES, those shown only where the runs have them (measured since a
#: later version: a report written before keeps its columns).
WHERE_MEASURED = ("worst_span_loss_percent", "saturation_percent")
#: Columns before ``status`` in results.csv that are not axes (what a SPEC derives).
NOT_AXES = {"force_amplitude"}


def _shown(measures: dict[str, str], found: list[dict[str, Interval]]) -> list[str]:
    """The names of ``measures`` a report shows: all, those of WHERE_MEASURED only where some group
    of ``found`` has them."""
    return [k for k in measures if k not in WHERE_MEASURED or any(k in m for m in found)]


def percent_change(value: float, reference: float) -> float:
    """How much ``value`` differs from ``reference`` [%]: a sigma against passive's, in every report."""
    return 100.0 * (value / reference - 1.0)


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
    def clustered(values: list[float], clusters: list[str]) -> Interval:
        """The interval of the clusters' means (each cluster's values averaged first), with the
        extremes of every value: ``--draws`` (module docstring)."""
        means: dict[str, list[float]] = {}
        for value, cluster in zip(values, clusters, strict=True):
            means.setdefault(cluster, []).append(value)
        over = Interval.of([statistics.fmean(v) for v in means.values()])
        return dataclasses.replace(over, smallest=min(values), largest=max(values))

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


def summarise(
    rows: list[dict[str, str]], over: str, draws: tuple[str, ...] = ()
) -> list[tuple[dict[str, str], dict[str, Interval]]]:
    """Groups of ``rows`` (status ok) by every axis but ``over`` and the ``draws`` and the measures,
    in first-seen order, each with its measures' intervals (over ``over``, its draws averaged)."""
    if not rows:
        return []
    columns = list(rows[0])
    # The campaign writes its axes first, then what it derives and the status, then the measures.
    head = columns[: columns.index("status")] if "status" in columns else columns
    axes = [c for c in head if c not in NOT_AXES and c != over and c not in draws]
    groups: dict[tuple[str, ...], list[dict[str, str]]] = {}
    for row in rows:
        if row.get("status") != "ok":
            continue
        groups.setdefault(tuple(row[a] for a in axes), []).append(row)
    out = []
    for key, members in groups.items():
        measures = {}
        for name in MEASURES:
            kept = [r for r in members if r.get(name) not in (None, "", "nan")]
            if kept:
                values = [float(r[name]) for r in kept]
                measures[name] = Interval.clustered(values, [r[over] for r in kept])
        out.append((dict(zip(axes, key, strict=True)), measures))
    return out


#: What ``--against`` reports besides the change of sigma: results.csv's name, its heading.
AGAINST_MEASURES = {
    "en50318_contact_force_mean": "Fm [N]",
    "en50318_statistical_min": "Fm-3sigma [N]",
    "en50318_contact_loss_percent": "loss [%]",
    "u_max_abs": "max |u| [N]",
    "force_hat_error_percent": "F_hat error [%]",
    "worst_span_loss_percent": "worst span's loss [%]",
    "saturation_percent": "saturated [%]",
}
#: Axes a run and its reference run may differ on besides the law (the reference reads no estimate).
PAIR_FREE = ("law", "observer")


@dataclass(frozen=True)
class Comparison:
    """One law's runs against the reference law's on the same other axes."""

    group: dict[str, str]
    sigma_change: Interval  # percent, per pair (per line, its draws averaged)
    pairs: int
    more_loss: int  # pairs where the run lost contact more than its reference run
    unpaired: int
    measures: dict[str, Interval]


def reference_of(against: str) -> tuple[str, str]:
    """(axis, value) of an ``--against`` argument: ``LAW`` (the axis ``law``) or ``AXIS=VALUE``."""
    axis, _, value = against.rpartition("=")
    return axis or "law", value


def compare(
    rows: list[dict[str, str]], over: str, reference: str, draws: tuple[str, ...] = ()
) -> list[Comparison]:
    """Every law but ``reference`` against it, pair by pair (module docstring), grouped by every axis
    but ``over`` and the ``draws`` (runs that are not ``ok`` are left out, with their pairs).
    ``reference`` ``AXIS=VALUE``: every other value of that axis against VALUE instead, each run
    paired with the run that has VALUE there and the same value on every other axis."""
    axis, value = reference_of(reference)
    ok = [r for r in rows if r.get("status") == "ok"]
    if not ok:
        return []
    columns = list(rows[0])
    head = columns[: columns.index("status")] if "status" in columns else columns
    axes = [c for c in head if c not in NOT_AXES]
    free = PAIR_FREE if axis == "law" else (axis,)
    pair_axes = [a for a in axes if a not in free]
    references = {tuple(r[a] for a in pair_axes): r for r in ok if r[axis] == value}
    groups: dict[tuple[str, ...], list[tuple[dict[str, str], dict[str, str] | None]]] = {}
    for row in ok:
        if row[axis] == value:
            continue
        key = tuple(row[a] for a in axes if a != over and a not in draws)
        groups.setdefault(key, []).append((row, references.get(tuple(row[a] for a in pair_axes))))
    out = []
    sigma = "en50318_contact_force_std"
    loss = "en50318_contact_loss_percent"
    for key, members in groups.items():
        pairs = [(run, ref) for run, ref in members if ref is not None]
        if not pairs:
            continue
        changes = [percent_change(float(run[sigma]), float(ref[sigma])) for run, ref in pairs]
        lines = [run[over] for run, _ in pairs]
        more = sum(float(run[loss]) > float(ref[loss]) for run, ref in pairs)
        measures = {}
        for name in AGAINST_MEASURES:
            kept = [r for r, _ in pairs if r.get(name) not in (None, "", "nan")]
            if kept:
                measures[name] = Interval.clustered([float(r[name]) for r in kept], [r[over] for r in kept])
        group = dict(zip([a for a in axes if a != over and a not in draws], key, strict=True))
        change = Interval.clustered(changes, lines)
        out.append(Comparison(group, change, len(pairs), more, len(members) - len(pairs), measures))
    return out


def write_against(
    out: Path, comparisons: list[Comparison], over: str, reference: str, draws: tuple[str, ...] = ()
) -> str:
    """``against.md`` and ``against.json`` in ``out``; returns the markdown."""
    axes = list(comparisons[0].group)
    shown = _shown(AGAINST_MEASURES, [c.measures for c in comparisons])
    header = [
        *axes,
        "pairs",
        "sigma change [%]",
        "worst [%]",
        "more loss",
        *(AGAINST_MEASURES[k] for k in shown),
    ]
    if draws:
        header.insert(len(axes) + 1, over)
    table = []
    for c in comparisons:
        change = c.sigma_change
        interval = f"{change.mean:+.1f}"
        if change.n > 1:
            interval += f" [{change.low:+.1f}, {change.high:+.1f}]"
        table.append(
            [
                *c.group.values(),
                str(c.pairs),
                *([str(change.n)] if draws else []),
                interval,
                f"{change.largest:+.1f}",
                str(c.more_loss),
                *(c.measures[k].text() if k in c.measures else "" for k in shown),
            ]
        )
    text = (
        f"# Against `{reference}` over `{over}` in {out.name}\n\n"
        f"Each run against the `{reference}` run on the same {over} and other axes: the change of the "
        "EN 50318 sigma [%] (mean [95 % confidence interval], worst = largest), the runs with more "
        f"contact loss than their `{reference}` run, then the runs' measures (mean [95 % interval] "
        "(smallest..largest)).\n\n"
        + (
            f"Draws within a line ({', '.join(draws)}) are averaged per {over} first; the interval is "
            f"over the {over} values (column {over}), the worst and the runs with more loss over every "
            "pair.\n\n"
            if draws
            else ""
        )
        + markdown.table(header, table)
        + "\n"
    )
    (out / "against.md").write_text(text)
    data = [
        {
            "group": c.group,
            "sigma_change_percent": vars(c.sigma_change),
            "pairs": c.pairs,
            "more_loss": c.more_loss,
            "unpaired": c.unpaired,
            "measures": {k: vars(v) for k, v in c.measures.items()},
        }
        for c in comparisons
    ]
    jsonio.write(out / "against.json", data)
    return text


def read_results(out: Path, prog: str) -> list[dict[str, str]] | None:
    """The rows of ``out/results.csv``; None (after one line on stderr naming ``prog``) if unreadable."""
    path = out / "results.csv"
    try:
        with path.open(newline="") as f:
            return list(csv.DictReader(f))
    except OSError as exc:
        print(f"{prog}: cannot read {path}: {exc.strerror or exc}", file=sys.stderr)
        return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="campaign_summary", description=__doc__)
    parser.add_argument("out", type=Path, help="a campaign's output directory (with results.csv)")
    parser.add_argument("--over", default="line_seed", help="the axis summarised over (default line_seed)")
    parser.add_argument(
        "--against",
        metavar="LAW|AXIS=VALUE",
        help="also compare every other law with LAW (or every other value of AXIS with VALUE), run by run",
    )
    parser.add_argument(
        "--draws",
        default="",
        metavar="AXIS[,AXIS...]",
        help="axes that are draws within one value of --over, averaged per value first (module docstring)",
    )
    args = parser.parse_args(argv)
    draws = tuple(a for a in args.draws.split(",") if a)
    path = args.out / "results.csv"
    rows = read_results(args.out, "campaign_summary")
    if rows is None:
        return 2
    groups = summarise(rows, args.over, draws)
    if not groups:
        print(f"campaign_summary: no run in {path}", file=sys.stderr)
        return 2
    axes = list(groups[0][0])
    shown = _shown(MEASURES, [m for _, m in groups])
    header = [*axes, args.over if draws else "runs", *(MEASURES[k] for k in shown)]
    table = [
        [*group.values(), str(next(iter(m.values())).n), *(m[k].text() if k in m else "" for k in shown)]
        for group, m in groups
    ]
    text = (
        f"# Summary over `{args.over}` of {args.out.name}\n\n"
        "Per measure: mean [95 % confidence interval] (smallest..largest) over the runs of each group"
        + (f", each {args.over}'s draws ({', '.join(draws)}) averaged first" if draws else "")
        + ".\n\n"
        + markdown.table(header, table)
        + "\n"
    )
    (args.out / "summary.md").write_text(text)
    data = [{"group": group, "measures": {k: vars(v) for k, v in m.items()}} for group, m in groups]
    jsonio.write(args.out / "summary.json", data)  # strict JSON: a NaN (no interval) as null
    print(text)
    if args.against:
        axis, _ = reference_of(args.against)
        if axis not in rows[0]:
            print(f"campaign_summary: {path} has no column '{axis}' to compare against", file=sys.stderr)
            return 2
        comparisons = compare(rows, args.over, args.against, draws)
        if not comparisons:
            print(f"campaign_summary: no run of {path} pairs with a {args.against} run", file=sys.stderr)
            return 2
        print(write_against(args.out, comparisons, args.over, args.against, draws))
    return 0


if __name__ == "__main__":
    sys.exit(main())
