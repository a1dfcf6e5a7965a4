"""References a reader can follow: no issue numbers, no paths outside the repository, and every
relative link in a Markdown file names a file that exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import ROOT, repository_files

pytestmark = pytest.mark.unit

#: "issue #12", "issue 12", "(#12)", "#10/#9": pointers into a tracker the reader does not have.
ISSUE = re.compile(r"(?i)\bissues? ?#?\d+\b|\(#\d+\b|(?<![\w&/])#\d+/#\d+")
OUTSIDE = re.compile(r"\.\./shared/|/work/shared|CATENARY_DATA")
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def test_the_patterns_see_what_they_should():
    assert ISSUE.search("see issue #12") and ISSUE.search("PacNode base (#8)") and ISSUE.search("#10/#9")
    assert not ISSUE.search("docs/paper_errata.md #5") and not ISSUE.search("catenary_data.md#2-the")
    assert OUTSIDE.search("text in ../shared/seed/")


def test_no_issue_numbers_and_no_paths_outside_the_repository():
    this = Path(__file__).resolve()
    problems = []
    for path in repository_files("*.md", "*.py", "*.yaml", "*.msg", "Makefile", "*.sh", "scripts/bin/*"):
        if path.resolve() == this:
            continue
        for n, line in enumerate(path.read_text(errors="replace").splitlines(), start=1):
            if ISSUE.search(line) or OUTSIDE.search(line):
                problems.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()[:100]}")
    assert problems == []


def test_relative_links_in_markdown_point_at_files_that_exist():
    missing = []
    for path in repository_files("*.md"):
        for target in LINK.findall(path.read_text()):
            if re.match(r"^[a-z]+:", target):  # http:, https:, mailto:
                continue
            if not (path.parent / target).exists():
                missing.append(f"{path.relative_to(ROOT)} -> {target}")
    assert missing == []


def github_anchor(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading: its rendered text, lower case, without
    punctuation other than '-' and '_', spaces as '-' (a link's text stays, its target goes)."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).replace("`", "")
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """The anchors of the headings of Markdown file ``path`` (a repeated one: -1, -2, ... as GitHub)."""
    seen: dict[str, int] = {}
    out = set()
    fenced = False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            fenced = not fenced
        if fenced or not re.match(r"^#{1,6} ", line):
            continue
        anchor = github_anchor(line.lstrip("#"))
        out.add(anchor if anchor not in seen else f"{anchor}-{seen[anchor]}")
        seen[anchor] = seen.get(anchor, 0) + 1
    return out


def test_the_anchor_rule_is_githubs():
    assert github_anchor(" Performance (`make bench`)") == "performance-make-bench"
    assert github_anchor(" The paper's Section 6 (`make reproduce`)") == "the-papers-section-6-make-reproduce"
    linked = " Real catenary ([docs/catenary.md](docs/catenary.md))"
    assert github_anchor(linked) == "real-catenary-docscatenarymd"


def test_links_to_a_heading_name_one_that_exists():
    """A link ``file.md#anchor`` (or ``#anchor`` in the same file) names a heading of that file."""
    missing = []
    for path in repository_files("*.md"):
        for target, anchor in re.findall(r"\]\(([^)#\s]*)#([^)\s]+)\)", path.read_text()):
            if re.match(r"^[a-z]+:", target) or (target and not target.endswith(".md")):
                continue
            linked = (path.parent / target) if target else path
            if linked.exists() and anchor not in anchors(linked):
                missing.append(f"{path.relative_to(ROOT)} -> {target}#{anchor}")
    assert missing == []
