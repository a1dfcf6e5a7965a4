"""Random contact-wire geometry deviation, drawn per dropper: vertical from a spectrum, longitudinal
Gaussian (the two kinds Song, Jiang, Nåvik and Rønnquist measured on Norwegian lines, Railway
Engineering Science 29:350-361, 2021, doi 10.1007/s40534-021-00251-0; docs/catenary.md, "Geometry
deviation", for which numbers are theirs and which are *judgement*).

* **Vertical**: the contact-wire height error u(x) at the droppers is a stationary Gaussian
  process along the line with the exponential correlation R(s) = sigma^2 exp(-|s| / ell), i.e.
  the one-sided spectral density (per cycle per metre, wavenumber kappa)

      S(kappa) = 4 sigma^2 ell / (1 + (2 pi kappa ell)^2),

  a first-order (Ornstein-Uhlenbeck) process. It is sampled exactly at the droppers, whatever
  their spacing: u_(i+1) = rho u_i + sqrt(1 - rho^2) sigma eps_i, rho = exp(-(x_(i+1) - x_i) / ell),
  eps_i independent standard normal. Every span differs (the process runs along the whole drawn
  stretch); the design pre-sag plus u is the height the dropper lengths are solved for (a
  dropper that would have to push hangs slack: ``static``).
* **Longitudinal**: each dropper's position moves by an independent normal error (standard
  deviation ``longitudinal_sigma``), clipped to +-3 standard deviations so the droppers stay
  ordered and inside their span.

Per-dropper sampling resolves wavelengths down to twice the dropper interval; the contact wire
between droppers follows from the mechanics.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .data import CatenaryData, SpanData

#: Longitudinal errors are clipped at this many standard deviations (droppers keep their order).
CLIP = 3.0


@dataclass(frozen=True)
class DeviationModel:
    """The deviation model of a catenary file (``deviation:``): vertical spectrum, longitudinal
    scatter (the seed is the file's ``line_seed``)."""

    vertical_sigma: float  # m, standard deviation of the height error at a dropper
    correlation_length: float  # m, ell of R(s) = sigma^2 exp(-|s| / ell)
    longitudinal_sigma: float  # m, standard deviation of a dropper's position error
    model: str = "exponential_psd"


def spectral_density(kappa: np.ndarray, sigma: float, ell: float) -> np.ndarray:
    """One-sided S(kappa) [m^2 / (1/m)] of the vertical deviation at wavenumbers ``kappa`` [1/m]."""
    return 4.0 * sigma**2 * ell / (1.0 + (2.0 * np.pi * np.asarray(kappa) * ell) ** 2)


def vertical_deviation(x: np.ndarray, sigma: float, ell: float, rng: np.random.Generator) -> np.ndarray:
    """The height error [m] at the ascending positions ``x`` [m]: the process above, sampled exactly."""
    u = np.empty(len(x))
    if len(x) == 0:
        return u
    eps = rng.standard_normal(len(x))
    u[0] = sigma * eps[0]  # the stationary distribution
    rho = np.exp(-np.diff(x) / ell)
    for i in range(1, len(x)):
        u[i] = rho[i - 1] * u[i - 1] + math.sqrt(1.0 - rho[i - 1] ** 2) * sigma * eps[i]
    return u


def apply_deviation(
    data: CatenaryData, model: DeviationModel, n_spans: int, rng: np.random.Generator
) -> CatenaryData:
    """``data`` with ``n_spans`` spans (its spans cycled), every dropper moved and raised or lowered
    by one draw of ``model`` from ``rng``; stitch droppers keep their design (not drawn)."""
    p = len(data.spans)
    spans = [data.spans[k % p] for k in range(n_spans)]
    starts = np.concatenate([[0.0], np.cumsum([s.length for s in spans])])
    moved: list[np.ndarray] = []
    for s in spans:
        gaps = np.diff([0.0, *s.dropper_positions, s.length])
        limit = CLIP * model.longitudinal_sigma
        if limit >= 0.5 * float(np.min(gaps)):
            raise ValueError(
                f"longitudinal_sigma = {model.longitudinal_sigma!r} m: allowed at most "
                f"{np.min(gaps) / (2 * CLIP):g} m (droppers {np.min(gaps):g} m apart must keep their order)"
            )
        shift = np.clip(rng.normal(0.0, model.longitudinal_sigma, len(s.dropper_positions)), -limit, limit)
        moved.append(np.asarray(s.dropper_positions) + shift)
    x = np.concatenate([starts[k] + m for k, m in enumerate(moved)])
    u = vertical_deviation(x, model.vertical_sigma, model.correlation_length, rng)
    out: list[SpanData] = []
    first = 0
    for s, m in zip(spans, moved, strict=True):
        n = len(m)
        presag = tuple(float(a - b) for a, b in zip(s.presag, u[first : first + n], strict=True))
        out.append(dataclasses.replace(s, dropper_positions=tuple(float(v) for v in m), presag=presag))
        first += n
    return dataclasses.replace(data, spans=tuple(out))
