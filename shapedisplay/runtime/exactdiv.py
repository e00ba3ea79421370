"""Division by a divisor fixed for a whole loop, correctly rounded, without a division per element.

``a / b`` in IEEE double precision is the correctly rounded quotient. A loop
dividing many ``a`` by one ``b`` can get the same bits from the reciprocal
``y = 1 / b`` (one division, outside the loop) and two fused multiply-adds
per element (Markstein's correction step):

    q = a * y            # within one ulp of a / b
    r = fma(-q, b, a)    # a - b q exactly (a fused multiply-add rounds once)
    q' = fma(r, y, q)    # = the correctly rounded a / b

With ``y`` the correctly rounded reciprocal (within half an ulp of ``1 / b``)
and ``q`` within one ulp of ``a / b``, ``q'`` is ``a / b`` rounded to nearest
(Markstein's theorem; P. Markstein, IBM J. Res. Dev. 34(1), 1990; J.-M.
Muller et al., *Handbook of Floating-Point Arithmetic*, the section on
Newton-Raphson-based division with an FMA), as long as nothing overflows or
underflows and ``a`` is finite. ``tests/test_bursts.py`` checks it against
``/`` on every sample index below 2**24 at the audio rates, on ten million
random pairs over sixty decades, and at the edges (zeros, signs, subnormal
and huge quotients excluded by the callers).

Why: a division costs several times a multiply-add even where the compiler
vectorises it, and the offline burst envelope divides twice per audio sample
(the sample time and the envelope phase). The fused multiply-add is LLVM's
``llvm.fma``: one instruction where the CPU has it, a correctly rounded
library call where it does not, so the bits never depend on the machine.

The conditions are checked, not assumed: :func:`divisor_ok` for the divisor
and :func:`span_nonzero` for the dividends, once per loop (the callers' dividends
are monotone along a loop, so its first and last one bound the rest); a
loop where they do not hold divides with ``/``. With both in range (dividend 0 or of magnitude 2**-960 .. 2**960,
divisor 2**-60 .. 2**60) the quotient, the reciprocal and the remainder are
normal numbers, which is all the theorem needs. A zero quotient is returned
as ``a * y``, which carries the sign ``a / b`` gives (the correction step
would turn ``-0`` into ``+0``).
"""
from __future__ import annotations

from numba import njit, types
from numba.extending import intrinsic


@intrinsic
def fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (``llvm.fma`` on float64)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)
    return sig, codegen


@njit(cache=True, inline="always", error_model="numpy")
def div_fixed(a, b, y):
    """``a / b`` bit for bit, given ``y = 1.0 / b`` (see the module docstring for when it holds)."""
    q = a * y
    r = fma(-q, b, a)
    return fma(r, y, q) if q != 0.0 else q


@njit(cache=True, inline="always", error_model="numpy")
def div_nonzero(a, b, y):
    """:func:`div_fixed` of a nonzero ``a`` (as :func:`span_nonzero` admits them): the quotient is then
    nonzero, so the test for a zero one goes (two vector instructions fewer in a loop the compiler
    vectorises)."""
    q = a * y
    return fma(fma(-q, b, a), y, q)


#: Dividends of magnitude in [TINY, HUGE] (or 0) and divisors in [1 / DIVISOR_RANGE, DIVISOR_RANGE] are safe.
TINY = 2.0 ** -960
HUGE = 2.0 ** 960
DIVISOR_RANGE = 2.0 ** 60


@njit(cache=True, inline="always", error_model="numpy")
def divisor_ok(b):
    """True if :func:`div_fixed` may divide by ``b`` (a magnitude in 2**-60 .. 2**60; False for inf, NaN)."""
    return 1.0 / DIVISOR_RANGE <= abs(b) <= DIVISOR_RANGE


@njit(cache=True, inline="always", error_model="numpy")
def span_nonzero(d0, d1):
    """True if every number between ``d0`` and ``d1`` is a dividend :func:`div_fixed` and :func:`div_nonzero`
    handle, none of them zero: both of one sign with magnitudes in 2**-960 .. 2**960 (False for a zero, NaN
    or inf). A loop whose dividends are monotone in its index checks its first and last one."""
    lo = min(d0, d1)
    hi = max(d0, d1)
    return (TINY <= lo and hi <= HUGE) or (-HUGE <= lo and hi <= -TINY)
