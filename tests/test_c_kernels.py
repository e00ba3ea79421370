"""The compiler's C kernels (``shapedisplay/author/sd_kernels.c``, compiled at install) against numpy, bit for bit.

Every kernel of ``_kernels`` runs in C; the reference here is numpy's
arithmetic a chunk at a time (the functions below: what the package did
before the kernels were compiled with it), run on copies of the same input.
Outputs are compared as bytes, so NaN, infinities and the sign of zero count
too; the chunk size is made small so that many chunk boundaries (and chunks
holding a NaN, whose peak the Python around numpy ignores) are crossed. The
kernels with another path in their callers (slopes in ``gradients``, codes to
heights in ``sources``) are compared with that path, the C kernels switched
off (``_kernels._C = False``).
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapedisplay.author import kernels as _kernels
from shapedisplay.errors import InputError

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")   # the numpy reference on inf and NaN

SPECIAL = [0.0, -0.0, 1.5, -1.5, 1e-320, -1e-320, 1e154, -1e154, 1e200, 3e307, np.inf, -np.inf, np.nan]


# --- the numpy reference: chunks of _kernels.CHUNK samples, as the C kernels take their peaks -------------

def _chunks(n):
    for i in range(0, n, _kernels.CHUNK):
        yield slice(i, min(i + _kernels.CHUNK, n))


def _magnitude_sq(gx, gy):
    m2 = np.multiply(gx, gx)
    m2 += np.multiply(gy, gy)
    return m2


def ref_wall_scan(gx, gy, limit2):
    count, peak, mask = 0, 0.0, np.zeros(gx.size, dtype=bool)
    with np.errstate(over="ignore"):
        for s in _chunks(gx.size):
            m2 = _magnitude_sq(gx[s], gy[s])
            peak = max(peak, float(m2.max()))        # a chunk holding a NaN: max(peak, nan) keeps the peak
            mask[s] = m2 > limit2
            count += int(np.count_nonzero(mask[s]))
    return count, peak, mask if count else None


def ref_clip_where(fx, fy, limit, mask):
    over = np.flatnonzero(mask)
    x, y = fx[over], fy[over]
    with np.errstate(over="ignore"):
        f = limit / np.sqrt(_magnitude_sq(x, y))
    fx[over] = x * f
    fy[over] = y * f
    return int(over.size)


def ref_clip_magnitude(fx, fy, limit, gain=None):
    if gain is not None:
        np.multiply(fx, gain, out=fx)
        np.multiply(fy, gain, out=fy)
    count, peak2 = 0, 0.0
    with np.errstate(over="ignore"):
        for s in _chunks(fx.size):
            m2 = _magnitude_sq(fx[s], fy[s])
            peak2 = max(peak2, float(m2.max()))
            over = np.flatnonzero(m2 > limit * limit)
            if over.size:
                f = limit / np.sqrt(m2[over])
                fx[s][over] *= f
                fy[s][over] *= f
                count += int(over.size)
    return count, float(np.sqrt(peak2))


def ref_encode(values, offset, scale, top, out, gain=None, base=0.0):
    c = values - offset if gain is None else values * gain + base - offset
    np.divide(c, scale, out=c)
    np.rint(c, out=c)
    np.clip(c, 0.0, top, out=c)
    out[...] = c


REFERENCE = {"wall_scan": ref_wall_scan, "clip_where": ref_clip_where, "clip_magnitude": ref_clip_magnitude,
             "encode": ref_encode}


def _both(name, *args):
    """(C result, numpy result) of ``_kernels.<name>`` and its reference, each on fresh copies of the arrays."""
    results = []
    for fn in (getattr(_kernels, name), REFERENCE[name]):
        copies = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
        results.append((fn(*copies), copies))
    return results


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return (a is None) == (b is None) and a.dtype == b.dtype and a.tobytes() == b.tobytes()
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return np.array([a]).tobytes() == np.array([b]).tobytes()
    return type(a) is type(b) and a == b


def _slopes(seed, n, specials):
    rng = np.random.default_rng(seed)
    gx, gy = rng.normal(0, 2, n), rng.normal(0, 2, n)
    if specials and n:
        idx = rng.integers(0, n, 2 * specials)
        gx[idx[:specials]] = rng.choice(SPECIAL, specials)
        gy[idx[specials:]] = rng.choice(SPECIAL, specials)
    return gx, gy


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(0, 700), st.integers(0, 12), st.sampled_from([1, 7, 64, 1 << 15]),
       st.sampled_from([0.0, 1e-300, 2.25, 1e300, np.inf]))
def test_slope_kernels_match_numpy(seed, n, specials, chunk, limit2):
    gx, gy = _slopes(seed, n, specials)
    saved = _kernels.CHUNK
    _kernels.CHUNK = chunk
    try:
        (c, _), (ref, _) = _both("wall_scan", gx, gy, limit2)
        assert _same(c, ref)
        limit = float(np.sqrt(limit2))
        (c, (cx, cy, _)), (ref, (rx, ry, _)) = _both("clip_magnitude", gx, gy, limit)
        assert _same(c, ref) and _same(cx, rx) and _same(cy, ry)
        for gain in (-1.0, 2.5e-3, -7e300):
            (c, (cx, cy, _, _)), (ref, (rx, ry, _, _)) = _both("clip_magnitude", gx, gy, limit, gain)
            assert _same(c, ref) and _same(cx, rx) and _same(cy, ry)
        mask = ref_mask = _both("wall_scan", gx, gy, limit2)[1][0][2]
        if ref_mask is None:
            mask = np.zeros(n, bool)
        (c, (cx, cy, _, _)), (ref, (rx, ry, _, _)) = _both("clip_where", gx, gy, limit, mask)
        assert _same(c, ref) and _same(cx, rx) and _same(cy, ry)
    finally:
        _kernels.CHUNK = saved


def test_chunks_holding_a_nan_leave_the_peak_as_numpy_does():
    """numpy's chunk maximum is NaN where the chunk holds one, and Python's max(peak, nan) keeps the peak:
    the C kernels skip that whole chunk's peak too (its other samples included)."""
    gx = np.array([1.0, 2.0, 9.0, np.nan, 3.0, 4.0, 5.0, 0.5])
    gy = np.zeros_like(gx)
    saved = _kernels.CHUNK
    _kernels.CHUNK = 4
    try:
        (c, _), (ref, _) = _both("wall_scan", gx, gy, 1.0)
        assert _same(c, ref) and c[1] == 25.0             # 81 sits in the chunk with the NaN
        (c, _), (ref, _) = _both("clip_magnitude", gx, gy, 100.0)
        assert _same(c, ref) and c[1] == 5.0
    finally:
        _kernels.CHUNK = saved


