"""Filtered contact-force reference F_r(t) and its first three derivatives.

The command F_c(t) is piecewise constant; the filter is p^4 / (s + p)^4, so F_r
has continuous derivatives up to the third order, which the backstepping law
needs (z1r = F_r / k_hat and alpha_2' need z1r''', docs/paper_errata.md #4).  The
response is written in closed form as a sum of filtered steps, so F_r at any
tick is a pure function of time: no filter state to drift, lose or replay.
Compiled (numba): the batch closed loop evaluates it inside compiled code.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .parameters import ReferenceParameters

#: A step older than this many filter time constants contributes below 1e-15 of its size.
_FORGET_AFTER = 60.0

#: ReferenceParameters.shape as the integer the compiled functions take.
SHAPE_CODES = {"constant": 0, "step": 1, "square": 2}


@njit(cache=True)
def filtered_step(tau: float, p: float) -> np.ndarray:
    """Unit step through p^4/(s+p)^4, and derivatives 1..3, at tau >= 0 after the step (an array)."""
    s0, s1, s2, s3 = filtered_step4(tau, p)
    return np.array([s0, s1, s2, s3])


@njit(cache=True)
def filtered_step4(tau: float, p: float) -> tuple[float, float, float, float]:
    """:func:`filtered_step` as four numbers.

    s(tau) = 1 - e^{-x} (1 + x + x^2/2 + x^3/6) with x = p tau; s' = p^4 tau^3 e^{-p tau} / 6.
    """
    if tau <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    x = p * tau
    e = math.exp(-x)
    s0 = 1.0 - e * (1.0 + x + x * x / 2.0 + x**3 / 6.0)
    s1 = p * e * x**3 / 6.0
    s2 = p * p * e * (x * x / 2.0 - x**3 / 6.0)
    s3 = p**3 * e * (x - x * x + x**3 / 6.0)
    return s0, s1, s2, s3


@njit(cache=True)
def reference_steps(
    t: float, shape: int, amplitude: float, initial: float, step_time: float, period: float, bandwidth: float
) -> tuple[np.ndarray, np.ndarray]:
    """(times, sizes) of the command's steps at or before t that still matter.

    A time of -inf stands for "the command was at this level since long ago".
    """
    if shape == 0:
        times, sizes = np.array([0.0]), np.array([amplitude])
    elif shape == 1:
        times, sizes = np.array([0.0, step_time]), np.array([initial, amplitude - initial])
    else:
        half = 0.5 * period
        horizon = t - _FORGET_AFTER / bandwidth
        first = max(0, math.floor(horizon / half))
        last = math.floor(t / half)
        # Levels before the first kept step: the command was at its level since long ago.
        lead = 1 if (first > 0 and first % 2 == 1) else 0
        n = max(0, last - first + 1)
        times, sizes = np.empty(lead + n), np.empty(lead + n)
        if lead:
            times[0], sizes[0] = -math.inf, amplitude
        for i in range(n):
            j = first + i
            times[lead + i] = j * half
            sizes[lead + i] = amplitude if j % 2 == 0 else -amplitude
    keep = times <= t
    return times[keep], sizes[keep]


@njit(cache=True)
def reference_at(
    t: float, shape: int, amplitude: float, initial: float, step_time: float, period: float, bandwidth: float
) -> np.ndarray:
    """(F_r, F_r', F_r'', F_r''') at time t: the sum of the filtered steps (an array)."""
    f0, f1, f2, f3 = reference_at4(t, shape, amplitude, initial, step_time, period, bandwidth)
    return np.array([f0, f1, f2, f3])


@njit(cache=True)
def _add_step(acc, t, time, size, bandwidth):
    """acc + the filtered step of ``size`` at ``time`` (a time of -inf: a level since long ago)."""
    f0, f1, f2, f3 = acc
    if not time <= t:  # not yet: reference_steps keeps the steps at or before t only
        return acc
    if time == -math.inf:
        return f0 + size, f1, f2, f3
    s0, s1, s2, s3 = filtered_step4(t - time, bandwidth)
    return f0 + size * s0, f1 + size * s1, f2 + size * s2, f3 + size * s3


@njit(cache=True)
def reference_at4(
    t: float, shape: int, amplitude: float, initial: float, step_time: float, period: float, bandwidth: float
) -> tuple[float, float, float, float]:
    """:func:`reference_at` as four numbers, without building the step list: the steps of
    :func:`reference_steps` in its order, summed as it sums them (nothing allocated)."""
    acc = (0.0, 0.0, 0.0, 0.0)
    if shape == 0:
        return _add_step(acc, t, 0.0, amplitude, bandwidth)
    if shape == 1:
        acc = _add_step(acc, t, 0.0, initial, bandwidth)
        return _add_step(acc, t, step_time, amplitude - initial, bandwidth)
    half = 0.5 * period
    horizon = t - _FORGET_AFTER / bandwidth
    first = max(0, math.floor(horizon / half))
    last = math.floor(t / half)
    if first > 0 and first % 2 == 1:  # the level before the first kept step, since long ago
        acc = _add_step(acc, t, -math.inf, amplitude, bandwidth)
    for j in range(first, last + 1):
        acc = _add_step(acc, t, j * half, amplitude if j % 2 == 0 else -amplitude, bandwidth)
    return acc


def reference_args(p: ReferenceParameters) -> tuple[int, float, float, float, float, float]:
    """The numbers :func:`reference_at` takes after t."""
    return (
        SHAPE_CODES[p.shape],
        float(p.force_amplitude),
        float(p.force_initial),
        float(p.step_time),
        float(p.period),
        float(p.filter_bandwidth),
    )


class ForceReference:
    """F_r and its derivatives (F_r, F_r', F_r'', F_r''') at time t."""

    def __init__(self, params: ReferenceParameters) -> None:
        self.params = params
        self._args_of: ReferenceParameters | None = None
        self._args: tuple = ()

    @property
    def args(self) -> tuple[int, float, float, float, float, float]:
        """:func:`reference_args` of the current ``params`` (recomputed when they are replaced)."""
        if self._args_of is not self.params:
            self._args, self._args_of = reference_args(self.params), self.params
        return self._args

    def steps_before(self, t: float) -> list[tuple[float, float]]:
        """(time, size) of the command's steps at or before t that still matter."""
        times, sizes = reference_steps(float(t), *self.args)
        return [(float(ts), float(size)) for ts, size in zip(times, sizes, strict=True)]

    def at(self, t: float) -> np.ndarray:
        """(F_r, F_r', F_r'', F_r''') at time t [N, N/s, N/s^2, N/s^3]."""
        return reference_at(float(t), *self.args)

    def command(self, t: float) -> float:
        """The unfiltered command F_c(t) [N]."""
        return sum(size for ts, size in self.steps_before(t) if ts <= t)
