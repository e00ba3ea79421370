"""Compile a height field into a friction-envelope table.

Pipeline: gradient analysis (slopes, walls, wall limiting) -> force profiles
(:mod:`shapedisplay.author.forces`) -> keep only the channels the mapping and the
device use -> quantize each channel from perceptual resolution -> table with
meta data and a compile report.

Quantization rule (``quantize="auto"``)
---------------------------------------
A channel is coded as ``value = offset + scale * code`` with the smallest
integer width (uint8, then uint16) whose worst-case error is within the
channel's *perceptual bound*; otherwise float32 (float64 if even that is too
coarse). With ``w`` the friction Weber fraction (``weber_fraction``, default
0.1), half a just-noticeable difference is not felt, so:

``normal_force`` (and other force/ratio channels)
    error <= w/2 * (smallest nonzero ``|value|`` of the channel): every rendered
    force is reproduced to within half a JND of itself.
``lateral_x``, ``lateral_y``
    error <= w/2 * mu_k * N_min: the lateral cue adds to the tangential force
    the finger feels, the smallest of which is kinetic friction at the
    smallest rendered normal force N_min.
``grad_x``, ``grad_y``
    error <= w/2 * mu_k / K_mu: the slope error changes mu_eff by at most
    half a JND of the kinetic friction coefficient.
``skin_stretch``
    error <= w/2 * (smallest nonzero stretch).

For integer codes the stated worst-case error is ``scale/2`` plus a few
ulps of the largest magnitude; for float32 ``max|value| * 2^-24``. A fixed
``quantize`` dtype is honoured and the report says whether it meets the bound.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from shapedisplay.errors import InputError, unknown_key
from shapedisplay.author.gradients import GRADIENT_METHODS, KERNEL_MIN_SIZE, detect_walls, gradient, limit_walls
from shapedisplay.author.heightfield import HeightField
from shapedisplay.author.forces import MappingOptions, lateral_force, needed_channels, normal_force, skin_stretch
from shapedisplay.table.model import CHANNELS, FrictionTable, Grid, Quantization

QUANTIZE_CHOICES = ("auto", "uint8", "uint16", "float32", "float64")
_TOP = {"uint8": 255, "uint16": 65535}
_EPS = np.finfo(np.float64).eps


@dataclass(frozen=True)
class CompileOptions:
    """How a height field is compiled.

    Attributes
    ----------
    quantize : {"auto", "uint8", "uint16", "float32", "float64"}
        "auto" picks per channel from the perceptual bound (module docs).
    weber_fraction : float
        Friction Weber fraction w (0 < w < 1; literature 0.1-0.2).
    gradient_method : {"central", "gaussian", "savgol"}
    gradient_kw : dict
        Options of the gradient method (gaussian ``sigma`` m; savgol ``window``, ``order``).
    max_slope : float
        Steepest renderable slope (dimensionless; inf = no limit). Steeper
        samples are walls.
    limit_walls : bool
        Clip wall slopes to ``max_slope`` (direction kept) before the slope
        and lateral mappings.
    keep : tuple of str
        Channels to store even if the device does not use them (must be
        producible by the mapping; grad_x/grad_y always are).
    """

    quantize: str = "auto"
    weber_fraction: float = 0.1
    gradient_method: str = "central"
    gradient_kw: dict = field(default_factory=dict)
    max_slope: float = 1.0            # 45 degrees
    limit_walls: bool = True
    keep: tuple = ()

    def __post_init__(self):
        if self.quantize not in QUANTIZE_CHOICES:
            raise unknown_key("quantization", self.quantize, QUANTIZE_CHOICES)
        w = float(self.weber_fraction)
        if not (0 < w < 1):
            raise InputError(f"`weber_fraction` must be within (0, 1) (got {self.weber_fraction!r})")
        object.__setattr__(self, "weber_fraction", w)
        if self.gradient_method not in GRADIENT_METHODS:
            raise unknown_key("gradient method", self.gradient_method, GRADIENT_METHODS)
        object.__setattr__(self, "gradient_kw", dict(self.gradient_kw or {}))
        from shapedisplay.author.gradients import _METHOD_KW
        for k in self.gradient_kw:
            if k not in _METHOD_KW[self.gradient_method]:
                raise unknown_key(f"option of gradient method '{self.gradient_method}'", k,
                                  _METHOD_KW[self.gradient_method] or ("(none)",))
        ms = float(self.max_slope)
        if math.isnan(ms) or ms <= 0:
            raise InputError(f"`max_slope` must be > 0 (got {self.max_slope!r})")
        object.__setattr__(self, "max_slope", ms)
        keep = (self.keep,) if isinstance(self.keep, str) else tuple(self.keep)
        for k in keep:
            if k not in CHANNELS:
                raise unknown_key("channel", k, CHANNELS)
        object.__setattr__(self, "keep", keep)

    def to_json(self) -> dict:
        d = asdict(self)
        d["keep"] = list(self.keep)
        d["max_slope"] = None if math.isinf(self.max_slope) else self.max_slope
        d["gradient_kw"] = {k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in self.gradient_kw.items()}
        return d

    @classmethod
    def from_json(cls, d: dict) -> "CompileOptions":
        valid = {f.name for f in fields(cls)}
        d = {k: v for k, v in d.items() if k in valid}
        if d.get("max_slope", 0) is None:
            d["max_slope"] = math.inf
        return cls(**d)


@dataclass(frozen=True)
class CompileResult:
    """A compiled table and its report (dict, JSON-safe; also in ``table.meta["report"]``)."""

    table: FrictionTable
    report: dict


# ----------------------------------------------------------------- quantization
def _min_nonzero_abs(values: np.ndarray, lo: float | None = None, hi: float | None = None) -> float:
    vmin = float(values.min()) if lo is None else lo
    vmax = float(values.max()) if hi is None else hi
    if vmin > 0:
        return vmin
    if vmax < 0:
        return -vmax
    a = np.abs(values)
    a[a == 0] = np.inf
    m = float(a.min())
    return m if math.isfinite(m) else 0.0


def perceptual_bound(name: str, values: np.ndarray, device, options: CompileOptions,
                     mapping: MappingOptions | None = None, n_min: float | None = None,
                     _range: tuple | None = None, _min_abs=None) -> tuple[float, str]:
    """Largest quantization error of channel ``name`` that is not felt (module docs).

    Returns
    -------
    bound : float
        In the channel's SI unit; ``inf`` if every value is zero.
    rule : str
        The rule used, for the report.
    """
    w2 = options.weber_fraction / 2
    mu_k = float(device.friction.mu_k)
    if name in ("lateral_x", "lateral_y"):
        if n_min is None:
            n_min = max(float(device.normal_force_range[0]), mapping.n_base if mapping else 0.5)
        ref = mu_k * n_min
        if ref > 0:
            return w2 * ref, f"w/2 * mu_k * N_min = {w2:g} * {mu_k:g} * {n_min:.6g} N"
    if name in ("grad_x", "grad_y") and mapping is not None and mapping.slope_friction_gain > 0 and mu_k > 0:
        return (w2 * mu_k / mapping.slope_friction_gain,
                f"w/2 * mu_k / K_mu = {w2:g} * {mu_k:g} / {mapping.slope_friction_gain:g}")
    lo, hi = _range if _range is not None else (None, None)
    m = _min_nonzero_abs(values, lo, hi) if _min_abs is None else _min_abs()
    if m == 0:
        return math.inf, "channel is zero everywhere"
    return w2 * m, f"w/2 * smallest nonzero |value| = {w2:g} * {m:.6g} {CHANNELS[name][0]}"


def _coding(dtype: str, lo: float, hi: float) -> Quantization:
    big = max(abs(lo), abs(hi))
    if dtype in _TOP:
        scale = (hi - lo) / _TOP[dtype] if hi > lo else 0.0
        err = scale / 2 + 4 * _EPS * big if scale > 0 else 0.0
        return Quantization(dtype, scale, lo, err)
    if dtype == "float32":
        if big > float(np.finfo(np.float32).max):
            return Quantization("float64", 1.0, 0.0, 0.0)   # would overflow float32
        return Quantization("float32", 1.0, 0.0, max(big * 2.0 ** -24, 2.0 ** -150) if big > 0 else 0.0)
    return Quantization("float64", 1.0, 0.0, 0.0)


def _minmax(values: np.ndarray) -> tuple[float, float]:
    if values.flags.c_contiguous and values.size >= KERNEL_MIN_SIZE:
        from shapedisplay.author import kernels as _kernels
        lo, hi = _kernels.minmax(values.reshape(-1))
        return float(lo), float(hi)
    return float(values.min()), float(values.max())


def _encode(q: Quantization, values: np.ndarray) -> np.ndarray:
    """``q.encode(values)`` in one pass for large integer-coded channels (same codes)."""
    if q.dtype in _TOP and q.scale > 0 and values.flags.c_contiguous and values.dtype == np.float64 \
            and values.size >= KERNEL_MIN_SIZE:
        from shapedisplay.author import kernels as _kernels
        out = np.empty(values.shape, dtype=np.dtype(q.dtype))
        _kernels.encode(values.reshape(-1), q.offset, q.scale, float(_TOP[q.dtype]), out.reshape(-1))
        return out
    return q.encode(values)


def _choose(name, values, device, options, mapping, n_min):
    if name not in CHANNELS:
        raise unknown_key("channel", name, CHANNELS)
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        raise InputError(f"channel '{name}' is empty")
    lo, hi = _minmax(values)
    return _choose_range(name, lo, hi, values, device, options, mapping, n_min)


def _choose_range(name, lo, hi, values, device, options, mapping, n_min, min_abs=None):
    """:func:`_choose` once the channel's range is known (``min_abs``: smallest nonzero |value|, when asked)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError(f"channel '{name}' holds NaN/inf values; cannot quantize")
    bound, rule = perceptual_bound(name, values, device, options, mapping, n_min, (lo, hi), min_abs)
    if options.quantize != "auto":
        return _coding(options.quantize, lo, hi), bound, rule
    for dt in ("uint8", "uint16", "float32"):
        q = _coding(dt, lo, hi)
        if q.max_error <= bound:
            return q, bound, rule
    return _coding("float64", lo, hi), bound, rule


