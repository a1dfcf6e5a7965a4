"""Running a campaign's points: one row of measures per point, tick by tick or through the batch.

A row never raises: a divergence or an exception is its status and reason. The measures
are ``pac_analysis.metrics.Metrics`` (raw contact force over the point's window) and the
EN 50367 criteria; with ``statistics: en50318`` also the EN 50318 statistics of the 20 Hz
low-passed force over the window (the window half-open, so whole spans hold whole
periods), max |du/dt|, the largest wire uplift at the contact point and the contact-force
estimate's error RMS(F_hat - F) as % of sigma_F (raw F, over the window). The EN 50367
criteria are then taken on the filtered statistics, as the standard defines them.
With ``statistics: en50318`` a row also gives the worst span's contact loss (the largest share over
the spans of the line the window covers whole: the design layout's supports on a drawn line, the
period's on another) and the saturation share: the window's ticks on which the command was limited,
by the safety chain (the law's command changed: the actuator's range as the controller is told it,
its slew limit) or by the actuator (its mean force over the tick changed by its rate limit).
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np

from pac_analysis.metrics import Metrics, RunSeries, metrics_from_series
from pac_common.contact_statistics import (
    ContactStatistics,
    en50367_criteria,
    lowpass,
    statistics,
    worst_span_loss_percent,
)
from pac_experiments.campaign.spec import Point, law_file_sha256, observer_file_sha256
from pac_rig.batch import batchable, run_batch
from pac_rig.closed_loop import DivergenceError, Scenario, TickRecord, build_cores, run_blocks, run_cores
from pac_rig.loop import TICK, compile_loop
from pac_rig.simulate import scenario_to_flat, simulate_to_bag

#: The measures of a run, named as in ``pac_analysis.metrics.Metrics`` (and its reports).
METRIC_COLUMNS = tuple(
    f.name for f in dataclasses.fields(Metrics) if f.name not in ("window_from", "window_to")
)
#: EN 50367 quality criteria on the mean contact force Fm and its standard deviation sigma.
EN50367_COLUMNS = ("en50367_sigma_ok", "en50367_min_ok")
#: ``statistics: en50318`` only.
EN50318_COLUMNS = (
    *(f"en50318_{f.name}" for f in dataclasses.fields(ContactStatistics)),
    "du_dt_max_abs",
    "uplift_max_mm",
    "force_hat_error_percent",
    "worst_span_loss_percent",
    "saturation_percent",
)
STATUS_OK, STATUS_DIVERGED, STATUS_ERROR = "ok", "diverged", "error"


#: What a row's measures read of a run, per tick: fields of ``pac_rig.loop.TICK`` (and traces of
#: the batch, ``pac_rig.batch.TRACES``).
MEASURED = (
    "contact_force", "stiffness", "force_reference", "stiffness_hat", "u", "contact_force_hat",
    "contact_uplift", "contact_position", "u_applied", "saturated",
)  # fmt: skip


def traces_of_records(records: list[TickRecord]) -> dict[str, np.ndarray]:
    """The measured traces of a run stepped through the core objects, or recorded to a bag (its
    per-tick records): the same numbers as the compiled loop's TICK fields."""
    return {
        "contact_force": np.array([r.truth.contact_force for r in records]),
        "stiffness": np.array([r.truth.stiffness for r in records]),
        "force_reference": np.array([r.command.force_reference for r in records]),
        "stiffness_hat": np.array([r.estimate.stiffness_hat for r in records]),
        "u": np.array([r.command.u for r in records]),
        "contact_force_hat": np.array([r.estimate.contact_force_hat for r in records]),
        "contact_uplift": np.array([r.truth.contact_uplift for r in records]),
        "contact_position": np.array([r.truth.contact_position for r in records]),
        "u_applied": np.array([r.truth.u_applied for r in records]),
        "saturated": np.array([r.command.saturated for r in records]),
    }


def run_traces(scenario: Scenario) -> tuple[dict[str, np.ndarray], str | None]:
    """The measured traces of ``scenario`` run offline, and why it diverged (None: it finished):
    the compiled loop's TICK blocks read as arrays (no per-tick objects), or the core objects
    stepped tick by tick where the loop has no compiled form (a law at Python speed)."""
    plant, observer, controller = build_cores(scenario)
    loop = compile_loop(plant, observer, controller, scenario.loop.command_delay_ticks)
    blocks: list[np.ndarray] = []
    records: list[TickRecord] = []
    diverged = None
    try:
        if loop is None:
            records.extend(run_cores(scenario, plant, observer, controller))
        else:
            blocks.extend(run_blocks(scenario, plant, loop))
    except DivergenceError as exc:
        diverged = str(exc)
    if loop is None:
        return traces_of_records(records), diverged
    ticks = np.concatenate(blocks) if blocks else np.empty(0, TICK)
    return {name: ticks[name] for name in MEASURED}, diverged


