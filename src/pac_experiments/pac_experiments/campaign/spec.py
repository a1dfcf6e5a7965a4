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
with every error found, one line each (:class:`SpecError`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pac_common.contact_statistics import target_mean_force, whole_spans
from pac_common.files import FileInputError, excerpt, read_yaml
from pac_common.parameters import ParameterError
from pac_controller.laws import LAWS
from pac_controller.parameters import LawParameters
from pac_controller.user_law import file_digest
from pac_observer.observers import OBSERVERS
from pac_observer.user_observer import load_observer_file
from pac_plant.catenary.catenary_file import load_catenary
from pac_plant.plants import plant_kind
from pac_rig import composition
from pac_rig.closed_loop import Scenario
from pac_rig.simulate import scenario_from_flat, scenario_to_flat

STATISTICS = ("raw", "en50318")
FORCE_TARGETS = ("en50367",)
#: Spans simulated after a ``window_spans`` window (the zero-phase filter's right-hand side).
TAIL_SPANS = 0.5
#: Grid points a SPEC may have (every grid's product of list lengths, summed): checked before a
#: point is built, so a SPEC of four 100-value lists is refused at once, not expanded.
MAX_POINTS = 10_000
KEYS = ("grid", "grids", "fixed", "window", "window_spans", "statistics", "force_target", "name")


#: Parameters added after campaigns were run, and the default that reproduces those runs: at it
#: they stay out of a point's key, so the results of earlier runs stay valid (resumable).
KEY_NEUTRAL_DEFAULTS = {
    "scenario": "",
    "catenary": "benchmark_55m",
    "fe_height_error": 0.0,
    "fe_wear": 0.0,
    "fe_imperfection_seed": 0,
    "line_seed": -1,
    "pantograph": "",
    "nominal_pantograph": "",
    "wind_uplift": 0.0,
    "actuator": "ideal",
    "actuator_static_force": 100.0,
    "roof_motion": "",
    "roof_seed": 0,
    "car_body": "high_speed_trailer",
    "sensors": "ground",
    "aero_turbulence": 0.0,
    "aero_turbulence_seed": 0,
    "fe_window_spans": 0.0,
    "pantographs": (0.0,),
    "controlled_pantograph": 0,
    "passive_pantograph": "three_mass",
    "passive_pantograph_uplift": 0.0,
    "all_pantographs_active": False,
    "force_estimate": "k_hat_z1",
    # line_adaptive's guard on what F_hat cannot bend, and its line map (its runs change with the
    # law's code: make campaigns and make fe-experiment run afresh, not resumed)
    "line_guard_bias": 0.25,
    "line_guard_reference": "runin",
    "line_guard_loss": 0.01,
    "line_guard_saturation": 0.25,
    "line_support_before": 0.0,
    "line_support_after": 0.0,
    "line_actuator_lag": 0.0,
    "line_guard_strikes": 3,
    "line_guard_loss_spans": 0,
    "line_guard_loss_margin": 0.05,
    "line_supports": (0.0,),
    "line_overlaps": (0.0,),
    "line_position_start": 0.0,
    "line_position_error": 0.0,
    "line_map": "",
    "head_balance_window": 2.0,
}
#: The prefix of one law's own parameters: a run of another law does not read them, so they hash at
#: their default there (a scenario's line map does not split the passive law's runs from its others).
LAW_OWN_PREFIXES = {"line_adaptive": "line_"}


class SpecError(ValueError):
    """A campaign SPEC that cannot run: every error found, one line each (``errors``)."""

    def __init__(self, errors: str | list[str]) -> None:
        self.errors = [errors] if isinstance(errors, str) else list(dict.fromkeys(errors))
        super().__init__("; ".join(self.errors))


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
    #: A user's law file (``law``): the SHA-256 of its text, which the key holds and the run checks
    law_file_sha256: str = ""
    #: A user's observer file (``observer``): the SHA-256 of its text, likewise
    observer_file_sha256: str = ""
    #: The scenario ``values`` give, as the SPEC's check built it (None: built from ``values`` when run)
    scenario: Scenario | None = field(default=None, compare=False, repr=False)

    def built(self) -> Scenario:
        """The point's scenario: the one its check built, else built from its values."""
        return self.scenario if self.scenario is not None else scenario_from_flat(self.values)


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
    """Read and check the SPEC's shape (not yet its values: see :func:`expand`).

    Raises SpecError with every shape error found (one line each)."""
    spec, errors = _read_spec(path)
    if errors or spec is None:
        raise SpecError(errors)
    return spec


def load_points(path: Path, announce: Callable[[Spec], None] | None = None) -> tuple[Spec, list[Point]]:
    """The SPEC and its points (:func:`expand`), every error of both in one SpecError.

    The points are checked even when the SPEC has shape errors elsewhere, as long as its grids
    and fixed values could be read, so one run names everything to fix. ``announce`` is told
    the SPEC before its points are checked (which may take a while)."""
    spec, errors = _read_spec(path)
    points: list[Point] = []
    if spec is not None:
        if announce is not None:
            announce(spec)
        try:
            points = expand(spec)
        except SpecError as exc:
            errors += exc.errors
    if errors or spec is None:
        raise SpecError(errors)
    return spec, points


def _read_spec(path: Path) -> tuple[Spec | None, list[str]]:
    """The SPEC and every shape error found. Where a field is wrong the spec holds its default
    (its points can still be checked); it is None when the grids or fixed values cannot be read."""
    try:
        data = read_yaml(path, "spec")
    except FileInputError as exc:
        return None, [str(exc)]
    if not isinstance(data, dict):
        return None, [f"spec {path} must be a mapping with 'grid' (or 'grids'), 'fixed', 'window'"]
    errors: list[str] = []

    def error(text: str) -> None:
        errors.append(f"spec {path}: {text}")

    for key in sorted(set(data) - set(KEYS), key=str):
        error(f"unknown key '{key}' = {excerpt(data[key])} (allowed: {', '.join(KEYS)})")
    readable = True  # grids and fixed usable: the points can be checked
    if ("grid" in data) == ("grids" in data):
        error("give exactly one of 'grid' (a mapping) or 'grids' (a list of mappings)")
        readable = False
    given = ([data["grid"]] if "grid" in data else data.get("grids")) if readable else []
    raw_grids: list[Any] = given if isinstance(given, list) else []
    if readable and not raw_grids:
        error(f"'grids' = {excerpt(given)}: allowed a non-empty list of mappings")
        readable = False
    fixed = data.get("fixed") or {}
    if not isinstance(fixed, dict):
        error(f"'fixed' = {excerpt(fixed)}: allowed a mapping of parameter: value")
        readable, fixed = False, {}
    grids = []
    for i, grid in enumerate(raw_grids):
        where = "grid" if "grid" in data else f"grids[{i}]"
        if not isinstance(grid, dict) or not grid:
            error(f"'{where}' is empty or not a mapping (parameter: [values, ...]), got {excerpt(grid)}")
            readable = False
            continue
        for name, values in grid.items():
            if not isinstance(values, list) or not values:
                error(f"{where}.{name} must be a non-empty list of values, got {excerpt(values)}")
                readable = False
            if name in fixed:
                # The grid's values would run while the report claims the fixed one.
                error(f"parameter '{name}' is both in 'fixed' and in '{where}': give it in one place")
                readable = False
        grids.append({str(k): list(v) if isinstance(v, list) else [v] for k, v in grid.items()})
    total = grid_size(grids)
    if total > MAX_POINTS:
        error(f"the grids have {total} points: allowed at most {MAX_POINTS} (split the campaign)")
        readable = False
    window_spans = None
    window = data.get("window", [3.0, None])
    #: The points' windows are not checked where the window itself is wrong (the whole run).
    unchecked_window = [0.0, None]
    if "window" in data and "window_spans" in data:
        error("give one of 'window' (seconds) or 'window_spans' (spans)")
        window = unchecked_window
    elif "window_spans" in data:
        ws = data["window_spans"]
        if not _number_pair(ws) or ws[1] is None or not 0.0 <= ws[0] < ws[1]:
            error(f"'window_spans' must be [from, to] spans, 0 <= from < to, got {excerpt(ws)}")
            window = unchecked_window
        else:
            window_spans = (float(ws[0]), float(ws[1]))
    if not _number_pair(window):
        error(f"'window' must be [from, to] in seconds, got {excerpt(window)}")
        window = unchecked_window
    statistics = data.get("statistics", "raw")
    if statistics not in STATISTICS:
        error(f"'statistics' = {excerpt(statistics)}: allowed {', '.join(STATISTICS)}")
        statistics = "raw"
    force_target = data.get("force_target")
    if force_target is not None:
        if force_target not in FORCE_TARGETS:
            error(f"'force_target' = {excerpt(force_target)}: allowed {', '.join(FORCE_TARGETS)}")
            force_target = None
        elif "force_amplitude" in fixed or any("force_amplitude" in g for g in grids):
            error("'force_target' sets force_amplitude: do not give it too")
    if not readable:
        return None, errors
    name = str(data.get("name") or Path(path).stem)
    spec = Spec(
        name,
        tuple(grids),
        dict(fixed),
        (float(window[0]), window[1]),
        window_spans,
        statistics,
        force_target,
    )
    return spec, errors


def grid_size(grids: tuple[dict[str, list[Any]], ...] | list[dict[str, list[Any]]]) -> int:
    """The number of points of the grids (before a point two grids share is counted once)."""
    return sum(math.prod(len(values) for values in grid.values()) for grid in grids)


def law_file_sha256(scenario: Scenario) -> str:
    """The SHA-256 of the text of the scenario's law file; "" for one of pac's laws."""
    law = scenario.controller.effective_law
    return "" if law in LAWS else file_digest(law)


def observer_file_sha256(scenario: Scenario) -> str:
    """The SHA-256 of the text of the scenario's observer file; "" for one of pac's observers."""
    observer = scenario.observer.observer
    return "" if observer in OBSERVERS else load_observer_file(observer).digest


def point_key(scenario: Scenario, window: tuple[float, float], statistics: str = "raw") -> str:
    """A stable hash of every parameter of the scenario (validated, normalised), the window,
    (when not the default) the statistics and (for a user's law or observer file) the file's text."""
    parameters = scenario_to_flat(scenario)
    law_defaults = LawParameters()
    for law, prefix in LAW_OWN_PREFIXES.items():
        if parameters.get("law") != law:
            for name in parameters:
                if name.startswith(prefix) and hasattr(law_defaults, name):
                    parameters[name] = getattr(law_defaults, name)
    for name, default in KEY_NEUTRAL_DEFAULTS.items():
        if parameters.get(name) == default:
            del parameters[name]
    content: dict[str, Any] = {"parameters": parameters, "window": list(window)}
    law_text = law_file_sha256(scenario)
    if law_text:  # a user's law file: its text, so the results of an edited file do not mix
        content["law_file_sha256"] = law_text
    observer_text = observer_file_sha256(scenario)
    if observer_text:  # a user's observer file: likewise
        content["observer_file_sha256"] = observer_text
    if statistics != "raw":
        content["statistics"] = statistics
    text = json.dumps(content, sort_keys=True, default=list)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _scenario(values: dict[str, Any], composed: bool = True) -> Scenario:
    """The point's scenario; SpecError with every refused value of the point (a parameter set
    stops at its first error, so each refused value is dropped and the rest checked again), and
    (``composed``) for parts that do not fit together (:func:`_check_fit`)."""
    errors: list[str] = []
    rest = dict(values)
    while True:
        try:
            scenario = scenario_from_flat(rest)
        except ParameterError as exc:
            errors.append(str(exc))
            if exc.name not in rest:
                break  # refused for a value the point does not give: nothing more to drop
            del rest[exc.name]
        except (TypeError, ValueError) as exc:
            errors.append(f"invalid point {excerpt(values)}: {excerpt(str(exc))}")
            break
        else:
            if not errors:
                if composed:
                    _check_fit(scenario)
                return scenario
            break
    raise SpecError(errors)


def _check_fit(scenario: Scenario) -> None:
    """SpecError for parts that do not fit together (pac_rig.composition) or a law file that
    cannot be loaded."""
    try:
        composition.check_pair(
            scenario.controller.effective_law,
            scenario.observer.observer,
            scenario.laws.force_estimate,
            scenario.plant.sensors,
        )
    except ParameterError as exc:
        raise SpecError(str(exc)) from None


def span_window(scenario: Scenario, spans: tuple[float, float]) -> tuple[float, float]:
    """The whole spans within spans a..b of the line as simulated time [s] at the scenario's speed
    (the run starts at a support, so position = speed x time from one)."""
    span = scenario.track.span_length
    x_from, x_to = whole_spans(spans[0] * span, spans[1] * span, span)
    v = scenario.track.speed_kmh / 3.6
    return x_from / v, x_to / v


def resolve(spec: Spec, values: dict[str, Any]) -> tuple[Scenario, dict[str, Any], tuple[float, float]]:
    """The point's scenario, its values with what the SPEC derives, and its window [s]."""
    # What the parts imply (pac_rig.composition): the observer a law needs, and on the FE line the
    # span of the line the plant runs (a campaign may vary the file).
    # The scenario is built once from the SPEC's values (so an error names a value the SPEC gave),
    # again only if deriving changed them, and the point carries it to its run.
    given = values
    scenario = _scenario(values, composed=False)  # every value valid before anything is derived
    if spec.force_target == "en50367":  # before deriving: what follows the reference derives from it
        values = {**values, "force_amplitude": target_mean_force(scenario.track.speed_kmh)}
    values, _ = composition.derive(values)  # a copy: what follows adds to it, never to the caller's
    if values != given:
        scenario = _scenario(values, composed=False)
    if spec.window_spans is not None:
        fe_span = load_catenary(scenario.plant.catenary).data.span
        if plant_kind(scenario.plant.catenary_model).line_from_file and scenario.track.span_length != fe_span:
            raise SpecError(
                f"invalid parameter 'span_length' = {scenario.track.span_length:g}: window_spans on the "
                f"FE line needs its (mean) span, {fe_span:g} m"
            )
        if "duration" not in values:
            span_time = scenario.track.span_length / (scenario.track.speed_kmh / 3.6)
            values["duration"] = round((spec.window_spans[1] + TAIL_SPANS) * span_time, 3)
            try:  # checked as a value given
                loop = dataclasses.replace(scenario.loop, duration=values["duration"])
            except ParameterError as exc:
                raise SpecError(str(exc)) from None
            scenario = dataclasses.replace(scenario, loop=loop)
    _check_fit(scenario)
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


def _grid_points(spec: Spec, errors: list[str] | None = None) -> Iterator[Point]:
    """Every point of every grid, validated, in grid order (a point two grids share comes twice).

    With ``errors``, an invalid point's errors go there and the next point is checked; without,
    the first invalid point raises SpecError."""
    for gi, grid in enumerate(spec.grids):
        names = list(grid)
        for combo in itertools.product(*grid.values()):
            try:
                scenario, values, window = resolve(
                    spec, {**spec.fixed, **dict(zip(names, combo, strict=True))}
                )
            except SpecError as exc:
                if errors is None:
                    raise
                errors += exc.errors
                continue
            key = point_key(scenario, window, spec.statistics)
            texts = law_file_sha256(scenario), observer_file_sha256(scenario)
            yield Point(key, values, gi, window, spec.statistics, *texts, scenario)


def expand(spec: Spec) -> list[Point]:
    """Every grid point, validated, in grid order; a point several grids share runs once.

    Raises SpecError with every distinct error of every point (one line each), before anything runs.
    """
    points: list[Point] = []
    seen: set[str] = set()
    errors: list[str] = []
    for point in _grid_points(spec, errors):
        if point.key not in seen:
            seen.add(point.key)
            points.append(point)
    if errors:
        raise SpecError(errors)
    return points


def grid_keys(spec: Spec) -> list[set[str]]:
    """The keys of each grid's points (the rows a grid's figures show)."""
    keys: list[set[str]] = [set() for _ in spec.grids]
    for point in _grid_points(spec):
        keys[point.grid].add(point.key)
    return keys
