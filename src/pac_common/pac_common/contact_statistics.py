"""Contact-force quality: the EN 50317 / EN 50318 statistics and the EN 50367 criteria, in one place.

Pure (numpy, scipy), no ROS: the bag metrics (``pac_analysis.metrics``), the campaigns and the
FE catenary experiments all take their statistics, names and criteria from here.  The data and
their sources: docs/catenary_data.md.

Names (one set, used in every report): ``contact_force_mean`` Fm, ``contact_force_std`` sigma,
``contact_force_min`` / ``contact_force_max`` the actual extremes, ``statistical_min`` /
``statistical_max`` Fm -/+ 3 sigma, ``contact_loss_percent`` the share of samples with
F <= 0.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

#: Low-pass cut-off of the contact force before its statistics (common practice for EN 50318
#: comparisons: docs/catenary_data.md §1).
CUTOFF_HZ = 20.0
#: Order of the Butterworth low-pass (applied forwards and backwards: zero phase, twice the order).
LOWPASS_ORDER = 4
#: EN 50367 quality criterion: sigma <= this times Fm.
SIGMA_LIMIT_RATIO = 0.3


@dataclass(frozen=True)
class ContactStatistics:
    """Statistics of a contact-force record over a window."""

    contact_force_mean: float  # Fm [N]
    contact_force_std: float  # sigma, population standard deviation [N]
    contact_force_min: float  # actual minimum [N]
    contact_force_max: float  # actual maximum [N]
    statistical_min: float  # Fm - 3 sigma [N]
    statistical_max: float  # Fm + 3 sigma [N]
    contact_loss_percent: float  # samples with F <= 0 [% of the window]

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class EN50367Verdict:
    """The EN 50367 quality criteria on Fm and sigma."""

    sigma_ok: bool  # sigma <= 0.3 Fm
    statistical_min_ok: bool  # Fm - 3 sigma > 0

    @property
    def passed(self) -> bool:
        return self.sigma_ok and self.statistical_min_ok


def target_mean_force(speed_kmh: float) -> float:
    """EN 50367 / TSI Energy target mean contact force on AC lines [N], v in km/h.

    Fm(v) = 0.00097 v^2 + 70 (docs/catenary_data.md §3).
    """
    return 0.00097 * speed_kmh**2 + 70.0


def en50367_criteria(mean: float, std: float) -> EN50367Verdict:
    """EN 50367: sigma <= 0.3 Fm, and Fm - 3 sigma > 0 (the statistical minimum stays in contact);
    docs/catenary_data.md §3."""
    sigma_ok, min_ok = _en50367(np.asarray(mean, dtype=float), np.asarray(std, dtype=float))
    return EN50367Verdict(sigma_ok=bool(sigma_ok), statistical_min_ok=bool(min_ok))


def en50367_passed(mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """Element by element (many runs at once): both EN 50367 criteria hold; False where Fm or sigma is NaN."""
    sigma_ok, min_ok = _en50367(np.asarray(mean, dtype=float), np.asarray(std, dtype=float))
    return np.asarray(sigma_ok & min_ok)


def _en50367(mean: np.ndarray, std: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return std <= SIGMA_LIMIT_RATIO * mean, mean - 3.0 * std > 0.0


def statistics(force: np.ndarray, loss_force: np.ndarray | None = None) -> ContactStatistics:
    """Statistics of the samples as given (no filtering).

    ``loss_force`` (same length) is what contact loss is counted on, when it differs from
    ``force`` (the unfiltered force when ``force`` is low-passed: a filter smears a lift-off).
    NaN everywhere for an empty record.
    """
    f = np.asarray(force, dtype=float)
    if f.size == 0:
        nan = math.nan
        return ContactStatistics(nan, nan, nan, nan, nan, nan, nan)
    lost = f if loss_force is None else np.asarray(loss_force, dtype=float)
    if lost.shape != f.shape:
        raise ValueError(f"loss_force has {lost.shape} samples, force {f.shape}")
    mean, std = float(np.mean(f)), float(np.std(f))
    return ContactStatistics(
        contact_force_mean=mean,
        contact_force_std=std,
        contact_force_min=float(np.min(f)),
        contact_force_max=float(np.max(f)),
        statistical_min=mean - 3.0 * std,
        statistical_max=mean + 3.0 * std,
        contact_loss_percent=loss_percent(lost),
    )


def loss_percent(force: np.ndarray) -> float:
    """The share of samples with F <= 0 [%]; NaN for none, or for a NaN among them (a NaN force is
    neither in contact nor lost: one makes the share unknown, not 0 %)."""
    f = np.asarray(force, dtype=float)
    return 100.0 * float(np.mean(f <= 0.0)) if f.size and np.all(np.isfinite(f)) else math.nan


def worst_span_loss_percent(force: np.ndarray, position: np.ndarray, supports: np.ndarray) -> float:
    """The largest :func:`loss_percent` over the spans the record covers whole: its samples grouped
    by the span (between two of the ascending ``supports`` [m]) their ``position`` [m] lies in, a
    span counted when the record reaches both its supports to within one sample's travel (part of a
    span is not its share). ``position`` rises through the record, as a train's does. NaN when no
    span is covered whole. Per span because contact loss gathers where the line is hard (after a
    support, at an overlap): a window's share spreads one span's losses over all of them."""
    f, x = np.asarray(force, dtype=float), np.asarray(position, dtype=float)
    edges = np.asarray(supports, dtype=float)
    if f.shape != x.shape:
        raise ValueError(f"position has {x.shape} samples, force {f.shape}")
    if f.size < 2 or not np.all(np.isfinite(x)):
        return math.nan
    step = float(np.max(np.diff(x)))
    span = np.searchsorted(edges, x, side="right") - 1
    shares = [
        loss_percent(f[span == k])
        for k in range(edges.size - 1)
        if x[0] <= edges[k] + step and x[-1] >= edges[k + 1] - step
    ]
    return max(shares) if shares else math.nan


def lowpass(force: np.ndarray, dt: float, cutoff: float = CUTOFF_HZ) -> np.ndarray:
    """Zero-phase Butterworth low-pass (no delay between force and position) of a record sampled every dt."""
    from scipy.signal import butter, sosfiltfilt  # here: scipy.signal costs ~0.3 s to import

    sos = butter(LOWPASS_ORDER, cutoff, fs=1.0 / dt, output="sos")
    return np.asarray(sosfiltfilt(sos, np.asarray(force, dtype=float)))


def position_window(position: np.ndarray, x_from: float, x_to: float) -> np.ndarray:
    """Mask of the samples with x_from <= position <= x_to; ValueError when there is none."""
    x = np.asarray(position, dtype=float)
    window = (x >= x_from) & (x <= x_to)
    if not np.any(window):
        raise ValueError(f"no samples between x = {x_from} and {x_to} m")
    return window


def whole_spans(x_from: float, x_to: float, span_length: float) -> tuple[float, float]:
    """The largest run of whole spans (support to support, supports at multiples of span_length)
    inside [x_from, x_to]: EN 50318 statistics are taken over whole spans so that every position
    in a span weighs the same.  ValueError when not one whole span fits."""
    if not span_length > 0.0:
        raise ValueError(f"span_length = {span_length}: allowed a number > 0 m")
    # A bound within rounding of a support counts as that support.
    first = math.ceil(x_from / span_length - 1e-9)
    last = math.floor(x_to / span_length + 1e-9)
    if last <= first:
        raise ValueError(f"no whole span of {span_length} m between x = {x_from} and {x_to} m")
    return first * span_length, last * span_length


def contact_statistics(
    force: np.ndarray,
    position: np.ndarray,
    dt: float,
    x_from: float,
    x_to: float,
    cutoff: float | None = CUTOFF_HZ,
) -> ContactStatistics:
    """EN 50318-style statistics of a force sampled every dt, over positions [x_from, x_to].

    The whole record is low-passed first (``cutoff`` None: not filtered), so that the filter's
    start and end transients stay outside the window; contact loss is counted on the unfiltered
    force.
    """
    raw = np.asarray(force, dtype=float)
    window = position_window(position, x_from, x_to)
    filtered = raw if cutoff is None else lowpass(raw, dt, cutoff)
    return statistics(filtered[window], loss_force=raw[window])
