"""A campaign's files: ``runs.jsonl`` (one row per finished run, appended; resume state) and
``results.csv`` (one row per grid point, grid order, no wall times: reproducible)."""

from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path
from typing import Any

from pac_common import jsonio
from pac_common.files import read_bytes, write_atomic
from pac_experiments.campaign.run import EN50318_COLUMNS, EN50367_COLUMNS, METRIC_COLUMNS
from pac_experiments.campaign.spec import Point, Spec

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
    """Rows already in ``DIR/runs.jsonl`` by key. A torn last line (a kill or a full disk
    mid-write) is ignored; any other line that is no row (not UTF-8, not JSON, nested too deep,
    no string key) is counted and named on stderr, never used: its run is done again."""
    done: dict[str, dict[str, Any]] = {}
    path = Path(out) / RUNS_FILE
    if not path.exists():
        return done
    lines = read_bytes(path, "runs").split(b"\n")  # not a regular file, or too large: FileInputError
    damaged: list[int] = []
    for number, line in enumerate(lines, 1):
        row = _row(line)
        if row is None:
            if line.strip() and number < len(lines) - (lines[-1] == b""):
                damaged.append(number)
            continue
        # A measure written as null (not a number) is NaN again, as the run returned it.
        done[row["key"]] = {k: math.nan if v is None and k in MEASURE_COLUMNS else v for k, v in row.items()}
    if damaged:
        print(
            f"campaign: {path}: {len(damaged)} line(s) are no run row and are ignored (first: line "
            f"{damaged[0]}); their runs are done again",
            file=sys.stderr,
        )
    return done


def _row(line: bytes) -> dict[str, Any] | None:
    """The row on one line of runs.jsonl, or None when it is not one."""
    try:
        row = json.loads(line.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None
    if isinstance(row, dict) and isinstance(row.get("key"), str):
        return row
    return None


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
    # A run's record is its flat scenario; a point's axes as the SPEC names them (``scenario``,
    # which the record holds expanded) come from the point.
    rows = [
        {**done[p.key], **{a: p.values[a] for a in spec.axes if a in p.values}}
        for p in points
        if p.key in done
    ]
    with write_atomic(Path(out) / RESULTS_FILE, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_cell(row.get(c, "")) for c in columns])
    return rows
