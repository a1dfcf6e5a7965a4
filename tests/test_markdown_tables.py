"""Every Markdown file in the repository renders its tables: each row has as many cells as its
header (a GitHub-flavoured renderer splits a row at every unescaped ``|``, code spans included);
and the one table writer escapes what would break a row."""

from __future__ import annotations

import re

import pytest
from conftest import ROOT, repository_files

from pac_common import markdown

pytestmark = pytest.mark.unit

DELIMITER = re.compile(r"^\s*\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)*\|?\s*$")


def table_problems(text: str) -> list[str]:
    """One line per table row whose cell count differs from its header's (code blocks skipped)."""
    problems = []
    lines = text.splitlines()
    fence = None
    i = 0
    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        if stripped.startswith(("```", "~~~")):
            marker = stripped[:3]
            fence = None if fence == marker else (fence or marker)
            i += 1
            continue
        if fence is None and "|" in line and i + 1 < len(lines) and DELIMITER.match(lines[i + 1]):
            width = len(markdown.split_row(line))
            if len(markdown.split_row(lines[i + 1])) != width:
                problems.append(f"line {i + 2}: delimiter row has a different width than the header")
            j = i + 2
            while j < len(lines) and lines[j].strip().startswith("|"):
                cells = len(markdown.split_row(lines[j]))
                if cells != width:
                    problems.append(f"line {j + 1}: {cells} cells for {width} columns")
                j += 1
            i = j
            continue
        i += 1
    return problems


def test_the_checker_sees_a_broken_row():
    good = "| a | b |\n|---|---:|\n| max \\|u\\| | 1 |\n"
    bad = "| a | b |\n|---|---:|\n| max |u| | 1 |\n"
    fenced = "```\n| a | b |\n|---|---|\n| 1 |\n```\n"
    assert table_problems(good) == []
    assert table_problems(bad) == ["line 3: 4 cells for 2 columns"]
    assert table_problems(fenced) == []


def test_every_markdown_file_renders_its_tables():
    files = repository_files("*.md")
    assert any(f.name == "README.md" for f in files)
    problems = [f"{f.relative_to(ROOT)} {p}" for f in files for p in table_problems(f.read_text())]
    assert problems == []


def test_the_table_writer_escapes_pipes_and_checks_widths():
    text = markdown.table(["measure", "value"], [["max |u|", 1.5], ["multi\nline", "x"]], ["l", "r"])
    assert text.splitlines() == [
        "| measure | value |",
        "|---|---:|",
        "| max \\|u\\| | 1.5 |",
        "| multi line | x |",
    ]
    assert table_problems(text) == []
    assert markdown.escape("already \\| escaped") == "already \\| escaped"
    with pytest.raises(ValueError, match="row 0 has 1 cells for 2 columns"):
        markdown.table(["a", "b"], [["only one"]])
