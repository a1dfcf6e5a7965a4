"""Products of the small matrices the cores use (4x4, 4x3, 4x2, 3x2), compiled as plain loops.

numba's ``@`` calls BLAS, whose per-call overhead dominates at these sizes; these loops
cost a few nanoseconds.  Results are the textbook sums in index order.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic


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


@intrinsic
def _fma(typingctx, a, b, c):
    """LLVM's fused multiply-add (one rounding), in software where the CPU has none."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        fnty = ir.FunctionType(double, [double, double, double])
        fn = builder.module.declare_intrinsic("llvm.fma", [double], fnty)
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True)
def fma(a: float, b: float, c: float) -> float:
    """a b + c rounded once (LLVM's fma intrinsic: a hardware instruction where the CPU has one,
    a correctly rounded library call where it has not, so the same number on every CPU).

    The lqr law's feedback is a dot product summed with it in index order; it was written so to
    match numpy's ``a @ x`` on the machine the law was first compiled on, which tests no longer
    ask for (they compare with numpy at a tolerance: docs/numerics.md).
    """
    return _fma(float(a), float(b), float(c))