def test_arrays_of_other_layouts_are_taken_as_flat_float64():
    """A strided or float32 array is copied to flat float64 for the C kernels; the in-place ones write back."""
    gx = np.arange(20.0)[::2]                             # not contiguous
    gy = np.ones(10)
    assert _kernels._c_for(gx, gy) is None                # the callers with a path of their own take it
    assert _kernels._c_for(np.ones(3, np.float32)) is None
    count, peak, mask = _kernels.wall_scan(gx, gy, 100.0)
    assert count == 5 and peak == 18.0 ** 2 + 1.0 and mask.tolist() == [False] * 5 + [True] * 5
    fx, fy = np.arange(40.0).reshape(4, 10)[:, ::2], np.zeros((4, 5), np.float32)
    rx, ry = fx.copy(), fy.astype(np.float64)
    assert _kernels.clip_magnitude(fx, fy, 10.0) == ref_clip_magnitude(rx.reshape(-1), ry.reshape(-1), 10.0)
    assert fx.tobytes() == rx.tobytes() and np.array_equal(fy, ry)
    with pytest.raises(ValueError, match="differ in size"):
        _kernels.wall_scan(np.ones(3), np.ones(4), 1.0)


def _codes(seed, n, top, specials):
    """Values, offset and scale as the compiler codes a channel (offset = min, scale = range / top), with
    quotients on and next to the half-way points between codes, where a product by the reciprocal could
    round to another code than the quotient."""
    rng = np.random.default_rng(seed)
    lo = float(rng.choice([0.0, -1.5, 0.3, -7e-4, 1e3]))
    scale = float(rng.choice([1.0, 0.1, 3.0, 1e-3, 7.7e-9, 1 / 3])) * float(rng.uniform(0.5, 2.0))
    k = rng.integers(-2, int(top) + 3, n) + 0.5
    half = lo + k * scale                               # on (or rounded next to) a half-way point
    steps = rng.integers(-3, 4, n)
    values = np.where(rng.random(n) < 0.5, np.nextafter(half, np.sign(steps) * np.inf), half)
    values = np.where(steps == 0, half, values)
    plain = rng.random(n) < 0.3
    values[plain] = lo + rng.uniform(-0.1, 1.1, int(plain.sum())) * scale * top
    if specials and n:
        values[rng.integers(0, n, specials)] = rng.choice([np.inf, -np.inf, 1e308, -1e308, 0.0, -0.0], specials)
    return values, lo, scale


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(1, 5000), st.sampled_from([(np.uint8, 255.0), (np.uint16, 65535.0)]),
       st.integers(0, 6))
def test_encode_matches_numpy_on_and_next_to_half_way_points(seed, n, kind, specials):
    dtype, top = kind
    values, lo, scale = _codes(seed, n, top, specials)
    (_, (_, _, _, _, c)), (_, (_, _, _, _, ref)) = _both("encode", values, lo, scale, top, np.zeros(n, dtype))
    assert _same(c, ref)
    # coded from heights it is a linear map of: N = h * gain + base
    gain, base = (1e3, 0.5) if seed % 2 else (-2.5, -1e-3)
    h = (values - base) / gain
    (_, (_, _, _, _, c, _, _)), (_, (_, _, _, _, ref, _, _)) = _both("encode", h, lo, scale, top, np.zeros(n, dtype),
                                                                     gain, base)
    assert _same(c, ref)


