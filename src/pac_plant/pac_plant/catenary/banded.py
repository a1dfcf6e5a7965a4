"""Compiled (numba) kernels for symmetric banded matrices in LAPACK lower storage ab[k, j] = A[j+k, j].

The per-step work of the line is two banded mat-vecs and two banded Cholesky solves;
in numpy each is a dozen slicing operations (~10 us overhead each), compiled they
are one pass over the band. The fast path (``chunk_factor`` / ``chunk_solve``) splits the solve
into overlapping chunks, one dependency chain per vector lane.
"""

from __future__ import annotations

import math

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


@numba.njit(cache=True)
def band_cholesky(ab: np.ndarray) -> np.ndarray:
    """L of A = L L^T for symmetric positive definite banded A in LAPACK lower storage, in the same
    storage (low[k, j] = L[j+k, j]): LAPACK's unblocked dpbtf2, column by column (the square root
    of the pivot, the column scaled by its inverse, the rank-one update of the trailing band). Our
    own rather than scipy's: the same bits on every CPU (no BLAS underneath), and the FE set-up
    then needs no scipy.linalg (0.1-0.2 s to import). Raises ValueError on a pivot that is not
    positive (a matrix that is not positive definite, or not finite)."""
    kd, n = ab.shape[0] - 1, ab.shape[1]
    low = ab.copy()
    for j in range(n):
        pivot = low[0, j]
        if not pivot > 0.0:
            raise ValueError("band_cholesky: the matrix is not positive definite")
        pivot = math.sqrt(pivot)
        low[0, j] = pivot
        kn = min(kd, n - 1 - j)
        scale = 1.0 / pivot
        for k in range(1, kn + 1):
            low[k, j] *= scale
        for c in range(1, kn + 1):
            lc = low[c, j]
            for r in range(c, kn + 1):
                low[r - c, j + c] -= low[r, j] * lc
    return low


def chol_factor(ab: np.ndarray) -> np.ndarray:
    """The banded Cholesky factor of ``ab`` laid out for ``band_chol_solve``: (n, kd+1), row j
    holding L[j+k, j] for k = 0..kd with the diagonal inverted (cache-friendly, no division)."""
    cb = np.ascontiguousarray(band_cholesky(np.ascontiguousarray(ab, dtype=float)).T)
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
def band_chol_solve_columns(cb: np.ndarray, b: np.ndarray, first: int = 0, stop: int = 0) -> None:
    """``band_chol_solve`` on every column of b (shape (n, m), rows contiguous) in place: the same
    operations on each column in the same order (each column is bit for bit its solve alone),
    a row of all the columns at a time so that the inner loop runs along contiguous memory.
    ``first``: b is zero above this row (the forward sweep starts there: above it, it would compute
    zeros); ``stop``: the rows above it are not wanted (the backward sweep ends there and leaves
    them unsolved)."""
    n, kd = cb.shape[0], cb.shape[1] - 1
    m = b.shape[1]
    for j in range(first, n):  # forward: L y = b, column-oriented
        inv = cb[j, 0]
        for c in range(m):
            b[j, c] *= inv
        for k in range(1, min(kd, n - 1 - j) + 1):
            f = cb[j, k]
            for c in range(m):
                b[j + k, c] -= f * b[j, c]
    for j in range(n - 1, stop - 1, -1):  # backward: L^T x = y, row-oriented
        top = min(kd, n - 1 - j)
        inv = cb[j, 0]
        for c in range(m):
            acc = b[j, c]
            for k in range(1, top + 1):
                acc -= cb[j, k] * b[j + k, c]
            b[j, c] = acc * inv


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
        low = narrow_band(band_cholesky(sub))  # low[k, j] = L[j+k, j]
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
    first: int = 0,
    last: int = -1,
    keep: int = 0,
) -> None:
    """Solve A x = b in place (b of shape (n,)) as CHUNKS independent banded LDL^T solves of
    overlapping diagonal blocks of A (``chunk_factor``), one block per vector lane: one
    banded solve is a chain (each row waits for the previous one), eight of them side by
    side fill the vector unit. The five previous rows stay in registers; the newest term is
    subtracted last (the chain per row is one fused multiply-add). ``w``: scratch
    (lc + 2 KD, CHUNKS). ``addend`` (length n, or empty: none) is added to the solution on
    the way out. Equal to ``band_chol_solve`` to rounding (``CHUNK_OVERLAP``).

    A column of A^-1 wanted near its load (a contact column, ``step``): b zero outside rows
    ``first`` .. ``last`` (-1: the end) and only the rows from ``keep`` on wanted. The forward
    sweep then starts at the first row that can be non-zero and the backward one stops below
    ``keep``: the rows from ``keep`` on are bit for bit the whole solve's (the rows skipped before
    ``first`` are exact zeros in it); below ``keep`` b holds some rows of each, not to be read."""
    lc = factors.shape[0] - 2 * KD
    if w.shape[0] < lc + KD or w.shape[1] != CHUNKS:
        raise ValueError("chunk_solve: scratch w too small (rows: at least the factors')")
    end = b.shape[0] if last < 0 else last
    j_first = j_need = KD + lc
    for c in range(CHUNKS):
        if starts[c] < end and starts[c] + lc > first:  # a block b is not zero in
            j_first = min(j_first, KD + max(first - starts[c], 0))
        if bounds[c + 1] > keep:  # a block that delivers rows wanted
            j_need = min(j_need, KD + max(keep, bounds[c]) - starts[c])
    j_low = KD + (j_need - KD) // CHUNKS * CHUNKS  # the backward sweep's last group of rows
    if j_low < j_first:
        w[j_low:j_first, :] = 0.0
    f = factors
    row = (KD + 1) * CHUNKS  # elements per row of f
    p1 = p2 = p3 = p4 = p5 = lanes.zeros()
    for j in range(j_first, KD + lc):  # forward: L y = b; p1..p5 = y[j-1]..y[j-5], lane c = chunk c
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
    for j in range(KD + lc - CHUNKS, j_low - 1, -CHUNKS):
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
