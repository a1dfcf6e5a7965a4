"""Two pantographs 200 m apart on the realistic line: the active one leading or trailing, the other
passive, against a passive pair (``make realistic-pair``).

Every run: ``realistic_electromechanical`` with two benchmark-like 3-mass pantographs 200 m apart
(``pantographs: [0, 200]``), each on the roof of its own car: the scenario's track under the
leading car, the same track 200 m later under the trailing one (``--fixed-roof``: both roofs fixed,
``roof_motion: ''``), F_r the EN 50367 target at each pantograph, at each speed of ``SPEEDS``
(``--speeds``). Five runs per line and speed: both
passive (law ``passive`` on the leading one), the
leading one active (law ``line_adaptive``, ``controlled_pantograph: 0``), the leading one active
with the effort weight that spares its follower (``PAIR_EFFORT_WEIGHT``), the trailing one active
(``controlled_pantograph: 1``; the run derives its run-in to last until the leading one's wave has
reached it, and the law's design for a pantograph behind another, pac_rig.composition), and both
active (``all_pantographs_active``: each the rig that would control it, run on one line by
``pac_rig.pair_loop``; the trailing one's run-in waits also for the leading one's learning); the
passive ones press with their file's uplift, the same target. Each pantograph's EN 50318 statistics (20 Hz
low-pass, contact loss
on the raw force) over the same stretch of line: from the support ``FIRST_SPAN`` to ``LAST_SPAN``
of the design layout counted from the start of the leading pantograph, which both pass
(``--spans``). ``--catenary`` runs the same on another line (``realistic_3km_sections``: tension
sections joined by overlaps, ``--spans 10 40`` to hold the first overlap; line_adaptive is told where
they are, as in ``realistic_sections_laws.yaml``).

Writes ``reports/realistic/pair/`` (pair.md, results.csv; ``--add-to CSV`` keeps an earlier run's
rows and adds these, each run against the passive pair on its line at its speed; with ``--configs``
only the configurations named run, and replace the earlier rows of the same lines and speeds).
"""

from __future__ import annotations

import argparse
import csv
import statistics as stats_lib
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from pac_common import markdown
from pac_common.contact_statistics import ContactStatistics, contact_statistics, target_mean_force
from pac_experiments.campaign.summary import Interval, percent_change
from pac_experiments.realistic import (
    REPORT_LINES,
    add_settings_option,
    settings_or_none,
    settings_text,
    write_results,
)

SEEDS = REPORT_LINES
SPEED = 300.0
#: The speeds of ``make realistic-pair``: the realistic experiment's.
SPEEDS = (250.0, 300.0, 320.0, 350.0)
SPACING = 200.0
FIRST_SPAN, LAST_SPAN = 10, 30  # supports counted from the leading pantograph's start
#: line_adaptive's effort weight mu for a leading pantograph that spares its follower: chosen on
#: design lines 0-9 as the smallest of 1, 1.5, 2 whose follower stayed within +5 % of its passive
#: pair sigma on every line (docs/realistic_scenario.md has the whole curve, ``--effort-weights``).
PAIR_EFFORT_WEIGHT = 1.5
#: A configuration: the law of the controlled pantograph, which one is controlled, law overrides.
Config = tuple[str, int, dict[str, Any]]
PANTOGRAPHS = ("leading", "trailing")
#: A configuration's ``controlled`` for both pantographs active (``pac_rig.pair_loop``).
BOTH = len(PANTOGRAPHS)


def configurations(
    effort_weights: tuple[float, ...] = (PAIR_EFFORT_WEIGHT,), settings: dict[str, Any] | None = None
) -> dict[str, Config]:
    """The runs per line: the passive pair, each pantograph active with the law's defaults (and
    ``settings`` on them), the leading one with each effort weight of ``effort_weights``, and both
    active (``BOTH``)."""
    given = dict(settings or {})
    spared: dict[str, Config] = {
        f"active leading, mu {mu:g}": ("line_adaptive", 0, {**given, "line_effort_weight": mu})
        for mu in effort_weights
    }
    return {
        "passive pair": ("passive", 0, {}),
        "active leading": ("line_adaptive", 0, given),
        **spared,
        "active trailing": ("line_adaptive", 1, given),
        "both active": ("line_adaptive", BOTH, given),
    }


