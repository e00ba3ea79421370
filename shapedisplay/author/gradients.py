"""Gradient analysis of height fields: slopes, walls, and how walls are limited.

Functions on arrays of shape (rows, cols): ``gx = dh/dx`` (along columns)
and ``gy = dh/dy`` (along rows), dimensionless slopes. A 1-D field (one row)
has ``gy = 0``.

Methods (:data:`GRADIENT_METHODS`, selected by name):

``"central"``
    Second-order central differences inside, second-order one-sided at the
    edges: error ``h^2/6 * f'''`` (O(dx^2)). Exact for quadratics.
``"gaussian"``
    Derivative of a Gaussian of standard deviation ``sigma`` (metres) —
    smooths noisy maps; the result is the exact slope of the height field
    convolved with that Gaussian (edges: nearest-value extension).
``"savgol"``
    Savitzky-Golay derivative along each axis with ``window`` samples (odd,
    or a length such as "1 mm") and polynomial ``order``: exact for
    polynomials of degree <= order inside the map.

A *wall* is a sample whose slope magnitude exceeds ``max_slope`` — too
steep to render (e.g. the vertical side of a mesh button, where the
finite-difference slope is height/dx). :func:`detect_walls` says where they
are; :func:`limit_walls` clips the slope magnitude to ``max_slope`` while
keeping its direction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from shapedisplay.errors import InputError, unknown_key
from shapedisplay.author.heightfield import HeightField


# ----------------------------------------------------------------- methods
def _diff_axis(h: np.ndarray, step: float, axis: int, out: np.ndarray) -> np.ndarray:
    """Second-order derivative along ``axis`` written into ``out`` (no large temporaries)."""
    n = h.shape[axis]
    hv = np.moveaxis(h, axis, -1)
    ov = np.moveaxis(out, axis, -1)
    if n < 2:
        ov[...] = 0.0
        return out
    if n == 2:
        np.subtract(hv[..., 1:], hv[..., :1], out=ov[..., :1])
        ov[..., 1:] = ov[..., :1]
        ov *= 1.0 / step
        return out
    np.subtract(hv[..., 2:], hv[..., :-2], out=ov[..., 1:-1])
    ov[..., 1:-1] *= 0.5 / step
    # second-order one-sided edges: (-3 f0 + 4 f1 - f2) / 2h, written as differences so that
    # a flat edge gives exactly 0
    ov[..., 0] = (4.0 * (hv[..., 1] - hv[..., 0]) - (hv[..., 2] - hv[..., 0])) * (0.5 / step)
    ov[..., -1] = (4.0 * (hv[..., -1] - hv[..., -2]) - (hv[..., -1] - hv[..., -3])) * (0.5 / step)
    return out


def central_band(h: np.ndarray, dx: float, dy: float, r0: int, r1: int, gx: np.ndarray, gy: np.ndarray) -> None:
    """Rows ``r0..r1-1`` of :func:`central`'s slopes of ``h`` (at least 3 x 3), written into ``gx``, ``gy``.

    The same operations on the same samples as the whole-array function, so
    the same values bit for bit; lets a large map be processed a band of
    rows at a time. In one pass in C where the compiler's C kernels are
    here (:mod:`shapedisplay.author.kernels`).
    """
    from shapedisplay.author import kernels as _kernels
    whole = h.ndim == 2 and h.dtype == np.float64 and h.flags.c_contiguous and gx.size == (r1 - r0) * h.shape[1]
    lib = _kernels._c_for(gx, gy) if whole else None
    if lib is not None and lib.sd_central_band(h.ctypes.data, h.shape[0], h.shape[1], r0, r1, 0.5 / dx,
                                               0.5 / dy, gx.ctypes.data, gy.ctypes.data) == 0:
        return
    _diff_axis(h[r0:r1], dx, 1, gx)
    rows = h.shape[0]
    lo, hi = max(r0, 1), min(r1, rows - 1)
    if hi > lo:
        inner = gy[lo - r0:hi - r0]
        np.subtract(h[lo + 1:hi + 1], h[lo - 1:hi - 1], out=inner)
        inner *= 0.5 / dy
    if r0 == 0:
        gy[0] = (4.0 * (h[1] - h[0]) - (h[2] - h[0])) * (0.5 / dy)
    if r1 == rows:
        gy[rows - 1 - r0] = (4.0 * (h[-1] - h[-2]) - (h[-1] - h[-3])) * (0.5 / dy)


def central(hf: HeightField) -> tuple[np.ndarray, np.ndarray]:
    """Central differences, O(dx^2) everywhere (one-sided second order at edges)."""
    h = hf.heights
    gx = _diff_axis(h, hf.dx, 1, np.empty_like(h))
    gy = np.zeros_like(h) if hf.rows == 1 else _diff_axis(h, hf.dy, 0, np.empty_like(h))
    return gx, gy


def gaussian(hf: HeightField, sigma=None) -> tuple[np.ndarray, np.ndarray]:
    """Derivative-of-Gaussian slopes; ``sigma`` in metres (or "0.2 mm"); default 1.5 dx."""
    from scipy import ndimage

    s = 1.5 * hf.dx if sigma is None else _positive_length(sigma, "sigma")
    sx, sy = s / hf.dx, s / hf.dy
    if sx > hf.cols or (hf.rows > 1 and sy > hf.rows):
        # the filter would smooth the map away, and its kernel (8 sigma) costs time in proportion
        raise InputError(
            f"gaussian `sigma` must not exceed the map extent ({hf.cols * hf.dx:g} m x {hf.rows * hf.dy:g} m; "
            f"got sigma={s:g} m)")
    h = hf.heights
    if hf.rows == 1:
        gx = ndimage.gaussian_filter1d(h[0], sx, order=1, mode="nearest")[None, :] / hf.dx
        return gx, np.zeros_like(h)
    gx = ndimage.gaussian_filter(h, (sy, sx), order=(0, 1), mode="nearest")
    gx /= hf.dx
    gy = ndimage.gaussian_filter(h, (sy, sx), order=(1, 0), mode="nearest")
    gy /= hf.dy
    return gx, gy


def savgol(hf: HeightField, window=7, order: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Savitzky-Golay derivative; ``window`` odd samples or a length; ``order`` < window."""
    from scipy.signal import savgol_filter

    order = int(order)
    if order < 1:
        raise InputError(f"savgol `order` must be >= 1 (got {order})")

    def win(step: float, n: int) -> int:
        if isinstance(window, str):
            w = int(round(_positive_length(window, "window") / step))
        else:
            w = int(window)
            if w != window or w % 2 == 0:
                raise InputError(f"savgol `window` must be an odd number of samples or a length (got {window!r})")
        w = w + 1 if w % 2 == 0 else w   # a length rounds up to an odd window
        if w <= order:
            raise InputError(f"savgol `window` ({w} samples) must exceed `order` ({order})")
        if w > n:
            raise InputError(f"savgol `window` ({w} samples) is longer than the map ({n} samples)")
        return w

    h = hf.heights
    gx = savgol_filter(h, win(hf.dx, hf.cols), order, deriv=1, delta=hf.dx, axis=1, mode="interp")
    if hf.rows == 1:
        return gx, np.zeros_like(h)
    gy = savgol_filter(h, win(hf.dy, hf.rows), order, deriv=1, delta=hf.dy, axis=0, mode="interp")
    return gx, gy


