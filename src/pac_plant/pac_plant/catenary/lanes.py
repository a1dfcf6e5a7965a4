"""Eight float64 lanes as one value in compiled code (an LLVM ``<8 x double>``), for the FE step.

numba leaves LLVM's straight-line (SLP) vectoriser off, and its loop vectoriser cannot pack
a recurrence (each row of a banded solve needs the previous row), so the FE kernels say
"eight at once" themselves: ``load``/``store`` eight consecutive float64 of a contiguous
array at an element offset, and lane-wise ``mul``, ``fma`` and ``fnma``. Each is one LLVM
vector instruction (``llvm.fma`` for the fused ones, so the rounding is that of one fused
multiply-add per lane whatever the target); on a machine without 512-bit registers LLVM
splits them. A lane's arithmetic is exactly the scalar arithmetic on that lane.
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, models, register_model

WIDTH = 8
_VEC = ir.VectorType(ir.DoubleType(), WIDTH)


class Lanes(types.Type):
    """The numba type of eight float64 lanes (never seen by Python)."""

    def __init__(self) -> None:
        super().__init__(name="Lanes8")


lanes8 = Lanes()


@register_model(Lanes)
class _LanesModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type) -> None:
        super().__init__(dmm, fe_type, _VEC)


def _pointer(context, builder, arr_type, arr, offset):
    ary = context.make_array(arr_type)(context, builder, arr)
    ptr = builder.gep(ary.data, [offset])
    return builder.bitcast(ptr, _VEC.as_pointer())


def _is_float_array(a: types.Type) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.float64 and a.layout == "C"


@intrinsic
def load(typingctx, arr, offset):
    """arr.flat[offset : offset + 8] as lanes (no bounds check: the caller's index arithmetic)."""
    if not (_is_float_array(arr) and isinstance(offset, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        ptr = _pointer(context, builder, sig.args[0], args[0], args[1])
        return builder.load(ptr, align=8)

    return lanes8(arr, offset), codegen


@intrinsic
def store(typingctx, arr, offset, value):
    """arr.flat[offset : offset + 8] = value."""
    if not (_is_float_array(arr) and isinstance(offset, types.Integer) and value == lanes8):
        return None

    def codegen(context, builder, sig, args):
        ptr = _pointer(context, builder, sig.args[0], args[0], args[1])
        builder.store(args[2], ptr, align=8)
        return context.get_dummy_value()

    return types.none(arr, offset, value), codegen


@intrinsic
def zeros(typingctx):
    """Eight zeros."""

    def codegen(context, builder, sig, args):
        return ir.Constant(_VEC, [0.0] * WIDTH)

    return lanes8(), codegen


@intrinsic
def splat(typingctx, x):
    """x in every lane."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context, builder, sig, args):
        v = builder.insert_element(ir.Constant(_VEC, ir.Undefined), args[0], ir.Constant(ir.IntType(32), 0))
        return builder.shuffle_vector(
            v, ir.Constant(_VEC, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH)
        )

    return lanes8(x), codegen


def _fma(builder, a, b, c):
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VEC, [_VEC] * 3), "llvm.fma.v8f64")
    return builder.call(fn, [a, b, c])


def _binary(instruction: str, doc: str):
    """The lane-wise intrinsic ``a <instruction> b`` (an IRBuilder method: fmul, fadd)."""

    @intrinsic
    def op(typingctx, a, b):
        if not (a == lanes8 and b == lanes8):
            return None

        def codegen(context, builder, sig, args):
            return getattr(builder, instruction)(args[0], args[1])

        return lanes8(a, b), codegen

    op.__doc__ = doc
    return op


mul = _binary("fmul", "a * b, lane by lane.")
add = _binary("fadd", "a + b, lane by lane.")


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c, lane by lane, one rounding."""
    if not (a == lanes8 and b == lanes8 and c == lanes8):
        return None

    def codegen(context, builder, sig, args):
        return _fma(builder, *args)

    return lanes8(a, b, c), codegen


@intrinsic
def fnma(typingctx, a, b, c):
    """c - a * b, lane by lane, one rounding."""
    if not (a == lanes8 and b == lanes8 and c == lanes8):
        return None

    def codegen(context, builder, sig, args):
        return _fma(builder, builder.fneg(args[0]), args[1], args[2])

    return lanes8(a, b, c), codegen


@numba.njit(cache=True)
def lanes_check(x: np.ndarray, y: np.ndarray, z: np.ndarray, out: np.ndarray) -> None:
    """out[0:8] = x*y, out[8:16] = x*y + z, out[16:24] = z - x*y, out[24:32] = x + z (the tests' probe)."""
    a, b, c = load(x, 0), load(y, 0), load(z, 0)
    store(out, 0, mul(a, b))
    store(out, 8, fma(a, b, c))
    store(out, 16, fnma(a, b, c))
    store(out, 24, add(a, c))


_I64 = ir.IntType(64)
_IVEC = ir.VectorType(_I64, WIDTH)


def _addresses(context, builder, sig, args):
    """Addresses of arr.flat[idx[c] + j] for the eight lanes c, as a vector of pointers."""
    ary = context.make_array(sig.args[0])(context, builder, args[0])
    idx = context.make_array(sig.args[1])(context, builder, args[1])
    offsets = builder.load(builder.bitcast(idx.data, _IVEC.as_pointer()), align=8)
    jv = builder.insert_element(ir.Constant(_IVEC, ir.Undefined), args[2], ir.Constant(ir.IntType(32), 0))
    jv = builder.shuffle_vector(
        jv, ir.Constant(_IVEC, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH)
    )
    byte = builder.mul(builder.add(offsets, jv), ir.Constant(_IVEC, [8] * WIDTH))
    base = builder.ptrtoint(ary.data, _I64)
    bv = builder.insert_element(ir.Constant(_IVEC, ir.Undefined), base, ir.Constant(ir.IntType(32), 0))
    bv = builder.shuffle_vector(
        bv, ir.Constant(_IVEC, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH)
    )
    return builder.inttoptr(
        builder.add(bv, byte), ir.VectorType(ir.DoubleType().as_pointer(), WIDTH)
    ), offsets


@intrinsic
def gather(typingctx, arr, idx, j):
    """Lane c = arr.flat[idx[c] + j] (idx: int64, at least 8 long; no bounds check)."""
    if not (
        _is_float_array(arr)
        and isinstance(idx, types.Array)
        and idx.dtype == types.int64
        and isinstance(j, types.Integer)
    ):
        return None

    def codegen(context, builder, sig, args):
        ptrs, _ = _addresses(context, builder, sig, args)
        fnty = ir.FunctionType(_VEC, [ptrs.type, ir.IntType(32), ir.VectorType(ir.IntType(1), WIDTH), _VEC])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.masked.gather.v8f64.v8p0")
        mask = ir.Constant(ir.VectorType(ir.IntType(1), WIDTH), [1] * WIDTH)
        return builder.call(fn, [ptrs, ir.Constant(ir.IntType(32), 8), mask, ir.Constant(_VEC, ir.Undefined)])

    return lanes8(arr, idx, j), codegen


@intrinsic
def scatter(typingctx, arr, idx, j, value, bounds):
    """arr.flat[idx[c] + j] = value[c] for the lanes c with bounds[c] <= idx[c] + j < bounds[c + 1]
    (bounds: int64, at least 9 long)."""
    ok = _is_float_array(arr) and value == lanes8 and isinstance(j, types.Integer)
    for a in (idx, bounds):
        ok = ok and isinstance(a, types.Array) and a.dtype == types.int64
    if not ok:
        return None

    def codegen(context, builder, sig, args):
        ptrs, offsets = _addresses(context, builder, sig, args)
        row = builder.add(
            offsets,
            builder.shuffle_vector(
                builder.insert_element(
                    ir.Constant(_IVEC, ir.Undefined), args[2], ir.Constant(ir.IntType(32), 0)
                ),
                ir.Constant(_IVEC, ir.Undefined),
                ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH),
            ),
        )
        bnd = context.make_array(sig.args[4])(context, builder, args[4])
        lo = builder.load(builder.bitcast(bnd.data, _IVEC.as_pointer()), align=8)
        hi = builder.load(
            builder.bitcast(builder.gep(bnd.data, [ir.Constant(_I64, 1)]), _IVEC.as_pointer()), align=8
        )
        mask = builder.and_(builder.icmp_signed(">=", row, lo), builder.icmp_signed("<", row, hi))
        fnty = ir.FunctionType(ir.VoidType(), [_VEC, ptrs.type, ir.IntType(32), mask.type])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.masked.scatter.v8f64.v8p0")
        builder.call(fn, [args[3], ptrs, ir.Constant(ir.IntType(32), 8), mask])
        return context.get_dummy_value()

    return types.none(arr, idx, j, value, bounds), codegen


def _mask(context, builder, offset, lo, hi):
    """Lane l on where lo <= offset + l < hi."""
    off = builder.insert_element(ir.Constant(_IVEC, ir.Undefined), offset, ir.Constant(ir.IntType(32), 0))
    off = builder.shuffle_vector(
        off, ir.Constant(_IVEC, ir.Undefined), ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH)
    )
    idx = builder.add(off, ir.Constant(_IVEC, list(range(WIDTH))))
    splat_lo = builder.shuffle_vector(
        builder.insert_element(ir.Constant(_IVEC, ir.Undefined), lo, ir.Constant(ir.IntType(32), 0)),
        ir.Constant(_IVEC, ir.Undefined),
        ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH),
    )
    splat_hi = builder.shuffle_vector(
        builder.insert_element(ir.Constant(_IVEC, ir.Undefined), hi, ir.Constant(ir.IntType(32), 0)),
        ir.Constant(_IVEC, ir.Undefined),
        ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), [0] * WIDTH),
    )
    return builder.and_(builder.icmp_signed(">=", idx, splat_lo), builder.icmp_signed("<", idx, splat_hi))


