"""Fixed-step integration kept apart from the dynamics (scipy style: ``f(t, x)``).

The plant and the observer hold their input constant (or interpolated) over one
sample period and need a deterministic stepper, so that a lock-step run over DDS
and the offline simulator give the same numbers bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

Dynamics = Callable[[float, np.ndarray], np.ndarray]


def rk4_step(f: Dynamics, t: float, x: np.ndarray, h: float) -> np.ndarray:
    """One classical Runge-Kutta step of ``x' = f(t, x)`` from ``t`` to ``t + h``."""
    k1 = f(t, x)
    k2 = f(t + 0.5 * h, x + (0.5 * h) * k1)
    k3 = f(t + 0.5 * h, x + (0.5 * h) * k2)
    k4 = f(t + h, x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)


def rk4_integrate(f: Dynamics, t0: float, x0: np.ndarray, duration: float, substeps: int) -> np.ndarray:
    """Integrate over ``duration`` with ``substeps`` equal RK4 steps."""
    h = duration / substeps
    x = x0
    for i in range(substeps):
        x = rk4_step(f, t0 + i * h, x, h)
    return x
