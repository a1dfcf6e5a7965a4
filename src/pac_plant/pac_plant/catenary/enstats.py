"""EN 50318 style contact-force statistics over a stretch of line."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt

#: Low-pass cut-off of the contact force for the statistics (common practice, CATENARY_DATA §1).
CUTOFF_HZ = 20.0


@dataclass(frozen=True)
class ContactStatistics:
    mean: float  # Fm [N]
    sigma: float  # standard deviation [N]
    stat_max: float  # Fm + 3 sigma [N]
    stat_min: float  # Fm - 3 sigma [N]
    max: float  # actual maximum of the filtered force [N]
    min: float  # actual minimum of the filtered force [N]
    loss_percent: float  # samples with no contact (unfiltered F <= 0) [% of the window]

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def lowpass(force: np.ndarray, dt: float, cutoff: float = CUTOFF_HZ) -> np.ndarray:
    """Zero-phase 4th-order Butterworth low-pass (no delay between force and position)."""
    sos = butter(4, cutoff, fs=1.0 / dt, output="sos")
    return sosfiltfilt(sos, force)


def contact_statistics(
    force: np.ndarray, position: np.ndarray, dt: float, x_from: float, x_to: float, cutoff: float = CUTOFF_HZ
) -> ContactStatistics:
    """Statistics of the contact force sampled every ``dt`` over positions [x_from, x_to]."""
    filtered = lowpass(np.asarray(force, dtype=float), dt, cutoff)
    window = (position >= x_from) & (position <= x_to)
    if not np.any(window):
        raise ValueError(f"no samples between x = {x_from} and {x_to} m")
    f = filtered[window]
    mean, sigma = float(np.mean(f)), float(np.std(f))
    return ContactStatistics(
        mean=mean,
        sigma=sigma,
        stat_max=mean + 3 * sigma,
        stat_min=mean - 3 * sigma,
        max=float(np.max(f)),
        min=float(np.min(f)),
        loss_percent=100.0 * float(np.mean(np.asarray(force)[window] <= 0.0)),
    )
