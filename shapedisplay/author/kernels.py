"""Kernels for the compiler's large-array work, in C (compiled at install) or in numpy chunks.

The slope kernels (:func:`wall_scan`, :func:`clip_where`,
:func:`clip_magnitude`), :func:`encode` and :func:`gray_to_heights` walk
flat arrays once; :func:`zbuffer` rasterises a triangle mesh
(:mod:`.raster`). They run in C: ``sd_kernels.c`` (beside this
module), compiled when the package is built or installed into the extension
module ``shapedisplay._kernels_c`` (``setup.py``) and loaded with ctypes
(:func:`c_kernels`, about a millisecond). The array kernels do the IEEE
operations numpy's whole-array and chunked arithmetic does, in the same order
on the same samples, built without fused multiply-adds, so the same values
bit for bit (``tests/test_c_kernels.py`` compares them with numpy), in one
loop. :func:`minmax` has no C twin: numpy does that work a chunk of
:data:`CHUNK` samples at a time, so its temporaries stay in the CPU cache.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

#: Samples per chunk: 32 Ki float64 = 256 KiB per temporary (fits an L2 cache). The C kernels take the
#: peak of a chunk as numpy's chunked arithmetic does (a chunk holding a NaN adds none).
CHUNK = 1 << 15
#: The C source of the kernels and of the wall-region count (shipped in the package, built into
#: :data:`EXTENSION`).
C_SOURCE = Path(__file__).resolve().parent / "sd_kernels.c"
#: The extension module the C kernels are compiled into (``setup.py``).
EXTENSION = "shapedisplay._kernels_c"
#: The loaded library; ``False`` switches :func:`c_kernels` off (the tests compare the numpy paths some
#: callers keep for other array layouts with the C ones).
_C = None
#: The loaded library whatever the switch says (:func:`library`).
_LIB = None


def library():
    """The compiled C kernels as a ctypes library, loaded once with their argument types declared.

    Raises :class:`~shapedisplay.errors.InputError` where the extension
    module is missing or does not load (a broken install).
    """
    global _LIB
    if _LIB is None:
        import ctypes

        from shapedisplay.extensions import extension_path, load_extension
        what = "the compiled C kernels"
        lib = load_extension(extension_path(EXTENSION, what), what, [C_SOURCE])
        vp, i64, f64 = ctypes.c_void_p, ctypes.c_int64, ctypes.c_double
        for name, args in (("sd_regions", [vp, i64, i64, i64, vp, vp]),
                           ("sd_wall_scan", [vp, vp, i64, f64, vp, vp, i64]),
                           ("sd_clip_where", [vp, vp, i64, f64, vp]),
                           ("sd_clip_magnitude", [vp, vp, i64, f64, vp, i64, f64]),
                           ("sd_central_band", [vp, i64, i64, i64, i64, f64, f64, vp, vp]),
                           ("sd_encode", [vp, i64, f64, f64, f64, f64, f64, vp, i64]),
                           ("sd_gray_to_heights", [vp, i64, i64, i64, i64, f64, f64, vp]),
                           ("sd_zbuffer", [vp, i64, vp, i64, vp, i64, i64, f64])):
            fn = getattr(lib, name)
            fn.argtypes = args
            fn.restype = None if name == "sd_gray_to_heights" else i64
        _LIB = lib
    return _LIB


def c_kernels():
    """:func:`library`, or None where switched off (``_C = False``: the tests compare the numpy paths)."""
    global _C
    if _C is None:
        _C = library()
    return _C or None


def _c_for(*slopes, mask=None):
    """:func:`c_kernels` if the slope arrays are C-contiguous float64 of one size (and ``mask``, if given,
    C-contiguous bool of that size), else None (for callers with a path of their own for other layouts)."""
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


def _flat(a, dtype=np.float64):
    """``a`` as a flat C-contiguous array of ``dtype``: a view where it is one already, else a copy."""
    return np.ascontiguousarray(a, dtype=dtype).reshape(-1)


def _same_size(*arrays):
    if any(a.size != arrays[0].size for a in arrays):
        raise ValueError(f"the arrays differ in size ({', '.join(str(a.size) for a in arrays)})")


def _write_back(a, flat):
    """Copy ``flat`` (a kernel's output from :func:`_flat` of ``a``) into ``a`` where it is a copy of ``a``."""
    if not (a.flags.c_contiguous and a.dtype == flat.dtype):
        a[...] = flat.reshape(a.shape)


def wall_scan(gx, gy, limit2):
    """One pass: (count of gx^2+gy^2 > limit2, max of gx^2+gy^2, mask or None) over flat arrays.

    The mask (flat bool, True where gx^2+gy^2 > limit2) is returned only
    where it holds such a sample; None means there is none. The peak is
    numpy's chunked maximum: a chunk of :data:`CHUNK` samples holding a NaN
    adds nothing to it (overflow shows as inf).
    """
    _same_size(gx, gy)
    x, y = _flat(gx), _flat(gy)
    mask = np.empty(x.size, dtype=bool)
    peak = np.zeros(1)
    count = c_kernels().sd_wall_scan(x.ctypes.data, y.ctypes.data, x.size, limit2, mask.ctypes.data,
                                     peak.ctypes.data, CHUNK)
    return count, float(peak[0]), mask if count else None


def clip_where(fx, fy, limit, mask):
    """Scale (fx, fy) in place to magnitude ``limit`` where ``mask`` (flat bool) is True, keeping direction.

    The samples of ``mask`` must be those with fx^2 + fy^2 > limit^2 (what
    :func:`wall_scan` returns): then this is :func:`clip_magnitude` without
    the pass that finds them (the same operations on the same samples).
    Returns the count clipped.
    """
    _same_size(fx, fy, mask)
    x, y, m = _flat(fx), _flat(fy), _flat(mask, np.bool_)
    count = c_kernels().sd_clip_where(x.ctypes.data, y.ctypes.data, x.size, limit, m.ctypes.data)
    _write_back(fx, x)
    _write_back(fy, y)
    return count


def clip_magnitude(fx, fy, limit, gain=None):
    """Scale (fx, fy) in place so that ``|(fx, fy)| <= limit``, keeping direction.

    Samples within the limit are untouched; beyond it both components are
    multiplied by ``limit / sqrt(fx^2 + fy^2)``. With ``gain``, both are
    first multiplied by it (in the same pass). Returns (count clipped, peak
    magnitude before clipping; the peak as :func:`wall_scan` takes it).
    """
    _same_size(fx, fy)
    x, y = _flat(fx), _flat(fy)
    peak = np.zeros(1)
    count = c_kernels().sd_clip_magnitude(x.ctypes.data, y.ctypes.data, x.size, limit, peak.ctypes.data, CHUNK,
                                          1.0 if gain is None else gain)
    _write_back(fx, x)
    _write_back(fy, y)
    return count, float(np.sqrt(peak[0]))


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


#: The integer codes :func:`encode` writes: dtype -> largest code.
TOPS = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}


