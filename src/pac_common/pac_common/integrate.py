"""Fixed-step integration kept apart from the dynamics (scipy style: ``f(t, x, *args)``).

The plant and the observer hold their input constant (or interpolated) over one
sample period and need a deterministic stepper, so that a lock-step run over DDS
and the offline simulator give the same numbers bit for bit.

Compiled (numba): ``f`` is a compiled function, ``args`` a tuple of its extra
arguments.  ``inline="always"`` inlines the stepper into its caller, which is what
lets the caller be cached on disk (a compiled function passed as an argument to a
separately compiled function cannot be cached).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always")
def rk4_step(f, t, x, h, args):
    """One classical Runge-Kutta step of ``x' = f(t, x, *args)`` from ``t`` to ``t + h``."""
    k1 = f(t, x, *args)
    k2 = f(t + 0.5 * h, _axpy(x, 0.5 * h, k1), *args)
    k3 = f(t + 0.5 * h, _axpy(x, 0.5 * h, k2), *args)
    k4 = f(t + h, _axpy(x, h, k3), *args)
    # x + (h / 6) (k1 + 2 (k2 + k3) + k4), element by element in that order (one array, not six)
    out = np.empty_like(x)
    xs, o, s1, s2, s3, s4 = x.ravel(), out.ravel(), k1.ravel(), k2.ravel(), k3.ravel(), k4.ravel()
    for i in range(xs.size):
        o[i] = xs[i] + (h / 6.0) * (s1[i] + 2.0 * (s2[i] + s3[i]) + s4[i])
    return out


@njit(inline="always")
def _axpy(x, a, k):
    """x + a k as one new array (C-contiguous x and k of the same shape)."""
    out = np.empty_like(x)
    xs, o, ks = x.ravel(), out.ravel(), k.ravel()
    for i in range(xs.size):
        o[i] = xs[i] + a * ks[i]
    return out


@njit(inline="always")
def rk4_integrate(f, t0, x0, duration, substeps, args):
    """Integrate over ``duration`` with ``substeps`` equal RK4 steps."""
    h = duration / substeps
    x = x0
    for i in range(substeps):
        x = rk4_step(f, t0 + i * h, x, h, args)
    return x
