"""A progress bar for long commands, on a terminal only (quiet in logs, pipes and tests)."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")


def progress(
    iterable: Iterable[T], total: int | None = None, desc: str = "", unit: str = "it"
) -> Iterator[T] | Iterable[T]:
    """``iterable`` wrapped in tqdm (on stderr) when stderr is a terminal, else unchanged."""
    if not sys.stderr.isatty():
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, unit_scale=True, leave=False, file=sys.stderr)
