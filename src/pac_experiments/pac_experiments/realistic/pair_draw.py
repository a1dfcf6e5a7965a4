"""What "more contact loss than the passive pair" can resolve: the pair's runs again on another draw,
against the pair report's draw 0 (``make realistic-pair-draw``).

The pair report (``make realistic-pair``, :mod:`pac_experiments.realistic.pair`) compares each run
with one run of the passive pair on the same line and speed. Two runs of the same train over the
same line differ by more than the control: the track under each car body, the turbulent uplift and
the sensors' noise (:data:`pac_experiments.realistic.DRAW_SEEDS`). This runs the pair report's
configurations (``--configs``: some of them; the passive pair always) again on draw ``--draw``
(each of those seeds set to it; the pair report's runs are draw 0), every other setting theirs, and
writes ``reports/realistic/pair_draw/`` (draw.md, results.csv):

- per speed and pantograph, on how many lines the passive pair's second draw loses more contact
  than its first, the range of that change [points] and of the sigma change;
- per configuration, speed and pantograph, against the passive pair of the same draw: the sigma
  change, the lines losing more contact on each draw, of them those beyond the largest rise of the
  passive pair between its two draws at that speed and pantograph, and the lines losing more on
  the average of both draws.

``--results`` rebuilds the report from an earlier run's results.csv without running.
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from statistics import fmean
from typing import Any

from pac_common import markdown
from pac_experiments.realistic import draw, write_results
from pac_experiments.realistic.pair import (
    PANTOGRAPHS,
    SEEDS,
    SPEEDS,
    Config,
    change,
    configurations,
    passive_pairs,
    picked,
    read_results,
    run_one,
)

OUT = Path("reports/realistic/pair_draw")
AGAINST = Path("reports/realistic/pair/results.csv")
PASSIVE = "passive pair"


@dataclass(frozen=True)
class DrawSpread:
    """One speed and pantograph: the passive pair's second draw against its first, line by line."""

    lines: int
    more_loss: int  # lines where the second draw loses more contact
    loss_change: tuple[float, float]  # smallest and largest change of the loss [points]
    sigma_change: tuple[float, float]  # smallest and largest change of sigma [%]

    @property
    def largest_rise(self) -> float:
        """The largest rise of the loss [points] (0 where no line loses more)."""
        return max(self.loss_change[1], 0.0)


def spread(first: list[dict[str, Any]], second: list[dict[str, Any]]) -> dict[tuple[float, str], DrawSpread]:
    """Per (speed, pantograph): the passive pair of ``second`` against that of ``first`` on the lines
    both ran (rows as :func:`pair.read_results` gives them)."""
    a, b = passive_pairs(first), passive_pairs(second)
    both = a.keys() & b.keys()
    result = {}
    for speed in sorted({v for _, v in both}):
        keys = sorted(key for key in both if key[1] == speed)
        for name in PANTOGRAPHS:
            changes = [change(b[k], a[k], name) for k in keys]
            sigma, loss = [c[0] for c in changes], [c[1] for c in changes]
            result[speed, name] = DrawSpread(
                len(keys),
                sum(c > 0.0 for c in loss),
                (min(loss), max(loss)),
                (min(sigma), max(sigma)),
            )
    return result


def _changes(
    rows: list[dict[str, Any]], speed: float, config: str, name: str
) -> dict[int, tuple[float, float]]:
    """Per line of ``rows`` (one draw): ``config``'s change of pantograph ``name``'s sigma [%] and loss
    [points] against the passive pair of the same draw, line and speed."""
    passive = passive_pairs(rows)
    return {
        r["line_seed"]: change(r, passive[r["line_seed"], speed], name)
        for r in rows
        if r["config"] == config and r["speed_kmh"] == speed and (r["line_seed"], speed) in passive
    }


@dataclass(frozen=True)
class AgainstPassive:
    """One configuration, speed and pantograph against the passive pair of the same draw, on each
    draw and over both (the lines both draws ran)."""

    lines: int
    sigma_change: tuple[float, float]  # mean change [%] on draw 0 and on the other draw
    more_loss: tuple[int, int]  # lines losing more contact, each draw
    beyond: tuple[int, int]  # of those, lines whose rise exceeds the passive pair's largest rise
    more_loss_both: int  # lines whose loss, averaged over both draws, exceeds the passive pair's


def against_passive(
    first: list[dict[str, Any]], second: list[dict[str, Any]], spreads: dict[tuple[float, str], DrawSpread]
) -> dict[tuple[float, str, str], AgainstPassive]:
    """Per (speed, configuration, pantograph) of ``first`` (draw 0; not the passive pair) that
    ``second`` (the other draw) ran too: :class:`AgainstPassive`, the largest rise from ``spreads``."""
    out = {}
    configs = dict.fromkeys(r["config"] for r in first if r["config"] != PASSIVE)
    for speed in sorted({v for v, _ in spreads}):
        for config in configs:
            for name in PANTOGRAPHS:
                a, b = _changes(first, speed, config, name), _changes(second, speed, config, name)
                lines = sorted(a.keys() & b.keys())
                if not lines:
                    continue
                largest = spreads[speed, name].largest_rise
                out[speed, config, name] = AgainstPassive(
                    len(lines),
                    (fmean(a[s][0] for s in lines), fmean(b[s][0] for s in lines)),
                    (sum(a[s][1] > 0.0 for s in lines), sum(b[s][1] > 0.0 for s in lines)),
                    (sum(a[s][1] > largest for s in lines), sum(b[s][1] > largest for s in lines)),
                    sum(a[s][1] + b[s][1] > 0.0 for s in lines),
                )
    return out