def encode(values, offset, scale, top, out, gain=None, base=0.0):
    """out[i] = clip(rint((v[i] - offset) / scale), 0, top) (integer out: uint8 with top 255 or uint16 with top
    65535; ``scale`` > 0) of v = values, or with ``gain`` of v = values * gain + base, computed in the same
    pass (a channel coded straight from the heights it is a linear map of). The codes are those of
    numpy's subtract, divide, rint and clip (ties to even, of the quotient). A NaN value has no code:
    :class:`~shapedisplay.errors.InputError` (the compiler codes only finite ranges)."""
    _same_size(values, out)
    if TOPS.get(out.dtype) != top:
        raise ValueError(f"codes of top {top} do not fit {out.dtype} (uint8: 255, uint16: 65535)")
    v = _flat(values)
    codes = out.reshape(-1) if out.flags.c_contiguous else np.empty(out.size, out.dtype)
    g, b = (1.0, 0.0) if gain is None else (gain, base)
    if c_kernels().sd_encode(v.ctypes.data, v.size, g, b, offset, scale, top, codes.ctypes.data, out.itemsize) < 0:
        from shapedisplay.errors import InputError
        raise InputError("a value to code is NaN (it has no code)")
    _write_back(out, codes)


def gray_to_heights(gray, step, lo):
    """``gray * step + lo`` as float64 (C order) of 2-D uint8/uint16 codes whose rows may be in reverse order
    (a negative row stride), in one pass in C; None where the C kernels are switched off or the codes are
    laid out otherwise (the caller converts with numpy then)."""
    lib = c_kernels()
    if lib is None or gray.ndim != 2 or gray.dtype not in (np.uint8, np.uint16) or gray.strides[1] != gray.itemsize \
            or gray.strides[0] % gray.itemsize:
        return None
    out = np.empty(gray.shape, dtype=np.float64)
    lib.sd_gray_to_heights(gray.ctypes.data, gray.shape[0], gray.shape[1], gray.strides[0] // gray.itemsize,
                           gray.itemsize, step, lo, out.ctypes.data)
    return out


def zbuffer(vertices, faces, zbuf, tol):
    """Max z-buffer of the triangles ``faces`` of ``vertices`` into ``zbuf`` in place (see :mod:`.raster`).

    ``vertices`` (n, 3) float64 and ``faces`` (m, 3) int64, both C-contiguous,
    ``zbuf`` (rows, cols) C-contiguous float64, ``tol`` the edge tolerance in
    samples. One pass over the triangles in C, each over the samples of its
    bounding box clipped to the grid.
    """
    for a, dtype in ((vertices, np.float64), (faces, np.int64), (zbuf, np.float64)):
        if not (a.flags.c_contiguous and a.dtype == dtype and a.ndim == 2):
            raise ValueError(f"zbuffer takes C-contiguous 2-D {np.dtype(dtype)} arrays (got {a.dtype} {a.shape})")
    if vertices.shape[1] != 3 or faces.shape[1] != 3:
        raise ValueError(f"zbuffer takes vertices (n, 3) and faces (m, 3) (got {vertices.shape}, {faces.shape})")
    rows, cols = zbuf.shape
    if c_kernels().sd_zbuffer(vertices.ctypes.data, len(vertices), faces.ctypes.data, len(faces),
                              zbuf.ctypes.data, rows, cols, tol) < 0:
        raise ValueError(f"`faces` index outside 0..{len(vertices) - 1}")
