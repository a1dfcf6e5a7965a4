"""EN 50367 / EN 50318-style contact-force quality measures and loop bookkeeping from a bag."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from pac_bag.reader import BagData, TopicData
from pac_common import contact_statistics, markdown, messages


def stamp_seconds(topic: TopicData) -> np.ndarray:
    return topic["header.stamp.sec"] + 1e-9 * topic["header.stamp.nanosec"]


@dataclass(frozen=True)
class Metrics:
    """Over the window [window_from, window_to] of simulated time.

    The contact-force fields are ``contact_statistics.ContactStatistics``'s, by the same names.
    """

    window_from: float
    window_to: float
    contact_force_mean: float  # Fm [N]
    contact_force_std: float  # sigma [N]
    contact_force_min: float
    contact_force_max: float
    statistical_min: float  # Fm - 3 sigma
    statistical_max: float  # Fm + 3 sigma
    contact_loss_percent: float  # share of ticks with F <= 0
    tracking_rms: float  # rms(F - F_r) [N]
    stiffness_rel_rms_percent: float  # rms((k_hat - k) / k) [%]
    u_max_abs: float
    u_rms: float
    ticks_expected: int
    ticks_recorded: int
    ticks_missing: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def _by_tick(a: TopicData, b: TopicData) -> tuple[np.ndarray, np.ndarray]:
    """Indices into a and b of the ticks both hold."""
    _, ia, ib = np.intersect1d(a["tick"], b["tick"], assume_unique=False, return_indices=True)
    return ia, ib


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else math.nan


@dataclass(frozen=True)
class RunSeries:
    """The per-tick series the measures need, from a bag or from a run in memory.

    ``tick``/``time`` are the run's clock (the plant's ticks when it has them); the
    contact force and the stiffness are aligned with them.  Reference and estimate
    may cover only some ticks: ``*_index`` are the positions in ``tick`` they belong to.
    ``u`` carries its own time (the controller's stamps).
    """

    tick: np.ndarray
    time: np.ndarray
    contact_force: np.ndarray | None = None  # F [N]
    stiffness: np.ndarray | None = None  # k [N/m]
    reference_index: np.ndarray | None = None
    force_reference: np.ndarray | None = None  # F_r [N] at tick[reference_index]
    estimate_index: np.ndarray | None = None
    stiffness_hat: np.ndarray | None = None  # k_hat [N/m] at tick[estimate_index]
    u_time: np.ndarray | None = None
    u: np.ndarray | None = None  # [N]


def _in_window(t: np.ndarray, window_from: float, window_to: float) -> np.ndarray:
    return (t >= window_from - 1e-12) & (t <= window_to + 1e-12)


def metrics_from_series(s: RunSeries, window_from: float = 3.0, window_to: float | None = None) -> Metrics:
    """Quality measures over the window (end: the last tick when None); NaN for what is absent.

    The one place the measures are computed: ``compute_metrics`` (bags) and the
    campaigns (runs in memory) both come here.  Raises ValueError when the window
    holds no contact-force sample although the run has some.
    """
    if s.tick.size == 0:
        raise ValueError("no tick in the run")
    end = float(s.time.max()) if window_to is None else window_to
    nan = math.nan
    tracking = stiff = u_max = u_rms = nan
    contact = contact_statistics.statistics(np.zeros(0))  # NaN: no contact force in the run
    if s.contact_force is not None and s.contact_force.size:
        win = _in_window(s.time, window_from, end)
        force = s.contact_force[win]
        if force.size == 0:
            raise ValueError(f"no plant_truth samples in the window [{window_from}, {end}] s")
        # The rig's force is its 1 kHz truth, not a measurement: no low-pass.
        contact = contact_statistics.statistics(force)
        if s.force_reference is not None and s.reference_index is not None and s.force_reference.size:
            it = s.reference_index
            keep = win[it]
            tracking = _rms(s.contact_force[it][keep] - s.force_reference[keep])
        if s.stiffness_hat is not None and s.estimate_index is not None and s.stiffness is not None:
            if s.stiffness_hat.size:
                it = s.estimate_index
                keep = win[it]
                k = s.stiffness[it][keep]
                stiff = 100.0 * _rms((s.stiffness_hat[keep] - k) / k)
    if s.u is not None and s.u_time is not None and s.u.size:
        u = s.u[_in_window(s.u_time, window_from, end)]
        if u.size:
            u_max, u_rms = float(np.max(np.abs(u))), _rms(u)
    expected = int(s.tick.max() - s.tick.min() + 1)
    recorded = int(np.unique(s.tick).size)
    return Metrics(
        window_from=window_from,
        window_to=end,
        **contact.as_dict(),
        tracking_rms=tracking,
        stiffness_rel_rms_percent=stiff,
        u_max_abs=u_max,
        u_rms=u_rms,
        ticks_expected=expected,
        ticks_recorded=recorded,
        ticks_missing=expected - recorded,
    )


def series_from_bag(bag: BagData) -> RunSeries:
    """The bag's topics as series aligned on the plant's ticks. Raises ValueError when no topic has ticks."""
    truth, command, estimate = (bag.topics.get(n) for n in ("plant_truth", "command", "estimate"))
    present = [t for t in bag.topics.values() if len(t) and "tick" in t.columns]
    if not present:
        raise ValueError("no pac topic with ticks in the bag")
    if truth is not None and not len(truth):
        truth = None
    clock = truth if truth is not None else present[0]
    fields: dict[str, Any] = {"tick": clock["tick"], "time": stamp_seconds(clock)}
    if truth is not None:
        fields["contact_force"] = truth["contact_force"]
        fields["stiffness"] = truth["stiffness"]
    if command is not None and len(command):
        fields["u_time"], fields["u"] = stamp_seconds(command), command["u"]
        if truth is not None:
            ic, it = _by_tick(command, truth)
            fields["reference_index"], fields["force_reference"] = it, command["force_reference"][ic]
    if truth is not None and estimate is not None and len(estimate):
        ie, it = _by_tick(estimate, truth)
        fields["estimate_index"], fields["stiffness_hat"] = it, estimate["stiffness_hat"][ie]
    return RunSeries(**fields)


def compute_metrics(bag: BagData, window_from: float = 3.0, window_to: float | None = None) -> Metrics:
    """Quality measures of a recorded run over the window; NaN (and an entry in ``missing_inputs(bag)``)
    for what a missing topic prevents. Raises ValueError when the bag has no tick at all."""
    return metrics_from_series(series_from_bag(bag), window_from, window_to)


def pantograph_statistics(
    bag: BagData, window_from: float = 3.0, window_to: float | None = None
) -> list[dict[str, Any]]:
    """EN 50318 statistics of every pantograph of ``pantograph_truth`` (none: an empty list): each
    one's force (20 Hz zero-phase low-pass) over the whole spans its contact point covers in the
    time window (spans of the ``run_status`` span length; supports at its multiples). One dict per
    pantograph: spacing, controlled, the stretch [m] and ``ContactStatistics``' fields. Raises
    ValueError when a pantograph covers no whole span in the window."""
    data = bag.topics.get("pantograph_truth")
    if data is None or not len(data):
        return []
    status = bag.topics.get("run_status")
    span = float(status["span_length"][0]) if status is not None and len(status) else 0.0
    t = stamp_seconds(data)
    end = float(t.max()) if window_to is None else window_to
    win = _in_window(t, window_from, end)
    force, position = np.atleast_2d(data["contact_force"]), np.atleast_2d(data["contact_position"])
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1e-3
    out = []
    for k in range(force.shape[1]):
        x = position[:, k]
        x_from, x_to = contact_statistics.whole_spans(float(x[win].min()), float(x[win].max()), span)
        stats = contact_statistics.contact_statistics(force[:, k], x, dt, x_from, x_to)
        out.append(
            {
                "spacing": float(data["spacing"][0][k]),
                "controlled": int(data["controlled"][0]) == k,
                "x_from": x_from,
                "x_to": x_to,
                **stats.as_dict(),
            }
        )
    return out


def pantograph_table(rows: list[dict[str, Any]]) -> str:
    """One row per pantograph: where it runs, which one is controlled, its EN 50318 statistics."""
    return markdown.table(
        [
            "pantograph",
            "behind the first [m]",
            "spans [m]",
            "Fm [N]",
            "σ [N]",
            "min [N]",
            "max [N]",
            "loss [%]",
        ],
        [
            [
                f"{k}{' (controlled)' if r['controlled'] else ''}",
                f"{r['spacing']:g}",
                f"{r['x_from']:g} to {r['x_to']:g}",
                f"{r['contact_force_mean']:.1f}",
                f"{r['contact_force_std']:.1f}",
                f"{r['contact_force_min']:.1f}",
                f"{r['contact_force_max']:.1f}",
                f"{r['contact_loss_percent']:.2f}",
            ]
            for k, r in enumerate(rows)
        ],
        "r",
    )


#: Which measures each topic feeds (for saying what a missing topic costs).
NEEDS = {
    "plant_truth": "contact-force measures, k_hat error, tracking RMS",
    "command": "tracking RMS, u measures",
    "estimate": "k_hat error",
}


def missing_inputs(bag: BagData) -> list[str]:
    """One line per pac topic the bag lacks, naming the measures it prevents, and one when
    contact forces are not finite (the contact-force measures are NaN then)."""
    lines = [
        f"no '{topic}' messages: {what} not computed"
        for topic, what in NEEDS.items()
        if topic not in bag.topics or not len(bag.topics[topic])
    ]
    truth = bag.topics.get("plant_truth")
    if truth is not None and len(truth) and "contact_force" in truth.columns:
        force = np.asarray(truth["contact_force"], dtype=float)
        bad = int(np.count_nonzero(~np.isfinite(force)))
        if bad:
            lines.append(
                f"'plant_truth': {bad} of {force.size} contact forces not finite: "
                "the contact-force measures are NaN"
            )
    return lines


_ROWS = (
    ("contact_force_mean", "Fm, mean contact force", "N"),
    ("contact_force_std", "sigma, standard deviation", "N"),
    ("statistical_max", "Fm + 3 sigma", "N"),
    ("statistical_min", "Fm - 3 sigma", "N"),
    ("contact_force_max", "actual maximum", "N"),
    ("contact_force_min", "actual minimum", "N"),
    ("contact_loss_percent", "contact lost (F <= 0)", "%"),
    ("tracking_rms", "tracking RMS, F - F_r", "N"),
    ("stiffness_rel_rms_percent", "k_hat relative RMS error", "%"),
    ("u_max_abs", "max |u|", "N"),
    ("u_rms", "RMS u", "N"),
    ("ticks_expected", "ticks expected", ""),
    ("ticks_recorded", "ticks recorded", ""),
    ("ticks_missing", "ticks missing", ""),
)


def markdown_table(runs: dict[str, Metrics]) -> str:
    """One column per run, one row per measure."""
    names = list(runs)
    first = next(iter(runs.values()))
    rows = []
    for key, label, unit in _ROWS:
        cells = []
        for name in names:
            value = getattr(runs[name], key)
            cells.append(f"{value:d}" if isinstance(value, int) else f"{value:.4g}")
        rows.append([label, unit, *cells])
    body = markdown.table(
        ["measure", "unit", *names], rows, [markdown.LEFT] * 2 + [markdown.RIGHT] * len(names)
    )
    return f"Window: t in [{first.window_from:g}, {first.window_to:g}] s\n\n{body}\n"


#: A wake-up period longer than this many nominal periods is late.
LATE_PERIOD_FACTOR = 1.5


@dataclass(frozen=True)
class LoopTiming:
    """Wall-clock behaviour of a live run, from PlantTruth's wall stamps and round trips."""

    ticks: int
    steps_per_second: float
    nominal_period_ms: float  # 1 / rate_hz, from the ticks' simulated stamps
    period_mean_ms: float
    period_p99_ms: float
    period_p999_ms: float
    period_max_ms: float
    #: wake-up periods longer than 1.5 nominal periods (1.5 ms at 1 kHz): a tick that came late
    late_periods: int
    on_time_periods_percent: float  # periods <= 1.5 nominal periods
    latency_p50_ms: float
    latency_p99_ms: float
    latency_max_ms: float
    commands_on_time_percent: float  # applied at the first instant after their measurement
    #: per topic: ticks of the run with no message in the bag.  In real time the loop topics
    #: keep only the newest sample, so a node that falls behind skips ticks by design.
    messages_lost: dict[str, int]

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def loop_timing(bag: BagData) -> LoopTiming:
    truth = bag.topics["plant_truth"]
    _, first = np.unique(truth["tick"], return_index=True)
    wall = truth["wall_stamp.sec"][first] + 1e-9 * truth["wall_stamp.nanosec"][first]
    if wall.size < 3 or not np.all(wall > 0):
        raise ValueError("plant_truth has no wall stamps: not a live run")
    # Tick 0 is re-sent until the loop is closed (start-up handshake): periods start at tick 1.
    wall = wall[1:]
    period = np.diff(wall) * 1e3
    # The nominal period from the simulated stamps (tick k is at k / rate_hz, exactly).
    stamps = stamp_seconds(truth)[first]
    ticks = truth["tick"][first]
    nominal_ms = 1e3 * float((stamps[-1] - stamps[0]) / (ticks[-1] - ticks[0]))
    late_ms = LATE_PERIOD_FACTOR * nominal_ms
    latency = truth["round_trip_latency"][first]
    latency = latency[np.isfinite(latency)] * 1e3
    age = truth["command_age_ticks"][first]
    applied = truth["applied_command_tick"][first] >= 0
    # The run is the plant's ticks (fallback commands after its end carry extrapolated ticks);
    # only the loop's topics have one message per tick (run_status has two per run).
    first_tick, last_tick = int(truth["tick"].min()), int(truth["tick"].max())
    span = last_tick - first_tick + 1
    lost = {}
    for topic, data in bag.topics.items():
        if topic not in messages.LOOP_TOPICS:
            continue
        ticks = data["tick"] if len(data) else np.zeros(0, dtype=np.int64)
        in_run = ticks[(ticks >= first_tick) & (ticks <= last_tick)]
        lost[topic] = span - int(np.unique(in_run).size)

    def pct(x: np.ndarray, q: float) -> float:
        return float(np.percentile(x, q)) if x.size else math.nan

    return LoopTiming(
        ticks=span,
        steps_per_second=float((wall.size - 1) / (wall[-1] - wall[0])),
        nominal_period_ms=nominal_ms,
        period_mean_ms=float(period.mean()),
        period_p99_ms=pct(period, 99),
        period_p999_ms=pct(period, 99.9),
        period_max_ms=float(period.max()),
        late_periods=int(np.sum(period > late_ms)),
        on_time_periods_percent=100.0 * float(np.mean(period <= late_ms)),
        latency_p50_ms=pct(latency, 50),
        latency_p99_ms=pct(latency, 99),
        latency_max_ms=float(latency.max()) if latency.size else math.nan,
        commands_on_time_percent=100.0 * float(np.mean(age[applied] == 2)) if applied.any() else math.nan,
        messages_lost=lost,
    )


def timing_table(runs: dict[str, LoopTiming], extra_rows: Sequence[Sequence[str]] = ()) -> str:
    """The loop timing of each run, one column per run; ``extra_rows`` (label, one cell per run)
    follow the measures (e.g. ``make bench``'s CPU shares)."""
    names = list(runs)
    rows = [
        ("steps_per_second", "steps/s", "{:.0f}"),
        ("period_mean_ms", "period mean [ms]", "{:.3f}"),
        ("period_p99_ms", "period p99 [ms]", "{:.3f}"),
        ("period_p999_ms", "period p99.9 [ms]", "{:.3f}"),
        ("period_max_ms", "period max [ms]", "{:.2f}"),
        ("nominal_period_ms", "nominal period T [ms]", "{:.3f}"),
        ("late_periods", "periods > 1.5 T", "{:d}"),
        ("on_time_periods_percent", "periods <= 1.5 T [%]", "{:.2f}"),
        ("latency_p50_ms", "y -> u latency p50 [ms]", "{:.3f}"),
        ("latency_p99_ms", "y -> u latency p99 [ms]", "{:.3f}"),
        ("latency_max_ms", "y -> u latency max [ms]", "{:.2f}"),
        ("commands_on_time_percent", "u applied one tick after y [%]", "{:.1f}"),
    ]
    table = [[label, *(fmt.format(getattr(runs[n], key)) for n in names)] for key, label, fmt in rows]
    for topic in runs[names[0]].messages_lost:
        table.append([f"ticks without {topic}", *(str(runs[n].messages_lost.get(topic, "")) for n in names)])
    table += [list(r) for r in extra_rows]
    return markdown.table(["measure", *names], table, [markdown.LEFT] + [markdown.RIGHT] * len(names)) + "\n"
