"""The result pages' tables (docs/results.md, docs/campaigns.md) are the committed reports' numbers,
to the digits printed: every figure of Section 6's table equals reports/reproduce/metrics.json
(written by `make reproduce`); the campaign tables equal
reports/campaigns/{laws_speeds,robustness}/results.csv (`make campaigns`); the tables of the laws
on the FE line are reports/catenary/laws/laws.md's (`make fe-experiment`)."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest

from pac_common import markdown

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[1]
#: Row label -> the metrics.json keys its cells show ("a / b": two keys).
ROWS = {
    "Fm, mean contact force [N]": ("contact_force_mean",),
    "σ [N]": ("contact_force_std",),
    "Fm − 3σ / Fm + 3σ [N]": ("statistical_min", "statistical_max"),
    "actual min / max [N]": ("contact_force_min", "contact_force_max"),
    "contact lost [%]": ("contact_loss_percent",),
    "tracking RMS F − F_r [N]": ("tracking_rms",),
    "k̂ relative RMS error [%]": ("stiffness_rel_rms_percent",),
    "max \\|u\\| [N]": ("u_max_abs",),
}
#: The pages that quote the reports.
PAGES = ("docs/results.md", "docs/campaigns.md")


def pages() -> str:
    return "\n\n".join((ROOT / page).read_text() for page in PAGES)


NUMBER = re.compile(r"^[−-]?\d+(\.\d+)?$")


def results_table() -> list[list[str]]:
    text = (ROOT / "docs" / "results.md").read_text().split("\n## The paper's Section 6", 1)[1]
    lines = [line for line in text.split("\n\n")[2].splitlines() if line.startswith("|")]
    return [markdown.split_row(line) for line in lines if not set(line) <= set("|-: ")]


def printed(cell: str) -> float | None:
    """The number a cell prints (bold and sign variants read), None for text cells."""
    text = cell.replace("*", "").strip()
    return float(text.replace("−", "-")) if NUMBER.match(text) else None


def test_section_6_table_is_the_committed_report():
    data = json.loads((ROOT / "reports" / "reproduce" / "metrics.json").read_text())
    header, *rows = results_table()
    runs = header[1:]
    assert set(runs) <= set(data), runs
    assert {row[0] for row in rows} == set(ROWS)
    checked = 0
    for row in rows:
        keys = ROWS[row[0]]
        for run, cell in zip(runs, row[1:], strict=True):
            parts = cell.split(" / ")
            if len(parts) != len(keys):
                assert printed(cell) is None, (row[0], run, cell)  # a remark, not a figure
                continue
            for key, part in zip(keys, parts, strict=True):
                value = printed(part)
                if value is None:
                    continue
                decimals = len(part.replace("*", "").strip().partition(".")[2])
                assert abs(data[run][key] - value) <= 0.5 * 10**-decimals + 1e-9, (
                    row[0],
                    run,
                    part,
                    data[run][key],
                )
                checked += 1
    assert checked >= 20  # the table was read (24 figures when this was written)


# -- the campaign tables (reports/campaigns/*/results.csv, written by `make campaigns`) ------------
CELL = re.compile(r"^(?P<sigma>[\d.]+)(?: \((?P<loss>[\d.]+) %\))?$")


def page_table(first_header_cell: str) -> list[list[str]]:
    """The pages' table whose header row starts with ``first_header_cell``: header, then rows."""
    lines = pages().splitlines()
    start = next(i for i, line in enumerate(lines) if markdown.split_row(line)[0] == first_header_cell)
    rows = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        if not set(line) <= set("|-: "):
            rows.append(markdown.split_row(line))
    return rows


def results(campaign: str) -> list[dict[str, str]]:
    with (ROOT / "reports" / "campaigns" / campaign / "results.csv").open() as f:
        return list(csv.DictReader(f))


def agrees(printed_text: str, value: float) -> bool:
    """``value`` rounds to ``printed_text`` (the digits the page prints)."""
    decimals = len(printed_text.partition(".")[2])
    return abs(value - float(printed_text)) <= 0.5 * 10**-decimals + 1e-12