@intrinsic
def load_masked(typingctx, arr, offset, lo, hi):
    """Lane l = arr.flat[offset + l] where lo <= offset + l < hi, else 0 (nothing read there)."""
    if not (_is_float_array(arr) and all(isinstance(t, types.Integer) for t in (offset, lo, hi))):
        return None

    def codegen(context, builder, sig, args):
        offset, lo, hi = (
            context.cast(builder, v, t, types.int64) for v, t in zip(args[1:], sig.args[1:], strict=True)
        )
        ptr = _pointer(context, builder, sig.args[0], args[0], offset)
        mask = _mask(context, builder, offset, lo, hi)
        fnty = ir.FunctionType(_VEC, [ptr.type, ir.IntType(32), mask.type, _VEC])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.masked.load.v8f64.p0")
        return builder.call(fn, [ptr, ir.Constant(ir.IntType(32), 8), mask, ir.Constant(_VEC, [0.0] * WIDTH)])

    return lanes8(arr, offset, lo, hi), codegen


@intrinsic
def store_masked(typingctx, arr, offset, value, lo, hi):
    """arr.flat[offset + l] = value[l] where lo <= offset + l < hi (nothing written elsewhere)."""
    if not (
        _is_float_array(arr)
        and value == lanes8
        and all(isinstance(t, types.Integer) for t in (offset, lo, hi))
    ):
        return None

    def codegen(context, builder, sig, args):
        offset, lo, hi = (
            context.cast(builder, v, t, types.int64)
            for v, t in ((args[1], sig.args[1]), (args[3], sig.args[3]), (args[4], sig.args[4]))
        )
        ptr = _pointer(context, builder, sig.args[0], args[0], offset)
        mask = _mask(context, builder, offset, lo, hi)
        fnty = ir.FunctionType(ir.VoidType(), [_VEC, ptr.type, ir.IntType(32), mask.type])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.masked.store.v8f64.p0")
        builder.call(fn, [args[2], ptr, ir.Constant(ir.IntType(32), 8), mask])
        return context.get_dummy_value()

    return types.none(arr, offset, value, lo, hi), codegen


