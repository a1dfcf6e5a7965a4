"""The actuator's compiled steps: the mean force over a tick for the command held over it.

Each step is ``<step>_apply(p, s, u) -> float`` on the ``ACTUATOR_PARAMS`` / ``ACTUATOR_STATE``
records (``actuators``); an actuator variant names its step in its registry line
(``ActuatorModel.step``), and the plant's step reaches it through ``actuator_dispatch``, generated
from ``actuators.ACTUATOR_STEPS``. The model and its closed form: ``actuators``' docstring.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def lag_rate(f0: float, d: float, h: float, tau: float, rate: float) -> tuple[float, float]:
    """(f(h), integral of f over [0, h]) for df/dt = clip((d - f) / tau, -rate, rate), f(0) = f0.

    While |d - f| > rate tau the rate limit binds (a ramp); from there the lag's own rate is below
    it and f = d - (d - f1) exp(-t / tau). tau = 0: a ramp to d, then d. rate = inf: no ramp.
    """
    e = d - f0
    sign = 1.0 if e >= 0.0 else -1.0
    knee = rate * tau if rate < np.inf else np.inf
    integral = 0.0
    rest = h
    f = f0
    if abs(e) > knee:
        ramp = (abs(e) - knee) / rate  # time until the lag takes over
        if ramp >= h:
            return f0 + sign * rate * h, f0 * h + 0.5 * sign * rate * h * h
        integral = f0 * ramp + 0.5 * sign * rate * ramp * ramp
        f = d - sign * knee
        rest = h - ramp
        e = d - f
    if tau > 0.0:
        g = math.exp(-rest / tau)
        return d - e * g, integral + d * rest - e * tau * (1.0 - g)
    return d, integral + d * rest


@njit(cache=True, error_model="numpy")
def ideal_apply(p, s, u: float) -> float:
    """The command is the force: ``u`` itself (not u * h / h), so a run without an actuator model
    has today's numbers bit for bit."""
    return u


@njit(cache=True, error_model="numpy")
def lag_apply(p, s, u: float) -> float:
    """Transport delay, range, rate limit and first-order lag (``actuators``' docstring); advances ``s``."""
    ring = s.ring
    size = ring.shape[0]
    s.head = (s.head + 1) % size
    ring[s.head] = u
    n = p.delay_ticks
    h = p.dt
    late = min(max(ring[(s.head - n) % size], p.low), p.high)  # u_(k-n), clipped to the range
    f, total = s.force, 0.0
    if p.delay_fraction > 0.0:
        early = min(max(ring[(s.head - n - 1) % size], p.low), p.high)  # u_(k-n-1)
        h1 = p.delay_fraction * h
        f, part = lag_rate(f, early, h1, p.tau, p.rate)
        total += part
        h -= h1
    f, part = lag_rate(f, late, h, p.tau, p.rate)
    s.force = f
    return (total + part) / p.dt
