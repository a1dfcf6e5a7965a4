"""Compiled (numba) kernels for symmetric banded matrices in LAPACK lower storage ab[k, j] = A[j+k, j].

The per-step work of the line is two banded mat-vecs and two banded Cholesky solves;
in numpy each is a dozen slicing operations (~10 us overhead each), compiled they
are one pass over the band.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def band_matvec(ab: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    """out = A x for symmetric banded A."""
    kd, n = ab.shape[0] - 1, ab.shape[1]
    for i in range(n):
        out[i] = ab[0, i] * x[i]
    for j in range(n):
        xj = x[j]
        acc = 0.0
        for k in range(1, kd + 1):
            i = j + k
            if i >= n:
                break
            a = ab[k, j]
            out[i] += a * xj
            acc += a * x[i]
        out[j] += acc


@numba.njit(cache=True)
def band_chol_solve(cb: np.ndarray, b: np.ndarray) -> None:
    """Solve L L^T x = b in place for b of shape (n, m); cb = cholesky_banded(A, lower=True)."""
    kd, n = cb.shape[0] - 1, cb.shape[1]
    m = b.shape[1]
    for j in range(n):  # forward: L y = b (column-oriented)
        d = cb[0, j]
        for c in range(m):
            b[j, c] /= d
        for k in range(1, kd + 1):
            i = j + k
            if i >= n:
                break
            lij = cb[k, j]
            for c in range(m):
                b[i, c] -= lij * b[j, c]
    for j in range(n - 1, -1, -1):  # backward: L^T x = y
        for k in range(1, kd + 1):
            i = j + k
            if i >= n:
                break
            lij = cb[k, j]
            for c in range(m):
                b[j, c] -= lij * b[i, c]
        d = cb[0, j]
        for c in range(m):
            b[j, c] /= d