#: name -> ``function(hf, **kw) -> (gx, gy)``
GRADIENT_METHODS = {"central": central, "gaussian": gaussian, "savgol": savgol}
_METHOD_KW = {"central": (), "gaussian": ("sigma",), "savgol": ("window", "order")}


def _positive_length(value, name: str) -> float:
    from shapedisplay.units import parse_quantity
    v = parse_quantity(value, "m", name) if isinstance(value, str) else float(value)
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"`{name}` must be a length > 0 (got {value!r})")
    return v


def gradient(hf: HeightField, method: str = "central", **kw) -> tuple[np.ndarray, np.ndarray]:
    """Slopes of a height field.

    Parameters
    ----------
    hf : HeightField
    method : {"central", "gaussian", "savgol"}
        See module docs. Keywords: gaussian ``sigma`` (m); savgol ``window``
        (samples or length), ``order``.

    Returns
    -------
    gx, gy : ndarray of shape (rows, cols), float64
        dh/dx and dh/dy (dimensionless); ``gy`` is zero for a 1-D field.
    """
    if method not in GRADIENT_METHODS:
        raise unknown_key("gradient method", method, GRADIENT_METHODS)
    for k in kw:
        if k not in _METHOD_KW[method]:
            raise unknown_key(f"option of gradient method '{method}'", k, _METHOD_KW[method] or ("(none)",))
    return GRADIENT_METHODS[method](hf, **kw)


