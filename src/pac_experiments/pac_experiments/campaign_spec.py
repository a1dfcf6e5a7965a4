"""A campaign's SPEC: reading and checking it, its points (validated scenarios) and their keys.

SPEC (YAML)::

    grid:                 # every combination of these lists (any simulate parameter, see
      c1: [20.0, 40.0]    #   ``ros2 run pac_rig simulate --list``)
      speed_kmh: [200.0, 300.0, 360.0]
    fixed:                # any simulate parameter, the same for every run (never also in a grid)
      duration: 6.0
    window: [3.0, 6.0]    # measures over this window of simulated time [s]

``grids:`` (a list of such mappings) instead of ``grid:`` runs the union of several grids.
Instead of ``window``, ``window_spans: [a, b]`` takes the measures over spans a..b of the
line (span_length at the point's speed: whole spans, so a span-periodic force has its true
mean over the window) and, unless ``duration`` is given, runs each point for b + 1/2 spans
(the 20 Hz filter then has data on both sides of the window). ``statistics: en50318`` adds
the EN 50318 columns (20 Hz low-pass; see ``campaign_run``); ``force_target: en50367`` sets
each point's ``force_amplitude`` to the EN 50367 target mean force at its speed. On the FE
line (``catenary_model: fe``) a point without ``span_length`` gets its catenary file's (mean)
span, so a grid may vary the line (``catenary: [benchmark_55m, stitched_hs_65m]``).
Every point is validated with ``scenario_from_flat`` before anything runs; a bad SPEC stops
with one line (:class:`SpecError`).
"""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from pac_common.contact_statistics import target_mean_force, whole_spans
from pac_common.parameters import ParameterError
from pac_plant.catenary.catenary_file import load_catenary
from pac_rig.closed_loop import Scenario
from pac_rig.simulate import scenario_from_flat, scenario_to_flat

STATISTICS = ("raw", "en50318")
FORCE_TARGETS = ("en50367",)
#: Spans simulated after a ``window_spans`` window (the zero-phase filter's right-hand side).
TAIL_SPANS = 0.5
KEYS = ("grid", "grids", "fixed", "window", "window_spans", "statistics", "force_target", "name")


#: Parameters added after campaigns were run, and the default that reproduces those runs: at it
#: they stay out of a point's key, so the results of earlier runs stay valid (resumable).
KEY_NEUTRAL_DEFAULTS = {
    "catenary": "benchmark_55m",
    "fe_height_error": 0.0,
    "fe_wear": 0.0,
    "fe_imperfection_seed": 0,
}


class SpecError(ValueError):
    """A campaign SPEC that cannot run; the message is one line."""


@dataclass(frozen=True)
class Spec:
    name: str
    grids: tuple[dict[str, list[Any]], ...]
    fixed: dict[str, Any]
    window: tuple[float, float | None]  # seconds (to: None = the end of the run)
    window_spans: tuple[float, float] | None = None  # instead of ``window`` when given
    statistics: str = "raw"
    force_target: str | None = None

    @property
    def axes(self) -> list[str]:
        """Every parameter a grid names (the campaign's varied ones), in order of first appearance."""
        out: list[str] = []
        for grid in self.grids:
            out += [name for name in grid if name not in out]
        return out

    def window_text(self) -> str:
        if self.window_spans is not None:
            a, b = self.window_spans
            return f"spans {a:g} to {b:g} of the line (whole spans at each point's speed)"
        end = "end" if self.window[1] is None else f"{self.window[1]:g}"
        return f"t in [{self.window[0]:g}, {end}] s of simulated time"


@dataclass(frozen=True)
class Point:
    """One run of the campaign: its values as the SPEC gives them (plus what the SPEC derives),
    its measuring window [s] and statistics, and its stable key."""

    key: str
    values: dict[str, Any]
    grid: int  # index of the grid it comes from
    window: tuple[float, float] = (0.0, 0.0)
    statistics: str = "raw"


