"""Height fields: heights in metres on a regular grid.

A :class:`HeightField` is the common currency of the authoring side: every
source (analytic primitive, image, mesh, scene) produces one, and gradient
analysis and force mapping consume it. Arrays are indexed (rows, cols); row
index grows with y, column index with x. Sample (r, c) sits at
``(x0 + c*dx, y0 + r*dy)``. A 1-D profile is a single row.

Orientation
-----------
Physical space has x to the right and y up the screen. A height map
written or shown as a picture is the top view of the surface, so a
picture's row 0 (its top edge) holds the *largest* y: picture rows run
opposite to height-field rows. :func:`grid_from_picture` and
:func:`picture_from_grid` are the one place that flips between the two;
every reader and writer of picture-ordered data (PNG/TIFF/JPEG pictures and
``.npy`` height arrays) goes through them.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from shapedisplay.errors import InputError

#: Largest grid accepted before allocation (samples); 16384^2 float64 = 2 GiB.
MAX_SAMPLES = 16384 * 16384
#: Longest side of a grid accepted before allocation (samples): the aspect ratio is at most
#: ``MAX_SIDE``:1, and a table keeps per-row bookkeeping (a row placed once per grid row) that
#: grows with the side, not the sample count (1 x 100,000,000 pixels took 7.5 GB).
MAX_SIDE = 65536


def check_grid_size(rows: int, cols: int, what: str, fix: str = "") -> None:
    """Refuse a grid that would exhaust memory, before anything is allocated.

    The one size rule of every source (pictures, arrays, meshes, primitives):
    at most :data:`MAX_SAMPLES` samples and :data:`MAX_SIDE` samples a side.
    ``fix`` says how the caller's input gets within the limits ("crop or
    resample the picture"); the message also names the constant to raise.
    """
    rows, cols = int(rows), int(cols)
    n = rows * cols
    how = f"; {fix}" if fix else ""
    if n > MAX_SAMPLES:
        raise InputError(
            f"{what}: grid of {cols} x {rows} = {n} samples ({n * 8 / 2**30:.1f} GiB as float64) "
            f"exceeds the limit of {MAX_SAMPLES} samples (shapedisplay.author.heightfield.MAX_SAMPLES){how}"
        )
    if max(rows, cols) > MAX_SIDE:
        raise InputError(
            f"{what}: grid of {cols} x {rows} samples has a side of {max(rows, cols)} samples, beyond the limit "
            f"of {MAX_SIDE} a side (aspect ratio at most {MAX_SIDE}:1; shapedisplay.author.heightfield.MAX_SIDE){how}"
        )


def check_spacing(value: float, name: str) -> float:
    """Return ``value`` as a float if it is a finite spacing > 0, else raise."""
    v = float(value)
    if not np.isfinite(v) or v <= 0:
        raise InputError(f"`{name}` must be a finite length > 0 (got {value!r})")
    return v


def parse_size(size, name: str = "size") -> tuple[float, float]:
    """A physical ``(width, height)`` in metres from "60x4mm" or a pair of lengths (metres or strings with
    units); both finite and > 0, errors naming ``name``."""
    from shapedisplay.units import parse_pair, parse_quantity
    if isinstance(size, str):
        w, h = parse_pair(size, "x", "m", name)
    else:
        try:
            w, h = size
        except (TypeError, ValueError):
            raise InputError(f"`{name}` must be (width, height) in metres (got {size!r})") from None
        pair = []
        for v, part in ((w, f"{name}[0] (width)"), (h, f"{name}[1] (height)")):
            try:
                pair.append(parse_quantity(v, "m", part) if isinstance(v, str) else float(v))
            except (TypeError, ValueError):
                raise InputError(f"`{part}` must be a length in metres or a string with its unit "
                                 f"(got {v!r})") from None
        w, h = pair
    if not (w > 0 and h > 0 and np.isfinite(w) and np.isfinite(h)):
        raise InputError(f"`{name}` must be positive (got width={w} m, height={h} m)")
    return float(w), float(h)


def grid_from_picture(values: np.ndarray) -> np.ndarray:
    """Picture order (row 0 = top edge) -> height-field order (row 0 = smallest y). A view, no copy."""
    return np.asarray(values)[::-1]


def picture_from_grid(values: np.ndarray) -> np.ndarray:
    """Height-field order (row 0 = smallest y) -> picture order (row 0 = top edge). A view, no copy."""
    return np.asarray(values)[::-1]


def height_range(value) -> tuple[float, float]:
    """``(low, high)`` metres from a pair of lengths or a string such as ``"0:2mm"``; low <= high."""
    from shapedisplay.units import parse_pair, parse_quantity
    if isinstance(value, str):
        lo, hi = parse_pair(value, ":", "m", "height_range")
    else:
        try:
            lo, hi = value
        except (TypeError, ValueError):
            raise InputError(f"`height_range` must be (low, high) in metres (got {value!r})") from None
        lo, hi = (parse_quantity(v, "m", f"height_range[{i}]", bare_ok=not isinstance(v, str))
                  for i, v in enumerate((lo, hi)))
    if not hi >= lo:
        raise InputError(f"`height_range` must have low <= high (got {lo} m .. {hi} m)")
    return float(lo), float(hi)


def height_scale(unit: str, m_per_unit: float, offset_m: float, rule: str, what: str = "data") -> dict:
    """The scale of a source, for reports: ``height = m_per_unit * value + offset_m`` (metres).

    ``what`` names the source quantity ("data", "model height", "gray level").
    """
    return {"source_unit": unit, "m_per_unit": float(m_per_unit), "offset_m": float(offset_m), "rule": rule,
            "what": what}


def fit_range(values: np.ndarray, height_range, what: str, mask=None,
              unit: str = "") -> tuple[np.ndarray, float, float, str]:
    """Fit the range of ``values`` onto ``height_range`` (lo, hi) metres, linearly.

    ``mask`` (bool, same shape): only the samples inside it set the range;
    ``unit``: the values' unit, named in the rule.
    Returns ``(heights, m_per_unit, offset_m, rule)``; constant data all go
    to ``lo``. The caller's array is not changed.
    """
    lo, hi = height_range
    vmin, vmax = finite_range(values if mask is None else values[mask], what)
    span = vmax - vmin
    a = (hi - lo) / span if span > 0 else 0.0
    out = np.array(values, dtype=np.float64)
    out -= vmin
    out *= a
    out += lo
    u = f" {unit}" if unit else ""
    rule = (f"data range {vmin:.6g}..{vmax:.6g}{u} fitted onto {lo * 1e3:.6g}..{hi * 1e3:.6g} mm" if span > 0
            else f"constant data {vmin:.6g}{u} placed at {lo * 1e3:.6g} mm")
    return out, a, lo - a * vmin, rule


def finite_range(values: np.ndarray, what: str) -> tuple[float, float]:
    """``(min, max)`` of ``values``; float data with a NaN or inf is refused, naming ``what``."""
    if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
        raise InputError(f"{what}: values must be finite ({int(np.count_nonzero(~np.isfinite(values)))} "
                         f"NaN/inf samples)")
    return float(values.min()), float(values.max())


@dataclass(frozen=True, eq=False)
class HeightField:
    """Heights on a regular grid.

    Parameters
    ----------
    heights : ndarray of shape (rows, cols), float64, metres
        Finite heights. ``rows == 1`` is a 1-D profile along x.
    dx, dy : float, metres
        Sample spacing along x (columns) and y (rows); both > 0.
    x0, y0 : float, metres
        Position of sample (0, 0).
    source : str
        Human-readable description of where the heights came from.
    meta : dict
        What the source knows: ``kind``, ``scale`` (source unit -> metres),
        ``notes`` (what was ignored or converted), ...
    mask : ndarray of shape (rows, cols), bool, or None
        True where the surface exists (a picture's opaque pixels); samples
        outside hold flat ground and the compiler does not store regions
        lying wholly outside. None = everywhere.
    """

    heights: np.ndarray
    dx: float
    dy: float
    x0: float = 0.0
    y0: float = 0.0
    source: str = ""
    meta: dict = field(default_factory=dict)
    mask: np.ndarray | None = None

    def __post_init__(self):
        h = np.asarray(self.heights, dtype=np.float64)
        if h.ndim == 1:
            h = h[None, :]
        if h.ndim != 2:
            raise InputError(f"`heights` must be a 2-D array (rows, cols) (got shape {h.shape})")
        if h.size == 0:
            raise InputError(f"`heights` is empty (got shape {h.shape})")
        if h.size == 1:
            raise InputError(f"`heights` has a single sample; a shape needs at least 2 (got shape {h.shape})")
        # a finite sum means every sample is finite (NaN and inf propagate through it): one pass,
        # no temporary; an overflowing sum of finite samples falls through to the full check
        with np.errstate(over="ignore", invalid="ignore"):
            total = float(np.add.reduce(h, axis=None))
        if not math.isfinite(total) and not np.isfinite(h).all():
            bad = ~np.isfinite(h)
            r, c = np.argwhere(bad)[0]
            raise InputError(
                f"`heights` must be finite: {int(bad.sum())} NaN/inf samples, first at row {r}, col {c} "
                f"(value {h[r, c]})"
            )
        h = np.ascontiguousarray(h)
        h.setflags(write=False)
        object.__setattr__(self, "heights", h)
        object.__setattr__(self, "dx", check_spacing(self.dx, "dx"))
        object.__setattr__(self, "dy", check_spacing(self.dy, "dy"))
        if self.mask is not None:
            m = np.asarray(self.mask)
            if m.dtype != bool or m.shape != h.shape:
                raise InputError(f"`mask` must be a bool array of the heights' shape {h.shape} "
                                 f"(got {m.dtype} {m.shape})")
            if not m.any():
                raise InputError("`mask` leaves no sample inside the shape (every pixel transparent)")
            m = np.ascontiguousarray(m)
            m.setflags(write=False)
            object.__setattr__(self, "mask", None if m.all() else m)
        for name in ("x0", "y0"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise InputError(f"`{name}` must be finite (got {v})")
            object.__setattr__(self, name, v)

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def rows(self) -> int:
        return self.heights.shape[0]

    @property
    def cols(self) -> int:
        return self.heights.shape[1]

    @property
    def is_1d(self) -> bool:
        """True for a single-row profile along x."""
        return self.rows == 1

    @property
    def x(self) -> np.ndarray:
        """Sample x positions, shape (cols,), metres."""
        return self.x0 + self.dx * np.arange(self.cols)

    @property
    def y(self) -> np.ndarray:
        """Sample y positions, shape (rows,), metres."""
        return self.y0 + self.dy * np.arange(self.rows)

    @property
    def size_m(self) -> tuple[float, float]:
        """Physical (width, height) covered by the samples, metres."""
        return self.cols * self.dx, self.rows * self.dy

    def sha256(self) -> str:
        """Hash of heights and grid: identifies the source in compiled tables.

        A height field mapped from integer codes (a picture's gray levels)
        hashes those codes and the map instead, once :meth:`made_from_codes`
        has said so: the map is linear, so the codes identify the heights as
        well, and 16-bit codes are a quarter of the bytes of float64 heights
        (a 4096x4096 map: 0.03 s instead of 0.11 s).
        """
        made = getattr(self, "_codes_sha256", None)
        if made is not None:
            return made
        d = self._grid_digest()
        d.update(np.ascontiguousarray(self.heights.astype("<f8", copy=False)))  # buffer, no copy
        if self.mask is not None:
            d.update(np.packbits(self.mask).tobytes())
        return d.hexdigest()

    def _grid_digest(self, *more: bytes):
        d = hashlib.sha256(b"".join(more))
        d.update(np.asarray(self.shape, dtype="<i8").tobytes())
        d.update(np.asarray([self.dx, self.dy, self.x0, self.y0], dtype="<f8").tobytes())
        return d

    def made_from_codes(self, codes: np.ndarray, full_scale: float, height_range) -> "HeightField":
        """Record that the heights are ``lo + codes * (hi - lo) / full_scale`` (``height_range`` = (lo, hi),
        ``codes`` the unsigned integer picture as read, row 0 its top edge; outside the mask, if any, the
        ground): :meth:`sha256` then hashes the codes and the mask. Returns the height field itself; a
        height field made from it (:meth:`with_heights`) hashes its heights again."""
        codes = np.asarray(codes)
        if codes.shape != self.shape or codes.dtype.kind != "u":
            raise InputError(f"`codes` must be unsigned integers of the heights' shape {self.shape} "
                             f"(got {codes.dtype} {codes.shape})")
        d = self._grid_digest(b"codes ", codes.dtype.str.encode(), b" ",
                              np.asarray([full_scale, *height_range], dtype="<f8").tobytes())
        d.update(np.ascontiguousarray(codes))
        if self.mask is not None:
            d.update(np.packbits(self.mask).tobytes())
        object.__setattr__(self, "_codes_sha256", d.hexdigest())
        return self

    def with_heights(self, heights: np.ndarray, source: str | None = None) -> "HeightField":
        """A copy on the same grid with new heights."""
        return HeightField(heights, self.dx, self.dy, self.x0, self.y0,
                           self.source if source is None else source, dict(self.meta), self.mask)

    def __repr__(self) -> str:
        return (f"HeightField({self.cols} x {self.rows} samples, dx={self.dx * 1e3:g} mm, dy={self.dy * 1e3:g} mm, "
                f"h=[{self.heights.min() * 1e3:.4g}, {self.heights.max() * 1e3:.4g}] mm, source={self.source!r})")