_ROWS = types.UniTuple(lanes8, WIDTH)


@intrinsic
def transpose(typingctx, rows):
    """The 8 x 8 transpose: lane l of result c = lane c of rows[l] (three rounds of shuffles)."""
    if rows != _ROWS:
        return None

    def codegen(context, builder, sig, args):
        r = [builder.extract_value(args[0], i) for i in range(WIDTH)]
        m = lambda *idx: ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), list(idx))  # noqa: E731
        for step, (lo_mask, hi_mask) in (
            (1, (m(0, 8, 2, 10, 4, 12, 6, 14), m(1, 9, 3, 11, 5, 13, 7, 15))),
            (2, (m(0, 1, 8, 9, 4, 5, 12, 13), m(2, 3, 10, 11, 6, 7, 14, 15))),
            (4, (m(0, 1, 2, 3, 8, 9, 10, 11), m(4, 5, 6, 7, 12, 13, 14, 15))),
        ):
            out = list(r)
            for i in range(WIDTH):
                if i & step:
                    continue
                out[i] = builder.shuffle_vector(r[i], r[i + step], lo_mask)
                out[i + step] = builder.shuffle_vector(r[i], r[i + step], hi_mask)
            r = out
        res = ir.Constant(context.get_value_type(_ROWS), ir.Undefined)
        for i in range(WIDTH):
            res = builder.insert_value(res, r[i], i)
        return res

    return _ROWS(rows), codegen


@intrinsic
def window(typingctx, lo, hi, k):
    """Lanes k .. k+7 of the sixteen (lo, hi): eight consecutive values from two loaded blocks
    (k a constant 0..8), one shuffle instead of an unaligned load."""
    if not (lo == lanes8 and hi == lanes8 and isinstance(k, types.IntegerLiteral)):
        return None
    shift = k.literal_value
    if not 0 <= shift <= WIDTH:
        return None

    def codegen(context, builder, sig, args):
        mask = ir.Constant(ir.VectorType(ir.IntType(32), WIDTH), list(range(shift, shift + WIDTH)))
        return builder.shuffle_vector(args[0], args[1], mask)

    return lanes8(lo, hi, k), codegen
