"""The FE step's eight-lane vector operations (pac_plant.catenary.lanes) against numpy on random
inputs: each compiled operation is exactly the per-lane scalar arithmetic (fused multiply-adds
against the exactly rounded x*y+z from rational arithmetic), the gathers, scatters, masked loads
and stores, shuffles and the 8 x 8 transpose move exactly the elements numpy indexing names."""

from fractions import Fraction

import numba
import numpy as np
import pytest

from pac_plant.catenary import lanes

pytestmark = pytest.mark.unit

W = lanes.WIDTH


@numba.njit(cache=True)
def _arithmetic(x, y, z, out):
    lanes.lanes_check(x, y, z, out)
    lanes.store(out, 32, lanes.splat(x[3]))
    lanes.store(out, 40, lanes.zeros())


@numba.njit(cache=True)
def _moves(m, idx, bounds, j, b, out):
    rows = (
        lanes.load(m, 0),
        lanes.load(m, 8),
        lanes.load(m, 16),
        lanes.load(m, 24),
        lanes.load(m, 32),
        lanes.load(m, 40),
        lanes.load(m, 48),
        lanes.load(m, 56),
    )
    cols = lanes.transpose(rows)
    for c in range(W):
        lanes.store(out, W * c, cols[c])
    lanes.store(out, 64, lanes.gather(b, idx, j))
    lanes.scatter(b, idx, j, lanes.load(m, 0), bounds)
    lanes.store(out, 72, lanes.window(rows[0], rows[1], 3))
    lanes.store(out, 80, lanes.window(rows[0], rows[1], 0))
    lanes.store(out, 88, lanes.window(rows[0], rows[1], 8))


@numba.njit(cache=True)
def _masked(src, offset, lo, hi, dst, out):
    v = lanes.load_masked(src, offset, lo, hi)
    lanes.store(out, 0, v)
    lanes.store_masked(dst, offset, lanes.load(out, 8), lo, hi)


def _fma_exact(x: float, y: float, z: float) -> float:
    """x*y + z rounded once (Fraction arithmetic is exact; float() of it rounds to nearest)."""
    return float(Fraction(x) * Fraction(y) + Fraction(z))


def test_lane_arithmetic_is_the_scalar_arithmetic_per_lane():
    rng = np.random.default_rng(11)
    for _ in range(50):
        x, y, z = (rng.normal(0.0, 10.0 ** rng.uniform(-3, 3), W) for _ in range(3))
        out = np.full(48, np.nan)
        _arithmetic(x, y, z, out)
        np.testing.assert_array_equal(out[0:8], x * y)
        np.testing.assert_array_equal(
            out[8:16], [_fma_exact(a, b, c) for a, b, c in zip(x, y, z, strict=True)]
        )
        np.testing.assert_array_equal(
            out[16:24], [_fma_exact(-a, b, c) for a, b, c in zip(x, y, z, strict=True)]
        )
        np.testing.assert_array_equal(out[24:32], x + z)
        np.testing.assert_array_equal(out[32:40], np.full(W, x[3]))
        np.testing.assert_array_equal(out[40:48], np.zeros(W))


def test_lane_moves_name_the_elements_numpy_indexing_names():
    rng = np.random.default_rng(12)
    for _ in range(50):
        m = rng.normal(size=64)
        b = rng.normal(size=200)
        idx = np.sort(rng.choice(150, W, replace=False)).astype(np.int64)
        bounds = np.sort(rng.integers(0, 200, W + 1)).astype(np.int64)
        j = int(rng.integers(0, 40))
        want_b = b.copy()
        rows = idx + j
        for c in range(W):  # scatter: lane c only where bounds[c] <= idx[c] + j < bounds[c + 1]
            if bounds[c] <= rows[c] < bounds[c + 1]:
                want_b[rows[c]] = m[c]
        gathered = b[rows].copy()
        out = np.full(96, np.nan)
        _moves(m, idx, bounds, j, b, out)
        np.testing.assert_array_equal(out[:64], m.reshape(W, W).T.ravel())
        np.testing.assert_array_equal(out[64:72], gathered)
        np.testing.assert_array_equal(b, want_b)
        np.testing.assert_array_equal(out[72:80], m[3:11])
        np.testing.assert_array_equal(out[80:88], m[0:8])
        np.testing.assert_array_equal(out[88:96], m[8:16])


def test_masked_load_and_store_touch_only_the_lanes_in_range():
    rng = np.random.default_rng(13)
    for _ in range(50):
        src, dst = rng.normal(size=40), rng.normal(size=40)
        offset = int(rng.integers(0, 32))
        lo, hi = sorted(int(v) for v in rng.integers(-5, 45, 2))
        out = np.concatenate([np.full(8, np.nan), rng.normal(size=8)])
        want_dst = dst.copy()
        want = np.zeros(W)
        for lane in range(W):
            if lo <= offset + lane < hi:
                want[lane] = src[offset + lane]
                want_dst[offset + lane] = out[8 + lane]
        _masked(src, offset, lo, hi, dst, out)
        np.testing.assert_array_equal(out[:8], want)
        np.testing.assert_array_equal(dst, want_dst)
