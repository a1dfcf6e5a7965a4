"""``make report BAG=<dir>`` / ``ros2 run pac_analysis report <bag> [<bag> ...]``.

Writes ``reports/<bag name>/`` (or ``reports/<a>_vs_<b>/`` for several bags):
``metrics.json`` and ``metrics.md`` (contact-force quality over ``--from``/``--to``,
default from 3 s to the end; loop timing for live bags) and PNG figures in the
style of the paper's Figs. 3-5, plus an overlay of the contact forces when given
several bags (e.g. passive vs active).  A damaged or incomplete bag gives one
line per problem on stderr, exit status 1, and the results that were computable.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from pac_bag.reader import BagData, BagError, read_bag
from pac_common import jsonio

from .metrics import (
    compute_metrics,
    loop_timing,
    markdown_table,
    missing_inputs,
    pantograph_statistics,
    pantograph_table,
    timing_table,
)
from .plots import overlay_figure, run_figure


def bag_names(bags: list[Path]) -> list[str]:
    """One distinct name per bag (its column, figure and part of the default folder): its folder's
    name, with as many parent folders as it takes to tell it from the others (``a/run`` and
    ``b/run``: ``a_run``, ``b_run``), numbered when the same bag is given twice."""
    parts = [path.absolute().parts[1:] for path in bags]  # without the root

    def named(i: int, depth: int) -> str:
        return "_".join(parts[i][-depth:])

    names = []
    for i in range(len(bags)):
        depth = 1
        while depth < len(parts[i]) and any(
            named(j, depth) == named(i, depth) for j in range(len(bags)) if parts[j] != parts[i]
        ):
            depth += 1
        names.append(named(i, depth))
    counted = [names[:i].count(n) for i, n in enumerate(names)]
    return [n if k == 0 else f"{n}_{k + 1}" for n, k in zip(names, counted, strict=True)]


def report(
    bags: list[Path], out: Path, window_from: float, window_to: float | None
) -> tuple[dict, list[str]]:
    problems: list[str] = []
    loaded: dict[str, BagData] = {}
    for path, name in zip(bags, bag_names(bags), strict=True):
        try:
            bag = read_bag(path)
        except BagError as exc:
            problems.append(str(exc))
            continue
        problems += [f"{path}: {w}" for w in bag.warnings]
        problems += [f"{path}: {m}" for m in missing_inputs(bag)]
        loaded[name] = bag
    if not loaded:
        return {}, problems
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {}
    metrics, timings, pantographs = {}, {}, {}
    for name, bag in loaded.items():
        entry: dict[str, Any] = {"bag": str(bag.path), "source": bag.metadata.get("source", "unknown")}
        try:
            metrics[name] = compute_metrics(bag, window_from, window_to)
            entry["metrics"] = metrics[name].as_dict()
        except ValueError as exc:
            problems.append(f"{bag.path}: {exc}")
        try:
            rows = pantograph_statistics(bag, window_from, window_to)
        except ValueError as exc:
            problems.append(f"{bag.path}: pantographs: {exc}")
            rows = []
        if rows:
            pantographs[name] = entry["pantographs"] = rows
        if "plant_truth" in bag.topics and bag.metadata.get("source") != "offline":
            try:
                timings[name] = loop_timing(bag)
                entry["loop_timing"] = timings[name].as_dict()
            except (ValueError, KeyError) as exc:
                if bag.metadata.get("source") == "live":
                    problems.append(f"{bag.path}: loop timing: {exc}")
        run_figure(bag, name, out / f"{name}.png")
        entry["figure"] = f"{name}.png"
        results[name] = entry
    if len(loaded) > 1 and all("plant_truth" in b.topics for b in loaded.values()):
        overlay_figure(loaded, " vs ".join(loaded), out / "overlay.png")
    text = [f"# Report: {', '.join(loaded) or '(no readable bag)'}", ""]
    if metrics:
        text += ["## Contact force", "", markdown_table(metrics)]
    for name, rows in pantographs.items():
        text += [
            f"## Every pantograph: {name} (EN 50318: 20 Hz low-pass, whole spans)",
            "",
            pantograph_table(rows),
        ]
    if timings:
        text += ["## Loop timing", "", timing_table(timings)]
    if problems:
        text += ["## Problems", ""] + [f"- {p}" for p in problems] + [""]
    text += [f"![{n}]({n}.png)" for n in loaded]
    if len(loaded) > 1:
        text.append("![overlay](overlay.png)")
    (out / "metrics.md").write_text("\n".join(text) + "\n")
    (out / "metrics.json").write_text(jsonio.dumps({"runs": results, "problems": problems}, indent=2))
    return results, problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="report", description=__doc__)
    parser.add_argument("bags", type=Path, nargs="+", help="bag directories (or .mcap files)")
    parser.add_argument("--from", dest="window_from", type=float, default=3.0, help="window start [s]")
    parser.add_argument(
        "--to", dest="window_to", type=float, default=None, help="window end [s] (default: end)"
    )
    parser.add_argument("--out", type=Path, default=None, help="output folder (default reports/<name>)")
    args = parser.parse_args(argv)
    window_to = math.inf if args.window_to is None else args.window_to
    if not (math.isfinite(args.window_from) and args.window_from >= 0.0 and args.window_from < window_to):
        parser.error(
            f"the window --from {args.window_from:g} --to {window_to:g}: allowed 0 <= from < to, "
            "both finite (--to may be left out: the end of the run)"
        )
    if args.window_to is not None and not math.isfinite(args.window_to):
        parser.error(f"--to {args.window_to:g}: allowed a finite number of seconds")
    name = "_vs_".join(bag_names(args.bags))
    out = args.out or Path("reports") / name
    try:
        results, problems = report(args.bags, out, args.window_from, args.window_to)
    except OSError as exc:  # e.g. run from a read-only folder: ./reports cannot be created
        where = exc.filename or out
        reason = exc.strerror or exc
        print(f"report: cannot write {where}: {reason} (choose another folder with --out)", file=sys.stderr)
        return 2
    for problem in problems:
        print(f"report: {problem}", file=sys.stderr)
    if not results:
        return 1
    print((out / "metrics.md").read_text())
    print(f"report: wrote {out}/ (metrics.json, metrics.md, figures)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
