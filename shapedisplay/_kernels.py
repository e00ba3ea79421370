"""Single-pass numba kernels for the compiler's large-array work.

Each kernel walks flat float64 arrays once and allocates nothing, which
matters for 4096x4096 maps (one numpy temporary is 128 MiB and a pass of
its own). They are imported lazily (numba is not loaded by
``import shapedisplay``) and cached on disk after the first compilation.
Results are bit-identical to the numpy expressions they replace; the tests
check that.
"""
from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def slope_scan(gx, gy, limit2):  # pragma: no cover - compiled
    """(count of gx^2+gy^2 > limit2, max of gx^2+gy^2) over flat arrays."""
    count = 0
    peak = 0.0
    for i in range(gx.size):
        m2 = gx[i] * gx[i] + gy[i] * gy[i]
        if m2 > peak:
            peak = m2
        if m2 > limit2:
            count += 1
    return count, peak


@numba.njit(cache=True, nogil=True)
def wall_mask(gx, gy, limit2, out):  # pragma: no cover - compiled
    """out[i] = gx^2 + gy^2 > limit2 (flat arrays)."""
    for i in range(gx.size):
        out[i] = gx[i] * gx[i] + gy[i] * gy[i] > limit2


@numba.njit(cache=True, nogil=True)
def clip_magnitude(fx, fy, limit):  # pragma: no cover - compiled
    """Scale (fx, fy) in place so that |(fx, fy)| <= limit, keeping direction.

    Samples within the limit are untouched. Returns (count clipped, peak
    magnitude before clipping).
    """
    limit2 = limit * limit
    count = 0
    peak2 = 0.0
    for i in range(fx.size):
        m2 = fx[i] * fx[i] + fy[i] * fy[i]
        if m2 > peak2:
            peak2 = m2
        if m2 > limit2:
            f = limit / np.sqrt(m2)
            fx[i] *= f
            fy[i] *= f
            count += 1
    return count, np.sqrt(peak2)


@numba.njit(cache=True, nogil=True)
def minmax(a):  # pragma: no cover - compiled
    """(min, max) of a flat array in one pass (NaN propagates)."""
    lo = a[0]
    hi = a[0]
    for i in range(1, a.size):
        v = a[i]
        if v < lo:
            lo = v
        if v > hi:
            hi = v
        if v != v:
            return v, v
    return lo, hi


@numba.njit(cache=True, nogil=True)
def encode(values, offset, scale, top, out):  # pragma: no cover - compiled
    """out[i] = clip(rint((values[i] - offset) / scale), 0, top) (integer out)."""
    for i in range(values.size):
        c = np.rint((values[i] - offset) / scale)
        if c < 0.0:
            c = 0.0
        elif c > top:
            c = top
        out[i] = c