OUT = Path("reports/realistic/pair")


def picked(configs: dict[str, Config], names: list[str] | None, prog: str) -> dict[str, Config] | None:
    """The configurations of ``configs`` named in ``names`` (``--configs``; None or empty: all);
    None after one line on stderr naming ``prog`` if a name is none of them."""
    unknown = [name for name in names or () if name not in configs]
    if unknown:
        print(
            f"{prog}: --configs {unknown[0]!r} is no configuration (one of: {', '.join(configs)})",
            file=sys.stderr,
        )
        return None
    return {name: config for name, config in configs.items() if name in names} if names else configs


def simulate(
    seed: int,
    config: Config,
    speed: float = SPEED,
    fixed_roof: bool = False,
    catenary: str | None = None,
    spans: tuple[int, int] = (FIRST_SPAN, LAST_SPAN),
) -> tuple[np.ndarray, float, float, float]:
    """One run of ``config``: its record (the compiled loop's ticks), the stretch judged (from
    support ``spans[0]`` to ``spans[1]`` of the leading one's start, [m]) and the sample period
    (``fixed_roof``: both roofs fixed, else the scenario's moving roof under each; ``catenary``: the
    line, default the scenario's). The run lasts until the trailing one has left the stretch.
    Both active (``BOTH``): the pair loop (``pac_rig.pair_loop``) of the rigs that would control
    each (``all_pantographs_active``: the law's design for its place; each its own roof; the
    trailing unit's sensor noise drawn from the next ``noise_seed``, so that the two suites do not
    read the same noise); the record is the leading unit's, with both pantographs' contact."""
    from pac_rig.closed_loop import run_blocks
    from pac_rig.pair_loop import pair_loop, run_pair_blocks

    law, controlled, overrides = config
    both = controlled == BOTH
    if both:
        overrides = {**overrides, "all_pantographs_active": True}
    values = run_values(seed, law, 0 if both else controlled, speed, fixed_roof, catenary, overrides)
    duration, first, last = stretch(values, speed, spans)
    s, plant, loop = compiled(values, duration)
    if both:
        trail = run_values(seed, law, 1, speed, fixed_roof, catenary, overrides)
        trail["noise_seed"] = int(trail.get("noise_seed", 0)) + 1
        _, plant2, loop2 = compiled(trail, duration)
        pair = pair_loop(plant, loop, plant2, loop2)
        out = np.concatenate([b[0] for b in run_pair_blocks(s.loop.ticks, plant, plant2, pair)])
    else:
        out = np.concatenate(list(run_blocks(s, plant, loop)))
    return out, first, last, s.loop.sample_period


def compiled(values: dict[str, Any], duration: float) -> tuple[Any, Any, Any]:
    """The scenario of ``values`` lasting ``duration``, its FE plant and its compiled loop (a pair
    loop's unit where ``all_pantographs_active``)."""
    from pac_plant.fe_plant import FEPlant
    from pac_rig.closed_loop import build_cores
    from pac_rig.loop import compile_loop
    from pac_rig.simulate import scenario_from_flat

    s = scenario_from_flat({**values, "duration": duration})
    plant, observer, controller = build_cores(s, bool(values.get("all_pantographs_active", False)))
    loop = compile_loop(plant, observer, controller, s.loop.command_delay_ticks)
    assert isinstance(plant, FEPlant) and loop is not None
    return s, plant, loop


