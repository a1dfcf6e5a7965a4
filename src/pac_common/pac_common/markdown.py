"""Markdown tables for every report pac writes: one writer, cells escaped, one cell per column.

A ``|`` inside a cell (``max |u|``) ends the cell in every Markdown renderer unless it is
escaped as ``\\|``; a newline ends the row.  Writing every table through :func:`table` keeps
each row as wide as its header (tests/test_markdown_tables.py checks every committed file).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

#: Column alignments: left (text) or right (numbers).
LEFT, RIGHT = "l", "r"


def escape(cell: Any) -> str:
    """The text of one cell: ``|`` escaped (an already escaped ``\\|`` stays as it is), newlines as spaces."""
    text = str(cell).replace("\r\n", " ").replace("\n", " ")
    out = []
    for i, ch in enumerate(text):
        if ch == "|" and (i == 0 or text[i - 1] != "\\"):
            out.append("\\|")
        else:
            out.append(ch)
    return "".join(out)


def row(cells: Iterable[Any]) -> str:
    """One table row of escaped cells."""
    return "| " + " | ".join(escape(c) for c in cells) + " |"


def table(header: Sequence[Any], rows: Iterable[Sequence[Any]], align: str | Sequence[str] = LEFT) -> str:
    """A Markdown table (no trailing newline).  ``align``: one of ``l``/``r`` for every column, or
    one per column.  Raises ValueError when a row has more or fewer cells than the header."""
    aligns = [align] * len(header) if isinstance(align, str) else list(align)
    if len(aligns) != len(header):
        raise ValueError(f"{len(aligns)} alignments for {len(header)} columns")
    rule = "|" + "".join("---:|" if a == RIGHT else "---|" for a in aligns)
    lines = [row(header), rule]
    for i, cells in enumerate(rows):
        cells = list(cells)
        if len(cells) != len(header):
            raise ValueError(f"row {i} has {len(cells)} cells for {len(header)} columns: {cells!r}")
        lines.append(row(cells))
    return "\n".join(lines)


def split_row(line: str) -> list[str]:
    """The cells of one table row as a renderer sees them (``\\|`` does not split a cell)."""
    text = line.strip()
    if text.startswith("|"):
        text = text[1:]
    if text.endswith("|") and not text.endswith("\\|"):
        text = text[:-1]
    cells, current, i = [], [], 0
    while i < len(text):
        if text[i] == "\\" and i + 1 < len(text) and text[i + 1] == "|":
            current.append("\\|")
            i += 2
            continue
        if text[i] == "|":
            cells.append("".join(current).strip())
            current = []
        else:
            current.append(text[i])
        i += 1
    cells.append("".join(current).strip())
    return cells
