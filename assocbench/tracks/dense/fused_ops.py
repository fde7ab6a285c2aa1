"""A fused multiply-add for the dense kernels: where the order of roundings is part of a result (the
true points, ICP's normal equations), ``fma`` rounds once on every machine, where LLVM might
contract ``a * b + c`` or not.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

ZERO21 = (0.0,) * 21   # the upper triangle of a 6 x 6 matrix, row by row, as ``outer_fma`` sums it


@intrinsic
def fma(typingctx, a, b, c):
    """``a · b + c`` rounded once (LLVM's ``llvm.fma.f64``; one instruction on x86-64 since Haswell)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double] * 3))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True, inline="always")
def outer_fma(h, a0, a1, a2, a3, a4, a5):
    """``h + a aᵀ`` on a symmetric 6 x 6 matrix's upper triangle (21 numbers, row by row), one
    rounding each; a tuple, so the sum stays in registers."""
    return (fma(a0, a0, h[0]), fma(a0, a1, h[1]), fma(a0, a2, h[2]), fma(a0, a3, h[3]), fma(a0, a4, h[4]),
            fma(a0, a5, h[5]), fma(a1, a1, h[6]), fma(a1, a2, h[7]), fma(a1, a3, h[8]), fma(a1, a4, h[9]),
            fma(a1, a5, h[10]), fma(a2, a2, h[11]), fma(a2, a3, h[12]), fma(a2, a4, h[13]), fma(a2, a5, h[14]),
            fma(a3, a3, h[15]), fma(a3, a4, h[16]), fma(a3, a5, h[17]), fma(a4, a4, h[18]), fma(a4, a5, h[19]),
            fma(a5, a5, h[20]))


@njit(cache=True)
def symmetric6(h):
    """The symmetric 6 x 6 matrix whose upper triangle ``h`` holds (``outer_fma``'s order)."""
    H = np.empty((6, 6))
    k = 0
    for r in range(6):
        for q in range(r, 6):
            H[r, q] = H[q, r] = h[k]
            k += 1
    return H
