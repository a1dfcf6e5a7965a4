"""Filtered contact-force reference F_r(t) and its first three derivatives.

The command F_c(t) is piecewise constant; the filter is p^4 / (s + p)^4, so F_r
has continuous derivatives up to the third order, which the backstepping law
needs (z1r = F_r / k_hat and alpha_2' need z1r''', PAPER_NOTES item 4).  The
response is written in closed form as a sum of filtered steps, so F_r at any
tick is a pure function of time: no filter state to drift, lose or replay.
"""

from __future__ import annotations

import math

import numpy as np

from .parameters import ReferenceParameters

#: A step older than this many filter time constants contributes below 1e-15 of its size.
_FORGET_AFTER = 60.0


def filtered_step(tau: float, p: float) -> np.ndarray:
    """Unit step through p^4/(s+p)^4, and derivatives 1..3, at tau >= 0 after the step.

    s(tau) = 1 - e^{-x} (1 + x + x^2/2 + x^3/6) with x = p tau; s' = p^4 tau^3 e^{-p tau} / 6.
    """
    if tau <= 0.0:
        return np.zeros(4)
    x = p * tau
    e = math.exp(-x)
    s0 = 1.0 - e * (1.0 + x + x * x / 2.0 + x**3 / 6.0)
    s1 = p * e * x**3 / 6.0
    s2 = p * p * e * (x * x / 2.0 - x**3 / 6.0)
    s3 = p**3 * e * (x - x * x + x**3 / 6.0)
    return np.array([s0, s1, s2, s3])


class ForceReference:
    """F_r and its derivatives (F_r, F_r', F_r'', F_r''') at time t."""

    def __init__(self, params: ReferenceParameters) -> None:
        self.params = params

    def steps_before(self, t: float) -> list[tuple[float, float]]:
        """(time, size) of the command's steps at or before t that still matter."""
        p = self.params
        horizon = t - _FORGET_AFTER / p.filter_bandwidth
        if p.shape == "constant":
            steps = [(0.0, p.force_amplitude)]
        elif p.shape == "step":
            steps = [(0.0, p.force_initial), (p.step_time, p.force_amplitude - p.force_initial)]
        else:
            half = 0.5 * p.period
            first = max(0, math.floor(horizon / half))
            last = math.floor(t / half)
            steps = [
                (j * half, p.force_amplitude if j % 2 == 0 else -p.force_amplitude)
                for j in range(first, last + 1)
            ]
            # Levels before the first kept step: the command was at its level since long ago.
            if first > 0 and first % 2 == 1:
                steps.insert(0, (-math.inf, p.force_amplitude))
        return [(ts, size) for ts, size in steps if ts <= t]

    def at(self, t: float) -> np.ndarray:
        """(F_r, F_r', F_r'', F_r''') at time t [N, N/s, N/s^2, N/s^3]."""
        p = self.params.filter_bandwidth
        out = np.zeros(4)
        for ts, size in self.steps_before(t):
            if ts == -math.inf:
                out[0] += size
            else:
                out += size * filtered_step(t - ts, p)
        return out

    def command(self, t: float) -> float:
        """The unfiltered command F_c(t) [N]."""
        return sum(size for ts, size in self.steps_before(t) if ts <= t)