def half_open(time_: np.ndarray, window: tuple[float, float], sample_period: float) -> np.ndarray:
    """The ticks of ``time_`` in [from, to) (to within a billionth of a tick): whole spans hold
    whole periods."""
    eps = 1e-9 * sample_period
    return (time_ >= window[0] - eps) & (time_ < window[1] - eps)


def en50318_measures(
    time_: np.ndarray,
    force: np.ndarray,
    u: np.ndarray,
    force_hat: np.ndarray,
    uplift: np.ndarray,
    window: tuple[float, float],
    sample_period: float,
) -> dict[str, float]:
    """The ``statistics: en50318`` columns over the half-open window [from, to) of ``time_``."""
    win = half_open(time_, window, sample_period)
    stats = statistics(lowpass(force, sample_period)[win], loss_force=force[win])
    f, err = force[win], force_hat[win] - force[win]
    du = np.diff(u[win])
    return {
        **{f"en50318_{k}": v for k, v in stats.as_dict().items()},
        "du_dt_max_abs": float(np.max(np.abs(du)) / sample_period) if du.size else math.nan,
        "uplift_max_mm": 1e3 * float(np.max(uplift[win])),
        "force_hat_error_percent": 100.0 * float(np.sqrt(np.mean(err**2)) / np.std(f))
        if np.std(f) > 0
        else math.nan,
    }


def line_supports(scenario: Scenario, position: np.ndarray) -> np.ndarray:
    """The supports [m] of the line ``position`` [m, rising] runs along: the design layout's on a
    line drawn from a file with one (what the infrastructure manager publishes), else the period's,
    a span length apart from the run's first position (every run starts at a support)."""
    from pac_plant.catenary.catenary_file import load_catenary
    from pac_plant.plants import plant_kind

    options = scenario.plant
    if plant_kind(options.catenary_model).line_from_file:
        supports = load_catenary(options.catenary).design_supports(options.drawn_line_seed)
        if supports is not None:
            return supports
    span = scenario.track.span_length
    return position[0] + span * np.arange(math.floor((position[-1] - position[0]) / span) + 2)


def limit_measures(
    scenario: Scenario, traces: dict[str, np.ndarray], win: np.ndarray, sample_period: float
) -> dict[str, float]:
    """``worst_span_loss_percent`` and ``saturation_percent`` over the ticks ``win`` (module
    docstring): the position is the contact point's where the plant reports it, else the distance
    run (v t from a support); the actuator's rate limit binds on a tick whose mean force moved by
    r h (to 1 ppm: a ramp held through the tick and the one before)."""
    from pac_plant.hardware.actuators import actuator_model

    v = scenario.track.speed_kmh / 3.6
    position = traces["contact_position"]
    if not np.all(np.isfinite(position)):
        position = v * sample_period * np.arange(position.size)
    force, x = traces["contact_force"][win], position[win]
    worst = worst_span_loss_percent(force, x, line_supports(scenario, x)) if x.size > 1 else math.nan
    limited = traces["saturated"][win].astype(bool)
    step = actuator_model(scenario.plant.actuator).rate_limit * sample_period
    if math.isfinite(step):
        moved = np.abs(np.diff(traces["u_applied"], prepend=traces["u_applied"][0]))[win]
        limited = limited | (moved >= step * (1.0 - 1e-6))
    return {
        "worst_span_loss_percent": worst,
        "saturation_percent": 100.0 * float(np.mean(limited)) if limited.size else math.nan,
    }


def measures(point: Point, traces: dict[str, np.ndarray], sample_period: float) -> dict[str, Any]:
    """The row's measures from a finished run's traces (:data:`MEASURED`, tick 0 on)."""
    every = np.arange(traces["u"].size)
    time_ = every * sample_period
    series = RunSeries(
        tick=every.astype(np.int64),
        time=time_,
        contact_force=traces["contact_force"],
        stiffness=traces["stiffness"],
        reference_index=every,
        force_reference=traces["force_reference"],
        estimate_index=every,
        stiffness_hat=traces["stiffness_hat"],
        u_time=time_,
        u=traces["u"],
    )
    m = metrics_from_series(series, point.window[0], point.window[1])
    row: dict[str, Any] = {k: getattr(m, k) for k in METRIC_COLUMNS}
    mean, sigma = m.contact_force_mean, m.contact_force_std
    if point.statistics == "en50318":
        row.update(
            en50318_measures(
                time_, traces["contact_force"], traces["u"], traces["contact_force_hat"],
                traces["contact_uplift"], point.window, sample_period,
            )
        )  # fmt: skip
        win = half_open(time_, point.window, sample_period)
        row.update(limit_measures(point.built(), traces, win, sample_period))
        mean, sigma = row["en50318_contact_force_mean"], row["en50318_contact_force_std"]
    verdict = en50367_criteria(mean, sigma)
    row.update(zip(EN50367_COLUMNS, (verdict.sigma_ok, verdict.statistical_min_ok), strict=True))
    return row