def slope_along(gx: np.ndarray, gy: np.ndarray, direction) -> np.ndarray:
    """Slope along a direction: ``grad h . u``.

    ``direction`` is an angle from +x in radians, or a vector (ux, uy)
    (normalised here; arrays broadcast against ``gx``).
    """
    if np.ndim(direction) == 0:
        ux, uy = math.cos(float(direction)), math.sin(float(direction))
    else:
        ux, uy = (np.asarray(v, dtype=np.float64) for v in direction)
        norm = np.hypot(ux, uy)
        if np.any(norm == 0) or not np.all(np.isfinite(norm)):
            raise InputError(f"`direction` must be a non-zero finite vector (got {direction!r})")
        ux, uy = ux / norm, uy / norm
    return gx * ux + gy * uy


def slope_magnitude(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """``|grad h|`` (dimensionless), shape of ``gx``."""
    return np.hypot(gx, gy)


# ----------------------------------------------------------------- walls
@dataclass
class WallReport:
    """Where the surface is too steep to render.

    Attributes
    ----------
    mask : ndarray (rows, cols) bool
        True at wall samples (slope magnitude > max_slope).
    count : int
    fraction : float
        count / samples.
    max_slope : float
        The limit used (dimensionless slope; inf = no limit).
    steepest : float
        Largest slope magnitude found.
    boxes_mm : list of [x_min, x_max, y_min, y_max]
        Bounding boxes (sample centres, mm) of connected wall regions, largest
        first (at most :attr:`MAX_BOXES`).
    regions : int
        Number of connected wall regions.
    limited : str
        How the walls were treated ("not limited", or the clipping rule).
    """

    mask: np.ndarray
    count: int
    fraction: float
    max_slope: float
    steepest: float
    boxes_mm: list = field(default_factory=list)
    regions: int = 0
    limited: str = "not limited"

    MAX_BOXES = 20

    @property
    def boxes(self) -> list:
        """Same as :attr:`boxes_mm` ([x_min, x_max, y_min, y_max] in mm)."""
        return self.boxes_mm

    def to_json(self) -> dict:
        """JSON-safe summary (no mask)."""
        return {"count": self.count, "fraction": self.fraction,
                "max_slope": None if math.isinf(self.max_slope) else self.max_slope,
                "steepest": self.steepest, "regions": self.regions, "boxes_mm": self.boxes_mm,
                "limited": self.limited}


def wall_lines(walls: dict, boxes: int = 5) -> list[str]:
    """The wall report's text (compile, inspect and the 3D preview say the same): count, share of the
    canvas, regions, and each of the ``boxes`` largest regions' box in mm with the widgets it touches."""
    if not walls.get("count"):
        steepest = walls.get("steepest")
        return ["walls: none" + (f" (steepest slope {steepest:.3g})" if isinstance(steepest, (int, float)) else "")]
    lines = [f"walls: {walls['count']} samples ({walls['fraction'] * 100:.3g} % of the canvas) in "
             f"{walls['regions']} region(s) steeper than {walls['max_slope']}, steepest {walls['steepest']:.3g}; "
             f"{walls['limited']}"]
    named = walls.get("region_widgets") or []
    shown = walls.get("boxes_mm") or []
    for i, b in enumerate(shown[:boxes]):
        ids = named[i] if i < len(named) else None
        where = (f": widget{'s' if len(ids) > 1 else ''} {', '.join(ids)}" if ids else
                 (": between widgets" if ids is not None else ""))
        lines.append(f"  x {b[0]:.4g}..{b[1]:.4g} mm, y {b[2]:.4g}..{b[3]:.4g} mm{where}")
    if walls["regions"] > min(len(shown), boxes):
        lines.append(f"  ... and {walls['regions'] - min(len(shown), boxes)} smaller region(s)")
    return lines


def _check_max_slope(max_slope) -> float:
    v = float(max_slope)
    if math.isnan(v) or v <= 0:
        raise InputError(f"`max_slope` must be > 0 (got {max_slope!r})")
    return v


#: Arrays at least this large go through the single-pass kernels (:mod:`._kernels`, C where it can be
#: built); smaller ones use plain numpy, which gives the same results without building anything.
KERNEL_MIN_SIZE = 1 << 16


def _flat(a) -> np.ndarray | None:
    """1-D view of a large C-contiguous float64 array (for the C kernels, :mod:`._kernels`), else None."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous \
            and a.size >= KERNEL_MIN_SIZE:
        return a.reshape(-1)
    return None


def _magnitude_sq(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """gx^2 + gy^2 with one float64 temporary (no hypot: several times slower)."""
    with np.errstate(over="ignore"):   # an overflow shows as inf; callers refuse it
        m2 = np.multiply(gx, gx)
        t = np.multiply(gy, gy)
        m2 += t
    return m2


def detect_walls(hf: HeightField, gx: np.ndarray, gy: np.ndarray, max_slope: float) -> WallReport:
    """Find samples steeper than ``max_slope`` and describe where they are.

    Parameters
    ----------
    hf : HeightField
        The field the slopes belong to (for positions).
    gx, gy : ndarray (rows, cols)
        Slopes.
    max_slope : float
        Steepest renderable slope (dimensionless, > 0; ``inf`` disables).

    Returns
    -------
    WallReport
        Boxes are those of the largest connected wall regions (by sample
        count), largest first.
    """
    limit = _check_max_slope(max_slope)
    fx, fy = _flat(gx), _flat(gy)
    if fx is not None and fy is not None and gx.shape == gy.shape and gx.size:
        from shapedisplay.author import kernels as _kernels
        count, peak2, flat_mask = _kernels.wall_scan(fx, fy, limit * limit)
        steepest = math.sqrt(peak2)
        if math.isinf(limit) or count == 0:
            return WallReport(np.zeros(gx.shape, dtype=bool), 0, 0.0, limit, steepest)
        mask = flat_mask.reshape(gx.shape)
    else:
        m2 = _magnitude_sq(gx, gy)
        steepest = math.sqrt(float(m2.max(initial=0.0)))
        if math.isinf(limit) or steepest <= limit:
            return WallReport(np.zeros(gx.shape, dtype=bool), 0, 0.0, limit, steepest)
        mask = np.greater(m2, limit * limit, out=np.empty(gx.shape, dtype=bool))
        del m2
    _check_steepest(hf, steepest)
    return wall_report(hf, mask, int(np.count_nonzero(mask)), limit, steepest)


def _check_steepest(hf: HeightField, steepest: float) -> None:
    if not math.isfinite(steepest):
        lo, hi = float(hf.heights.min()), float(hf.heights.max())
        raise InputError(
            f"slopes overflow float64 (|grad h| beyond 1e154): heights {lo:g}..{hi:g} m over spacing "
            f"dx={hf.dx:g} m, dy={hf.dy:g} m; check the units of the size and height range ({hf.source})")


def wall_report(hf: HeightField, mask: np.ndarray, count: int, limit: float, steepest: float) -> WallReport:
    """The :class:`WallReport` of ``count`` > 0 wall samples in ``mask`` (regions and their boxes)."""
    n, top, spans = wall_regions(mask, WallReport.MAX_BOXES)
    boxes = [[round((hf.x0 + c0 * hf.dx) * 1e3, 6), round((hf.x0 + c1 * hf.dx) * 1e3, 6),
              round((hf.y0 + r0 * hf.dy) * 1e3, 6), round((hf.y0 + r1 * hf.dy) * 1e3, 6)]
             for r0, r1, c0, c1 in spans]
    return WallReport(mask, count, count / mask.size, limit, steepest, boxes, int(n))


def wall_regions(mask: np.ndarray, k: int) -> tuple[int, np.ndarray, list]:
    """Connected regions of ``mask`` (4-connected, as ``scipy.ndimage.label``) and the ``k`` largest.

    Parameters
    ----------
    mask : ndarray (rows, cols) bool
    k : int
        How many of the largest regions to describe.

    Returns
    -------
    n : int
        Number of regions.
    top : ndarray (min(k, n),) int64
        Labels (``ndimage.label`` numbering: raster order of each region's
        first sample) of the largest regions, largest first; equal sizes in
        label order.
    spans : list of (row_min, row_max, col_min, col_max)
        Inclusive sample bounds of each region in ``top``.

    One pass over the mask's rows in C (``sd_regions`` in ``sd_kernels.c``:
    union-find over the runs of each row, each region's size and box kept at
    its root; no label per sample): about 0.13 s for a noisy 4096x4096 map's
    2.2 million regions. The tests hold it to ``scipy.ndimage.label``.
    """
    from shapedisplay.author import kernels as _kernels
    m = np.ascontiguousarray(mask, dtype=bool)
    if m.ndim != 2 or m.size == 0:
        return 0, np.zeros(0, np.int64), []
    rows, cols = m.shape
    top = np.zeros(max(k, 1), np.int64)
    spans = np.zeros(4 * max(k, 1), np.int64)
    n = int(_kernels.library().sd_regions(m.ctypes.data, rows, cols, k, top.ctypes.data, spans.ctypes.data))
    if n < 0:
        raise InputError(f"not enough memory to count the wall regions of a {cols} x {rows} map")
    kept = min(k, n)
    box = spans[:4 * kept].reshape(kept, 4).tolist()
    return n, top[:kept].copy(), [tuple(b) for b in box]


def _check_finite_peak(peak: float) -> None:
    if not math.isfinite(peak):   # |g|^2 overflowed: the direction cannot be kept, limiting would give 0
        raise InputError("slopes overflow float64 (|grad h| beyond 1e154); check the units of the spacing and heights")


def limit_walls(gx: np.ndarray, gy: np.ndarray, max_slope: float, *, out=None,
                walls: WallReport | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Clip the slope magnitude to ``max_slope``, keeping its direction.

    Where ``|grad h| > max_slope`` the slope becomes
    ``max_slope * grad h / |grad h|``; elsewhere it is unchanged.
    ``out=(gx_out, gy_out)`` may be ``(gx, gy)`` to work in place.
    ``walls``: the report :func:`detect_walls` gave for these slopes and
    this ``max_slope`` (with its mask); only its wall samples are then
    visited (same result, without a pass over every sample).
    """
    limit = _check_max_slope(max_slope)
    if out is None:
        out = (np.array(gx, dtype=np.float64, copy=True), np.array(gy, dtype=np.float64, copy=True))
    ox, oy = out
    if ox is not gx:
        ox[...] = gx
    if oy is not gy:
        oy[...] = gy
    if math.isinf(limit):
        return ox, oy
    fx, fy = _flat(ox), _flat(oy)
    if fx is not None and fy is not None and ox.shape == oy.shape and ox.size:
        from shapedisplay.author import kernels as _kernels
        if walls is not None and walls.mask is not None and walls.mask.shape == ox.shape \
                and walls.max_slope == limit and math.isfinite(walls.steepest):
            _kernels.clip_where(fx, fy, float(limit), np.ascontiguousarray(walls.mask).reshape(-1))
            return ox, oy
        _, peak = _kernels.clip_magnitude(fx, fy, float(limit))
        _check_finite_peak(peak)
        return ox, oy
    f = _magnitude_sq(ox, oy)
    peak2 = float(f.max(initial=0.0))
    _check_finite_peak(peak2)
    if peak2 <= limit * limit:
        return ox, oy
    # factor min(1, limit/|g|): exactly 1 (values unchanged) where |g| <= limit
    with np.errstate(divide="ignore", over="ignore"):   # |g| = 0 or subnormal: factor inf -> 1 below
        np.divide(limit * limit, f, out=f)
    np.minimum(f, 1.0, out=f)
    np.sqrt(f, out=f)
    ox *= f
    oy *= f
    return ox, oy
