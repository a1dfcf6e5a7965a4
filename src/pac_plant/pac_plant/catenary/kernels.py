"""Compiled (numba) kernels for symmetric banded matrices in LAPACK lower storage ab[k, j] = A[j+k, j].

The per-step work of the line is two banded mat-vecs and two banded Cholesky solves;
in numpy each is a dozen slicing operations (~10 us overhead each), compiled they
are one pass over the band.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def band_matvec2(a1: np.ndarray, x1: np.ndarray, a2: np.ndarray, x2: np.ndarray, out: np.ndarray) -> None:
    """out = A1 x1 + A2 x2 for symmetric banded A1, A2 (lower storage, same shape): one pass."""
    kd, n = a1.shape[0] - 1, a1.shape[1]
    for i in range(n):
        out[i] = a1[0, i] * x1[i] + a2[0, i] * x2[i]
    for j in range(n):
        y1, y2 = x1[j], x2[j]
        acc = 0.0
        top = min(kd, n - 1 - j)
        for k in range(1, top + 1):
            i = j + k
            p, q = a1[k, j], a2[k, j]
            out[i] += p * y1 + q * y2
            acc += p * x1[i] + q * x2[i]
        out[j] += acc


def chol_factor(ab: np.ndarray) -> np.ndarray:
    """The banded Cholesky factor of ``ab`` laid out for ``band_chol_solve``: (n, kd+1), row j
    holding L[j+k, j] for k = 0..kd with the diagonal inverted (cache-friendly, no division)."""
    from scipy.linalg import cholesky_banded

    cb = np.ascontiguousarray(cholesky_banded(ab, lower=True).T)
    cb[:, 0] = 1.0 / cb[:, 0]
    return cb


@numba.njit(cache=True)
def band_chol_solve(cb: np.ndarray, b: np.ndarray) -> None:
    """Solve L L^T x = b in place (b of shape (n,)); cb from ``chol_factor``."""
    n, kd = cb.shape[0], cb.shape[1] - 1
    for j in range(n):  # forward: L y = b, column-oriented
        bj = b[j] * cb[j, 0]
        b[j] = bj
        for k in range(1, min(kd, n - 1 - j) + 1):
            b[j + k] -= cb[j, k] * bj
    for j in range(n - 1, -1, -1):  # backward: L^T x = y, row-oriented
        acc = b[j]
        for k in range(1, min(kd, n - 1 - j) + 1):
            acc -= cb[j, k] * b[j + k]
        b[j] = acc * cb[j, 0]