def same_value(a: Any, b: Any) -> bool:
    """A SPEC's value vs a row's normalised one (ints vs floats, lists vs tuples)."""
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(same_value(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool):
        return float(a) == float(b)
    return a == b


def _number_pair(value: Any) -> bool:
    return (
        isinstance(value, list)
        and len(value) == 2
        and all(w is None or (isinstance(w, int | float) and not isinstance(w, bool)) for w in value)
        and value[0] is not None
    )


def load_spec(path: Path) -> Spec:
    """Read and check the SPEC's shape (not yet its values: see :func:`expand`)."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise SpecError(f"cannot read spec {path}: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        mark = getattr(exc, "problem_mark", None)  # where the parser stopped (0-based)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise SpecError(f"spec {path} is not valid YAML{where} ({first})") from None
    if not isinstance(data, dict):
        raise SpecError(f"spec {path} must be a mapping with 'grid' (or 'grids'), 'fixed', 'window'")
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise SpecError(f"spec {path}: unknown key '{unknown[0]}' (allowed: {', '.join(KEYS)})")
    if ("grid" in data) == ("grids" in data):
        raise SpecError(
            f"spec {path}: give exactly one of 'grid' (a mapping) or 'grids' (a list of mappings)"
        )
    raw_grids = [data["grid"]] if "grid" in data else data["grids"]
    if not isinstance(raw_grids, list) or not raw_grids:
        raise SpecError(f"spec {path}: 'grids' must be a non-empty list of mappings")
    fixed = data.get("fixed") or {}
    if not isinstance(fixed, dict):
        raise SpecError(f"spec {path}: 'fixed' must be a mapping of parameter: value")
    grids = []
    for i, grid in enumerate(raw_grids):
        where = "grid" if "grid" in data else f"grids[{i}]"
        if not isinstance(grid, dict) or not grid:
            raise SpecError(f"spec {path}: '{where}' is empty or not a mapping (parameter: [values, ...])")
        for name, values in grid.items():
            if not isinstance(values, list) or not values:
                raise SpecError(
                    f"spec {path}: {where}.{name} must be a non-empty list of values, got {values!r}"
                )
            if name in fixed:
                # The grid's values would run while the report claims the fixed one.
                raise SpecError(
                    f"spec {path}: parameter '{name}' is both in 'fixed' and in '{where}': "
                    "give it in one place"
                )
        grids.append({str(k): list(v) for k, v in grid.items()})
    if "window" in data and "window_spans" in data:
        raise SpecError(f"spec {path}: give one of 'window' (seconds) or 'window_spans' (spans)")
    window_spans = None
    if "window_spans" in data:
        ws = data["window_spans"]
        if not _number_pair(ws) or ws[1] is None or not 0.0 <= ws[0] < ws[1]:
            raise SpecError(
                f"spec {path}: 'window_spans' must be [from, to] spans, 0 <= from < to, got {ws!r}"
            )
        window_spans = (float(ws[0]), float(ws[1]))
    window = data.get("window", [3.0, None])
    if not _number_pair(window):
        raise SpecError(f"spec {path}: 'window' must be [from, to] in seconds, got {window!r}")
    statistics = data.get("statistics", "raw")
    if statistics not in STATISTICS:
        raise SpecError(f"spec {path}: 'statistics' = {statistics!r}: allowed {', '.join(STATISTICS)}")
    force_target = data.get("force_target")
    if force_target is not None:
        if force_target not in FORCE_TARGETS:
            raise SpecError(
                f"spec {path}: 'force_target' = {force_target!r}: allowed {', '.join(FORCE_TARGETS)}"
            )
        if "force_amplitude" in fixed or any("force_amplitude" in g for g in grids):
            raise SpecError(f"spec {path}: 'force_target' sets force_amplitude: do not give it too")
    name = str(data.get("name") or Path(path).stem)
    return Spec(
        name,
        tuple(grids),
        dict(fixed),
        (float(window[0]), window[1]),
        window_spans,
        statistics,
        force_target,
    )


def point_key(scenario: Scenario, window: tuple[float, float], statistics: str = "raw") -> str:
    """A stable hash of every parameter of the scenario (validated, normalised), the window
    and (when not the default) the statistics."""
    parameters = scenario_to_flat(scenario)
    for name, default in KEY_NEUTRAL_DEFAULTS.items():
        if parameters.get(name) == default:
            del parameters[name]
    content: dict[str, Any] = {"parameters": parameters, "window": list(window)}
    if statistics != "raw":
        content["statistics"] = statistics
    text = json.dumps(content, sort_keys=True, default=list)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _scenario(values: dict[str, Any]) -> Scenario:
    try:
        return scenario_from_flat(values)
    except ParameterError as exc:
        raise SpecError(str(exc)) from None
    except (TypeError, ValueError) as exc:
        raise SpecError(f"invalid point {values}: {exc}") from None


def span_window(scenario: Scenario, spans: tuple[float, float]) -> tuple[float, float]:
    """The whole spans within spans a..b of the line as simulated time [s] at the scenario's speed
    (the run starts at a support, so position = speed x time from one)."""
    span = scenario.track.span_length
    x_from, x_to = whole_spans(spans[0] * span, spans[1] * span, span)
    v = scenario.track.speed_kmh / 3.6
    return x_from / v, x_to / v


def resolve(spec: Spec, values: dict[str, Any]) -> tuple[Scenario, dict[str, Any], tuple[float, float]]:
    """The point's scenario, its values with what the SPEC derives, and its window [s]."""
    values = dict(values)
    scenario = _scenario(values)
    if spec.force_target == "en50367":
        values["force_amplitude"] = target_mean_force(scenario.track.speed_kmh)
    if scenario.plant.catenary_model == "fe" and "span_length" not in values:
        # The laws are told the span of the line the plant runs (a campaign may vary the file).
        values["span_length"] = load_catenary(scenario.plant.catenary).data.span
        scenario = _scenario(values)
    if spec.window_spans is not None:
        fe_span = load_catenary(scenario.plant.catenary).data.span
        if scenario.plant.catenary_model == "fe" and scenario.track.span_length != fe_span:
            raise SpecError(
                f"invalid parameter 'span_length' = {scenario.track.span_length:g}: window_spans on the "
                f"FE line needs its (mean) span, {fe_span:g} m"
            )
        if "duration" not in values:
            span_time = scenario.track.span_length / (scenario.track.speed_kmh / 3.6)
            values["duration"] = round((spec.window_spans[1] + TAIL_SPANS) * span_time, 3)
    scenario = _scenario(values)
    duration = scenario.loop.duration
    if spec.window_spans is not None:
        w_from, w_to = span_window(scenario, spec.window_spans)
    else:
        w_from, w_to = spec.window[0], duration if spec.window[1] is None else float(spec.window[1])
    if duration <= 0.0:
        raise SpecError("invalid parameter 'duration' = 0.0: allowed (0, 86400] s offline")
    if not 0.0 <= w_from < w_to <= duration:
        raise SpecError(
            f"invalid window [{w_from:g}, {w_to:g}] s: allowed 0 <= from < to <= duration ({duration:g} s)"
        )
    return scenario, values, (w_from, w_to)


def _grid_points(spec: Spec) -> Iterator[Point]:
    """Every point of every grid, validated, in grid order (a point two grids share comes twice)."""
    for gi, grid in enumerate(spec.grids):
        names = list(grid)
        for combo in itertools.product(*grid.values()):
            scenario, values, window = resolve(spec, {**spec.fixed, **dict(zip(names, combo, strict=True))})
            yield Point(point_key(scenario, window, spec.statistics), values, gi, window, spec.statistics)


def expand(spec: Spec) -> list[Point]:
    """Every grid point, validated, in grid order; a point several grids share runs once.

    Raises SpecError (one line) on the first invalid point, before anything runs.
    """
    points: list[Point] = []
    seen: set[str] = set()
    for point in _grid_points(spec):
        if point.key not in seen:
            seen.add(point.key)
            points.append(point)
    return points


def grid_keys(spec: Spec) -> list[set[str]]:
    """The keys of each grid's points (the rows a grid's figures show)."""
    keys: list[set[str]] = [set() for _ in spec.grids]
    for point in _grid_points(spec):
        keys[point.grid].add(point.key)
    return keys