def quantization_for(name: str, values: np.ndarray, device, options: CompileOptions,
                     mapping: MappingOptions | None = None, n_min: float | None = None) -> Quantization:
    """Coding of channel ``name`` holding ``values`` (rows, cols), SI.

    ``options.quantize == "auto"``: smallest of uint8/uint16/float32/float64
    whose worst-case error (``max_error``) is within :func:`perceptual_bound`.
    Otherwise the given dtype.
    """
    return _choose(name, values, device, options, mapping, n_min)[0]


# ----------------------------------------------------------------- meta
def table_meta(device, mapping: MappingOptions, options: CompileOptions, source_description: str,
               source_sha256: str, report: dict | None = None) -> dict:
    """The table header's free part.

    Keys: ``device`` (:meth:`DeviceProfile.to_json`: pad, friction, burst,
    rates, ranges), ``mapping`` (incl. ``slope_friction_gain`` K_mu and
    ``n_base``, the constant N when the table has no normal_force),
    ``source`` {description, sha256}, ``compile`` (options), ``report``,
    ``tick_rate_hz`` and ``velocity_range_m_s`` (from the device).
    """
    return {
        "device": device.to_json(),
        "mapping": mapping.to_json(),
        "source": {"description": str(source_description), "sha256": str(source_sha256)},
        "compile": options.to_json(),
        "report": report or {},
        "tick_rate_hz": float(device.tick_rate_hz),
        "velocity_range_m_s": [float(v) for v in device.velocity_range],
    }


