"""Single-pass kernels for the compiler's large-array work, in C or in cache-sized numpy chunks.

Each kernel walks flat float64 arrays once. Where a C compiler is there,
the slope kernels (:func:`wall_scan`, :func:`clip_where`,
:func:`clip_magnitude`) and :func:`encode` run as their twins in ``sd_kernels.c`` (beside
this module), built once into the cache directory as the C runtime is
(:func:`c_kernels`): the same IEEE operations in the same order on the
same samples, built without fused multiply-adds, so the same values bit
for bit (the tests compare them), in one loop. Otherwise, and for the
others, numpy does the work a chunk of :data:`CHUNK` samples at a time,
so its temporaries are a few hundred KiB that stay in the CPU cache
instead of 128 MiB numpy temporaries of a 4096x4096 map (each a pass of
its own through memory). Not numba: loading numba and its cached kernels
costs a compile process about 0.6 s of start-up, more than these passes
take on a 4096x4096 map; loading the C library takes about a millisecond.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

#: Samples per chunk: 32 Ki float64 = 256 KiB per temporary (fits an L2 cache).
CHUNK = 1 << 15
#: The C source of the kernels' twins and of the wall-region count (shipped in the package).
C_SOURCE = Path(__file__).resolve().parent / "sd_kernels.c"
_C = None


def c_kernels():
    """The C kernels as a ctypes library, or None where they cannot be built or loaded here.

    Built from :data:`C_SOURCE` by the system C compiler (``$CC``, ``cc``,
    ``gcc`` or ``clang``) once per source version into the cache directory
    (``$XDG_CACHE_HOME/shapedisplay``), as the C runtime is; about half a
    second the first time. Without a compiler every kernel runs in numpy.
    """
    global _C
    if _C is None:
        import ctypes

        from .errors import ShapeDisplayError
        from .cbuild import load_shared, shared_library_path
        try:
            lib = load_shared(shared_library_path("sd_kernels", [C_SOURCE]), [C_SOURCE],
                              what="the compiler's C kernels")
        except ShapeDisplayError:
            _C = False
        else:
            vp, i64, f64 = ctypes.c_void_p, ctypes.c_int64, ctypes.c_double
            for name, args in (("sd_regions", [vp, i64, i64, i64, vp, vp]),
                               ("sd_wall_scan", [vp, vp, i64, f64, vp, vp, i64]),
                               ("sd_clip_where", [vp, vp, i64, f64, vp]),
                               ("sd_clip_magnitude", [vp, vp, i64, f64, vp, i64, f64]),
                               ("sd_central_band", [vp, i64, i64, i64, i64, f64, f64, vp, vp]),
                               ("sd_encode", [vp, i64, f64, f64, f64, f64, f64, vp, i64]),
                               ("sd_png_gray16", [vp, i64, i64, vp, vp]),
                               ("sd_gray_to_heights", [vp, i64, i64, i64, i64, f64, f64, vp])):
                fn = getattr(lib, name)
                fn.argtypes = args
                fn.restype = None if name == "sd_gray_to_heights" else i64
            _C = lib
    return _C or None


def _c_for(*slopes, mask=None):
    """:func:`c_kernels` if the slope arrays are C-contiguous float64 of one size (and ``mask``, if given,
    C-contiguous bool of that size), else None: numpy's path."""
    n = slopes[0].size
    for a in slopes:
        if not (a.flags.c_contiguous and a.dtype == np.float64 and a.size == n):
            return None
    if mask is not None and not (mask.flags.c_contiguous and mask.dtype == np.bool_ and mask.size == n):
        return None
    return c_kernels()


def _chunks(n: int):
    for i in range(0, n, CHUNK):
        yield slice(i, min(i + CHUNK, n))


def _magnitude_sq(gx, gy, m2, t):
    """``m2 = gx*gx + gy*gy`` into the chunk buffers ``m2``, ``t`` (overflow shows as inf)."""
    np.multiply(gx, gx, out=m2)
    np.multiply(gy, gy, out=t)
    np.add(m2, t, out=m2)
    return m2


