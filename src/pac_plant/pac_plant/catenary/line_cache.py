"""A whole line's solved dropper lengths on disk: solved once per drawn line, read by later runs.

The unstrained dropper lengths of a whole line (``Line._chord_dropper_lengths``: a solve of ~500
columns and ~30 static solves, most of a 3 km line's set-up) are a function of the line's data
and of the code that solves them, nothing else: what a line's dropper schedule is to the line
built from it. Where the environment variable ``PAC_LINE_CACHE`` names a directory (``env.sh``
sets ``build/line_cache``, which ``make setup`` empties; unset or empty: no cache), the lengths
are kept there, one small file per line, under a key of both (the data's ``repr`` and the bytes
of this package's sources). A later run of the same line (every law, speed and draw of a
campaign that shares a line seed) reads them and sets the static state from them: the same to
the bit as solving them, since the solve ends by setting them the same way
(``tests/test_line_cache.py``).

What is read is checked before it is used: its shape, finite and positive lengths, and the
pre-sag they give within ``RESIDUAL_BOUND`` of the target. A file that fails (damaged, or written
by other code under a colliding key) is said in one line on stderr, solved again and written over.
Files are written whole (a temporary file renamed), so runs in parallel never read a partial one.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

#: The environment variable that names the cache's directory (unset or empty: no cache).
ENVIRONMENT = "PAC_LINE_CACHE"
#: Largest |pre-sag - target| [m] that cached lengths may give: 10x the solve's tolerance on the
#: lengths (1e-9 m), which bounds the residual the solve leaves (measured: 1.9e-10 and 2.3e-10 m
#: on realistic_3km lines 0 and 100).
RESIDUAL_BOUND = 1e-8


def directory() -> Path | None:
    """The cache's directory, or None when there is none."""
    value = os.environ.get(ENVIRONMENT, "")
    return Path(value) if value else None


@functools.cache
def code_fingerprint() -> str:
    """The sha256 of this package's sources (any change to how a line is built or solved misses
    the lengths solved before it)."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def line_key(*parts: object) -> str:
    """The key of a line made from ``parts`` (its data and options, as ``Line`` was given them)."""
    digest = hashlib.sha256(code_fingerprint().encode())
    digest.update(repr(parts).encode())
    return digest.hexdigest()[:32]


def _path(key: str) -> Path | None:
    where = directory()
    return None if where is None else where / "dropper_lengths" / f"{key}.npy"


def read(key: str, count: int) -> np.ndarray | None:
    """The ``count`` lengths kept under ``key``, or None (no cache, none kept, or unreadable: said
    in one line)."""
    path = _path(key)
    if path is None or not path.is_file():
        return None
    try:
        lengths = np.load(path, allow_pickle=False)
        if lengths.shape != (count,) or lengths.dtype != np.float64 or not np.all(np.isfinite(lengths)):
            raise ValueError(f"holds {lengths.dtype} {lengths.shape}, not {count} finite lengths")
        if not np.all(lengths > 0.0):
            raise ValueError("holds a length that is not positive")
    except (OSError, ValueError) as exc:
        reject(key, str(exc))
        return None
    return lengths


def reject(key: str, why: str) -> None:
    """Say in one line that the file under ``key`` is not used (it is solved again and replaced)."""
    print(
        f"pac: line cache: ignoring {_path(key)} ({why}); solving the dropper lengths again", file=sys.stderr
    )


def write(key: str, lengths: np.ndarray) -> None:
    """Keep ``lengths`` under ``key`` (nothing without a cache; a directory that cannot be written
    leaves the run as it is: the cache is only a shortcut)."""
    path = _path(key)
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".tmp", delete=False) as tmp:
            np.save(tmp, np.asarray(lengths, dtype=np.float64), allow_pickle=False)
        os.replace(tmp.name, path)
    except OSError as exc:
        print(f"pac: line cache: could not write {path} ({exc}); the run goes on without it", file=sys.stderr)
