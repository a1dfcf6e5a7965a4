"""Newmark's average-acceleration step (gamma = 1/2, beta = 1/4) on banded M, K with Rayleigh
damping C = alpha M + beta K: the right-hand side before the solve and the update after it
(compiled; the plain and the padded, lane-parallel forms).
"""

from __future__ import annotations

import numba
import numpy as np

from . import lanes
from .banded import KD, band_matvec2


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


LAG = 4  # blocks between making z and reading it (``newmark_rhs_mass``)


@numba.njit(cache=True, fastmath={"contract"})
def newmark_rhs_mass(
    mp: np.ndarray,
    d: np.ndarray,
    v: np.ndarray,
    a: np.ndarray,
    dt: float,
    alpha: float,
    beta: float,
    z: np.ndarray,
    tail: np.ndarray,
    out: np.ndarray,
) -> None:
    """The Newmark right-hand side with one banded product (M only): out = M z and tail = g w
    such that A^-1 (``newmark_rhs``) = A^-1 out + tail.

    With w = 2/dt d + v and x1 = 4/dt^2 d + 4/dt v + a + alpha w, the right-hand side is
    M x1 + beta K w; A = (1 + 2/dt beta) K + (4/dt^2 + 2/dt alpha) M gives
    A^-1 K w = (w - (4/dt^2 + 2/dt alpha) A^-1 M w) / (1 + 2/dt beta), hence
    z = x1 - g (4/dt^2 + 2/dt alpha) w with g = beta / (1 + 2/dt beta). Exact algebra: K (its
    band and its flops) leaves the step. ``mp``: ``pad_band(M)``; z of length n + 2 KD, zero ends."""
    n = d.shape[0]
    c0, c1, c2 = 4.0 / (dt * dt), 2.0 / dt, 4.0 / dt
    g = beta / (1.0 + c1 * beta)
    gm = g * (c0 + c1 * alpha)
    W = lanes.WIDTH
    stride = mp.shape[1]
    whole = n - n % W
    # z is made LAG blocks of eight rows ahead of the product that reads it (rows i-KD .. i+7+KD):
    # read back while still in the first-level cache, but after its stores have left the store
    # buffer (an unaligned load that straddles a pending vector store stalls).
    nz = z.shape[0]
    zp = zc = lanes.zeros()
    vc0, vc1, vc2 = lanes.splat(c0), lanes.splat(c1), lanes.splat(c2)
    valpha, vgm, vg = lanes.splat(alpha), lanes.splat(gm), lanes.splat(g)
    for i in range(0, whole + LAG * W, W):
        ahead = i
        if ahead < whole:  # z, tail of rows ahead .. ahead+7
            dd, vv = lanes.load(d, ahead), lanes.load(v, ahead)
            w = lanes.fma(vc1, dd, vv)
            x1 = lanes.add(lanes.fma(vc0, dd, lanes.mul(vc2, vv)), lanes.load(a, ahead))
            lanes.store(z, KD + ahead, lanes.fnma(vgm, w, lanes.fma(valpha, w, x1)))
            lanes.store(tail, ahead, lanes.mul(vg, w))
        elif ahead == whole:
            for r in range(whole, n):  # the rows left over, the same arithmetic one at a time
                w1 = c1 * d[r] + v[r]
                z[KD + r] = (c0 * d[r] + c2 * v[r] + a[r]) + alpha * w1 - gm * w1
                tail[r] = g * w1
        if i < LAG * W:
            continue
        # The product for rows r = i-LAG*8 .. +7: out[r] = sum of M[r, r+k] z[r+k] over the band,
        # z[r+k] taken from the blocks before, at and after r by a shuffle (one load per block).
        r = i - LAG * W
        j = KD + r
        if r == 0:  # (z has KD, not 8, zeros in front: nothing is read before it)
            zp, zc = lanes.load_masked(z, j - W, 0, nz), lanes.load(z, j)
        zn = lanes.load_masked(z, j + W, 0, nz)
        acc = lanes.mul(lanes.load(mp, j), zc)
        acc = lanes.fma(lanes.load(mp, stride + j), lanes.window(zc, zn, 1), acc)
        acc = lanes.fma(lanes.load(mp, stride + j - 1), lanes.window(zp, zc, 7), acc)
        acc = lanes.fma(lanes.load(mp, 2 * stride + j), lanes.window(zc, zn, 2), acc)
        acc = lanes.fma(lanes.load(mp, 2 * stride + j - 2), lanes.window(zp, zc, 6), acc)
        acc = lanes.fma(lanes.load(mp, 3 * stride + j), lanes.window(zc, zn, 3), acc)
        acc = lanes.fma(lanes.load(mp, 3 * stride + j - 3), lanes.window(zp, zc, 5), acc)
        acc = lanes.fma(lanes.load(mp, 4 * stride + j), lanes.window(zc, zn, 4), acc)
        acc = lanes.fma(lanes.load(mp, 4 * stride + j - 4), lanes.window(zp, zc, 4), acc)
        acc = lanes.fma(lanes.load(mp, 5 * stride + j), lanes.window(zc, zn, 5), acc)
        acc = lanes.fma(lanes.load(mp, 5 * stride + j - 5), lanes.window(zp, zc, 3), acc)
        lanes.store(out, r, acc)
        zp, zc = zc, zn
    for r in range(whole, n):  # the rows left over (M[r, r-k] = mp[k, KD+r-k])
        j = KD + r
        acc = mp[0, j] * z[j]
        for k in range(1, KD + 1):
            acc = mp[k, j] * z[j + k] + acc
            acc = mp[k, j - k] * z[j - k] + acc
        out[r] = acc