def run_values(
    seed: int,
    law: str,
    controlled: int,
    speed: float,
    fixed_roof: bool,
    catenary: str | None,
    overrides: dict[str, Any],
) -> dict[str, Any]:
    """The flat parameters of the rig controlling pantograph ``controlled`` of the pair, derived
    (``composition.derive``)."""
    from pac_rig import composition

    values: dict[str, Any] = {
        "scenario": "realistic_electromechanical",
        **({"roof_motion": ""} if fixed_roof else {}),
        **({"catenary": catenary} if catenary else {}),
        "pantographs": (0.0, SPACING),
        "controlled_pantograph": controlled,
        "law": law,
        "line_seed": seed,
        "speed_kmh": speed,
        "force_amplitude": round(target_mean_force(speed), 3),
        **overrides,
    }
    return composition.derive(values)[0]


def stretch(values: dict[str, Any], speed: float, spans: tuple[int, int]) -> tuple[float, float, float]:
    """(the run's duration [s], the stretch judged [m]) of a pair's run on ``values``: from support
    ``spans[0]`` to ``spans[1]`` of the leading one's start, the run lasting until the trailing one
    has left it."""
    from pac_plant.fe_plant import FEPlant
    from pac_rig.closed_loop import build_cores
    from pac_rig.simulate import scenario_from_flat

    pair_unit = bool(values.get("all_pantographs_active", False))
    plant, _, _ = build_cores(scenario_from_flat({**values, "duration": 0.01}), pair_unit)
    assert isinstance(plant, FEPlant)
    supports = plant.line.layout.support_x
    lead_start = float(plant.sim.x)  # the leading pantograph's contact point at the start
    first = supports[np.searchsorted(supports, lead_start) + spans[0]]
    last = supports[np.searchsorted(supports, lead_start) + spans[1]]
    duration = (last + SPACING + 0.5 * (supports[1] - supports[0]) - lead_start) / (speed / 3.6)
    return round(duration, 3), float(first), float(last)


def run_one(
    seed: int,
    name: str,
    config: Config,
    speed: float = SPEED,
    fixed_roof: bool = False,
    catenary: str | None = None,
    spans: tuple[int, int] = (FIRST_SPAN, LAST_SPAN),
) -> dict[str, Any]:
    """One run of configuration ``name`` (:func:`simulate`): each pantograph's sigma, Fm and
    contact loss over the stretch judged."""
    law, controlled, _ = config
    out, first, last, dt = simulate(seed, config, speed, fixed_roof, catenary, spans)
    row: dict[str, Any] = {
        "line_seed": seed,
        "config": name,
        "active": "" if law == "passive" else "both" if controlled == BOTH else PANTOGRAPHS[controlled],
        "speed_kmh": speed,
    }
    for pantograph, st in zip(PANTOGRAPHS, pantograph_statistics(out, first, last, dt), strict=True):
        row[f"{pantograph}_sigma"], row[f"{pantograph}_mean"] = st.contact_force_std, st.contact_force_mean
        row[f"{pantograph}_loss_percent"] = st.contact_loss_percent
    return row


def pantograph_statistics(out: np.ndarray, first: float, last: float, dt: float) -> list[ContactStatistics]:
    """Each pantograph's EN 50318 statistics (leading first) of a run's record over [first, last]."""
    return [
        contact_statistics(
            out["pantograph_contact_force"][:, k], out["pantograph_contact_position"][:, k], dt, first, last
        )
        for k in range(len(PANTOGRAPHS))
    ]


def _run(args: tuple[int, str, Config, float, bool, str | None, tuple[int, int]]) -> dict[str, Any]:
    return run_one(*args)


def _seed_text(seeds: list[int]) -> str:
    """``100-119`` for a run of consecutive seeds, else the seeds listed."""
    if seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}-{seeds[-1]}"
    return ", ".join(map(str, seeds))


