"""EN 50367 / EN 50318-style contact-force quality measures and loop bookkeeping from a bag."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .bag import BagData, TopicData


def stamp_seconds(topic: TopicData) -> np.ndarray:
    return topic["header.stamp.sec"] + 1e-9 * topic["header.stamp.nanosec"]


@dataclass(frozen=True)
class Metrics:
    """Over the window [window_from, window_to] of simulated time."""

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


def compute_metrics(bag: BagData, window_from: float = 3.0, window_to: float | None = None) -> Metrics:
    """Quality measures of a run; NaN where a topic the measure needs is missing."""
    truth = bag.topics.get("plant_truth")
    if truth is None or len(truth) == 0:
        raise ValueError("bag has no plant_truth messages: contact-force metrics need them")
    t = stamp_seconds(truth)
    end = float(t.max()) if window_to is None else window_to
    win = (t >= window_from - 1e-12) & (t <= end + 1e-12)
    force = truth["contact_force"][win]
    if force.size == 0:
        raise ValueError(f"no plant_truth samples in the window [{window_from}, {end}] s")
    mean, std = float(force.mean()), float(force.std())
    tracking = stiff = math.nan
    u_max = u_rms = math.nan
    command = bag.topics.get("command")
    if command is not None and len(command):
        ic, it = _by_tick(command, truth)
        keep = win[it]
        tracking = _rms(truth["contact_force"][it][keep] - command["force_reference"][ic][keep])
        u = command["u"][
            (stamp_seconds(command) >= window_from - 1e-12) & (stamp_seconds(command) <= end + 1e-12)
        ]
        u_max, u_rms = float(np.max(np.abs(u))) if u.size else math.nan, _rms(u)
    estimate = bag.topics.get("estimate")
    if estimate is not None and len(estimate):
        ie, it = _by_tick(estimate, truth)
        keep = win[it]
        k = truth["stiffness"][it][keep]
        stiff = 100.0 * _rms((estimate["stiffness_hat"][ie][keep] - k) / k)
    ticks = truth["tick"]
    expected = int(ticks.max() - ticks.min() + 1)
    recorded = int(np.unique(ticks).size)
    return Metrics(
        window_from=window_from,
        window_to=end,
        contact_force_mean=mean,
        contact_force_std=std,
        contact_force_min=float(force.min()),
        contact_force_max=float(force.max()),
        statistical_min=mean - 3.0 * std,
        statistical_max=mean + 3.0 * std,
        contact_loss_percent=100.0 * float(np.mean(force <= 0.0)),
        tracking_rms=tracking,
        stiffness_rel_rms_percent=stiff,
        u_max_abs=u_max,
        u_rms=u_rms,
        ticks_expected=expected,
        ticks_recorded=recorded,
        ticks_missing=expected - recorded,
    )


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
    lines = [
        f"Window: t in [{first.window_from:g}, {first.window_to:g}] s",
        "",
        "| measure | unit | " + " | ".join(names) + " |",
        "|---|---|" + "---:|" * len(names),
    ]
    for key, label, unit in _ROWS:
        cells = []
        for name in names:
            value = getattr(runs[name], key)
            cells.append(f"{value:d}" if isinstance(value, int) else f"{value:.4g}")
        lines.append(f"| {label} | {unit} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