def test_encode_ties_go_to_the_even_code_where_the_reciprocal_would_not():
    """20.5 * 0.1 / 0.1 is 20.5 exactly, while its product by 1 / 0.1 rounds above it: the code is the
    quotient's (20, ties to even), not the product's (21); 3.5 * 0.7 the other way (4, not 3)."""
    for s, half, code in ((0.1, 20.5, 20), (0.7, 3.5, 4)):
        x = half * s
        assert x / s == half and np.rint(x * (1 / s)) != code
        values = np.full(3000, x)
        (_, (_, _, _, _, c)), (_, (_, _, _, _, ref)) = _both("encode", values, 0.0, s, 255.0,
                                                             np.zeros(3000, np.uint8))
        assert _same(c, ref) and set(c.tolist()) == {code}


def test_encode_refuses_a_nan():
    """The C twin reports a NaN quotient (-1) instead of choosing a code for it: no code, one line (the
    compiler codes only channels of finite range)."""
    values = np.linspace(0.0, 1.0, 5000)
    values[4321] = np.nan
    with pytest.raises(InputError, match="NaN"):
        _kernels.encode(values, 0.0, 1 / 255, 255.0, np.zeros(5000, np.uint8))
    out = np.zeros(5000, np.uint8)
    assert _kernels.c_kernels().sd_encode(values.ctypes.data, 5000, 1.0, 0.0, 0.0, 1 / 255, 255.0, out.ctypes.data,
                                          1) == -1
    with pytest.raises(ValueError, match="top 255.0 do not fit uint16"):
        _kernels.encode(np.zeros(3), 0.0, 1.0, 255.0, np.zeros(3, np.uint16))


def test_encode_into_a_strided_array_writes_back():
    values = np.linspace(-1.0, 2.0, 3001)
    out = np.zeros((3001, 2), np.uint16)
    _kernels.encode(values, 0.0, 1 / 65535, 65535.0, out[:, 1])
    ref = np.zeros(3001, np.uint16)
    ref_encode(values.copy(), 0.0, 1 / 65535, 65535.0, ref)
    assert np.array_equal(out[:, 1], ref) and not out[:, 0].any()


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(3, 40), st.integers(3, 40), st.integers(0, 8),
       st.sampled_from([1e-4, 0.37, 3.0]), st.sampled_from([1e-4, 0.37, 3.0]), st.data())
def test_central_band_matches_numpy(seed, rows, cols, specials, dx, dy, data):
    """Slopes of any band of rows (first, last, inner, all), heights with huge values (differences that
    overflow to inf, edge formulas that make NaN) and signed zeros: the numpy slopes byte for byte."""
    from shapedisplay.author.gradients import central_band
    rng = np.random.default_rng(seed)
    h = rng.normal(0, 1e-3, (rows, cols))
    if specials:
        h.flat[rng.integers(0, h.size, specials)] = rng.choice([0.0, -0.0, 1e308, -1e308, 5e-324, 1e154], specials)
    r0 = data.draw(st.integers(0, rows - 1))
    r1 = data.draw(st.integers(r0 + 1, rows))
    out = []
    for use_c in (True, False):
        gx, gy = np.full((r1 - r0, cols), 7.0), np.full((r1 - r0, cols), 7.0)
        saved = _kernels._C
        if not use_c:
            _kernels._C = False
        try:
            with np.errstate(all="ignore"):
                central_band(h, dx, dy, r0, r1, gx, gy)
        finally:
            _kernels._C = saved
        out.append((gx.tobytes(), gy.tobytes()))
    assert out[0] == out[1]


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("flipped", [False, True])
def test_gray_to_heights_in_c_matches_numpy(dtype, flipped):
    """Codes to heights in one C pass (rows read bottom first too, as a picture is put on the grid): the
    values numpy's convert, multiply, add give, byte for byte, with a step and offset that round."""
    from shapedisplay.author.sources import gray_to_heights
    rng = np.random.default_rng(7)
    top = np.iinfo(dtype).max
    g = rng.integers(0, top + 1, (300, 257)).astype(dtype)
    g[0, 0], g[-1, -1] = 0, top
    codes = g[::-1] if flipped else g
    c = gray_to_heights(codes, float(top), (-3e-4, 2.1e-3))
    saved = _kernels._C
    _kernels._C = False
    try:
        ref = gray_to_heights(codes, float(top), (-3e-4, 2.1e-3))
    finally:
        _kernels._C = saved
    assert c.flags.c_contiguous and c.dtype == np.float64 and c.tobytes() == ref.tobytes()
    assert _kernels.gray_to_heights(g[:, ::2], 1.0, 0.0) is None       # columns apart: numpy's path