def _buffers(n: int):
    k = min(n, CHUNK)
    return np.empty(k), np.empty(k)


def wall_scan(gx, gy, limit2):
    """One pass: (count of gx^2+gy^2 > limit2, max of gx^2+gy^2, mask or None) over flat arrays.

    The mask (flat bool, True where gx^2+gy^2 > limit2) is allocated only
    once a chunk holds such a sample; None means there is none.
    """
    lib = _c_for(gx, gy)
    if lib is not None:              # the C twin writes every sample's mask entry
        mask = np.empty(gx.size, dtype=bool)
        peak = np.zeros(1)
        count = lib.sd_wall_scan(gx.ctypes.data, gy.ctypes.data, gx.size, limit2, mask.ctypes.data,
                                 peak.ctypes.data, CHUNK)
        return count, float(peak[0]), mask if count else None
    count = 0
    peak = 0.0
    mask = None
    b1, b2 = _buffers(gx.size)
    bb = np.empty(b1.size, dtype=bool)
    with np.errstate(over="ignore"):
        for s in _chunks(gx.size):
            k = s.stop - s.start
            m2 = _magnitude_sq(gx[s], gy[s], b1[:k], b2[:k])
            peak = max(peak, float(m2.max()))
            w = np.greater(m2, limit2, out=bb[:k])
            c = int(np.count_nonzero(w))
            if c and mask is None:
                mask = np.empty(gx.size, dtype=bool)
                mask[:s.start] = False
            count += c
            if mask is not None:
                mask[s] = w
    return count, peak, mask


def clip_where(fx, fy, limit, mask):
    """Scale (fx, fy) in place to magnitude ``limit`` where ``mask`` (flat bool) is True, keeping direction.

    The samples of ``mask`` must be those with fx^2 + fy^2 > limit^2 (what
    :func:`wall_scan` returns): then this is :func:`clip_magnitude` without
    the pass that finds them (the same operations on the same samples).
    Returns the count clipped.
    """
    lib = _c_for(fx, fy, mask=mask)
    if lib is not None:
        return lib.sd_clip_where(fx.ctypes.data, fy.ctypes.data, fx.size, limit, mask.ctypes.data)
    count = 0
    with np.errstate(over="ignore"):
        for s in _chunks(fx.size):
            over = np.flatnonzero(mask[s])
            if over.size:
                cx = fx[s]
                cy = fy[s]
                x = cx[over]
                y = cy[over]
                m2 = np.multiply(x, x)
                m2 += np.multiply(y, y)
                f = limit / np.sqrt(m2)
                x *= f
                y *= f
                cx[over] = x
                cy[over] = y
                count += int(over.size)
    return count


def clip_magnitude(fx, fy, limit, gain=None):
    """Scale (fx, fy) in place so that |(fx, fy)| <= limit, keeping direction.

    Samples within the limit are untouched; beyond it both components are
    multiplied by ``limit / sqrt(fx^2 + fy^2)``. With ``gain``, both are
    first multiplied by it (in the same pass where C does the work). Returns
    (count clipped, peak magnitude before clipping).
    """
    lib = _c_for(fx, fy)
    if lib is not None:
        peak = np.zeros(1)
        count = lib.sd_clip_magnitude(fx.ctypes.data, fy.ctypes.data, fx.size, limit, peak.ctypes.data, CHUNK,
                                      1.0 if gain is None else gain)
        return count, float(np.sqrt(peak[0]))
    if gain is not None:
        np.multiply(fx, gain, out=fx)
        np.multiply(fy, gain, out=fy)
    limit2 = limit * limit
    count = 0
    peak2 = 0.0
    b1, b2 = _buffers(fx.size)
    with np.errstate(over="ignore"):
        for s in _chunks(fx.size):
            k = s.stop - s.start
            m2 = _magnitude_sq(fx[s], fy[s], b1[:k], b2[:k])
            peak2 = max(peak2, float(m2.max()))
            over = np.flatnonzero(m2 > limit2)
            if over.size:
                f = limit / np.sqrt(m2[over])
                cx = fx[s]
                cy = fy[s]
                cx[over] *= f
                cy[over] *= f
                count += int(over.size)
    return count, float(np.sqrt(peak2))