def read_results(path: Path) -> list[dict[str, Any]]:
    """The rows of a results.csv that :func:`write_report` wrote, with their numbers as numbers."""
    with path.open(newline="") as f:
        rows: list[dict[str, Any]] = list(csv.DictReader(f))
    for row in rows:
        for key, value in row.items():
            if key in ("line_seed", "draw"):  # integers, written back as read (a rebuilt report)
                row[key] = int(value)
            elif key not in ("config", "active"):
                row[key] = float(value)
    return rows


def replaced(
    rows: list[dict[str, Any]], configs: set[str], runs: set[tuple[int, float]]
) -> list[dict[str, Any]]:
    """``rows`` without those of configurations ``configs`` on the (line seed, speed) pairs of
    ``runs``: the rows a run of those configurations replaces (``--configs`` with ``--add-to``)."""
    return [r for r in rows if not (r["config"] in configs and (r["line_seed"], r["speed_kmh"]) in runs)]


def passive_pairs(rows: list[dict[str, Any]]) -> dict[tuple[int, float], dict[str, Any]]:
    """The passive pair's row of each (line seed, speed) of ``rows``."""
    return {(r["line_seed"], r["speed_kmh"]): r for r in rows if r["config"] == "passive pair"}


def change(row: dict[str, Any], passive: dict[str, Any], pantograph: str) -> tuple[float, float]:
    """Pantograph ``pantograph``'s sigma change [%] and contact loss change [points] in ``row``
    against ``passive`` (rows of results.csv)."""
    return (
        percent_change(row[f"{pantograph}_sigma"], passive[f"{pantograph}_sigma"]),
        row[f"{pantograph}_loss_percent"] - passive[f"{pantograph}_loss_percent"],
    )


