"""The step's constants and state packed into a few flat buffers: a call from Python pays ~0.1 us
per array argument (numba types each one), so the plant's tick passes buffers and a layout, and
``unpack`` rebuilds the named tuples inside the compiled code.
"""

from __future__ import annotations

import numba
import numpy as np

from .step import StepConstants, StepState, fe_advance

# -- packed arguments: a call from Python pays ~0.1 us per array argument (numba types each one) --
#: Kind of each field of StepConstants / StepState: f = float64, i = int64, then the dimension.
CONSTANT_KINDS = (
    "f2", "f2", "f3", "i1", "i1", "f1", "f1", "f2", "f2", "f1",
    "f1", "i1", "i1", "i1", "f2", "f2", "f2", "f1", "f1", "i1", "i1", "i1", "f1", "f1", "f1",
    "i2", "f2", "f1", "i1", "f1", "i2", "i2", "f3", "f3", "i2", "i2",
)  # fmt: skip
STATE_KINDS = (
    "f1", "f1", "f1", "f1", "f1", "f1", "f1", "f1", "i1", "i1", "f3", "i1", "f2", "f2", "f2",
    "f1", "i1", "i2", "f1",
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
        # The buffers are new zeros whose pages the system maps when first written: an array of
        # zeros (the contact columns not yet solved: 16 MB on a 3 km line) is left to them.
        if arr.any() or np.signbit(arr).any():
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
        _v1(cf, cl, 6), _v2(cf, cl, 7), _v2(cf, cl, 8), _v1(cf, cl, 9), _v1(cf, cl, 10),
        _v1(ci, cl, 11), _v1(ci, cl, 12), _v1(ci, cl, 13), _v2(cf, cl, 14), _v2(cf, cl, 15),
        _v2(cf, cl, 16), _v1(cf, cl, 17), _v1(cf, cl, 18), _v1(ci, cl, 19), _v1(ci, cl, 20),
        _v1(ci, cl, 21), _v1(cf, cl, 22), _v1(cf, cl, 23), _v1(cf, cl, 24), _v2(ci, cl, 25),
        _v2(cf, cl, 26), _v1(cf, cl, 27), _v1(ci, cl, 28), _v1(cf, cl, 29), _v2(ci, cl, 30),
        _v2(ci, cl, 31), _v3(cf, cl, 32), _v3(cf, cl, 33), _v2(ci, cl, 34), _v2(ci, cl, 35),
    )  # fmt: skip
    s = StepState(
        _v1(sf, sl, 0), _v1(sf, sl, 1), _v1(sf, sl, 2), _v1(sf, sl, 3), _v1(sf, sl, 4), _v1(sf, sl, 5),
        _v1(sf, sl, 6), _v1(sf, sl, 7), _v1(si, sl, 8), _v1(si, sl, 9), _v3(sf, sl, 10), _v1(si, sl, 11),
        _v2(sf, sl, 12), _v2(sf, sl, 13), _v2(sf, sl, 14), _v1(sf, sl, 15), _v1(si, sl, 16),
        _v2(si, sl, 17), _v1(sf, sl, 18),
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
