"""Sources of height fields: analytic primitives, images, arrays, meshes.

Every function here returns a :class:`~shapedisplay.author.heightfield.HeightField`
(heights in metres). Lengths may be given as SI floats (metres) or as
strings with units ("12 mm"); forces likewise ("0.5 N", "2 N/mm").

Sample positions
----------------
Grids are *cell-centred*: a region of width W split into ``cols`` cells has
``dx = W / cols`` and sample ``c`` at the centre of cell ``c``, i.e.
``x = x_left + (c + 0.5) * dx``. For an image of ``--size W x H`` this puts
pixel (r, c) at its centre: ``x = (c + 0.5) W / cols``,
``y = (rows - r - 0.5) H / rows``: the picture is the top view, its
bottom-left corner at (0, 0), x to the right and y up (picture row r is
height-field row ``rows - 1 - r``; see :mod:`shapedisplay.author.heightfield`).

Published profiles
------------------
:func:`ramp_profile` and :func:`tent_profile` express the normal-force
normal-force profiles as heights: with the height mapping
``N = n_base + n_gain * h`` and ``n_base = n1`` they give exactly the
published N(x) at every sample (:func:`ramp_force`, :func:`tent_force`).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from shapedisplay.errors import FileFormatError, InputError, unknown_key
from shapedisplay.author.heightfield import (HeightField, check_grid_size, check_spacing, finite_range as _minmax_finite,
                                             fit_range, height_range as _height_range, height_scale, parse_size)
from shapedisplay.author.imageio import PICTURE_SUFFIXES   # numpy only; Pillow is imported when a picture is read
from shapedisplay.author.instruments import SCAN_SUFFIXES, load_scan
from shapedisplay.author.shapes import PRIMITIVE_EDGES, rounded_rect_distance
from shapedisplay.units import parse_quantity

#: Suffixes load_source understands, by kind.
IMAGE_SUFFIXES = PICTURE_SUFFIXES + (".npy",)
#: Relief of an SVG icon compiled without a height range, m: a drawing states none (a scene's image
#: widget has the same default).
ICON_HEIGHT = (0.0, 2e-3)
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")
#: Kinds of file source that load into a height field (:func:`load_source`); instrument files are "scan".
HEIGHT_MAP_KINDS = ("image", "scan", "mesh")
EDGE_PROFILES = tuple(PRIMITIVE_EDGES)          # "ramp", "cosine", "step" (author/shapes.py)
LINE_PROFILES = ("cosine", "tent", "box")


# ----------------------------------------------------------------- helpers
def _length(value, name: str, positive: bool = False, allow_none: bool = False):
    """A length in metres from an SI float or a string with units."""
    if value is None and allow_none:
        return None
    v = parse_quantity(value, "m", name, bare_ok=not isinstance(value, str)) if isinstance(value, str) \
        else _finite(value, name)
    if positive and not v > 0:
        raise InputError(f"`{name}` must be > 0 (got {value!r})")
    return v


def _quantity(value, unit: str, name: str) -> float:
    if isinstance(value, str):
        return parse_quantity(value, unit, name)
    return _finite(value, name)


def _finite(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"`{name}` must be a number (got {value!r})") from None
    if not math.isfinite(v):
        raise InputError(f"`{name}` must be finite (got {value!r})")
    return v


def _size(size, name: str = "size") -> tuple[float, float]:
    return parse_size(size, name)


def _cells(extent: float, spacing: float, name: str) -> int:
    n = int(round(extent / spacing))
    if n < 1:
        raise InputError(f"`{name}`: extent {extent} m is smaller than the spacing {spacing} m")
    return n


def _grid(size, dx, dy):
    """Cell-centred grid over (0..w, 0..h): returns X, Y (rows, cols), dx, dy."""
    w, h = _size(size)
    dx = check_spacing(_length(dx, "dx"), "dx")
    dy = dx if dy is None else check_spacing(_length(dy, "dy"), "dy")
    cols, rows = _cells(w, dx, "size width"), _cells(h, dy, "size height")
    check_grid_size(rows, cols, "primitive")
    dx, dy = w / cols, h / rows
    x = (np.arange(cols) + 0.5) * dx
    y = (np.arange(rows) + 0.5) * dy
    return x[None, :], y[:, None], dx, dy, (w, h)


def _center(center, extent: tuple[float, float]) -> tuple[float, float]:
    if center is None:
        return extent[0] / 2, extent[1] / 2
    cx, cy = center
    return _length(cx, "center[0]"), _length(cy, "center[1]")


def _field(heights, dx, dy, source: str, **meta) -> HeightField:
    return HeightField(heights, dx, dy, 0.5 * dx, 0.5 * dy, source, meta)


# ----------------------------------------------------------------- published profiles
def ramp_force(x, l1, l2, n1=0.5, n2=None, k=None, l0=0.0, l3=None):
    """Published ramp (plateau) normal-force profile N(x), newtons.

    ``N = n1`` for x < l1, ``k (x - l1) + n1`` for l1 <= x < l2, ``n2``
    beyond; ``k = (n2 - n1) / (l2 - l1)`` (give ``n2`` or ``k``).
    ``l0``/``l3`` only bound the domain and do not change the values.
    """
    n1, n2, k = _ramp_levels(l1, l2, n1, n2, k)
    x = np.asarray(x, dtype=np.float64)
    return np.where(x < l1, n1, np.where(x < l2, k * (x - l1) + n1, n2))


def tent_force(x, l1, l2, n1=0.5, n2=None, k=None, l0=0.0, l3=None, l4=None):
    """Published tent (bump) normal-force profile N(x), newtons.

    ``n1`` for x < l1, ``k (x - l1) + n1`` up to the apex at ``l2``,
    ``-k (x - l2) + n2`` down to ``l3 = 2 l2 - l1``, then ``n1``.
    """
    n1, n2, k = _ramp_levels(l1, l2, n1, n2, k)
    l3 = 2 * l2 - l1 if l3 is None else l3
    x = np.asarray(x, dtype=np.float64)
    return np.where(x < l1, n1, np.where(x < l2, k * (x - l1) + n1,
                                         np.where(x < l3, -k * (x - l2) + n2, n1)))


def _ramp_levels(l1, l2, n1, n2, k):
    if not l2 > l1:
        raise InputError(f"profile needs l1 < l2 (got l1={l1}, l2={l2})")
    if (n2 is None) == (k is None):
        raise InputError(f"give exactly one of `n2` (N) and `k` (N/m) (got n2={n2!r}, k={k!r})")
    if k is None:
        k = (n2 - n1) / (l2 - l1)
    else:
        n2 = n1 + k * (l2 - l1)
    return n1, n2, k


def _profile_args(l1, l2, n1, n2, k, n_gain, dx):
    l1, l2 = _length(l1, "l1"), _length(l2, "l2")
    n1 = _quantity(n1, "N", "n1")
    n2 = None if n2 is None else _quantity(n2, "N", "n2")
    k = None if k is None else _quantity(k, "N/m", "k")
    n_gain = _quantity(n_gain, "N/m", "n_gain")
    if not n_gain > 0:
        raise InputError(f"`n_gain` must be > 0 (got {n_gain} N/m)")
    dx = check_spacing(_length(dx, "dx"), "dx")
    n1, n2, k = _ramp_levels(l1, l2, n1, n2, k)
    return l1, l2, n1, n2, k, n_gain, dx


def _profile_field(force, l0, l_end, n1, n_gain, dx, rows, dy, source, meta) -> HeightField:
    if not l_end > l0:
        raise InputError(f"profile needs its end beyond its start (got {l0} m .. {l_end} m)")
    cols = _cells(l_end - l0, dx, "profile length")
    rows = int(rows)
    if rows < 1:
        raise InputError(f"`rows` must be >= 1 (got {rows})")
    check_grid_size(rows, cols, "profile")
    dx = (l_end - l0) / cols
    dy = dx if dy is None else check_spacing(_length(dy, "dy"), "dy")
    x = l0 + (np.arange(cols) + 0.5) * dx
    h = (force(x) - n1) / n_gain
    meta = dict(meta, n_base=n1, n_gain=n_gain)
    return HeightField(np.repeat(h[None, :], rows, axis=0), dx, dy, x[0], 0.5 * dy, source, meta)


def ramp_profile(l1, l2, l3, *, n1=0.5, n2=None, k=None, l0=0.0, n_gain=1000.0, dx=1e-4,
                 rows: int = 1, dy=None) -> HeightField:
    """Published ramp/plateau profile as a height field.

    Parameters
    ----------
    l1, l2, l3 : float (m) or str
        Ramp start, ramp end (plateau start), end of the profile.
    n1 : float (N) or str
        Base force N1 (0.5 N published).
    n2, k : float or str
        Plateau force N2 (N) or rate k (N/m, e.g. "0.1 N/mm"); exactly one.
    l0 : float (m) or str
        Start of the profile.
    n_gain : float (N/m) or str
        Gain G of the height mapping the profile is meant for: the heights are
        ``h = (N(x) - n1) / n_gain`` so that ``N = n1 + n_gain h`` is exact.
    dx : float (m) or str
        Sample spacing (adjusted so cells tile [l0, l3] exactly).
    rows, dy : int, float
        Repeat the profile over ``rows`` rows spaced ``dy`` (default 1 row: 1-D).

    Returns
    -------
    HeightField
        Shape (rows, cols); samples at cell centres ``l0 + (c + 0.5) dx``;
        ``meta`` holds ``n_base`` and ``n_gain``.
    """
    l1, l2, n1, n2, k, n_gain, dx = _profile_args(l1, l2, n1, n2, k, n_gain, dx)
    l0, l3 = _length(l0, "l0"), _length(l3, "l3")
    if not l0 <= l1 < l2 <= l3:
        raise InputError(f"ramp needs l0 <= l1 < l2 <= l3 (got {l0}, {l1}, {l2}, {l3} m)")
    return _profile_field(lambda x: ramp_force(x, l1, l2, n1, n2), l0, l3, n1, n_gain, dx, rows, dy,
                          f"ramp profile N1={n1:g} N N2={n2:g} N L1={l1 * 1e3:g} mm L2={l2 * 1e3:g} mm",
                          {"profile": "ramp", "l0": l0, "l1": l1, "l2": l2, "l3": l3, "n1": n1, "n2": n2, "k": k})


def tent_profile(l1, l2, l4, *, n1=0.5, n2=None, k=None, l0=0.0, l3=None, n_gain=1000.0, dx=1e-4,
                 rows: int = 1, dy=None) -> HeightField:
    """Published tent (bump) profile as a height field.

    Rises with rate k from ``n1`` at ``l1`` to ``n2`` at ``l2``, falls back
    with the same rate to ``n1`` at ``l3 = 2 l2 - l1`` (if given, ``l3`` must
    equal that), stays at ``n1`` to ``l4``. Other parameters as
    :func:`ramp_profile`; heights ``h = (N(x) - n1) / n_gain``.
    """
    l1, l2, n1, n2, k, n_gain, dx = _profile_args(l1, l2, n1, n2, k, n_gain, dx)
    l0, l4 = _length(l0, "l0"), _length(l4, "l4")
    sym = 2 * l2 - l1
    if l3 is not None:
        l3 = _length(l3, "l3")
        if not math.isclose(l3, sym, rel_tol=1e-9, abs_tol=1e-12):
            raise InputError(f"tent with equal rates needs l3 = 2*l2 - l1 = {sym} m (got l3={l3} m)")
    l3 = sym
    if not l0 <= l1 < l2 < l3 <= l4 + 1e-12:
        raise InputError(f"tent needs l0 <= l1 < l2 < l3 <= l4 (got {l0}, {l1}, {l2}, {l3}, {l4} m)")
    return _profile_field(lambda x: tent_force(x, l1, l2, n1, n2), l0, l4, n1, n_gain, dx, rows, dy,
                          f"tent profile N1={n1:g} N N2={n2:g} N L1={l1 * 1e3:g} mm L2={l2 * 1e3:g} mm",
                          {"profile": "tent", "l0": l0, "l1": l1, "l2": l2, "l3": l3, "l4": l4,
                           "n1": n1, "n2": n2, "k": k})


# ----------------------------------------------------------------- bumps and widgets
def gaussian_bump(height, sigma, size, dx, *, dy=None, center=None) -> HeightField:
    """Gaussian bump ``h = height * exp(-r^2 / (2 sigma^2))`` (negative height: dent).

    Parameters
    ----------
    height : float (m) or str
        Peak height; negative for a dent.
    sigma : float (m) or str
        Standard deviation (> 0).
    size : (width, height) m, or str "WxH mm"
        Extent of the field; samples at cell centres.
    dx, dy : float (m) or str
        Spacing (dy defaults to dx).
    center : (x, y) m
        Bump centre (default: middle of the field).
    """
    a = _length(height, "height")
    s = _length(sigma, "sigma", positive=True)
    X, Y, dx, dy, ext = _grid(size, dx, dy)
    cx, cy = _center(center, ext)
    r2 = (X - cx) ** 2 + (Y - cy) ** 2
    return _field(a * np.exp(-r2 / (2 * s * s)), dx, dy, f"gaussian bump h={a * 1e3:g} mm sigma={s * 1e3:g} mm",
                  primitive="gaussian_bump", height=a, sigma=s, center=[cx, cy])


def raised_cosine_bump(height, radius, size, dx, *, dy=None, center=None) -> HeightField:
    """Raised-cosine bump ``h = height (1 + cos(pi r / radius)) / 2`` for r < radius, else 0.

    Smooth (C1) with compact support; negative ``height`` gives a dent.
    Other parameters as :func:`gaussian_bump`.
    """
    a = _length(height, "height")
    rad = _length(radius, "radius", positive=True)
    X, Y, dx, dy, ext = _grid(size, dx, dy)
    cx, cy = _center(center, ext)
    r = np.hypot(X - cx, Y - cy)
    h = np.where(r < rad, a * 0.5 * (1 + np.cos(np.pi * np.minimum(r, rad) / rad)), 0.0)
    return _field(h, dx, dy, f"raised-cosine bump h={a * 1e3:g} mm R={rad * 1e3:g} mm",
                  primitive="raised_cosine_bump", height=a, radius=rad, center=[cx, cy])


def rounded_button(width, depth, height, size, dx, *, dy=None, center=None, corner_radius=0.0,
                   edge="cosine", edge_width=None) -> HeightField:
    """Rounded-rectangle button (negative ``height``: a recessed well).

    Parameters
    ----------
    width, depth : float (m) or str
        Outer extent of the button along x and y.
    height : float (m) or str
        Height of the top face.
    size, dx, dy, center : as :func:`gaussian_bump`
    corner_radius : float (m) or str
        Radius of the rectangle's corners (0 = sharp; at most half the
        smaller side).
    edge : {"ramp", "cosine", "step"}
        How the rim rises from 0 at the outline to ``height`` at
        ``edge_width`` inside it ("step": a vertical wall).
    edge_width : float (m) or str
        Width of the rim (default 20 % of the smaller side; ignored for "step").
    """
    w = _length(width, "width", positive=True)
    d = _length(depth, "depth", positive=True)
    a = _length(height, "height")
    rc = _length(corner_radius, "corner_radius")
    if not 0 <= rc <= min(w, d) / 2:
        raise InputError(f"`corner_radius` must be within 0..{min(w, d) / 2} m (got {rc} m)")
    if edge not in EDGE_PROFILES:
        raise unknown_key("edge profile", edge, EDGE_PROFILES)
    ew = 0.2 * min(w, d) if edge_width is None else _length(edge_width, "edge_width", positive=True)
    X, Y, dx, dy, ext = _grid(size, dx, dy)
    cx, cy = _center(center, ext)
    inward = -rounded_rect_distance(X - cx, Y - cy, w / 2, d / 2, rc)
    h = a * PRIMITIVE_EDGES[edge](inward / ew)       # "step": 1 wherever inward > 0, whatever the width
    return _field(h, dx, dy, f"rounded button {w * 1e3:g}x{d * 1e3:g} mm h={a * 1e3:g} mm edge={edge}",
                  primitive="rounded_button", width=w, depth=d, height=a, corner_radius=rc, edge=edge,
                  edge_width=ew, center=[cx, cy])


def _line_feature(amp, width, size, dx, dy, center, angle, profile, name):
    wd = _length(width, "width", positive=True)
    if profile not in LINE_PROFILES:
        raise unknown_key("line profile", profile, LINE_PROFILES)
    th = float(angle) if not isinstance(angle, str) else parse_quantity(angle, "rad", "angle", bare_ok=True)
    X, Y, dx, dy, ext = _grid(size, dx, dy)
    cx, cy = _center(center, ext)
    # distance across the feature's axis, which runs at `angle` from +x
    u = np.abs(-(X - cx) * math.sin(th) + (Y - cy) * math.cos(th))
    t = u / (wd / 2)
    if profile == "cosine":
        f = np.where(t < 1, 0.5 * (1 + np.cos(np.pi * np.minimum(t, 1))), 0.0)
    elif profile == "tent":
        f = np.clip(1 - t, 0.0, 1.0)
    else:
        f = (t <= 1).astype(np.float64)
    return _field(amp * f, dx, dy, f"{name} {abs(amp) * 1e3:g} mm x {wd * 1e3:g} mm ({profile})",
                  primitive=name, amplitude=amp, width=wd, angle=th, profile=profile, center=[cx, cy])


def groove(depth, width, size, dx, *, dy=None, center=None, angle=math.pi / 2, profile="cosine") -> HeightField:
    """Straight groove of ``depth`` (> 0, metres down) and full ``width``.

    The groove's axis runs through ``center`` at ``angle`` (radians or
    "90 deg") from +x; the default runs along y. ``profile`` is the
    cross-section: "cosine" (raised cosine), "tent" or "box" (vertical walls).
    """
    dep = _length(depth, "depth", positive=True)
    return _line_feature(-dep, width, size, dx, dy, center, angle, profile, "groove")


def ridge(height, width, size, dx, *, dy=None, center=None, angle=math.pi / 2, profile="cosine") -> HeightField:
    """Straight ridge of ``height`` (> 0) and full ``width``; see :func:`groove`."""
    hgt = _length(height, "height", positive=True)
    return _line_feature(hgt, width, size, dx, dy, center, angle, profile, "ridge")


def step_edge(height, size, dx, *, dy=None, position=None, axis="x", width=0.0) -> HeightField:
    """Step of ``height`` where the coordinate along ``axis`` passes ``position``.

    ``width`` = 0 gives a vertical wall (a single-sample jump, which gradient
    analysis reports as a wall); ``width`` > 0 a linear ramp of that width
    centred on ``position``.
    """
    a = _length(height, "height")
    if axis not in ("x", "y"):
        raise unknown_key("step axis", axis, ("x", "y"))
    wd = _length(width, "width")
    if wd < 0:
        raise InputError(f"`width` must be >= 0 (got {wd} m)")
    X, Y, dx, dy, ext = _grid(size, dx, dy)
    coord = X if axis == "x" else Y
    pos = (ext[0] if axis == "x" else ext[1]) / 2 if position is None else _length(position, "position")
    if wd == 0:
        f = (coord >= pos).astype(np.float64)
    else:
        f = np.clip((coord - pos) / wd + 0.5, 0.0, 1.0)
    h = np.broadcast_to(a * f, (Y.shape[0], X.shape[1]))
    return _field(h, dx, dy, f"step edge {a * 1e3:g} mm along {axis}",
                  primitive="step_edge", height=a, position=pos, axis=axis, width=wd)


# ----------------------------------------------------------------- arrays and files
def from_array(heights, dx, dy=None, *, x0=None, y0=None, source: str = "array") -> HeightField:
    """Height field from an array of heights in metres.

    Parameters
    ----------
    heights : array-like of shape (rows, cols) or (cols,), metres
    dx, dy : float (m) or str
        Spacing; ``dy`` defaults to ``dx``.
    x0, y0 : float (m) or str
        Position of sample (0, 0); default ``dx/2``, ``dy/2`` (cell centres
        of a region starting at 0, like images).
    """
    dx = check_spacing(_length(dx, "dx"), "dx")
    dy = dx if dy is None else check_spacing(_length(dy, "dy"), "dy")
    x0 = 0.5 * dx if x0 is None else _length(x0, "x0")
    y0 = 0.5 * dy if y0 is None else _length(y0, "y0")
    arr = np.asarray(heights)
    if arr.dtype.kind not in "uif":
        raise InputError(f"`heights` must be a numeric array (got dtype {arr.dtype})")
    return HeightField(arr, dx, dy, x0, y0, source)


def gray_to_heights(gray: np.ndarray, full_scale: float, height_range) -> np.ndarray:
    """Map gray values linearly: 0 -> ``lo``, ``full_scale`` -> ``hi`` (metres), float64."""
    lo, hi = height_range
    step = (hi - lo) / full_scale
    from shapedisplay.author.gradients import KERNEL_MIN_SIZE
    if gray.size >= KERNEL_MIN_SIZE:           # one pass in C, the same values
        from shapedisplay.author import kernels as _kernels
        out = _kernels.gray_to_heights(gray, step, lo)
        if out is not None:
            return out
    out = np.array(gray, dtype=np.float64)   # a copy: the caller's array is never scaled in place
    out *= step
    out += lo
    return out


#: Units of float height data (``z_units``), metres per unit.
Z_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9}


def _z_unit(z_units) -> tuple[str, float]:
    name = "m" if z_units is None else str(z_units).strip()
    if name not in Z_UNITS:
        raise unknown_key("z unit", name, Z_UNITS)
    return name, Z_UNITS[name]


def load_image(path, size, height_range, *, resolution=None, channel=None, z_units=None,
               flags: dict | None = None, pixels=None) -> HeightField:
    """Height field from a picture (PNG, JPEG, TIFF, ...) or a ``.npy`` array.

    Pictures and arrays are in picture order: row 0 is the top edge of the
    top view, i.e. the largest y (see :mod:`shapedisplay.author.heightfield`).

    Parameters
    ----------
    path : path-like
        A picture Pillow reads (:mod:`shapedisplay.author.imageio`) or ``.npy``.
    size : (width, height) m or str "60x4mm"
        Physical size of the whole picture; ``dx = width / cols``,
        ``dy = height / rows``. Samples sit at pixel centres (module docs).
        ``None`` only with ``resolution``, or for an SVG that states its size.
    height_range : (low, high) m or str "0:2mm", or None
        Integer pictures and integer arrays (uint8/uint16): heights of gray 0
        and of full scale (255 or 65535), required. Float data (float TIFF,
        float ``.npy``, normal maps): the data's min..max is fitted onto
        this range; None keeps the data's own scale in ``z_units``.
    resolution : float (m) or str, optional
        Pixel size (dx = dy) instead of ``size``; for an SVG, also with
        ``size``: the spacing it is drawn at (:mod:`shapedisplay.author.vector`).
    channel : {"luminance", "r", "g", "b", "a", "normal"}, optional
        Channel of a colour picture (:func:`shapedisplay.author.imageio.read_picture`).
    z_units : {"m", "mm", "um", "nm"}, optional
        Unit of float data (default metres). Refused for integer codes.
    flags : dict, optional
        How the caller spells an option in messages (``{"height": "--height"}``).
    pixels : (cols, rows), optional
        An SVG is drawn with at least this many pixels (the caller's grid);
        pixel pictures keep their own.

    Returns
    -------
    HeightField
        Shape (rows, cols) of the picture, ``meta["scale"]`` the scale from
        source units to metres, ``meta["notes"]`` what was converted or
        ignored, ``mask`` from the picture's alpha.
    """
    from shapedisplay.author.heightfield import grid_from_picture
    from shapedisplay.author.imageio import PICTURE_SUFFIXES, read_npy, read_picture

    path = Path(path)
    suffix = path.suffix.lower()
    where = f"image '{path}'"
    notes, mask, slopes, desc = [], None, None, ""
    if suffix in PICTURE_SUFFIXES:
        if suffix == ".svg":                   # its size (stated or given) and the raster it is drawn at
            from shapedisplay.author.vector import raster_plan
            size, pixels, size_note = raster_plan(path, size, resolution, pixels, flags)
            resolution = None                  # drawn to fill `size`: the resolution chose the raster
        pic = read_picture(path, channel, pixels=pixels)
        values, full, mask, slopes, desc, notes = (pic.values, pic.full_scale, pic.mask, pic.slopes,
                                                   pic.description, list(pic.notes))
        if suffix == ".svg":
            notes += [size_note] if size_note else []
            if height_range is None and z_units is None and slopes is None:     # a drawing states no relief
                height_range = ICON_HEIGHT
                notes.append(f"height {ICON_HEIGHT[0] * 1e3:g}:{ICON_HEIGHT[1] * 1e3:g} mm, the default of an "
                             f"SVG icon (an image widget's too; give `{(flags or {}).get('height', 'height_range')}` "
                             f"to choose)")
    elif suffix == ".npy":
        where = f"array '{path}'"
        if channel is not None:
            raise InputError(f"`channel` applies to colour pictures, not to {where}")
        values = read_npy(path)
        if values.ndim == 1:
            values = values[None, :]
        if values.dtype.kind in "ui":
            if values.dtype.itemsize > 2 or values.dtype.kind == "i" and values.min(initial=0) < 0:
                raise FileFormatError(f"{where}: integer heights must be uint8 or uint16 gray codes (got "
                                      f"{values.dtype}); use a float array for heights in a length unit")
            full = float(np.iinfo(values.dtype).max) if values.dtype.kind == "u" else \
                float(np.iinfo(np.uint8 if values.dtype.itemsize == 1 else np.uint16).max)
        else:
            full = None
        desc = f"{values.dtype} array"
    else:
        from shapedisplay.author.vector import refuse_vector_format
        refuse_vector_format(path, where)
        raise unknown_key("image type", suffix or "(no suffix)", IMAGE_SUFFIXES)
    rows, cols = values.shape
    if rows * cols < 2:
        raise InputError(f"{where}: {cols} x {rows} pixels; a height map needs at least 2 samples")
    if size is not None and resolution is not None:
        raise InputError(f"{where}: give `size` or `resolution`, not both (got size={size!r}, "
                         f"resolution={resolution!r})")
    if size is None:
        if resolution is None:
            raise InputError(f"{where}: give `size` (physical width x height) or `resolution`")
        dx = dy = check_spacing(_length(resolution, "resolution"), "resolution")
        w, h = cols * dx, rows * dy
    else:
        w, h = _size(size)
        dx, dy = w / cols, h / rows
    hr = None if height_range is None else _height_range(height_range)
    if mask is not None:
        mask = np.ascontiguousarray(grid_from_picture(mask))
    integer = full is not None and slopes is None
    if integer and z_units is not None:
        raise InputError(f"`z_units` applies to float data; {where} holds integer gray codes (0..{full:g}), "
                         f"mapped by the height range")
    if slopes is not None:                       # a normal map: integrate the slopes (metres)
        from shapedisplay.author.imageio import frankot_chellappa
        p, q = grid_from_picture(slopes[0]), grid_from_picture(slopes[1])
        values = frankot_chellappa(p, q, dx, dy)
        values -= values.min()
        unit, per = "m", 1.0
        notes.append("normal map integrated to heights (Frankot-Chellappa; +y = green)")
    elif integer:
        if hr is None:
            raise InputError(f"{where} needs `{(flags or {}).get('height', 'height_range')}` (the heights of gray 0 "
                             f"and full scale, e.g. 0:2mm); it holds {desc} gray codes 0..{full:g}")
        vmin, vmax = _minmax_finite(values, where)
        if vmin < 0 or vmax > full:
            raise InputError(f"{where}: gray values must lie within 0..{full:g} (got {vmin:g}..{vmax:g})")
        values = grid_from_picture(values)
        unit, per = "gray level", None
    else:
        unit, per = _z_unit(z_units)
        values = grid_from_picture(values)
    if integer:
        heights = gray_to_heights(values, full, hr)
        a = (hr[1] - hr[0]) / full
        scale = height_scale(unit, a, hr[0], f"gray 0..{full:g} onto {hr[0] * 1e3:.6g}..{hr[1] * 1e3:.6g} mm",
                             "gray level")
    elif hr is not None:
        heights, a, b, rule = fit_range(values, hr, where, mask, unit)
        scale = height_scale(unit, a, b, rule)
    else:
        _minmax_finite(values, where)
        heights = np.array(values, dtype=np.float64)
        if per != 1.0:
            heights *= per
        scale = height_scale(unit, per, 0.0, f"data in {unit}" + (" (integrated slopes)" if slopes is not None
                                                                    else ""))
    codes = pic.values if integer and suffix in PICTURE_SUFFIXES else None   # picture order: contiguous
    del values
    if mask is not None:
        m = mask
        ground = hr[0] if hr is not None else float(heights[m].min())
        heights[~m] = ground          # flat ground outside the shape
        mask = m
    desc_s = f"{path.name} {cols}x{rows} px ({desc}), {w * 1e3:g}x{h * 1e3:g} mm"
    if hr is not None:
        desc_s += f", h {hr[0] * 1e3:g}..{hr[1] * 1e3:g} mm"
    hf = HeightField(heights, dx, dy, 0.5 * dx, 0.5 * dy, desc_s,
                     {"kind": "image", "file": str(path), "size_m": [w, h],
                      "height_range_m": None if hr is None else list(hr), "scale": scale, "notes": notes,
                      "picture": desc}, mask)
    if codes is not None and codes.dtype.kind == "u":
        hf.made_from_codes(codes, full, hr)
    return hf


def resolution_option(text, name: str = "resolution") -> float:
    """Parse a resolution string ("0.1mm") into a sample spacing > 0, metres; errors name ``name``."""
    v = parse_quantity(text, "m", name)
    if not v > 0:
        raise InputError(f"`{name}` must be a length > 0 (got {text!r})")
    return v


#: Command-line source options (library names) -> the kinds of file source each applies to.
#: One table for every command that loads a source (compile, preview, heightmap).
OPTION_KINDS = {
    "size": HEIGHT_MAP_KINDS, "height": HEIGHT_MAP_KINDS, "resolution": HEIGHT_MAP_KINDS,
    "channel": ("image", "scan"), "z_units": ("image", "scan"),
    "up": ("mesh",), "units": ("mesh",), "samples": ("mesh",), "grid": ("mesh",), "supersample": ("mesh",),
    "supersample_mode": ("mesh",), "background": ("mesh",), "margin": ("mesh",),
}
_KIND_WORDS = {("image",): "image sources", ("mesh",): "meshes", ("image", "mesh"): "images and meshes",
               ("image", "scan"): "image sources", HEIGHT_MAP_KINDS: "images and meshes"}
_WHAT = {"image": "an image", "scan": "an instrument scan", "mesh": "a mesh",
         "scene": "a scene: it sets its own geometry and mapping",
         "svg": "an SVG mockup: it sets its own geometry and mapping", "table": "a compiled table"}


def source_kind(path) -> str:
    """What a file is, by its suffix: "table" (.npz), "scene" (.toml), "svg", "image", "scan" or "mesh".

    Any other suffix is an error listing the ones known.
    """
    path = Path(os.fspath(path))
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return "table"
    if suffix == ".toml":
        return "scene"
    if suffix == ".svg":                       # a UI mock-up is a scene, any other SVG a picture
        from shapedisplay.author.scene.svg import is_mockup
        return "svg" if is_mockup(path) else "image"
    if suffix in IMAGE_SUFFIXES:
        return "image"
    if suffix in SCAN_SUFFIXES:
        return "scan"
    if suffix in MESH_SUFFIXES:
        return "mesh"
    from shapedisplay.author.vector import refuse_vector_format
    refuse_vector_format(path, f"source '{path}'")
    err = unknown_key("source type", suffix or "(no suffix)",
                      IMAGE_SUFFIXES + SCAN_SUFFIXES + MESH_SUFFIXES + (".toml", ".svg"))
    raise InputError(f"source '{path}': {err}")


def check_applicable(path, given: dict, flags: dict | None = None, kinds: dict | None = None) -> str:
    """Refuse options that do not apply to the source at ``path``; return its kind (:func:`source_kind`).

    Parameters
    ----------
    given : dict name -> value
        Options as the library names them; None means not given.
    flags : dict name -> str, optional
        How the caller spells each option (the command line: ``--name``
        with dashes), for the message; default the name itself.
    kinds : dict name -> tuple of kinds, optional
        Rules added to (or replacing) :data:`OPTION_KINDS`.
    """
    kind = source_kind(path)
    rules = {**OPTION_KINDS, **(kinds or {})}
    for name, value in given.items():
        if value is None:
            continue
        if name not in rules:
            raise unknown_key("source option", name, rules)
        ok = rules[name]
        if kind not in ok:
            flag = (flags or {}).get(name, name)
            raise InputError(f"`{flag}` applies to {_KIND_WORDS[tuple(ok)]}, not to '{path}' ({_WHAT[kind]})")
    return kind


def _up_option(text: str, name: str = "up"):
    if "," in text:
        try:
            return [float(v) for v in text.split(",")]
        except ValueError:
            raise InputError(f"`{name}` direction must be three numbers 'dx,dy,dz' (got {text!r})") from None
    return text


def _samples_option(text, name: str) -> tuple[int, int]:
    """``COLSxROWS`` (width first, as every size is printed) -> the mesh loader's ``grid=(rows, cols)``."""
    parts = str(text).lower().replace(" ", "").split("x")
    try:
        cols, rows = (int(v) for v in parts)
    except ValueError:
        raise InputError(f"`{name}` must look like COLSxROWS, e.g. 512x256 (got {text!r})") from None
    if cols < 2 or rows < 2:
        raise InputError(f"`{name}` must be at least 2x2 samples (got {cols} cols x {rows} rows)")
    return rows, cols


def source_options(path, *, flags: dict | None = None, **given) -> dict:
    """:func:`load_source` keyword arguments from command-line strings (None = not given).

    ``given`` holds options of :data:`OPTION_KINDS` by name (``size``,
    ``height``, ``resolution``, ``channel``, ``z_units``, ``up``, ``units``,
    ``samples`` (COLSxROWS), ``grid`` (its former spelling, ROWSxCOLS), ...);
    ``flags`` how a caller spells one differently
    (the command line passes ``--name``; default the name itself). Options that do not
    apply to the kind of source are refused (:func:`check_applicable`). A
    scene, an SVG mockup or a table takes none and gets ``{}``.
    """
    from shapedisplay.units import parse_pair

    flags = dict(flags or {})

    def flag(name):
        return flags.get(name, name)

    kind = check_applicable(path, given, flags)
    if kind not in HEIGHT_MAP_KINDS:
        return {}
    given = {k: v for k, v in given.items() if v is not None}
    opts: dict = {}
    if "size" in given:
        text = given["size"]
        if kind == "mesh" and "x" not in str(text):
            opts["size"] = _length(text, flag("size"), positive=True)
        else:
            w, h = parse_pair(text, "x", "m", flag("size"))
            if not (w > 0 and h > 0):
                raise InputError(f"`{flag('size')}` must be positive (got {text!r}: width={w} m, height={h} m)")
            opts["size"] = (w, h)
    if "height" in given:
        lo, hi = parse_pair(given["height"], ":", "m", flag("height"))
        if not hi >= lo:
            raise InputError(f"`{flag('height')}` must run low:high (got {given['height']!r})")
        opts["height_range"] = (lo, hi)
    if "resolution" in given:
        opts["resolution"] = resolution_option(given["resolution"], flag("resolution"))
    if "up" in given:
        opts["up"] = _up_option(given["up"], flag("up"))
    if "samples" in given:
        if "grid" in given:
            raise InputError(f"give `{flag('samples')}` (COLSxROWS) or `{flag('grid')}` (ROWSxCOLS), not both")
        if "resolution" in given:
            raise InputError(f"give either `{flag('resolution')}` or `{flag('samples')}`, not both "
                             f"(got {given['resolution']!r} and {given['samples']!r})")
        opts["grid"] = _samples_option(given["samples"], flag("samples"))
    for name in ("channel", "z_units", "units", "grid", "supersample_mode", "background", "margin"):
        if name in given:
            opts[name] = given[name]
    if "supersample" in given:
        try:
            opts["supersample"] = int(given["supersample"])
        except (TypeError, ValueError):
            raise InputError(f"`{flag('supersample')}` must be a whole number (got {given['supersample']!r})") \
                from None
    if kind == "image" and "size" not in opts and "resolution" not in opts and Path(path).suffix.lower() != ".svg":
        raise InputError(f"image '{path}' needs `{flag('size')}` (physical width x height, e.g. 60x4mm) "
                         f"or `{flag('resolution')}`")
    return opts


def fits_force_range_by_default(hf: HeightField, *, n_gain_given: bool, height_given: bool) -> bool:
    """Whether a compile fits the heights to the device's force range (:func:`forces.fit_to_force_range`).

    The rule: a mesh is fitted unless the user chose its scale, with an
    explicit height gain (``--n-gain``) or relief (``--height``). Pictures
    and data carry the scale the user gave them and are never rescaled.
    """
    return hf.meta.get("kind") == "mesh" and not n_gain_given and not height_given


def load_source(path, *, flags: dict | None = None, **opts) -> HeightField:
    """Load any file source as a height field, dispatching on its suffix.

    Pictures and ``.npy`` -> :func:`load_image` (options ``size``,
    ``height_range``, ``resolution``, ``channel``, ``z_units``); instrument
    files (``.txt`` text exports, ``.gsf``) ->
    :func:`shapedisplay.author.instruments.load_scan` (the same options;
    the file states its size and z unit);
    ``.stl``/``.obj``/``.ply``/``.off``/``.glb``/``.gltf`` ->
    :func:`shapedisplay.author.mesh.mesh_to_heightfield` (options ``resolution``,
    ``grid``, ``up``, ``units``, ``size``, ``height_range``, ``background``,
    ``supersample``, ``supersample_mode``, ``margin``). Options
    that are None are dropped; an option the loader does not take is an
    error naming the nearest valid one. ``flags`` spells an option in
    messages as the caller wrote it (``{"height": "--height"}``).
    """
    path = Path(os.fspath(path))
    suffix = path.suffix.lower()
    opts = {k: v for k, v in opts.items() if v is not None}
    if suffix in MESH_SUFFIXES:
        valid = ("resolution", "grid", "up", "units", "size", "height_range", "background", "supersample",
                 "supersample_mode", "margin")
        for k in opts:
            if k not in valid:
                raise unknown_key("mesh option", k, valid)
        if not path.is_file():
            raise FileFormatError(f"mesh '{path}': no such file")
        from shapedisplay.author.mesh import mesh_to_heightfield
        return mesh_to_heightfield(path, **opts)
    if suffix in IMAGE_SUFFIXES or suffix in SCAN_SUFFIXES:
        valid = ("size", "height_range", "resolution", "channel", "z_units")
        for k in opts:
            if k not in valid:
                raise unknown_key("image option", k, valid)
        load = load_scan if suffix in SCAN_SUFFIXES else load_image
        return load(path, opts.get("size"), opts.get("height_range"), resolution=opts.get("resolution"),
                    channel=opts.get("channel"), z_units=opts.get("z_units"), flags=flags)
    from shapedisplay.author.vector import refuse_vector_format
    refuse_vector_format(path, f"source '{path}'")
    err = unknown_key("source type", suffix or "(no suffix)", IMAGE_SUFFIXES + SCAN_SUFFIXES + MESH_SUFFIXES)
    raise InputError(f"source '{path}': {err}")