def write_report(rows: list[dict[str, Any]], against: list[dict[str, Any]], k: int, out: Path) -> str:
    """draw.md and results.csv (``rows``: the pair's configurations on draw ``k``; ``against``: the
    pair report's rows, draw 0)."""
    write_results(rows, out)
    spreads = spread(against, rows)
    first = [
        [
            f"{speed:g}",
            name,
            f"{s.more_loss} of {s.lines}",
            f"{s.loss_change[0]:+.2f} … {s.loss_change[1]:+.2f}",
            f"{s.sigma_change[0]:+.1f} … {s.sigma_change[1]:+.1f}",
        ]
        for (speed, name), s in spreads.items()
    ]
    second = [
        [
            f"{speed:g}",
            config,
            name,
            str(c.lines),
            f"{c.sigma_change[0]:+.1f} / {c.sigma_change[1]:+.1f}",
            f"{c.more_loss[0]} / {c.more_loss[1]}",
            f"{c.beyond[0]} / {c.beyond[1]}",
            str(c.more_loss_both),
        ]
        for (speed, config, name), c in against_passive(against, rows, spreads).items()
    ]
    text = (
        "# The pair on a second draw: what one run against one run resolves\n\n"
        "Generated by `make realistic-pair-draw` "
        "(src/pac_experiments/pac_experiments/realistic/pair_draw.py): the runs of the pair report "
        f"again on draw {k} (roof_seed, aero_turbulence_seed, noise_seed = {k}; the pair report's runs "
        "are draw 0), every other setting theirs.\n\n"
        f"## The passive pair, draw {k} against draw 0, line by line\n\n"
        + markdown.table(
            [
                "v [km/h]",
                "pantograph",
                "lines losing more contact",
                "change of the loss [points]",
                "sigma change [%]",
            ],
            first,
        )
        + "\n\n## Each configuration against the passive pair of the same draw\n\n"
        f"Per draw (0 / {k}): the mean sigma change over the lines, the lines losing more contact "
        "than the passive pair on the same line, and of those the lines whose rise exceeds the passive "
        "pair's largest rise between its two draws at that speed and pantograph (beyond the draw). Both "
        "draws: lines whose loss averaged over the two draws exceeds the passive pair's average.\n\n"
        + markdown.table(
            [
                "v [km/h]",
                "configuration",
                "pantograph",
                "lines",
                "sigma vs passive pair [%]",
                "more loss",
                "beyond the draw",
                "more loss, both draws",
            ],
            second,
        )
        + "\n"
    )
    (out / "draw.md").write_text(text)
    return text


def _run(args: tuple[int, float, int, str, Config]) -> dict[str, Any]:
    seed, speed, k, name, (law, controlled, overrides) = args
    return {**run_one(seed, name, (law, controlled, {**overrides, **draw(k)}), speed), "draw": k}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="realistic_pair_draw", description=__doc__.split("\n\n")[0])
    parser.add_argument("--draw", type=int, default=1, help="the draw (default %(default)s; not 0)")
    parser.add_argument(
        "--against", type=Path, default=AGAINST, help="the pair report's results.csv (default: %(default)s)"
    )
    parser.add_argument("--out", type=Path, default=OUT, help="report folder (default: %(default)s)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS), help="line seeds")
    parser.add_argument(
        "--speeds", type=float, nargs="+", default=list(SPEEDS), help="km/h (default: %(default)s)"
    )
    parser.add_argument("--results", type=Path, metavar="CSV", help="an earlier run's results.csv: no runs")
    parser.add_argument(
        "--configs",
        nargs="+",
        metavar="NAME",
        help=f"only these configurations of the pair report (default: every one; {PASSIVE!r} always)",
    )
    args = parser.parse_args(argv)
    configs = picked(configurations(), args.configs and [PASSIVE, *args.configs], "realistic_pair_draw")
    if configs is None:
        return 2
    if args.draw == 0:
        print("realistic_pair_draw: --draw 0 is the pair report's own draw; give another", file=sys.stderr)
        return 2
    try:
        against = read_results(args.against)
        rows = read_results(args.results) if args.results else None
    except (OSError, KeyError, ValueError) as error:
        print(f"realistic_pair_draw: cannot read results: {error}", file=sys.stderr)
        return 2
    passive = passive_pairs(against)
    missing = [(v, s) for v in args.speeds for s in args.seeds if (s, v) not in passive]
    if rows is None and missing:
        speed, seed = missing[0]
        print(
            f"realistic_pair_draw: {args.against} has no passive pair on line {seed} at {speed:g} km/h",
            file=sys.stderr,
        )
        return 2
    if rows is None:
        jobs = [
            (seed, speed, args.draw, name, config)
            for speed in args.speeds
            for seed in args.seeds
            for name, config in configs.items()
        ]
        with ProcessPoolExecutor(args.workers) as pool:
            rows = list(pool.map(_run, jobs))
    drawn = {int(r.get("draw", -1)) for r in rows}
    if drawn != {args.draw}:
        print(
            f"realistic_pair_draw: {args.results} holds draws {sorted(drawn)}, not {args.draw}",
            file=sys.stderr,
        )
        return 2
    if not passive_pairs(rows).keys() & passive.keys():
        print("realistic_pair_draw: no line and speed in both results", file=sys.stderr)
        return 2
    print(write_report(rows, against, args.draw, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