def run_point(point: Point, bag_dir: str | None = None) -> dict[str, Any]:
    """Run one scenario; never raises: a divergence or an exception is the row's status and reason."""
    start = time.perf_counter()
    row: dict[str, Any] = {"key": point.key, "status": STATUS_OK, "reason": ""}
    ticks = 0
    rate = 0.0
    try:
        scenario = point.built()
        rate = scenario.loop.rate_hz
        row.update(scenario_to_flat(scenario))
        if law_file_sha256(scenario) != point.law_file_sha256:  # the key says which text ran
            raise ValueError(f"the law file {point.values['law']} changed since the campaign was checked")
        if observer_file_sha256(scenario) != point.observer_file_sha256:
            observer = scenario.observer.observer
            raise ValueError(f"the observer file {observer} changed since the campaign was checked")
        if bag_dir is None:
            traces, diverged = run_traces(scenario)
        else:
            bag_path = Path(bag_dir) / point.key
            shutil.rmtree(bag_path, ignore_errors=True)  # a partial bag of an interrupted run
            records: list[TickRecord] = []
            diverged = simulate_to_bag(scenario, bag_path, point.key, on_record=records.append).diverged
            traces = traces_of_records(records)
        ticks = traces["u"].size
        if diverged:
            row.update(status=STATUS_DIVERGED, reason=diverged.splitlines()[0])
        else:
            row.update(measures(point, traces, scenario.loop.sample_period))
    except Exception as exc:  # noqa: BLE001 - any failure of one run is that run's row, not the campaign's end
        row.update(status=STATUS_ERROR, reason=f"{type(exc).__name__}: {exc}".splitlines()[0])
    row["ticks_run"] = ticks
    row["simulated_seconds"] = ticks / rate if rate else 0.0
    row["wall_seconds"] = time.perf_counter() - start
    return row


def run_batched(points: list[Point], threads: int = 1) -> dict[str, dict[str, Any]]:
    """Rows of the points the compiled batch runs (``pac_rig.batch.batchable``), by key.

    One ``run_batch`` call for all of them (no per-tick Python; ``threads`` threads); its traces equal
    ``closed_loop.run``'s bit for bit (tests/test_batch.py), so the rows equal
    :func:`run_point`'s. A run that diverges is its ``diverged`` row, as :func:`run_point` writes
    it from the ``DivergenceError`` (the same tick and reason; not run a second time); a point that
    does not validate is left to :func:`run_point`.
    """
    chosen: list[tuple[Point, Scenario]] = []
    for point in points:
        try:
            scenario = point.built()
        except Exception:  # noqa: BLE001 - run_point reports it as the row's error
            continue
        if batchable(scenario):
            chosen.append((point, scenario))
    if not chosen:
        return {}
    start = time.perf_counter()
    result = run_batch([s for _, s in chosen], threads=threads)
    wall = (time.perf_counter() - start) / len(chosen)
    rows = {}
    for i, (point, scenario) in enumerate(chosen):
        reached, diverged = int(result.ticks[i]), result.diverged[i]
        if diverged is not None:
            reason = str(DivergenceError(reached, diverged)).splitlines()[0]
            rows[point.key] = {
                "key": point.key,
                "status": STATUS_DIVERGED,
                "reason": reason,
                **scenario_to_flat(scenario),
                "ticks_run": reached,
                "simulated_seconds": reached / scenario.loop.rate_hz,
                "wall_seconds": wall,
            }
            continue
        row: dict[str, Any] = {"key": point.key, "status": STATUS_OK, "reason": ""}
        row.update(scenario_to_flat(scenario))
        traces = {name: result.traces[name][i, :reached] for name in MEASURED}
        row.update(measures(point, traces, scenario.loop.sample_period))
        row["ticks_run"] = reached
        row["simulated_seconds"] = reached / scenario.loop.rate_hz
        row["wall_seconds"] = wall
        rows[point.key] = row
    return rows


def run_chunk(points: list[Point], bag_dir: str | None = None, threads: int = 1) -> list[dict]:
    """The Dask task: several runs in one task, so the per-task overhead is paid once per chunk
    (and, with ``threads`` > 1, the in-process campaign's step: ``dask_runner.execute_in_process``).

    Without bags, the points the compiled batch can run go through it in one call; the rest
    (other laws, the FE line, divergences) run tick by tick. If the batch itself fails, its
    points run tick by tick and each of their rows says why in ``batch_error`` (the campaign
    prints it).
    """
    batched: dict[str, dict[str, Any]] = {}
    batch_error = ""
    if bag_dir is None:
        try:
            batched = run_batched(points, threads)
        except Exception as exc:  # noqa: BLE001 - every point then runs tick by tick and reports for itself
            batch_error = f"{type(exc).__name__}: {exc}".splitlines()[0]
    rows = []
    for p in points:
        row = batched.get(p.key) or run_point(p, bag_dir)
        if batch_error:
            row["batch_error"] = batch_error
        rows.append(row)
    return rows
