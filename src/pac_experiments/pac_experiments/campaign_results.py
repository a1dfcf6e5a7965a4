"""A campaign's files: ``runs.jsonl`` (one row per finished run, appended; resume state) and
``results.csv`` (one row per grid point, grid order, no wall times: reproducible)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

from pac_common import jsonio

from .campaign_run import EN50318_COLUMNS, EN50367_COLUMNS, METRIC_COLUMNS
from .campaign_spec import Point, Spec

#: Always in results.csv, whether varied or not.
ALWAYS = ("law", "speed_kmh")
RUNS_FILE = "runs.jsonl"
RESULTS_FILE = "results.csv"
#: The measures of a row: numbers, NaN where not measured (``null`` in runs.jsonl, strict JSON).
MEASURE_COLUMNS = frozenset(METRIC_COLUMNS) | frozenset(EN50318_COLUMNS)


def runs_line(row: dict[str, Any]) -> str:
    """One line of ``runs.jsonl``: the row as strict JSON (a NaN measure as ``null``)."""
    return jsonio.dumps(row) + "\n"


def read_done(out: Path) -> dict[str, dict[str, Any]]:
    """Rows already in ``DIR/runs.jsonl`` by key (a torn last line, from a kill, is ignored)."""
    done: dict[str, dict[str, Any]] = {}
    path = Path(out) / RUNS_FILE
    if not path.exists():
        return done
    for line in path.read_text().splitlines():
        try:
            row = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(row, dict) and "key" in row:
            # A measure written as null (not a number) is NaN again, as the run returned it.
            done[row["key"]] = {
                k: math.nan if v is None and k in MEASURE_COLUMNS else v for k, v in row.items()
            }
    return done


def _cell(value: Any) -> Any:
    if isinstance(value, list | tuple):
        return json.dumps(list(value))
    return value


def result_columns(spec: Spec) -> list[str]:
    axes = spec.axes
    derived = ["force_amplitude"] if spec.force_target and "force_amplitude" not in axes else []
    return (
        [*axes, *(a for a in ALWAYS if a not in axes), *derived, "status", "reason"]
        + list(METRIC_COLUMNS)
        + (list(EN50318_COLUMNS) if spec.statistics == "en50318" else [])
        + list(EN50367_COLUMNS)
        + ["ticks_run", "simulated_seconds", "key"]
    )


def write_results(spec: Spec, points: list[Point], done: dict[str, dict], out: Path) -> list[dict]:
    """``results.csv``: one row per grid point that has run, in grid order; returns those rows."""
    columns = result_columns(spec)
    rows = [done[p.key] for p in points if p.key in done]
    tmp = Path(out) / (RESULTS_FILE + ".tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_cell(row.get(c, "")) for c in columns])
    tmp.replace(Path(out) / RESULTS_FILE)
    return rows