def minmax(a):
    """(min, max) of a flat array in one pass (NaN propagates)."""
    return minmax_update(a)


def minmax_update(a, state=None):
    """:func:`minmax` of consecutive pieces of one flat array: ``state`` is what the previous piece returned.

    Every piece but the last must hold a whole number of chunks: the pieces
    then see the chunks :func:`minmax` of the whole array sees, and the
    result after the last piece is its result (even for NaN and signed zeros).
    """
    lo, hi = (a[0], a[0]) if state is None else state
    if lo != lo:
        return lo, hi
    for s in _chunks(a.size):
        c = a[s]
        cl, ch = c.min(), c.max()
        if cl != cl or ch != ch:
            return cl, cl
        lo = min(lo, cl)
        hi = max(hi, ch)
    return lo, hi


def encode(values, offset, scale, top, out, gain=None, base=0.0):
    """out[i] = clip(rint((v[i] - offset) / scale), 0, top) (integer out: uint8 with top 255 or uint16 with top
    65535; ``scale`` > 0) of v = values, or with ``gain`` of v = values * gain + base, computed in the same
    pass (a channel coded straight from the heights it is a linear map of)."""
    lib = _c_for(values)
    if lib is not None and out.flags.c_contiguous and out.size == values.size \
            and (out.dtype, top) in ((np.uint8, 255.0), (np.uint16, 65535.0)):
        g, b = (1.0, 0.0) if gain is None else (gain, base)
        if lib.sd_encode(values.ctypes.data, values.size, g, b, offset, scale, top, out.ctypes.data,
                         out.itemsize) >= 0:
            return
        # a NaN: numpy's path codes the whole array as before
    b1, _ = _buffers(values.size)
    for s in _chunks(values.size):
        c = b1[:s.stop - s.start]
        if gain is None:
            np.subtract(values[s], offset, out=c)
        else:
            np.multiply(values[s], gain, out=c)
            c += base
            c -= offset
        np.divide(c, scale, out=c)
        np.rint(c, out=c)
        np.clip(c, 0.0, top, out=c)
        out[s] = c


def png_gray16(data: bytes, rows: int, cols: int):
    """The pixels (uint16, rows x cols) of a non-interlaced 16-bit grey PNG from its inflated image data, or
    None where the C kernels are not here, the data is not ``rows * (2 * cols + 1)`` bytes or a row names
    a filter PNG does not have (the caller decodes with Pillow then)."""
    lib = c_kernels()
    if lib is None or len(data) != rows * (2 * cols + 1):
        return None
    out = np.empty((rows, cols), dtype=np.uint16)
    two_rows = np.empty(4 * cols, dtype=np.uint8)
    if lib.sd_png_gray16(np.frombuffer(data, dtype=np.uint8).ctypes.data, rows, cols, two_rows.ctypes.data,
                         out.ctypes.data) < 0:
        return None
    return out


def gray_to_heights(gray, step, lo):
    """``gray * step + lo`` as float64 (C order) of 2-D uint8/uint16 codes whose rows may be in reverse order
    (a negative row stride), in one pass in C; None where the C kernels are not here or the codes are laid
    out otherwise (numpy's path then)."""
    lib = c_kernels()
    if lib is None or gray.ndim != 2 or gray.dtype not in (np.uint8, np.uint16) or gray.strides[1] != gray.itemsize \
            or gray.strides[0] % gray.itemsize:
        return None
    out = np.empty(gray.shape, dtype=np.float64)
    lib.sd_gray_to_heights(gray.ctypes.data, gray.shape[0], gray.shape[1], gray.strides[0] // gray.itemsize,
                           gray.itemsize, step, lo, out.ctypes.data)
    return out