def write_report(
    rows: list[dict[str, Any]],
    out: Path,
    fixed_roof: bool = False,
    catenary: str | None = None,
    spans: tuple[int, int] = (FIRST_SPAN, LAST_SPAN),
    settings: dict[str, Any] | None = None,
) -> str:
    """pair.md: per speed, configuration and pantograph, sigma and loss over the lines, and the
    change of each pantograph's sigma against the passive pair on the same line at the same speed
    (``settings``: the law's settings the runs were given, named in the header)."""
    write_results(rows, out)
    passive = passive_pairs(rows)
    table = []
    groups = dict.fromkeys((r["speed_kmh"], r["config"]) for r in rows)  # in the order of the runs
    for speed, config in sorted(groups, key=lambda g: g[0]):  # stable: each speed's runs in order
        members = [r for r in rows if r["config"] == config and r["speed_kmh"] == speed]
        for name in PANTOGRAPHS:
            sigma = Interval.of([r[f"{name}_sigma"] for r in members])
            paired = [
                (r, passive[r["line_seed"], speed]) for r in members if (r["line_seed"], speed) in passive
            ]
            changes = [change(r, p, name) for r, p in paired]
            sigma_change = Interval.of([c[0] for c in changes])
            more = sum(c[1] > 0.0 for c in changes)
            loss = stats_lib.fmean(r[f"{name}_loss_percent"] for r in members)
            active = members[0]["active"] in (name, "both")
            table.append(
                [
                    f"{speed:g}",
                    config,
                    name + (" (active)" if active else ""),
                    str(len(members)),
                    sigma.text(),
                    ""
                    if config == "passive pair"
                    else f"{sigma_change.mean:+.1f} [{sigma_change.low:+.1f}, {sigma_change.high:+.1f}] "
                    f"(worst {sigma_change.largest:+.1f})",
                    f"{loss:.3f}",
                    "" if config == "passive pair" else str(more),
                ]
            )
    header = [
        "v [km/h]",
        "configuration",
        "pantograph",
        "lines",
        "sigma [N]",
        "sigma vs passive pair [%]",
        "mean loss [%]",
        "more loss than passive pair",
    ]
    speeds = ", ".join(f"{v:g}" for v in sorted({r["speed_kmh"] for r in rows}))
    roof = "with the roof fixed" if fixed_roof else "with each pantograph on its own car's moving roof"
    line = f" on {catenary}" if catenary else ""
    text = (
        "# Two pantographs 200 m apart on the realistic line\n\n"
        f"Generated by `make {'realistic-pair-sections' if catenary else 'realistic-pair'}` "
        "(src/pac_experiments/pac_experiments/realistic/pair.py): "
        f"realistic_electromechanical{line} {roof}, {speeds} km/h, line seeds "
        f"{_seed_text(sorted({r['line_seed'] for r in rows}))}, "
        "EN 50318 statistics of each pantograph over supports "
        f"{spans[0]}-{spans[1]} of the leading one's start. "
        + (f"line_adaptive with {settings_text(settings)}. " if settings else "")
        + "sigma: mean [95 % interval] (smallest..largest) over the lines; the change against the "
        "passive pair on the same line, per line.\n\n" + markdown.table(header, table) + "\n"
    )
    (out / "pair.md").write_text(text)
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="realistic_pair", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=OUT, help="report folder (default: %(default)s)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS), help="line seeds")
    parser.add_argument(
        "--speeds", type=float, nargs="+", default=list(SPEEDS), help="km/h (default: %(default)s)"
    )
    parser.add_argument(
        "--add-to",
        type=Path,
        metavar="CSV",
        help="an earlier run's results.csv: its rows are kept and these runs added (one report of both)",
    )
    parser.add_argument(
        "--effort-weights",
        type=float,
        nargs="+",
        default=[PAIR_EFFORT_WEIGHT],
        help="a leading line_adaptive run per effort weight mu (line_effort_weight; default: %(default)s)",
    )
    parser.add_argument(
        "--fixed-roof", action="store_true", help="both roofs fixed (default: the scenario's moving roof)"
    )
    parser.add_argument("--catenary", help="the line (default: the scenario's)")
    parser.add_argument(
        "--spans",
        type=int,
        nargs=2,
        default=[FIRST_SPAN, LAST_SPAN],
        metavar=("FIRST", "LAST"),
        help="the stretch judged: supports FIRST to LAST of the leading one's start (default: %(default)s)",
    )
    parser.add_argument(
        "--configs",
        nargs="+",
        metavar="NAME",
        help="only these configurations (default: every one); with --add-to they replace the earlier "
        "run's rows of the same configurations, lines and speeds",
    )
    add_settings_option(parser, "every active run")
    args = parser.parse_args(argv)
    settings = settings_or_none(args.param, "realistic_pair")
    if settings is None:
        return 2
    spans = (args.spans[0], args.spans[1])
    if not 0 <= spans[0] < spans[1]:
        print(
            f"realistic_pair: --spans {spans[0]} {spans[1]}: FIRST must be >= 0 and below LAST",
            file=sys.stderr,
        )
        return 2
    configs = picked(configurations(tuple(args.effort_weights), settings), args.configs, "realistic_pair")
    if configs is None:
        return 2
    try:
        earlier = read_results(args.add_to) if args.add_to else []
    except (OSError, KeyError, ValueError) as error:
        print(f"realistic_pair: cannot read {args.add_to}: {error}", file=sys.stderr)
        return 2
    runs = {(s, v) for s in args.seeds for v in args.speeds}
    if args.configs:
        earlier = replaced(earlier, set(configs), runs)
    again = {(r["line_seed"], r["speed_kmh"]) for r in earlier if r["config"] in configs} & runs
    if again:
        seed, speed = min(again)
        print(f"realistic_pair: {args.add_to} has line {seed} at {speed:g} km/h already", file=sys.stderr)
        return 2
    jobs = [
        (seed, name, config, speed, args.fixed_roof, args.catenary, spans)
        for speed in args.speeds
        for seed in args.seeds
        for name, config in configs.items()
    ]
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(_run, jobs))
    print(write_report(earlier + rows, args.out, args.fixed_roof, args.catenary, spans, settings))
    return 0


if __name__ == "__main__":
    sys.exit(main())
