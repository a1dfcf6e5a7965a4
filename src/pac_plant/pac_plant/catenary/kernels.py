"""Compiled (numba) kernels for symmetric banded matrices in LAPACK lower storage ab[k, j] = A[j+k, j].

The per-step work of the line is two banded mat-vecs and two banded Cholesky solves;
in numpy each is a dozen slicing operations (~10 us overhead each), compiled they
are one pass over the band.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from . import lanes


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
def band_inverse_band(cb: np.ndarray) -> np.ndarray:
    """The band of A^-1 (lower storage: z[k, j] = (A^-1)[j+k, j], k = 0..kd) from A's Cholesky
    factor ``cb`` (``chol_factor``): the Takahashi recurrence on A^-1 = L^-T L^-1, i.e.
    L^T Z = L^-1, whose upper-triangle rows read, for j >= i,
    Z[i, j] = (delta_ij / L[i, i] - sum_{k=i+1}^{i+kd} L[k, i] Z[k, j]) / L[i, i];
    every Z[k, j] it needs lies in the band (k, j in (i, i+kd]), computed at a later row. O(n kd^2)
    against O(n^2 kd) for the band by solves (a whole line: 10 ms against 14 s)."""
    n, kd = cb.shape[0], cb.shape[1] - 1
    z = np.zeros((kd + 1, n))
    for i in range(n - 1, -1, -1):
        top = min(kd, n - 1 - i)
        inv = cb[i, 0]  # 1 / L[i, i]
        for d in range(top, -1, -1):  # Z[i, i+d]: off the diagonal first, the diagonal last
            j = i + d
            acc = inv if d == 0 else 0.0
            for m in range(1, top + 1):
                k = i + m  # Z[k, j], k and j both in (i, i + kd]: in the band, either way round
                zkj = z[k - j, j] if k >= j else z[j - k, k]
                acc -= cb[i, m] * zkj
            z[d, i] = acc * inv
    return z


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


# -- the fast path's kernels: padded band product, two-chain solve ------------------------------------
#: Rows of overlap (20 nodes) each chunk of ``chunk_solve`` carries past its own part. A^-1 decays by
#: about 10x per node along the line (the implicit step's mass term 4/dt^2 M dominates A), so what
#: the truncated chunk misses at its inner rows is < 1e-19 of the solution: rounding.
CHUNK_OVERLAP = 80
#: Sub-diagonals the fast kernels carry. The band is 7 wide (4 DOFs per node) but the wires'
#: matrices couple (w, w') of one wire at node i only with node i+1 of the same wire, so M, K and
#: the Cholesky factor of A (fill stays inside this profile) are exactly zero on diagonals 6 and
#: 7: skipping them changes no result and saves 2 of 7 multiply-adds per row (``narrow_band``).
KD = 5


def narrow_band(ab: np.ndarray) -> np.ndarray:
    """Rows 0..KD of ``ab`` (LAPACK lower storage); raises if a dropped diagonal is not exactly zero."""
    if np.any(ab[KD + 1 :] != 0.0):
        raise ValueError(f"the band has non-zero entries beyond {KD} sub-diagonals")
    return np.ascontiguousarray(ab[: KD + 1])


def pad_band(ab: np.ndarray) -> np.ndarray:
    """``narrow_band(ab)`` with KD zero columns in front: row-wise products can then read
    A[i, i-k] = ab[k, i-k] for every i without a branch (``newmark_rhs_mass``)."""
    nb = narrow_band(ab)
    out = np.zeros((KD + 1, nb.shape[1] + KD))
    out[:, KD:] = nb
    return out


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


CHUNKS = lanes.WIDTH  # independent dependency chains in ``chunk_solve``, one per vector lane


def chunk_factor(ab: np.ndarray, overlap: int = CHUNK_OVERLAP) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LDL^T factors of CHUNKS overlapping diagonal blocks of A for ``chunk_solve``, lane-major.

    Returns (factors (lc + 2 KD, KD + 1, CHUNKS), lc a multiple of CHUNKS: row r + KD of chunk c
    holds the unit lower
    factor's L[r, r-k] for k = 1..KD and 1/D[r] at k = 0, zero rows around; starts (CHUNKS,):
    first row of each chunk in A; bounds (CHUNKS + 1,): chunk c delivers rows bounds[c] ..
    bounds[c+1], with at least ``overlap`` rows of its block on either side of them (where A
    goes on)). LDL^T rather than L L^T: each row of either sweep then waits on one fused
    multiply-add of the previous row, not on a multiply-add and a scaling."""
    from scipy.linalg import cholesky_banded

    n, kd = ab.shape[1], KD
    bounds = np.array([round(c * n / CHUNKS) for c in range(CHUNKS + 1)], dtype=np.int64)
    lc = -(-(int(np.max(np.diff(bounds))) + 2 * overlap) // CHUNKS) * CHUNKS  # whole groups of 8 rows
    if lc > n:
        raise ValueError(f"chunk_factor: {n} unknowns, fewer than one chunk of {lc} rows")
    starts = np.array([min(max(bounds[c] - overlap, 0), n - lc) for c in range(CHUNKS)], dtype=np.int64)
    factors = np.zeros((lc + 2 * kd, kd + 1, CHUNKS))
    for c in range(CHUNKS):
        sub = ab[:, starts[c] : starts[c] + lc].copy()
        for k in range(1, sub.shape[0]):
            sub[k, lc - k :] = 0.0  # couplings that leave the block
        low = narrow_band(cholesky_banded(sub, lower=True))  # low[k, j] = L[j+k, j]
        diag = low[0].copy()
        for k in range(1, kd + 1):
            factors[kd + k : kd + lc, k, c] = low[k, : lc - k] / diag[: lc - k]
        factors[kd : kd + lc, 0, c] = 1.0 / (diag * diag)
    return factors, starts, bounds


@numba.njit(cache=True)
def chunk_solve(
    factors: np.ndarray,
    starts: np.ndarray,
    bounds: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
    addend: np.ndarray,
) -> None:
    """Solve A x = b in place (b of shape (n,)) as CHUNKS independent banded LDL^T solves of
    overlapping diagonal blocks of A (``chunk_factor``), one block per vector lane: one
    banded solve is a chain (each row waits for the previous one), eight of them side by
    side fill the vector unit. The five previous rows stay in registers; the newest term is
    subtracted last (the chain per row is one fused multiply-add). ``w``: scratch
    (lc + 2 KD, CHUNKS). ``addend`` (length n, or empty: none) is added to the solution on
    the way out. Equal to ``band_chol_solve`` to rounding (``CHUNK_OVERLAP``)."""
    lc = factors.shape[0] - 2 * KD
    if w.shape[0] < lc + KD or w.shape[1] != CHUNKS:
        raise ValueError("chunk_solve: scratch w too small (rows: at least the factors')")
    f = factors
    row = (KD + 1) * CHUNKS  # elements per row of f
    p1 = p2 = p3 = p4 = p5 = lanes.zeros()
    for j in range(KD, KD + lc):  # forward: L y = b; p1..p5 = y[j-1]..y[j-5], lane c = chunk c
        o = j * row
        acc = lanes.gather(b, starts, j - KD)  # b[starts[c] + j - KD]
        acc = lanes.fnma(lanes.load(f, o + 5 * CHUNKS), p5, acc)
        acc = lanes.fnma(lanes.load(f, o + 4 * CHUNKS), p4, acc)
        acc = lanes.fnma(lanes.load(f, o + 3 * CHUNKS), p3, acc)
        acc = lanes.fnma(lanes.load(f, o + 2 * CHUNKS), p2, acc)
        y = lanes.fnma(lanes.load(f, o + CHUNKS), p1, acc)
        lanes.store(w, j * CHUNKS, y)
        p5, p4, p3, p2, p1 = p4, p3, p2, p1, y
    # Backward: D L^T x = y, eight rows at a time; each group of eight solutions is turned into
    # eight runs of the natural order (an 8 x 8 transpose) and written out at once, chunk c
    # writing (plus the addend) only the rows it delivers.
    add = addend.shape[0] != 0
    p1 = p2 = p3 = p4 = p5 = lanes.zeros()
    for j in range(KD + lc - CHUNKS, KD - 1, -CHUNKS):
        x7 = _back_row(f, w, j + 7, p1, p2, p3, p4, p5)
        x6 = _back_row(f, w, j + 6, x7, p1, p2, p3, p4)
        x5 = _back_row(f, w, j + 5, x6, x7, p1, p2, p3)
        x4 = _back_row(f, w, j + 4, x5, x6, x7, p1, p2)
        x3 = _back_row(f, w, j + 3, x4, x5, x6, x7, p1)
        x2 = _back_row(f, w, j + 2, x3, x4, x5, x6, x7)
        x1 = _back_row(f, w, j + 1, x2, x3, x4, x5, x6)
        x0 = _back_row(f, w, j, x1, x2, x3, x4, x5)
        p1, p2, p3, p4, p5 = x0, x1, x2, x3, x4
        cols = lanes.transpose((x0, x1, x2, x3, x4, x5, x6, x7))
        for c in range(CHUNKS):
            r, lo, hi = starts[c] + j - KD, bounds[c], bounds[c + 1]
            x = cols[c]
            if add:
                x = lanes.add(x, lanes.load_masked(addend, r, lo, hi))
            lanes.store_masked(b, r, x, lo, hi)


@numba.njit(cache=True, inline="always")
def _back_row(
    f: np.ndarray,
    w: np.ndarray,
    j: int,
    p1: lanes.Lanes,
    p2: lanes.Lanes,
    p3: lanes.Lanes,
    p4: lanes.Lanes,
    p5: lanes.Lanes,
) -> lanes.Lanes:
    """Row j of the backward sweep of ``chunk_solve`` (p1..p5: the solution at rows j+1..j+5)."""
    row = (KD + 1) * CHUNKS
    acc = lanes.mul(lanes.load(w, j * CHUNKS), lanes.load(f, j * row))
    acc = lanes.fnma(lanes.load(f, (j + 5) * row + 5 * CHUNKS), p5, acc)
    acc = lanes.fnma(lanes.load(f, (j + 4) * row + 4 * CHUNKS), p4, acc)
    acc = lanes.fnma(lanes.load(f, (j + 3) * row + 3 * CHUNKS), p3, acc)
    acc = lanes.fnma(lanes.load(f, (j + 2) * row + 2 * CHUNKS), p2, acc)
    return lanes.fnma(lanes.load(f, (j + 1) * row + CHUNKS), p1, acc)


# -- the whole Newmark step of line + pantograph, compiled (``integrator.ContactSimulation``) ----------
MAX_ACTIVE_SET_PASSES = 25
#: Nodes on each side of node i kept of A^-1 e_i (w and w' of the contact wire): beyond them the
#: column is < 1e-19 of its peak (``CHUNK_OVERLAP``).
UNIT_REACH = 20

# Indices into StepState.scalars / StepState.counters.
X, OFFSET, DELTA, INPUT_FORCE = 0, 1, 2, 3
IN_CONTACT, STEPS, PASSES_MAX, UNCONVERGED, N_SLACK, YC_LO, YC_HI = 0, 1, 2, 3, 4, 5, 6
#: ``fe_step`` return codes.
STEP_OK, STEP_OFF_LINE = 0, 1


class StepConstants(NamedTuple):
    """What does not change during a run: line matrices, factor, droppers, pantograph, numbers.

    ``m_pad`` = ``pad_band(M)`` (the step needs no K, see ``newmark_rhs_mass``);
    ``ydrop[:, j]`` is A^-1 g_j for dropper j (its rows at the contact DOFs are read),
    ``ydrop_patches[j]`` the same column on the rows ``unit_start`` of the dropper's node +
    0..width-1 (the update adds it for a slack dropper; outside, the column is < 1e-18 of its
    peak), ``ddrop`` = G^T A^-1 G.
    ``numbers`` = (dt, speed, alpha, beta, kp, c0, c1, length, span, shift_at);
    ``indices`` = (head, input, endless, shift_dofs, droppers_per_span, controlled contact) (head
    and input: the controlled pantograph's, in the stacked pantograph vector).
    Contact k (one per pantograph, the pantographs' DOFs stacked with the controlled one's first):
    ``p_heads[k]`` / ``p_inputs[k]`` its head and input DOF, ``p_lag[k]`` its distance behind x
    [m], ``p_uplift[k]`` the force held on its input (ignored for the controlled one) [N].
    ``y_rest`` = A^-1 ``Line.rest_load()`` where droppers hang slack at rest, else empty.
    """

    m_pad: np.ndarray
    chol: np.ndarray
    chunk_factors: np.ndarray
    chunk_starts: np.ndarray
    chunk_bounds: np.ndarray
    x_nodes: np.ndarray
    w_static: np.ndarray
    ydrop: np.ndarray
    ydrop_patches: np.ndarray
    ddrop: np.ndarray
    kdrop: np.ndarray
    e0: np.ndarray
    dwc: np.ndarray
    dwm: np.ndarray
    fixed: np.ndarray
    p_mass: np.ndarray
    p_damping: np.ndarray
    p_ainv: np.ndarray
    p_ground: np.ndarray
    numbers: np.ndarray
    indices: np.ndarray
    p_heads: np.ndarray
    p_inputs: np.ndarray
    p_lag: np.ndarray
    p_uplift: np.ndarray
    y_rest: np.ndarray


class StepState(NamedTuple):
    """The integrator's whole state, mutated in place by ``fe_step``.

    ``scalars`` = (x, offset, delta, input_force); ``counters`` = (in_contact, steps,
    active_set_passes_max, active_set_unconverged, n_slack, the range of ``work[1]`` that is
    not zero); ``slack[:n_slack]`` the slack droppers (ascending); ``unit_patches[i, r]`` =
    A^-1 e_(4i+r) on the rows ``unit_start(i)`` + 0..width-1 (``unit_ready[i]``: computed);
    ``work`` (1 + contacts, n): scratch and A^-1 g_k of contact k in row 1 + k, not zero on
    ``yc_range[k]`` only; ``padded`` (2, n + 2 KD), ``chunk_work``: scratch. ``deltas[k]``,
    ``touching[k]``: penetration and contact of contact k (the controlled one's also in
    scalars[DELTA], counters[IN_CONTACT]).
    """

    d: np.ndarray
    v: np.ndarray
    a: np.ndarray
    p: np.ndarray
    vp: np.ndarray
    ap: np.ndarray
    roof_rest: np.ndarray
    scalars: np.ndarray
    counters: np.ndarray
    slack: np.ndarray
    unit_patches: np.ndarray
    unit_ready: np.ndarray
    work: np.ndarray
    padded: np.ndarray
    chunk_work: np.ndarray
    deltas: np.ndarray
    touching: np.ndarray
    yc_range: np.ndarray


@numba.njit(cache=True)
def hermite_weights(x_nodes: np.ndarray, x: float) -> tuple[int, np.ndarray]:
    """(element, Hermite weights) of position x: ``Line.locate`` + ``hermite_shape`` (x on the line)."""
    e = int(np.searchsorted(x_nodes, x, side="right")) - 1
    e = min(max(e, 0), x_nodes.shape[0] - 2)
    h = x_nodes[e + 1] - x_nodes[e]
    xi = (x - x_nodes[e]) / h
    x2, x3 = xi * xi, xi * xi * xi
    n = np.empty(4)
    n[0] = 1 - 3 * x2 + 2 * x3
    n[1] = h * (xi - 2 * x2 + x3)
    n[2] = 3 * x2 - 2 * x3
    n[3] = h * (x3 - x2)
    return e, n


@numba.njit(cache=True)
def unit_start(n_dof: int, width: int, node: int) -> int:
    """First row of the stored part of A^-1 e_i for the DOFs of ``node`` (UNIT_REACH nodes back)."""
    return min(max(4 * (node - UNIT_REACH), 0), n_dof - width)


@numba.njit(cache=True)
def _unit_patches(c: StepConstants, s: StepState, node: int) -> None:
    """A^-1 e_i for w, w' of the contact wire at ``node`` (two banded solves, once per node)."""
    if s.unit_ready[node]:
        return
    n, width = s.d.shape[0], s.unit_patches.shape[2]
    lo = unit_start(n, width, node)
    col = s.work[0]
    for r in range(2):
        col[:] = 0.0
        col[4 * node + r] = 1.0
        chunk_solve(c.chunk_factors, c.chunk_starts, c.chunk_bounds, col, s.chunk_work, col[:0])
        s.unit_patches[node, r, :] = col[lo : lo + width]
    s.unit_ready[node] = 1


@numba.njit(cache=True)
def prepare_unit_patches(c: StepConstants, s: StepState, node_from: int, node_to: int) -> None:
    """The contact columns of nodes node_from .. node_to (inclusive) now, not at their first use."""
    for node in range(max(node_from, 0), min(node_to, s.unit_ready.shape[0] - 1) + 1):
        _unit_patches(c, s, node)


@numba.njit(cache=True)
def shift_window(c: StepConstants, s: StepState) -> None:
    """Move the window one span forward: states shift back one span, the new span is at rest."""
    sh, dps = c.indices[3], c.indices[4]
    for vec in (s.d, s.v, s.a):
        n = vec.shape[0]
        vec[: n - sh] = vec[sh:].copy()
        vec[n - sh :] = 0.0
        vec[c.fixed] = 0.0
    ns, kept = s.counters[N_SLACK], 0
    for q in range(ns):
        if s.slack[q] >= dps:
            s.slack[kept] = s.slack[q] - dps
            kept += 1
    s.counters[N_SLACK] = kept
    s.scalars[X] -= c.numbers[8]
    s.scalars[OFFSET] += c.numbers[8]


@numba.njit(cache=True)
def _woodbury_coefficients(
    c: StepConstants,
    slack: np.ndarray,
    active: np.ndarray,
    gc_y: np.ndarray,
    gc_yc: np.ndarray,
    gc_ydrop: np.ndarray,
    gd_y: np.ndarray,
    gd_yc: np.ndarray,
    ws_x: np.ndarray,
) -> np.ndarray:
    """r - z of q = y + Y (r - z), z = cap^-1 U^T (y + Y r), cap = S^-1 + U^T A^-1 U: U = the slack
    droppers' g_j, then the contacts in ``active`` (contact k: its row k of the gc_ arrays)."""
    kp = c.numbers[4]
    ns = slack.shape[0]
    m = ns + active.shape[0]
    cap = np.zeros((m, m))
    uy = np.zeros(m)
    r = np.zeros(m)
    sinv = np.empty(m)
    for i in range(ns):
        si = slack[i]
        for j in range(ns):
            cap[i, j] = c.ddrop[si, slack[j]]
        cap[i, i] -= 1.0 / c.kdrop[si]
        uy[i] = gd_y[si]
        r[i] = c.kdrop[si] * c.e0[si]
        sinv[i] = -1.0 / c.kdrop[si]
    for a in range(active.shape[0]):
        k, ia = active[a], ns + a
        for b in range(active.shape[0]):
            cap[ia, ns + b] = gc_yc[k, active[b]]
        cap[ia, ia] += 1.0 / kp
        for j in range(ns):
            cap[ia, j] = gc_ydrop[k, slack[j]]
            cap[j, ia] = gd_yc[k, slack[j]]
        uy[ia] = gc_y[k]
        r[ia] = kp * ws_x[k]
        sinv[ia] = 1.0 / kp
    rhs = uy.copy()
    for i in range(m):
        acc = 0.0
        for j in range(m):
            cij = cap[i, j] - sinv[i] if i == j else cap[i, j]
            acc += cij * r[j]
        rhs[i] += acc
    return r - np.linalg.solve(cap, rhs)


@numba.njit(cache=True)
def fe_step(c: StepConstants, s: StepState, input_force: float) -> int:
    """One Newmark step of line + pantographs with ``input_force`` [N] at the new time (see
    ``integrator``): the window shift, right-hand side, banded solve, contact columns, active
    set with the Woodbury capacitance solve, update. Returns STEP_OK or STEP_OFF_LINE (the
    pantograph would leave the line; nothing but a due window shift has happened then).

    Contact k (``p_lag``, ``p_heads``, ``p_inputs``) touches the wire at x - p_lag[k]; the
    controlled one (``indices[5]``) takes ``input_force``, every other one its held ``p_uplift``.
    With one contact the arithmetic is the single-pantograph step's, operation for operation."""
    dt, speed, alpha, beta, kp, c0, c1 = (
        c.numbers[0],
        c.numbers[1],
        c.numbers[2],
        c.numbers[3],
        c.numbers[4],
        c.numbers[5],
        c.numbers[6],
    )
    length, shift_at = c.numbers[7], c.numbers[9]
    endless, ctrl = c.indices[2], c.indices[5]
    x_new = s.scalars[X] + speed * dt
    if endless != 0 and x_new > shift_at:
        shift_window(c, s)
        x_new = s.scalars[X] + speed * dt
    if x_new > length:
        return STEP_OFF_LINE
    d, v, a = s.d, s.v, s.a
    n = d.shape[0]
    npc = c.p_lag.shape[0]
    elem = np.empty(npc, dtype=np.int64)
    nsh = np.empty((npc, 4))
    dofs = np.empty((npc, 4), dtype=np.int64)
    for k in range(npc):
        e, w = hermite_weights(c.x_nodes, x_new - c.p_lag[k])
        elem[k] = e
        nsh[k] = w
        dofs[k, 0], dofs[k, 1], dofs[k, 2], dofs[k, 3] = 4 * e, 4 * e + 1, 4 * e + 4, 4 * e + 5
        _unit_patches(c, s, e)  # (before the solve: they use y_l as scratch)
        _unit_patches(c, s, e + 1)
    y_l = s.work[0]
    z, tail = s.padded[0], s.padded[1, :n]
    newmark_rhs_mass(c.m_pad, d, v, a, dt, alpha, beta, z, tail, y_l)
    chunk_solve(c.chunk_factors, c.chunk_starts, c.chunk_bounds, y_l, s.chunk_work, tail)
    if c.y_rest.shape[0]:  # A^-1 of the constant rest load (droppers slack at rest; else empty)
        for i in range(n):
            y_l[i] += c.y_rest[i]
    # Contact columns A^-1 g_k (line part) from the stored patches; zero outside their [lo, hi).
    width = s.unit_patches.shape[2]
    for k in range(npc):
        yc_l = s.work[1 + k]
        yc_l[s.yc_range[k, 0] : s.yc_range[k, 1]] = 0.0
        for i in range(4):
            node = elem[k] + i // 2
            lo = unit_start(n, width, node)
            col = s.unit_patches[node, i % 2]
            for q in range(width):
                yc_l[lo + q] -= col[q] * nsh[k, i]
        s.yc_range[k, 0] = unit_start(n, width, elem[k])
        s.yc_range[k, 1] = unit_start(n, width, elem[k] + 1) + width
    # Pantographs (stacked: one block of the matrices each).
    npn = s.p.shape[0]
    bp = np.empty(npn)
    u1 = c0 * s.p + (4.0 / dt) * s.vp + s.ap
    u2 = c1 * s.p + s.vp
    for i in range(npn):
        fi = c.p_ground[i] * s.roof_rest[i]
        for k in range(npc):
            if i == c.p_inputs[k]:
                fi += input_force if k == ctrl else c.p_uplift[k]
        acc1 = 0.0
        acc2 = 0.0
        for j in range(npn):
            acc1 += c.p_mass[i, j] * u1[j]
            acc2 += c.p_damping[i, j] * u2[j]
        bp[i] = fi + acc1 + acc2
    y_p = np.zeros(npn)
    for i in range(npn):
        for j in range(npn):
            y_p[i] += c.p_ainv[i, j] * bp[j]
    # Projections on the contact directions g_k and on the dropper directions g_j.
    nd = c.e0.shape[0]
    ws_x = np.zeros(npc)
    gc_y = np.empty(npc)
    gc_yc = np.empty((npc, npc))
    gc_ydrop = np.empty((npc, nd))
    gd_yc = np.empty((npc, nd))
    for k in range(npc):
        hk = c.p_heads[k]
        gc_y[k] = y_p[hk]
        for j in range(npc):
            gc_yc[k, j] = c.p_ainv[hk, c.p_heads[j]]
        for i in range(4):
            ws_x[k] += nsh[k, i] * c.w_static[dofs[k, i]]
            gc_y[k] -= nsh[k, i] * y_l[dofs[k, i]]
            for j in range(npc):
                gc_yc[k, j] -= nsh[k, i] * s.work[1 + j, dofs[k, i]]
    gd_y = np.empty(nd)
    for j in range(nd):
        for k in range(npc):
            acc = 0.0
            for i in range(4):
                acc += nsh[k, i] * c.ydrop[dofs[k, i], j]
            gc_ydrop[k, j] = -acc
            gd_yc[k, j] = s.work[1 + k, c.dwm[j]] - s.work[1 + k, c.dwc[j]]
        gd_y[j] = y_l[c.dwm[j]] - y_l[c.dwc[j]]
    touch = s.touching.copy()
    slack = s.slack[: s.counters[N_SLACK]].copy()
    passes = 0
    coef = np.zeros(1)
    delta = np.zeros(npc)
    e_drop = np.empty(nd)
    active = np.flatnonzero(touch)
    while passes < MAX_ACTIVE_SET_PASSES:
        passes += 1
        ns = slack.shape[0]
        active = np.flatnonzero(touch)
        m = ns + active.shape[0]
        if ns == 0 and active.shape[0] <= 1:  # the usual case of one pantograph, in scalars
            coef = np.zeros(m)
            if m:
                k = active[0]
                r_c = kp * ws_x[k]
                coef[0] = r_c - (gc_y[k] + gc_yc[k, k] * r_c) / (gc_yc[k, k] + 1.0 / kp)
        else:
            coef = _woodbury_coefficients(c, slack, active, gc_y, gc_yc, gc_ydrop, gd_y, gd_yc, ws_x)
        for k in range(npc):
            delta[k] = gc_y[k] - ws_x[k]
        for j in range(nd):
            e_drop[j] = c.e0[j] + gd_y[j]
        if ns:
            for k in range(npc):
                acc = 0.0
                for q in range(ns):
                    acc += gc_ydrop[k, slack[q]] * coef[q]
                delta[k] += acc
            for j in range(nd):
                acc = 0.0
                for q in range(ns):
                    acc += c.ddrop[j, slack[q]] * coef[q]
                e_drop[j] += acc
        for b in range(active.shape[0]):
            kb, cb = active[b], coef[ns + b]
            for k in range(npc):
                delta[k] += gc_yc[k, kb] * cb
            for j in range(nd):
                e_drop[j] += gd_yc[kb, j] * cb
        new_slack = np.flatnonzero(e_drop < 0.0)
        consistent = new_slack.shape[0] == ns and np.all(new_slack == slack)
        for k in range(npc):
            new_touch = 1 if delta[k] > 0.0 else 0
            consistent = consistent and new_touch == touch[k]
            touch[k] = new_touch
        if consistent or passes == MAX_ACTIVE_SET_PASSES:
            if not consistent:  # keep the set the solution was computed for; count it
                s.counters[UNCONVERGED] += 1
                for k in range(npc):
                    touch[k] = 0
                for b in range(active.shape[0]):
                    touch[active[b]] = 1
            break
        slack = new_slack
    s.counters[PASSES_MAX] = max(s.counters[PASSES_MAX], passes)
    ns = slack.shape[0]
    d_new = y_l  # scratch, consumed by newmark_update below
    p_new = y_p.copy()
    width = c.ydrop_patches.shape[1]
    for q in range(ns):
        cq = coef[q]
        yq = c.ydrop_patches[slack[q]]
        lo = unit_start(n, width, c.dwc[slack[q]] // 4)
        for r in range(width):
            d_new[lo + r] += yq[r] * cq
    for b in range(active.shape[0]):
        kb, cc = active[b], coef[ns + b]
        yc_l = s.work[1 + kb]
        for r in range(s.yc_range[kb, 0], s.yc_range[kb, 1]):
            d_new[r] += yc_l[r] * cc
        for i in range(npn):
            p_new[i] += c.p_ainv[i, c.p_heads[kb]] * cc
    newmark_update(d, v, a, d_new, dt)
    for i in range(npn):
        ap_new = c0 * (p_new[i] - s.p[i]) - (4.0 / dt) * s.vp[i] - s.ap[i]
        s.vp[i] = s.vp[i] + 0.5 * dt * (s.ap[i] + ap_new)
        s.ap[i] = ap_new
        s.p[i] = p_new[i]
    s.scalars[X] = x_new
    for k in range(npc):
        s.touching[k] = touch[k]
        s.deltas[k] = delta[k] if touch[k] else min(delta[k], 0.0)
    s.counters[IN_CONTACT] = s.touching[ctrl]  # the controlled contact's, where the loop reads them
    s.scalars[DELTA] = s.deltas[ctrl]
    s.slack[:ns] = slack
    s.counters[N_SLACK] = ns
    s.scalars[INPUT_FORCE] = input_force
    s.counters[STEPS] += 1
    return STEP_OK


# Indices into the ``contact_readings`` output.
CONTACT_UPLIFT, SUPPORT_UPLIFT, STATIC_STIFFNESS, STATIC_HEIGHT, STATIC_SLOPE = 0, 1, 2, 3, 4


@numba.njit(cache=True)
def contact_readings(c: StepConstants, s: StepState, flexibility: np.ndarray, out: np.ndarray) -> None:
    """``readings_at`` the controlled pantograph's contact point."""
    readings_at(c, s, flexibility, s.scalars[X] - c.p_lag[c.indices[5]], out)


@numba.njit(cache=True)
def pantograph_contact(c: StepConstants, s: StepState, k: int) -> tuple[float, float]:
    """Contact k (pantograph k's head): its penalty force kp delta_k where it touches, else 0 [N],
    and its contact point's distance from the line's start (x plus what an endless line shifted,
    minus its lag) [m]. The one home of both: the compiled loop and ``ContactSimulation`` call it."""
    force = c.numbers[4] * s.deltas[k] if s.touching[k] != 0 else 0.0
    return force, s.scalars[X] + s.scalars[OFFSET] - c.p_lag[k]


@numba.njit(cache=True)
def readings_at(c: StepConstants, s: StepState, flexibility: np.ndarray, x: float, out: np.ndarray) -> None:
    """What the plant reports at a contact point x (``Line``'s formulas, compiled): the wire's
    uplift there and at the nearest support [m], the static point stiffness 1 / (N^T F_e N)
    from the element's 4x4 flexibility block [N/m], the static wire height [m] and slope."""
    span = c.numbers[8]
    e, n = hermite_weights(c.x_nodes, x)
    dofs = np.array([4 * e, 4 * e + 1, 4 * e + 4, 4 * e + 5])
    up, ws, nfn = 0.0, 0.0, 0.0
    for i in range(4):
        up += n[i] * s.d[dofs[i]]
        ws += n[i] * c.w_static[dofs[i]]
        acc = 0.0
        for j in range(4):
            acc += flexibility[e, i, j] * n[j]
        nfn += n[i] * acc
    h = c.x_nodes[e + 1] - c.x_nodes[e]
    xi = (x - c.x_nodes[e]) / h
    x2 = xi * xi
    dn = (6 * (x2 - xi) / h, 1 - 4 * xi + 3 * x2, 6 * (xi - x2) / h, 3 * x2 - 2 * xi)
    slope = 0.0
    for i in range(4):
        slope += dn[i] * c.w_static[dofs[i]]
    es, ns = hermite_weights(c.x_nodes, np.rint(x / span) * span)
    sup = 0.0
    for i in range(4):
        sup += ns[i] * s.d[4 * es + (i % 2) + 4 * (i // 2)]
    out[CONTACT_UPLIFT] = up
    out[SUPPORT_UPLIFT] = sup
    out[STATIC_STIFFNESS] = 1.0 / nfn
    out[STATIC_HEIGHT] = ws
    out[STATIC_SLOPE] = slope


@numba.njit(cache=True)
def fe_advance(
    c: StepConstants,
    s: StepState,
    input_force: float,
    steps: int,
    flexibility: np.ndarray,
    readings: np.ndarray,
) -> int:
    """``steps`` x ``fe_step`` with the force held, then ``contact_readings`` (skipped if
    ``readings`` is empty): one plant tick."""
    for _ in range(steps):
        status = fe_step(c, s, input_force)
        if status != STEP_OK:
            return status
    if readings.shape[0]:
        contact_readings(c, s, flexibility, readings)
    return STEP_OK


# -- packed arguments: a call from Python pays ~0.1 us per array argument (numba types each one) --
#: Kind of each field of StepConstants / StepState: f = float64, i = int64, then the dimension.
CONSTANT_KINDS = (
    "f2", "f2", "f3", "i1", "i1", "f1", "f1", "f2", "f2", "f2", "f1",
    "f1", "i1", "i1", "i1", "f2", "f2", "f2", "f1", "f1", "i1", "i1", "i1", "f1", "f1", "f1",
)  # fmt: skip
STATE_KINDS = (
    "f1", "f1", "f1", "f1", "f1", "f1", "f1", "f1", "i1", "i1", "f3", "i1", "f2", "f2", "f2",
    "f1", "i1", "i2",
)  # fmt: skip
_ALIGN = 8  # elements: every packed array starts on a 64-byte boundary


def pack(
    arrays: tuple[np.ndarray, ...], kinds: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """(float buffer, int buffer, layout, views): ``arrays`` copied into two flat buffers; the views
    (same shapes, into the buffers) replace them, so Python and compiled code share the memory.
    layout[k] = (offset, shape0, shape1, shape2) of field k in its buffer."""
    if len(arrays) != len(kinds):
        raise ValueError(f"{len(arrays)} arrays for {len(kinds)} kinds")
    sizes = {"f": 0, "i": 0}
    layout = np.zeros((len(arrays), 4), dtype=np.int64)
    for k, (arr, kind) in enumerate(zip(arrays, kinds, strict=True)):
        if arr.ndim != int(kind[1]) or arr.dtype != (np.float64 if kind[0] == "f" else np.int64):
            raise ValueError(f"field {k}: {arr.dtype} {arr.ndim}-d, expected kind {kind}")
        layout[k, 0] = sizes[kind[0]]
        layout[k, 1 : 1 + arr.ndim] = arr.shape
        sizes[kind[0]] += -(-arr.size // _ALIGN) * _ALIGN
    buffers = {"f": np.zeros(sizes["f"]), "i": np.zeros(sizes["i"], dtype=np.int64)}
    views = []
    for k, (arr, kind) in enumerate(zip(arrays, kinds, strict=True)):
        view = buffers[kind[0]][layout[k, 0] : layout[k, 0] + arr.size].reshape(arr.shape)
        view[...] = arr
        views.append(view)
    return buffers["f"], buffers["i"], layout, views


@numba.njit(cache=True, inline="always")
def _v1(buf: np.ndarray, lay: np.ndarray, k: int) -> np.ndarray:
    return buf[lay[k, 0] : lay[k, 0] + lay[k, 1]]


@numba.njit(cache=True, inline="always")
def _v2(buf: np.ndarray, lay: np.ndarray, k: int) -> np.ndarray:
    return buf[lay[k, 0] : lay[k, 0] + lay[k, 1] * lay[k, 2]].reshape((lay[k, 1], lay[k, 2]))


@numba.njit(cache=True, inline="always")
def _v3(buf: np.ndarray, lay: np.ndarray, k: int) -> np.ndarray:
    n = lay[k, 1] * lay[k, 2] * lay[k, 3]
    return buf[lay[k, 0] : lay[k, 0] + n].reshape((lay[k, 1], lay[k, 2], lay[k, 3]))


@numba.njit(cache=True)
def unpack(
    cf: np.ndarray, ci: np.ndarray, cl: np.ndarray, sf: np.ndarray, si: np.ndarray, sl: np.ndarray
) -> tuple[StepConstants, StepState]:
    """The StepConstants and StepState that ``pack`` stored (field order and kinds as declared)."""
    c = StepConstants(
        _v2(cf, cl, 0), _v2(cf, cl, 1), _v3(cf, cl, 2), _v1(ci, cl, 3), _v1(ci, cl, 4), _v1(cf, cl, 5),
        _v1(cf, cl, 6), _v2(cf, cl, 7), _v2(cf, cl, 8), _v2(cf, cl, 9), _v1(cf, cl, 10), _v1(cf, cl, 11),
        _v1(ci, cl, 12), _v1(ci, cl, 13), _v1(ci, cl, 14), _v2(cf, cl, 15), _v2(cf, cl, 16),
        _v2(cf, cl, 17), _v1(cf, cl, 18), _v1(cf, cl, 19), _v1(ci, cl, 20), _v1(ci, cl, 21),
        _v1(ci, cl, 22), _v1(cf, cl, 23), _v1(cf, cl, 24), _v1(cf, cl, 25),
    )  # fmt: skip
    s = StepState(
        _v1(sf, sl, 0), _v1(sf, sl, 1), _v1(sf, sl, 2), _v1(sf, sl, 3), _v1(sf, sl, 4), _v1(sf, sl, 5),
        _v1(sf, sl, 6), _v1(sf, sl, 7), _v1(si, sl, 8), _v1(si, sl, 9), _v3(sf, sl, 10), _v1(si, sl, 11),
        _v2(sf, sl, 12), _v2(sf, sl, 13), _v2(sf, sl, 14), _v1(sf, sl, 15), _v1(si, sl, 16),
        _v2(si, sl, 17),
    )  # fmt: skip
    return c, s


@numba.njit(cache=True)
def fe_advance_packed(
    cf: np.ndarray,
    ci: np.ndarray,
    cl: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    sl: np.ndarray,
    input_force: float,
    steps: int,
    flexibility: np.ndarray,
    readings: np.ndarray,
) -> int:
    """``fe_advance`` on ``pack``ed constants (cf, ci, cl) and state (sf, si, sl): what Python calls
    (10 arguments to type instead of 38)."""
    c, s = unpack(cf, ci, cl, sf, si, sl)
    return fe_advance(c, s, input_force, steps, flexibility, readings)
