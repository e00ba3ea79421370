"""Two helpers of compiled loops that change no arithmetic: an array without its reference count, and a
loop counter as an unsigned index.

Compiled code keeps an array's reference count with atomic operations: a call taking an array as an argument
changes it on entry and at every return, and so does every view taken of it. A loop that calls a kernel (or
slices a row) thousands of times per run pays that on every call. :func:`borrowed` hands the loop the same
array without an owner; the caller's own argument keeps the memory alive for the call. An index of a signed
type gets a check for a negative value (counted from the end) at every access unless the compiler proves
it non-negative, which it cannot for counters carried across nested loops; :func:`unsigned` makes the type
say so.
"""
from __future__ import annotations

from numba import types
from numba.extending import intrinsic


@intrinsic
def borrowed(typingctx, arr):
    """In compiled code, ``arr`` without its reference count: the same data, shape and strides, no owner.
    It must not outlive ``arr`` (use it only while the caller's argument keeps the memory alive) and must
    not be returned to Python."""
    if not isinstance(arr, types.Array):
        return None

    def codegen(context, builder, sig, args):
        src = context.make_array(sig.args[0])(context, builder, value=args[0])
        dst = context.make_array(sig.return_type)(context, builder)
        context.populate_array(dst, data=src.data, shape=src.shape, strides=src.strides, itemsize=src.itemsize,
                               meminfo=None, parent=None)
        return dst._getvalue()
    return arr(arr), codegen


@intrinsic
def unsigned(typingctx, i):
    """In compiled code, the integer ``i`` (>= 0, or a mask of all ones for -1) as an unsigned 64-bit
    index: the same bits, indexing without the check for a negative value."""
    if not isinstance(i, types.Integer):
        return None
    return types.uint64(i), lambda context, builder, sig, args: context.cast(builder, args[0], sig.args[0],
                                                                              types.uint64)
