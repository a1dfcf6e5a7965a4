"""Strict JSON for every file pac writes: a non-finite number becomes ``null``, never a bare ``NaN``.

``json.dumps`` writes ``NaN``/``Infinity`` (not JSON) and calls ``default=`` only for objects
it cannot serialise, never for floats; so values are cleaned first and ``allow_nan=False``
guarantees the result parses with any strict parser.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any


def finite_or_none(value: Any) -> Any:
    """``value`` with every non-finite float (numpy scalars and arrays included) replaced by None."""
    if isinstance(value, Mapping):
        return {str(k): finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalar or array
        return finite_or_none(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(value: Any, **kwargs: Any) -> str:
    """Strict JSON text of ``value`` (non-finite numbers as null)."""
    return json.dumps(finite_or_none(value), allow_nan=False, **kwargs)


def write(path: Path | str, value: Any) -> None:
    """``value`` as indented strict JSON in ``path``."""
    Path(path).write_text(dumps(value, indent=2) + "\n")