def test_laws_table_is_the_committed_campaign():
    """σ [N] (contact loss %, shown when not 0) of each law at each speed, as laws_speeds' results.csv."""
    header, *rows = page_table("km/h")
    by_point = {(r["law"], float(r["speed_kmh"])): r for r in results("laws_speeds")}
    checked, wrong = 0, []
    for row in rows:
        for law, cell in zip(header[1:], row[1:], strict=True):
            measured = by_point[(law, float(row[0]))]
            sigma, loss = float(measured["contact_force_std"]), float(measured["contact_loss_percent"])
            match = CELL.match(cell)
            assert match, (law, row[0], cell)
            if not agrees(match["sigma"], sigma) or not (
                agrees(match["loss"], loss) if match["loss"] else loss == 0
            ):
                wrong.append(f"{law} at {row[0]} km/h: page {cell}, results.csv {sigma:.4g} ({loss:.3g} %)")
            checked += 1
    assert wrong == []
    assert checked >= 30  # the table was read (5 speeds x 6 laws when this was written)


#: The robustness table's rows: the parameter a row varies; every other one at the SPEC's value.
ROBUSTNESS_ROWS = {"plant masses": "plant_mass_scale", "α": "alpha"}
ROBUSTNESS_DEFAULTS = {
    "plant_mass_scale": 1.0,
    "alpha": 0.5,
    "k0": 4000.0,
    "command_delay_ticks": 1.0,
    "speed_kmh": 360.0,
}


def test_robustness_table_is_the_committed_campaign():
    """σ [N] of each law under each mismatch (``a / b / c`` for the values the row names), as
    robustness's results.csv (noise-free points)."""
    header, *rows = page_table("mismatch")
    points = [r for r in results("robustness") if r["noise_std"] == "[0.0, 0.0]"]
    checked, wrong = 0, []
    for row in rows:
        name = next(n for prefix, n in ROBUSTNESS_ROWS.items() if row[0].startswith(prefix))
        values = [float(v) for v in re.findall(r"[\d.]+", row[0].split("×" if "×" in row[0] else "=")[1])]
        for law, cell in zip(header[1:], row[1:], strict=True):
            shown = cell.split(" / ")
            assert len(shown) == len(values), (row[0], law, cell)
            for value, text in zip(values, shown, strict=True):
                want = {**ROBUSTNESS_DEFAULTS, name: value}
                match = [
                    r for r in points if r["law"] == law and all(float(r[k]) == v for k, v in want.items())
                ]
                assert len(match) == 1, (row[0], law, value)
                sigma = float(match[0]["contact_force_std"])
                if not agrees(text, sigma):
                    wrong.append(f"{law}, {name} = {value:g}: page {text}, results.csv {sigma:.4g}")
                checked += 1
    assert wrong == []
    assert checked >= 25  # the table was read (7 values x 4 laws when this was written)


def markdown_tables(text: str) -> list[str]:
    """Every Markdown table of ``text``, as its block of consecutive ``|`` lines."""
    tables, block = [], []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            block.append(line.rstrip())
        elif block:
            tables.append("\n".join(block))
            block = []
    return tables


def test_fe_laws_tables_are_the_committed_report():
    """docs/results.md's tables of the laws on the FE line are copied from reports/catenary/laws/laws.md
    (written by `make fe-experiment`): each one appears there verbatim."""
    readme = (ROOT / "docs" / "results.md").read_text()
    section = readme.split("**The control laws on the line**", 1)[1].split("**Reading.**", 1)[0]
    report = markdown_tables((ROOT / "reports" / "catenary" / "laws" / "laws.md").read_text())
    tables = markdown_tables(section)
    assert len(tables) >= 2  # the goals and every law (the section was found and read)
    for table in tables:
        assert table in report, table.splitlines()[0]


def test_lines_speeds_table_is_the_committed_campaign():
    """EN 50318 σ [N] passive / line_adaptive (contact loss %, shown when not 0) on each line at
    each speed, as lines_speeds' results.csv."""
    header, *rows = page_table("speed [km/h]")
    by_point = {(r["law"], r["catenary"], float(r["speed_kmh"])): r for r in results("lines_speeds")}
    checked, wrong = 0, []
    for row in rows:
        for line, pair in zip(header[1:], row[1:], strict=True):
            for law, cell in zip(("passive", "line_adaptive"), pair.split(" / "), strict=True):
                measured = by_point[(law, line, float(row[0]))]
                sigma = float(measured["en50318_contact_force_std"])
                loss = float(measured["en50318_contact_loss_percent"])
                match = CELL.match(cell)
                assert match, (law, line, row[0], cell)
                if not agrees(match["sigma"], sigma) or not (
                    agrees(match["loss"], loss) if match["loss"] else loss == 0
                ):
                    wrong.append(
                        f"{law} on {line} at {row[0]} km/h: page {cell}, csv {sigma:.4g} ({loss:.3g} %)"
                    )
                checked += 1
    assert wrong == []
    assert checked >= 18  # the table was read (3 speeds x 3 lines x 2 laws when this was written)