def _device(device):
    from shapedisplay.table.devices import DeviceProfile, load_device
    if device is None or isinstance(device, str):
        return load_device(device)
    if not isinstance(device, DeviceProfile):
        raise InputError(f"`device` must be a DeviceProfile, a bundled name or a TOML path (got {type(device).__name__})")
    return device


def _producible(name: str, mapping: MappingOptions, is_1d: bool) -> str | None:
    """None if the compiler can produce ``name`` for this mapping, else why not."""
    if name in ("grad_y", "lateral_y") and is_1d:
        return "1-D source has no y direction"
    if name in ("normal_force", "grad_x", "grad_y"):
        return None
    if name in ("lateral_x", "lateral_y"):
        return None if mapping.lateral != "off" else "the mapping has no lateral cue"
    if name == "skin_stretch":
        return None if mapping.skin_stretch > 0 else "the mapping has no skin stretch"
    return "not produced by a height mapping"


# ----------------------------------------------------------------- compile
def compile_heightfield(hf: HeightField, device=None, mapping: MappingOptions = MappingOptions(),
                        options: CompileOptions = CompileOptions()) -> CompileResult:
    """Compile a height field into a friction-envelope table.

    Parameters
    ----------
    hf : HeightField
        Heights (rows, cols) in metres; one row compiles to a 1-D table.
    device : DeviceProfile, str or None
        Target device (bundled name or TOML path; None = default profile).
    mapping : MappingOptions
    options : CompileOptions

    Returns
    -------
    CompileResult
        ``table`` on the grid of ``hf`` (same rows, cols, spacing and origin)
        holding only the needed channels; ``report`` with keys ``kept``,
        ``left_out`` {name: reason}, ``quantization`` {name: dtype, scale,
        offset, max_error, bound, rule, meets_bound}, ``walls``, ``clamped``,
        ``stored_bytes``, ``dense_bytes``, ``bytes_saved``.
    """
    if not isinstance(hf, HeightField):
        raise InputError(f"`hf` must be a HeightField (got {type(hf).__name__})")
    if not isinstance(mapping, MappingOptions):
        raise InputError(f"`mapping` must be MappingOptions (got {type(mapping).__name__})")
    if not isinstance(options, CompileOptions):
        raise InputError(f"`options` must be CompileOptions (got {type(options).__name__})")
    device = _device(device)
    kept, left_out = needed_channels(device, mapping, hf.is_1d)
    for k in options.keep:
        if k in kept:
            continue
        why = _producible(k, mapping, hf.is_1d)
        if why is not None:
            raise InputError(f"cannot keep channel '{k}': {why}")
        kept.append(k)
        left_out.pop(k, None)
    kept = [n for n in CHANNELS if n in kept]
    if not kept:
        raise InputError(f"nothing to store: device '{device.name}' (outputs {list(device.outputs)}) uses none of the "
                         f"channels mapping '{mapping.spec}' produces; left out: "
                         + "; ".join(f"{k}: {v}" for k, v in left_out.items() if k in
                                     ("normal_force", "grad_x", "lateral_x", "skin_stretch")))

    band = _band_rows(hf, kept, mapping, options)
    if band:
        walls, codes, quant, qinfo, clamped = _compile_by_bands(hf, device, mapping, options, kept, band)
    else:
        walls, codes, quant, qinfo, clamped = _compile_whole(hf, device, mapping, options, kept)
    return _assemble(hf, device, mapping, options, kept, left_out, walls, codes, quant, qinfo, clamped)


