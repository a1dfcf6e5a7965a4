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


@numba.njit(cache=True)
def newmark_rhs(
    m: np.ndarray,
    k: np.ndarray,
    d: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    dt: float,
    alpha: float,
    beta: float,
    x1: np.ndarray,
    x2: np.ndarray,
    out: np.ndarray,
) -> None:
    """out = M (4/dt^2 d + 4/dt v + a) + C (2/dt d + v), C = alpha M + beta K (x1, x2: scratch)."""
    c0, c1, c2 = 4.0 / (dt * dt), 2.0 / dt, 4.0 / dt
    for i in range(d.shape[0]):
        w = c1 * d[i] + v[i]
        x1[i] = c0 * d[i] + c2 * v[i] + a[i] + alpha * w
        x2[i] = beta * w
    band_matvec2(m, x1, k, x2, out)


@numba.njit(cache=True)
def newmark_update(d: np.ndarray, v: np.ndarray, a: np.ndarray, d_new: np.ndarray, dt: float) -> None:
    """Average-acceleration update in place: a, v from the new displacement; d <- d_new."""
    c0, c2, h = 4.0 / (dt * dt), 4.0 / dt, 0.5 * dt
    for i in range(d.shape[0]):
        a_new = c0 * (d_new[i] - d[i]) - c2 * v[i] - a[i]
        v[i] += h * (a[i] + a_new)
        a[i] = a_new
        d[i] = d_new[i]
