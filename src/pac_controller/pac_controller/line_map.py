"""A map ``line_adaptive`` learned on one pass over a line, for the next pass of the same train.

On a line whose spans differ, the pattern the law learns over every span (its harmonics U_h)
leaves each span's own shape: on the realistic line's passive run at 300 km/h, 22.8 N of the
force's 51.8 N (docs/laws.md). A train that passes over the same line again can learn that
too: the law records, per span m of the design layout, the harmonics it applied (A_m) and the
force error (E_m), and the map for the next pass is one step of the law's own update on each
span's own error (``line_adaptive_kernels.line_next_map``)::

    W_m = A_m - gamma (conj(D_h) E_m + mu A_m) / (|D_h|^2 + mu)

with the responses D_h the pass identified. A pass on a map (``line_map:=FILE``) starts every
span from its W_m, with the responses frozen at the map's and the guard's passive bar the map's
(no passive run-in), and records its own A_m, E_m for the pass after it: iterative learning
control over passes, indexed by the position the train believes (line map and odometry).

The file is JSON (a few kB): what it was learned on (the layout's supports, ticks per span N,
harmonics H), the harmonics W_m per span, the identified responses, the guard's passive bar, the
line model's fit, U_0 and how many passes built it. :func:`read_line_map` checks every value
before anything runs; a bad file is one line (:class:`LineMapError`, a ``ParameterError``: the
tools exit 2). A map is for the line, speed and rate it was learned at: :meth:`LineMap.check_fits`
refuses another layout, another N or another H in one line.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pac_common.data_file import DataFileError

#: The file's ``format`` (a reader refuses any other).
FORMAT = "pac line_adaptive map 1"
#: Supports closer than this [m] are the same support (the layout is written with repr's digits).
SUPPORT_TOLERANCE = 1e-6


class LineMapError(DataFileError):
    """A line map that cannot be used; the message is one line."""

    KIND = "line map"


@dataclass(frozen=True)
class LineMap:
    """A learned map (module docstring); arrays by span of the layout (rows) and harmonic (columns)."""

    supports: np.ndarray  # the design layout's supports [m] it was learned on
    period_ticks: int  # N, ticks per span at the speed and rate it was learned at
    harmonics: np.ndarray  # W_m,h: S x H complex [N]
    response_z: np.ndarray  # Z_h, S_h: the identified responses D_h = (Z_h - s0) / (S_h + s0)
    response_s: np.ndarray
    passive_sigma: float  # the guard's bar: sigma_b of the passive spans [N]
    passive_loss: float  # the worst passive span's nearly-lost share
    line_stiffness: float  # the line model's fit k_s [N/m], c [N s/m], and whether it stands in
    line_damping: float
    model_valid: bool
    u_mean: float  # U_0 [N]
    passes: int  # passes over the line this map was learned from

    def check_fits(self, supports: np.ndarray, period_ticks: int, harmonics: int, source: str = "") -> None:
        """Refuse, in one line, a map of another layout, speed or rate than this run's."""
        where = source or "the map"
        if len(supports) != len(self.supports) or not np.allclose(
            supports, self.supports, rtol=0.0, atol=SUPPORT_TOLERANCE
        ):
            raise LineMapError(
                where, "supports", f"{len(self.supports)} supports",
                f"the run's design layout ({len(supports)} supports, line_supports): a map is for the "
                "line it was learned on",
            )  # fmt: skip
        if self.period_ticks != period_ticks or self.harmonics.shape[1] != harmonics:
            raise LineMapError(
                where, "period_ticks", f"N = {self.period_ticks}, H = {self.harmonics.shape[1]}",
                f"the run's N = {period_ticks} ticks per span and H = {harmonics} harmonics: a map is for "
                "the speed, rate and line_max_frequency it was learned at",
            )  # fmt: skip

    def as_json(self) -> dict[str, Any]:
        """The file's content."""
        return {
            "format": FORMAT,
            "passes": self.passes,
            "period_ticks": self.period_ticks,
            "supports": [float(x) for x in self.supports],
            "harmonics": _pairs(self.harmonics),
            "response_z": _pairs(self.response_z),
            "response_s": [float(x) for x in self.response_s],
            "passive_sigma": self.passive_sigma,
            "passive_loss": self.passive_loss,
            "line_stiffness": self.line_stiffness,
            "line_damping": self.line_damping,
            "model_valid": self.model_valid,
            "u_mean": self.u_mean,
        }


