"""The numba tools every kernel of the package shares: :func:`njit` (compiled once, cached
on disk), :func:`fma` (a multiply-add rounded once, the same on every CPU) and :func:`div`
(IEEE division, no zero check). Public so
that kernels outside the corruptions (the evaluation's) compile the same way."""

from __future__ import annotations

from llvmlite import ir
from numba.extending import intrinsic

from ._jit import njit

__all__ = ["div", "fma", "njit"]


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM's ``llvm.fma``: the CPU's fused multiply-add, or
    the C library's exact ``fma`` on a CPU without one), for float32 or float64 operands
    of one type."""
    def codegen(context, builder, signature, args):
        ty = args[0].type
        fn = builder.module.declare_intrinsic("llvm.fma", [ty], ir.FunctionType(ty, [ty, ty, ty]))
        return builder.call(fn, args)

    return a(a, b, c), codegen


@intrinsic
def div(typingctx, a, b):
    """``a / b`` as IEEE divides (infinity or NaN for ``b = 0``) for float32 or float64
    operands of one type, as numpy does: numba's own ``/`` checks each divisor for zero to
    raise ZeroDivisionError, which also keeps a loop from vectorising."""
    def codegen(context, builder, signature, args):
        return builder.fdiv(args[0], args[1])

    return a(a, b), codegen
