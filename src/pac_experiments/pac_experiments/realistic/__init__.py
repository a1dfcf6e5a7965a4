"""The realistic scenario's experiments: the line as drawn, the pantograph pair, passes on a
learned map, and their figures."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys
from pathlib import Path
from typing import Any

#: The line seeds the law's design was chosen on (the design studies used 0-9 to 0-59; docs/laws.md).
DESIGN_LINES = tuple(range(60))
#: The line seeds the realistic reports are given on (every report campaign and experiment).
REPORT_LINES = tuple(range(100, 120))
#: Lines neither the design nor the reports used (``make realistic-held-out``, from 120 on).
HELD_OUT_FROM = 120

#: What differs between two runs of the same train over the same line: the track under the car
#: body, the turbulent uplift and the sensors' noise, each drawn from its seed. Draw 0 is the
#: scenario's; :func:`draw` gives another.
DRAW_SEEDS = ("roof_seed", "aero_turbulence_seed", "noise_seed")


def draw(k: int) -> dict[str, int]:
    """The scenario parameters of draw ``k`` (every seed of :data:`DRAW_SEEDS` set to ``k``)."""
    return dict.fromkeys(DRAW_SEEDS, k)


def law_settings(items: list[str]) -> dict[str, Any]:
    """``name:=value`` items (``-p``, as ros2 takes them), each a parameter of the laws, for every
    line_adaptive run of an experiment; a ValueError (one line) for an item that is not one."""
    from pac_controller.parameters import LawParameters
    from pac_rig.cli import OverrideError, parse_overrides

    try:
        settings = parse_overrides(items)
    except OverrideError as exc:
        raise ValueError(str(exc)) from None
    names = {field.name for field in dataclasses.fields(LawParameters)}
    for name in settings:
        if name not in names:
            raise ValueError(f"-p {name}: not a parameter of the laws (pac_controller.parameters)")
    return settings


def settings_text(settings: dict[str, Any]) -> str:
    """The settings of :func:`law_settings` for a report's header ("" for none)."""
    return ", ".join(f"{name}:={value}" for name, value in settings.items())


def add_settings_option(parser: argparse.ArgumentParser, runs: str) -> None:
    """``-p NAME:=VALUE`` (repeated): a parameter of line_adaptive for ``runs``."""
    parser.add_argument(
        "-p",
        "--param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help=f"a parameter of line_adaptive for {runs} (default: as derived for a user)",
    )


def settings_or_none(items: list[str], prog: str) -> dict[str, Any] | None:
    """:func:`law_settings` of ``items``; None after one line on stderr naming ``prog`` if refused."""
    try:
        return law_settings(items)
    except ValueError as error:
        print(f"{prog}: {error}", file=sys.stderr)
        return None


def write_results(rows: list[dict[str, Any]], out: Path) -> None:
    """``out``/results.csv: one row per run, the columns of the first (``out`` made if missing)."""
    out.mkdir(parents=True, exist_ok=True)
    with (out / "results.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