def _pairs(values: np.ndarray) -> list:
    """Complex numbers as [re, im] pairs (JSON has none), nested as the array."""
    return np.stack([values.real, values.imag], axis=-1).tolist()


def write_line_map(learned: LineMap, path: str | Path) -> None:
    """Write ``learned`` to ``path`` whole or not at all (a temporary file renamed over it)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(learned.as_json(), indent=1) + "\n")
    tmp.replace(path)


def _number(source: str, key: str, value: Any, low: float = -math.inf, positive: bool = False) -> float:
    bad = isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value)
    if bad or value < low or (positive and value <= 0):
        allowed = "a finite number" + (" > 0" if positive else f" >= {low:g}" if low > -math.inf else "")
        raise LineMapError(source, key, value, allowed)
    return float(value)


def _complex(source: str, key: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    try:
        pairs = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        pairs = np.empty(0)
    if pairs.shape != (*shape, 2) or not np.all(np.isfinite(pairs)):
        size = " x ".join(str(n) for n in shape)
        raise LineMapError(source, key, value, f"{size} finite [re, im] pairs")
    return pairs[..., 0] + 1j * pairs[..., 1]


def read_line_map(path: str | Path) -> LineMap:
    """The map in ``path``, every value checked (:class:`LineMapError`: one line)."""
    source = str(path)
    try:
        raw = json.loads(Path(path).read_text())
    except OSError as exc:
        raise LineMapError(source, "file", source, f"a readable file ({exc.strerror or exc})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LineMapError(source, "file", source, f"JSON ({exc})".splitlines()[0]) from None
    if not isinstance(raw, dict) or raw.get("format") != FORMAT:
        value = raw.get("format") if isinstance(raw, dict) else raw
        raise LineMapError(source, "format", value, f"'{FORMAT}' (a map written by pac)")
    supports = raw.get("supports")
    if (
        not isinstance(supports, list)
        or len(supports) < 2
        or not all(
            isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in supports
        )
        or not all(b > a for a, b in zip(supports, supports[1:], strict=False))
    ):
        raise LineMapError(source, "supports", supports, "at least two finite positions, increasing")
    period = raw.get("period_ticks")
    if isinstance(period, bool) or not isinstance(period, int) or period < 2:
        raise LineMapError(source, "period_ticks", period, "an integer >= 2")
    passes = raw.get("passes")
    if isinstance(passes, bool) or not isinstance(passes, int) or passes < 1:
        raise LineMapError(source, "passes", passes, "an integer >= 1")
    rows = raw.get("harmonics")
    width = len(rows[0]) if isinstance(rows, list) and rows and isinstance(rows[0], list) else 0
    if width < 1:
        raise LineMapError(
            source, "harmonics", rows, "one row of [re, im] pairs per span, at least one harmonic"
        )
    harmonics = _complex(source, "harmonics", rows, (len(supports) - 1, width))
    response_s = np.asarray(
        [
            _number(source, "response_s", x, 0.0)
            for x in _list(source, "response_s", raw.get("response_s"), width)
        ]
    )
    model_valid = raw.get("model_valid")
    if not isinstance(model_valid, bool):
        raise LineMapError(source, "model_valid", model_valid, "true or false")
    return LineMap(
        supports=np.asarray(supports, dtype=np.float64),
        period_ticks=period,
        harmonics=harmonics,
        response_z=_complex(source, "response_z", raw.get("response_z"), (width,)),
        response_s=response_s,
        # the guard's bar: at 0 it would never judge the map's spans
        passive_sigma=_number(source, "passive_sigma", raw.get("passive_sigma"), positive=True),
        passive_loss=_number(source, "passive_loss", raw.get("passive_loss"), 0.0),
        line_stiffness=_number(source, "line_stiffness", raw.get("line_stiffness"), 0.0),
        line_damping=_number(source, "line_damping", raw.get("line_damping"), 0.0),
        model_valid=model_valid,
        u_mean=_number(source, "u_mean", raw.get("u_mean")),
        passes=passes,
    )


def _list(source: str, key: str, value: Any, length: int) -> list:
    if not isinstance(value, list) or len(value) != length:
        raise LineMapError(source, key, value, f"a list of {length} numbers")
    return value


__all__ = ["FORMAT", "LineMap", "LineMapError", "read_line_map", "write_line_map"]