def _qinfo(q, bound, rule) -> dict:
    return {"dtype": q.dtype, "scale": q.scale, "offset": q.offset, "max_error": float(q.max_error),
            "bound": None if math.isinf(bound) else bound, "rule": rule, "meets_bound": bool(q.max_error <= bound)}


def _limited(walls, kept, options) -> bool:
    """Set ``walls.limited``; True if the wall slopes are to be clipped."""
    uses_slopes = any(n in kept for n in ("grad_x", "grad_y", "lateral_x", "lateral_y"))
    if walls.count == 0:
        walls.limited = "no walls"
    elif not uses_slopes:
        walls.limited = "not needed: no kept channel uses slopes (N steps where the walls are)"
    elif options.limit_walls:
        walls.limited = f"slope magnitude clipped to {options.max_slope:g}, direction kept"
        return True
    else:
        walls.limited = "not limited (limit_walls=False)"
    return False


#: Maps of at least this many samples compile a band of rows at a time when they can (:func:`_band_rows`).
BANDS_MIN_SIZE = 1 << 20
#: Samples per band, about (2 MiB per float64 array of a band).
BAND_SAMPLES = 1 << 18


def _band_rows(hf, kept, mapping, options) -> int:
    """Rows per band if this compile can run band by band (:func:`_compile_by_bands`), else 0.

    Band by band: central slopes; only normal_force (from height, no
    perceptual reshaping) and the gradient law's lateral_x/lateral_y kept.
    A band holds a whole number of the range passes' chunks, so every range
    is the whole array's bit for bit.
    """
    from shapedisplay.author.kernels import CHUNK
    if hf.heights.size < max(BANDS_MIN_SIZE, KERNEL_MIN_SIZE) or hf.rows < 3 or hf.cols < 3 \
            or options.gradient_method != "central" or not set(kept) <= {"normal_force", "lateral_x", "lateral_y"}:
        return 0
    if "normal_force" in kept and (not mapping.height or mapping.perceptual_exponent is not None
                                   or math.copysign(1.0, mapping.n_base) < 0):   # -0.0 would make -0.0 forces
        return 0
    if "lateral_x" in kept and mapping.lateral != "gradient":
        return 0
    unit = CHUNK // math.gcd(hf.cols, CHUNK)
    band = unit * max(1, BAND_SAMPLES // (unit * hf.cols))
    return band if band < hf.rows else 0


def _encode_into(q: Quantization, values: np.ndarray, out: np.ndarray, gain=None, base=0.0) -> None:
    """``out[...] = _encode(q, v)`` for a band of a large channel (flat, C-contiguous), v = ``values``, or with
    ``gain`` v = ``values * gain + base`` (computed in the coding pass where the kernels code it)."""
    if q.dtype in _TOP and q.scale > 0:
        from shapedisplay.author import kernels as _kernels
        _kernels.encode(values, q.offset, q.scale, float(_TOP[q.dtype]), out, gain=gain, base=base)
    else:
        if gain is not None:
            values = values * gain
            values += base
        out[...] = q.encode(values)


def _compile_by_bands(hf, device, mapping, options, kept, band):
    """What :func:`_compile_whole` computes, a band of rows at a time.

    The slopes, N and the lateral forces never exist as whole float64
    arrays (on a 4096x4096 map, 384 MiB of memory the process does not take
    from the system, page by page; a band's arrays stay in the CPU cache).
    Pass 1 finds the walls and each channel's range; pass 2 computes each
    band again and codes it. Every value comes from the same operations on
    the same samples as the whole-array path: the same table bit for bit
    (the tests compare them). Rare cases (clamped N, a range that needs the
    smallest nonzero value) take one more pass.
    """
    from shapedisplay.author import kernels as _kernels
    from shapedisplay.author.forces import _check_lateral_peak, clamp_note, lateral_clip_note
    from shapedisplay.author.gradients import WallReport, _check_steepest, central_band, wall_report

    h = hf.heights
    rows, cols = h.shape
    limit = options.max_slope
    need_n = bool(mapping.height) and "normal_force" in kept
    lateral = "lateral_x" in kept
    lo_n, hi_n = device.normal_force_range
    fmax = float(device.lateral_force_max)
    gxb, gyb = np.empty((band, cols)), np.empty((band, cols))
    nb = np.empty((band, cols)) if need_n else None
    bands = [(r0, min(r0 + band, rows)) for r0 in range(0, rows, band)]

    def forces_n(r0, r1, clamp):
        n = np.multiply(h[r0:r1], mapping.n_gain, out=nb[:r1 - r0])
        n += mapping.n_base
        if clamp:
            np.clip(n, lo_n, hi_n, out=n)
        return n.reshape(-1)

    def forces_lateral(r0, r1, wall_mask):
        gx, gy = gxb[:r1 - r0], gyb[:r1 - r0]
        central_band(h, hf.dx, hf.dy, r0, r1, gx, gy)
        fx, fy = gx.reshape(-1), gy.reshape(-1)
        if wall_mask is not None:
            _kernels.clip_where(fx, fy, limit, wall_mask[r0 * cols:r1 * cols])
        # without a force beyond the limit in pass 1, clipping changes nothing: the gain alone
        _kernels.clip_magnitude(fx, fy, fmax if fmax > 0 and lat_count else math.inf, gain=-mapping.lateral_gain)
        return fx, fy

    # -- pass 1: walls, ranges
    mask, count, peak2 = None, 0, 0.0
    h_range = n_range = fx_range = fy_range = None
    lat_count, lat_peak = 0, 0.0
    clip_walls = lateral and options.limit_walls
    for r0, r1 in bands:
        gx, gy = gxb[:r1 - r0], gyb[:r1 - r0]
        central_band(h, hf.dx, hf.dy, r0, r1, gx, gy)
        fx, fy = gx.reshape(-1), gy.reshape(-1)
        c, p2, m = _kernels.wall_scan(fx, fy, limit * limit)
        peak2 = max(peak2, p2)
        if c:
            if not math.isinf(limit):
                _check_steepest(hf, math.sqrt(p2))    # what the whole-array scan refuses, before anything else
            if mask is None:
                mask = np.zeros(rows * cols, dtype=bool)
            mask[r0 * cols:r1 * cols] = m
            count += c
            if clip_walls:
                _kernels.clip_where(fx, fy, limit, m)
        if need_n:
            h_range = _kernels.minmax_update(h[r0:r1].reshape(-1), h_range)
        if lateral:
            cnt, peak = _kernels.clip_magnitude(fx, fy, fmax if fmax > 0 else math.inf, gain=-mapping.lateral_gain)
            lat_count += cnt
            lat_peak = max(lat_peak, peak)
            fx_range = _kernels.minmax_update(fx, fx_range)
            fy_range = _kernels.minmax_update(fy, fy_range)
    if need_n:
        # N = h * n_gain + n_base rounds monotonically (and is never -0.0: see _band_rows): its range is the
        # map of the heights' range, as the range of every sample's N would be
        ends = sorted(float(v) * mapping.n_gain + mapping.n_base for v in h_range)
        n_range = (ends[0], ends[1])
    steepest = math.sqrt(peak2)
    if math.isinf(limit) or count == 0:
        walls = WallReport(np.zeros(h.shape, dtype=bool), 0, 0.0, limit, steepest)
    else:
        _check_steepest(hf, steepest)
        walls = wall_report(hf, mask.reshape(h.shape), count, limit, steepest)
    wall_mask = mask if _limited(walls, kept, options) else None
    walls.mask = mask = None

    codes, quant, qinfo, clamped = {}, {}, {}, {}

    def min_abs(values_of):   # smallest nonzero |value| over the bands (as _min_nonzero_abs)
        m = math.inf
        for r0, r1 in bands:
            a = np.abs(values_of(r0, r1))
            a[a == 0] = np.inf
            m = min(m, float(a.min()))
        return m if math.isfinite(m) else 0.0

    def choose(name, rng, n_min, values_of):
        lo, hi = float(rng[0]), float(rng[1])
        q, bound, rule = _choose_range(name, lo, hi, None, device, options, mapping, n_min,
                                       lambda: lo if lo > 0 else -hi if hi < 0 else min_abs(values_of))
        quant[name] = q
        qinfo[name] = _qinfo(q, bound, rule)
        codes[name] = np.empty(h.shape, dtype=np.dtype(q.dtype))

    n_min = min(max(mapping.n_base, lo_n), hi_n)
    clamp = False
    if need_n:
        amin, amax = float(n_range[0]), float(n_range[1])
        below = above = 0
        clamp = amin < lo_n or amax > hi_n
        if clamp:   # count and clamp, and the range of the clamped forces
            n_range = None
            for r0, r1 in bands:
                n = forces_n(r0, r1, False)
                below += int(np.count_nonzero(n < lo_n)) if amin < lo_n else 0
                above += int(np.count_nonzero(n > hi_n)) if amax > hi_n else 0
                np.clip(n, lo_n, hi_n, out=n)
                n_range = _kernels.minmax_update(n, n_range)
        clamped["normal_force"] = clamp_note(lo_n, hi_n, "N", amin, amax, below, above, h.size)
        vmin, vmax = float(n_range[0]), float(n_range[1])
        n_of = lambda r0, r1: forces_n(r0, r1, clamp)   # noqa: E731
        n_min = (vmin if vmin > 0 else -vmax if vmax < 0 else min_abs(n_of)) or n_min
        choose("normal_force", n_range, None, n_of)
    if lateral:
        _check_lateral_peak(lat_peak)
        clamped["lateral"] = lateral_clip_note(fmax, lat_count, lat_peak, h.size)
        choose("lateral_x", fx_range, n_min, lambda r0, r1: forces_lateral(r0, r1, wall_mask)[0])
        if "lateral_y" in kept:
            choose("lateral_y", fy_range, n_min, lambda r0, r1: forces_lateral(r0, r1, wall_mask)[1])

    # -- pass 2: code each band
    for r0, r1 in bands:
        out = slice(r0 * cols, r1 * cols)
        if need_n:
            q, target = quant["normal_force"], codes["normal_force"].reshape(-1)[out]
            if clamp:
                _encode_into(q, forces_n(r0, r1, clamp), target)
            else:   # N computed inside the coding pass, from the heights
                _encode_into(q, h[r0:r1].reshape(-1), target, gain=mapping.n_gain, base=mapping.n_base)
        if lateral:
            fx, fy = forces_lateral(r0, r1, wall_mask)
            _encode_into(quant["lateral_x"], fx, codes["lateral_x"].reshape(-1)[out])
            if "lateral_y" in kept:
                _encode_into(quant["lateral_y"], fy, codes["lateral_y"].reshape(-1)[out])
    return walls, codes, quant, qinfo, clamped


def _compile_whole(hf, device, mapping, options, kept):
    """Walls and coded channels computed on whole arrays (any method and mapping)."""
    # -- gradient analysis (walls are analysed for every compile)
    gx, gy = gradient(hf, options.gradient_method, **options.gradient_kw)
    walls = detect_walls(hf, gx, gy, options.max_slope)
    uses_slopes = any(n in kept for n in ("grad_x", "grad_y", "lateral_x", "lateral_y"))
    if _limited(walls, kept, options):
        limit_walls(gx, gy, options.max_slope, out=(gx, gy), walls=walls)
    walls.mask = None
    if not uses_slopes:
        del gx, gy
        gx = gy = None

    # -- channels, one at a time: compute, quantize, code, free
    codes, quant, qinfo, clamped = {}, {}, {}, {}

    def code(name, values, n_min=None):
        q, bound, rule = _choose(name, values, device, options, mapping, n_min)
        codes[name] = _encode(q, values)
        quant[name] = q
        qinfo[name] = _qinfo(q, bound, rule)

    n = None
    lo_n, hi_n = device.normal_force_range
    n_min = min(max(mapping.n_base, lo_n), hi_n)
    if mapping.height and (any(k in kept for k in ("normal_force", "skin_stretch"))
                           or (mapping.lateral == "normal" and "lateral_x" in kept)):
        n, clamped["normal_force"] = normal_force(hf, device, mapping)
        n_min = _min_nonzero_abs(n) or n_min
        if "normal_force" in kept:
            code("normal_force", n)
    elif "normal_force" in kept:  # kept on request with a constant N
        n, clamped["normal_force"] = normal_force(hf.with_heights(np.zeros(hf.shape)), device,
                                                  mapping.with_(height=True))
        code("normal_force", n)
        n = None
    if "grad_x" in kept:
        code("grad_x", gx)
    if "grad_y" in kept:
        code("grad_y", gy)
    if "lateral_x" in kept:
        fx, fy, clamped["lateral"] = lateral_force(gx, None if hf.is_1d else gy, device, mapping,
                                                   n if mapping.height else None,
                                                   out=(gx, None if hf.is_1d else gy))
        code("lateral_x", fx, n_min)
        if "lateral_y" in kept:
            code("lateral_y", fy, n_min)
        del fx, fy
    gx = gy = None
    if "skin_stretch" in kept:
        s, clamped["skin_stretch"] = skin_stretch(n if mapping.height else None, hf.shape, device, mapping)
        code("skin_stretch", s)
        del s
    return walls, codes, quant, qinfo, clamped


def _assemble(hf, device, mapping, options, kept, left_out, walls, codes, quant, qinfo, clamped):
    """The table and report from the coded channels."""
    grid = Grid(hf.rows, hf.cols, hf.dx, hf.dy, hf.x0, hf.y0)
    # an extruded profile (every row identical in every stored channel) keeps one row
    repeated = hf.rows > 1 and all(bool((c[1] == c[0]).all()) for c in codes.values()) \
        and all(bool((c == c[:1]).all()) for c in codes.values())
    tiles = None
    if repeated:
        layout = f"one {hf.cols}-sample row stored once and placed on all {hf.rows} rows (rows identical)"
        stored = int(sum(c[0].nbytes for c in codes.values()))
    elif hf.mask is not None:
        tiles, bg_codes = _mask_tiles(codes, hf.mask)
        n_tiles = -(-hf.rows // MASK_TILE) * -(-hf.cols // MASK_TILE)
        stored = int(sum(c.nbytes for _, chans in tiles for c in chans.values()))
        layout = (f"masked: {len(tiles)} of {n_tiles} tiles of {MASK_TILE}x{MASK_TILE} samples stored; the rest "
                  f"lies outside the picture's opaque area (flat ground, not stored)")
    else:
        layout = "dense: one block covering the canvas"
        stored = int(sum(c.nbytes for c in codes.values()))
    dense = int(grid.rows * grid.cols * len(CHANNELS) * 4)
    report = {
        "source": hf.source,
        "grid": grid.to_json(),
        "is_1d": hf.is_1d,
        "device": device.name,
        "mapping": mapping.spec,
        "kept": kept,
        "left_out": left_out,
        "quantization": qinfo,
        "walls": walls.to_json(),
        "clamped": clamped,
        "layout": layout,
        "stored_bytes": stored,
        "dense_bytes": dense,
        "bytes_saved": dense - stored,
        "dense_rule": "dense = rows*cols * every format channel * 4 bytes (float32)",
        "scale": _scale_report(hf.meta.get("scale"), mapping),
        "source_notes": list(hf.meta.get("notes", [])),
    }
    meta = table_meta(device, mapping, options, hf.source, hf.sha256(), report)
    background = {k: 0.0 for k in codes}
    if repeated:
        table = FrictionTable.from_repeated_row(grid, {n: c[0] for n, c in codes.items()}, quant, background, meta)
    elif tiles is not None:
        background = {n: float(quant[n].decode(np.asarray([bg_codes[n]]))[0]) for n in codes}
        placed = [(rc, {n: quant[n].decode(c) for n, c in chans.items()}) for rc, chans in tiles]
        table = FrictionTable.from_patches(grid, placed, quant, background, meta)
    else:
        table = FrictionTable.from_codes(grid, codes, quant, background, meta)
    return CompileResult(table, report)


#: Tile size (samples) of tables compiled from masked sources.
MASK_TILE = 32


def _mask_tiles(codes: dict, mask: np.ndarray):
    """Tiles to store of a masked source: those touching the mask or differing from the outside value.

    The outside value of each channel is its most common code outside the
    mask (flat ground); a tile left out holds exactly that code in every
    channel, so leaving it out changes nothing the renderer reads.
    Returns ``([((row0, col0), {name: codes}), ...], {name: outside code})``.
    """
    outside = ~mask
    bg = {}
    for n, c in codes.items():
        vals, counts = np.unique(c[outside], return_counts=True)
        bg[n] = vals[int(np.argmax(counts))]
    rows, cols = mask.shape
    tiles = []
    for r0 in range(0, rows, MASK_TILE):
        for c0 in range(0, cols, MASK_TILE):
            sl = (slice(r0, r0 + MASK_TILE), slice(c0, c0 + MASK_TILE))
            if mask[sl].any() or any(bool((c[sl] != bg[n]).any()) for n, c in codes.items()):
                tiles.append(((r0, c0), {n: c[sl] for n, c in codes.items()}))
    return tiles, bg


def _scale_report(scale: dict | None, mapping: MappingOptions) -> dict | None:
    """Scale from source units to height to force, for the compile report."""
    if not scale:
        return None
    out = dict(scale)
    a = float(scale["m_per_unit"])
    unit = scale["source_unit"]
    g = mapping.n_gain if mapping.height else 0.0
    out["n_per_m"] = g
    out["n_per_source_unit"] = a * g
    what = "1 gray level" if unit == "gray level" else f"1 {unit} of {scale.get('what', 'data')}"
    text = f"{what} -> {_si(a, 'm')} of height"
    if mapping.height:
        text += f" -> {_si(a * g, 'N')} of normal force (n_gain {g * 1e-3:.4g} N/mm"
        text += ", perceptual reshaping on top)" if mapping.perceptual_exponent is not None else ")"
    out["text"] = text
    return out


def _si(v: float, unit: str) -> str:
    """``3.5e-6, 'm'`` -> ``'3.5 um'``."""
    if v == 0:
        return f"0 {unit}"
    for f, p in ((1.0, ""), (1e-3, "m"), (1e-6, "u"), (1e-9, "n"), (1e-12, "p")):
        if abs(v) >= f:
            return f"{v / f:.4g} {p}{unit}"
    return f"{v:.4g} {unit}"


def format_report(report: dict) -> str:
    """Human-readable multi-line summary of a compile report."""
    g = report["grid"]
    lines = [f"source: {report['source']}",
             f"grid: {g['cols']} x {g['rows']} samples, dx={g['dx_m'] * 1e3:.4g} mm, dy={g['dy_m'] * 1e3:.4g} mm"
             + (" (1-D)" if report.get("is_1d") else ""),
             f"device: {report['device']}   mapping: {report['mapping']}"]
    sc = report.get("scale")
    if sc:
        lines.append(f"scale: {sc['text']}; {sc['rule']}")
    for note in report.get("source_notes", []):
        lines.append(f"note: {note}")
    lines.append("kept:")
    for name in report["kept"]:
        q = report["quantization"][name]
        unit = CHANNELS[name][0]
        bound = "no bound" if q["bound"] is None else f"bound {q['bound']:.3g} {unit}"
        ok = "" if q["meets_bound"] else "  (exceeds the perceptual bound)"
        lines.append(f"  {name:<16} {q['dtype']:<8} max error {q['max_error']:.3g} {unit} ({bound}){ok}")
    lines.append("left out:")
    for name, why in report["left_out"].items():
        lines.append(f"  {name:<16} {why}")
    from shapedisplay.author.gradients import wall_lines
    lines += wall_lines(report["walls"])
    for name, c in report["clamped"].items():
        n_cl = c["below"] + c["above"]
        if n_cl:
            lines.append(f"clamped {name}: {n_cl} samples ({c['fraction'] * 100:.3g} %) to "
                         f"{c['range']} {c['unit']}, by up to {c['max_excess']:.3g} {c['unit']}")
    lines.append(f"layout: {report['layout']}")
    lines.append(f"stored {report['stored_bytes']} bytes; dense {report['dense_bytes']} bytes; "
                 f"saved {report['bytes_saved']} bytes")
    return "\n".join(lines)
