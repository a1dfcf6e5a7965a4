"""A whole line's dropper lengths kept on disk (pac_plant.catenary.line_cache): a line built from
them is the solved line to the bit; a missing, damaged or wrong file is solved again; no cache, no
files."""

import dataclasses

import numpy as np
import pytest

from pac_plant.catenary import line_cache
from pac_plant.catenary.catenary_file import load_catenary
from pac_plant.catenary.line import Line

pytestmark = pytest.mark.unit

LINE_FILE = load_catenary("realistic_3km")


def build(seed: int = 0, stiffer_droppers: bool = False) -> Line:
    data = LINE_FILE.line(seed)
    if stiffer_droppers:  # the same layout, the same number of spans and droppers: only the data differ
        data = dataclasses.replace(data, dropper_ea=1.01 * data.dropper_ea)
    return Line(data, LINE_FILE.numerics, n_spans=data.n_spans)


def kept_files(where) -> list:
    return sorted((where / "dropper_lengths").glob("*.npy")) if (where / "dropper_lengths").exists() else []


def same_line(a: Line, b: Line) -> None:
    for name in ("w_static", "f_static"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(a.droppers.length0, b.droppers.length0)
    np.testing.assert_array_equal(a.droppers.elongation0, b.droppers.elongation0)
    np.testing.assert_array_equal(a.K.ab, b.K.ab)
    np.testing.assert_array_equal(a.rest_slack, b.rest_slack)


def test_a_line_from_kept_lengths_is_the_solved_line(tmp_path, monkeypatch):
    """Solved without a cache, solved into one, then read from it: the same line to the bit; another
    seed, and the same line with other dropper data, keep a file of their own."""
    monkeypatch.setenv(line_cache.ENVIRONMENT, "")
    solved = build()
    monkeypatch.setenv(line_cache.ENVIRONMENT, str(tmp_path))
    first = build()
    assert len(kept_files(tmp_path)) == 1
    read = build()
    same_line(solved, first)
    same_line(solved, read)
    assert solved.presag_residual() < line_cache.RESIDUAL_BOUND
    build(seed=1)
    assert len(kept_files(tmp_path)) == 2
    build(stiffer_droppers=True)
    assert len(kept_files(tmp_path)) == 3


def test_reading_skips_the_solve(tmp_path, monkeypatch):
    """With the lengths kept, building the line does not run the chord passes."""
    monkeypatch.setenv(line_cache.ENVIRONMENT, str(tmp_path))
    build()
    calls = []
    original = Line._chord_dropper_lengths
    monkeypatch.setattr(
        Line, "_chord_dropper_lengths", lambda self, *a: calls.append(1) or original(self, *a)
    )
    build()
    assert calls == []


@pytest.mark.parametrize(
    "spoil",
    [
        lambda path: path.write_bytes(path.read_bytes()[:60]),  # cut short
        lambda path: np.save(path, np.load(path)[:-1]),  # one length missing
        lambda path: np.save(path, np.load(path) * 1.001),  # lengths that miss the pre-sag
        lambda path: np.save(path, np.where(np.arange(len(np.load(path))) == 3, np.nan, np.load(path))),
    ],
    ids=["truncated", "short", "wrong", "nan"],
)
def test_a_spoilt_file_is_said_in_one_line_and_solved_again(tmp_path, monkeypatch, capsys, spoil):
    monkeypatch.setenv(line_cache.ENVIRONMENT, str(tmp_path))
    solved = build()
    (path,) = kept_files(tmp_path)
    spoil(path)
    capsys.readouterr()
    again = build()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "line cache: ignoring" in err[0]
    assert "solving the dropper lengths again" in err[0]
    same_line(solved, again)
    np.testing.assert_array_equal(np.load(path), solved.droppers.length0)  # written over


def test_no_cache_writes_nothing_and_other_code_misses(tmp_path, monkeypatch):
    """Without the variable nothing is written; a different code fingerprint does not read what the
    present code kept."""
    monkeypatch.setenv(line_cache.ENVIRONMENT, "")
    monkeypatch.chdir(tmp_path)
    build()
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setenv(line_cache.ENVIRONMENT, str(tmp_path))
    build()
    monkeypatch.setattr(line_cache, "code_fingerprint", lambda: "another version")
    build()
    assert len(kept_files(tmp_path)) == 2
