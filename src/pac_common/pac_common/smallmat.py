"""Products of the small matrices the cores use (4x4, 4x3, 4x2, 3x2), compiled as plain loops.

numba's ``@`` calls BLAS, whose per-call overhead dominates at these sizes; these loops
cost a few nanoseconds.  Results are the textbook sums in index order.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def matmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a b for 2-D a (n x m) and b (m x p)."""
    n, m, p = a.shape[0], a.shape[1], b.shape[1]
    out = np.zeros((n, p))
    for i in range(n):
        for j in range(p):
            s = 0.0
            for k in range(m):
                s += a[i, k] * b[k, j]
            out[i, j] = s
    return out


@njit(cache=True)
def matvec(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """a x for 2-D a (n x m) and 1-D x (m)."""
    n, m = a.shape
    out = np.zeros(n)
    for i in range(n):
        s = 0.0
        for k in range(m):
            s += a[i, k] * x[k]
        out[i] = s
    return out
