"""Force mapping: from heights and slopes to the channels a device renders.

Mappings, all on arrays of shape (rows, cols):

height
    ``N = n_base + n_gain * h`` (n_base is the published N1 = 0.5 N), clamped to
    the device's ``normal_force_range``. With ``perceptual_exponent`` beta the
    height increment is reshaped so equal height steps feel like equal steps:
    ``N = n_base + sign(h) * phi(|h|)`` with ``phi`` from :func:`perceptual_scale`
    (``phi(h_max) = n_gain * h_max``, so the extremes are unchanged).
slope friction (one-sided)
    ``mu_eff = mu0 + K_mu * max(0, grad h . v_hat)`` — uphill resists, downhill
    releases. Depends on the direction of motion, so the table keeps
    ``grad_x``/``grad_y`` and the runtime applies it; ``K_mu`` is
    ``slope_friction_gain`` (per unit slope).
lateral cue
    ``"gradient"``: ``F = -lateral_gain * grad h`` (N per unit slope);
    ``"normal"``: ``F = -N * grad h`` (frictionless slope under load N).
    Opposes +grad: uphill resists, downhill assists. The magnitude is clamped
    to the device's ``lateral_force_max`` (direction kept).
skin stretch
    Tactor stiffness ``k_s = mu_s N_ref / delta_target`` with ``N_ref =
    n_base`` (Provancher and Sylvester); at breakaway the stretch is ``delta = mu_s N / k_s
    = delta_target * N / n_base``, clamped to ``skin_stretch_max``.

Which channels a table keeps is decided by :func:`needed_channels`: a
channel is kept only if the mapping produces it *and* the device's outputs
use it.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np

from shapedisplay.errors import InputError, did_you_mean, unknown_key
from shapedisplay.author.heightfield import HeightField
from shapedisplay.units import parse_quantity

#: Power-law exponents beta of psi = k phi^beta, measured per haptic dimension (the one table of them).
EXPONENTS = {
    "bumpiness": 0.76,     # lowest measured on virtual surfaces
    "friction": 1.26,      # stickiness / friction, highest measured
    "stickiness": 1.26,
    "vibration": 0.6,      # ~250 Hz on the finger
}
LATERAL_LAWS = ("off", "gradient", "normal")
#: Defaults used when a mapping spec names a cue without its gain.
DEFAULT_SLOPE_FRICTION_GAIN = 0.2      # per unit slope: mu rises 0.2 on a 45 deg uphill
DEFAULT_LATERAL_GAIN = 1.0             # N per unit slope
DEFAULT_SKIN_STRETCH = 0.55e-3         # m, a studied stretch level (Provancher and Sylvester)
#: Device outputs that render friction (and so use normal force and slopes).
FRICTION_OUTPUTS = ("burst", "skin_stretch", "contactor", "normal")


@dataclass(frozen=True)
class MappingOptions:
    """How heights become forces. SI units; validated on construction.

    Attributes
    ----------
    height : bool
        Produce ``normal_force`` from heights; if False the runtime uses a
        constant N = ``n_base``.
    n_base : float, N
        Normal force on flat ground (N1; published 0.5 N).
    n_gain : float, N/m
        Height gain G (1000 N/m = 1 N/mm).
    slope_friction_gain : float, per unit slope
        K_mu of the one-sided slope-friction mapping; > 0 keeps grad_x/grad_y.
    lateral : {"off", "gradient", "normal"}
        Lateral-force law.
    lateral_gain : float, N per unit slope
        K of the gradient law.
    skin_stretch : float, m
        Stretch target at breakaway on flat ground; > 0 keeps skin_stretch.
    perceptual_exponent : float or None
        beta of the power law for "equal perceived steps" of height (None: linear).
    perceptual_threshold : float, N
        phi_th of the threshold-corrected form psi = k (phi - phi_th)^beta.
    """

    height: bool = True
    n_base: float = 0.5                 # N
    n_gain: float = 1000.0              # N/m
    slope_friction_gain: float = 0.0    # K_mu, per unit slope
    lateral: str = "off"                # off | gradient | normal
    lateral_gain: float = 0.0           # N per unit slope
    skin_stretch: float = 0.0           # m
    perceptual_exponent: float | None = None
    perceptual_threshold: float = 0.0   # N

    def __post_init__(self):
        if isinstance(self.perceptual_exponent, str):       # a dimension of EXPONENTS, or a number
            b = self.perceptual_exponent.strip()
            if b not in EXPONENTS:
                try:
                    float(b)
                except ValueError:
                    raise InputError(f"mapping `perceptual_exponent` must be a number > 0 or one of "
                                     f"{', '.join(EXPONENTS)} (got {b!r}){did_you_mean(b, EXPONENTS)}") from None
            object.__setattr__(self, "perceptual_exponent", EXPONENTS[b] if b in EXPONENTS else float(b))
        for name, unit in (("n_base", "N"), ("n_gain", "N/m"), ("slope_friction_gain", "1"),
                           ("lateral_gain", "N"), ("skin_stretch", "m"), ("perceptual_threshold", "N")):
            v = getattr(self, name)
            if isinstance(v, str):
                v = parse_quantity(v, unit, name)
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise InputError(f"mapping `{name}` must be a number (got {v!r})") from None
            if not math.isfinite(v) or v < 0:
                raise InputError(f"mapping `{name}` must be finite and >= 0 (got {name}={v!r})")
            object.__setattr__(self, name, v)
        if self.lateral not in LATERAL_LAWS:
            raise unknown_key("lateral law", self.lateral, LATERAL_LAWS)
        if self.lateral == "gradient" and self.lateral_gain <= 0:
            raise InputError(f"mapping `lateral_gain` must be > 0 with lateral='gradient' (got {self.lateral_gain})")
        b = self.perceptual_exponent
        if b is not None and not (math.isfinite(float(b)) and float(b) > 0):
            raise InputError(f"mapping `perceptual_exponent` must be > 0 (got {b!r})")
        if b is not None:
            object.__setattr__(self, "perceptual_exponent", float(b))
        object.__setattr__(self, "height", bool(self.height))

    # ------------------------------------------------------------------ spec strings
    @classmethod
    def parse(cls, spec: str = "height", **kw) -> "MappingOptions":
        """Build options from a CLI spec such as ``"height+lateral"``.

        Terms joined by ``+`` (or ``,``):

        ``height``           normal force from height (N = n_base + n_gain h)
        ``slope``            one-sided slope friction (K_mu default 0.2 per unit slope)
        ``lateral``          lateral cue, gradient law (K default 1 N per unit slope)
        ``lateral-normal``   lateral cue, F = -N grad h
        ``stretch``          skin-stretch channel (target default 0.55 mm)
        ``perceptual``       equal perceived steps (beta default 0.76, bumpiness)

        Keywords override fields (``n_base="0.5N"``, ``lateral_gain=2`` ...);
        None values are ignored. A gain turns its term on (``lateral_gain``
        adds ``lateral``, ``slope_friction_gain`` ``slope``, ``skin_stretch``
        ``stretch``, ``perceptual_exponent`` ``perceptual``). A spec without
        ``height`` keeps N constant.
        """
        terms = [t.strip().lower() for t in str(spec).replace(",", "+").split("+") if t.strip()]
        if not terms:
            raise InputError(f"`mapping` is empty (got {spec!r}); valid terms: {', '.join(_TERMS)}")
        kw = {k: v for k, v in kw.items() if v is not None}
        valid = {f.name for f in fields(cls)}
        for k in kw:
            if k not in valid:
                raise unknown_key("mapping option", k, valid)
        opts: dict = {"height": False}
        for t in terms:
            t = t.replace("_", "-")
            if t not in _TERMS:
                raise unknown_key("mapping term", t, _TERMS)
            if t == "height":
                opts["height"] = True
            elif t == "slope":
                opts["slope_friction_gain"] = DEFAULT_SLOPE_FRICTION_GAIN
            elif t == "lateral":
                opts["lateral"], opts["lateral_gain"] = "gradient", DEFAULT_LATERAL_GAIN
            elif t == "lateral-normal":
                opts["lateral"] = "normal"
            elif t in ("stretch", "skin-stretch"):
                opts["skin_stretch"] = DEFAULT_SKIN_STRETCH
            elif t == "perceptual":
                opts["perceptual_exponent"] = EXPONENTS["bumpiness"]
        if "lateral" in terms and "lateral-normal" in terms:
            raise InputError(f"`mapping` may hold one lateral law, 'lateral' (F = -K grad h) or 'lateral-normal' "
                             f"(F = -N grad h) (got {spec!r})")
        if "lateral_gain" in kw and "lateral" not in kw:
            if opts.get("lateral") == "normal":
                raise InputError(f"`lateral_gain` is K of the 'lateral' law F = -K grad h; 'lateral-normal' uses N "
                                 f"instead (got lateral_gain={kw['lateral_gain']!r} with mapping {spec!r})")
            # like the other gains, giving K asks for its term
            opts["lateral"] = "gradient"
        opts.update(kw)
        return cls(**opts)

    def to_json(self) -> dict:
        d = asdict(self)
        d["spec"] = self.spec
        return d

    @classmethod
    def from_json(cls, d: dict) -> "MappingOptions":
        valid = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in valid})

    @property
    def spec(self) -> str:
        """The spec string this mapping corresponds to (gains not included)."""
        terms = []
        if self.height:
            terms.append("height")
        if self.slope_friction_gain > 0:
            terms.append("slope")
        if self.lateral == "gradient":
            terms.append("lateral")
        elif self.lateral == "normal":
            terms.append("lateral-normal")
        if self.skin_stretch > 0:
            terms.append("stretch")
        if self.perceptual_exponent is not None:
            terms.append("perceptual")
        return "+".join(terms) or "constant"

    def height_of_force(self, n):
        """Height (m) whose normal force is ``n`` (N) under the linear mapping: ``(n - n_base) / n_gain``.

        The inverse of ``N = n_base + n_gain h``; refused for a mapping that is
        not linear in height (no height term, a perceptual exponent, n_gain 0).
        """
        if not self.height or self.perceptual_exponent is not None or self.n_gain <= 0:
            raise InputError(f"a force turns into a height only under the linear mapping with n_gain > 0 "
                             f"(got mapping {self.spec!r}, n_gain={self.n_gain:g} N/m)")
        return (np.asarray(n, dtype=np.float64) - self.n_base) / self.n_gain if np.ndim(n) \
            else (float(n) - self.n_base) / self.n_gain

    def with_(self, **changes) -> "MappingOptions":
        return replace(self, **changes)


_TERMS = ("height", "slope", "lateral", "lateral-normal", "stretch", "skin-stretch", "perceptual")


# ----------------------------------------------------------------- perceptual scaling
def equal_steps(t, lo: float, hi: float, beta: float, threshold: float = 0.0):
    """Stimulus whose perceived magnitude grows linearly with ``t``: the inverted power law.

    With Stevens' law ``psi = k (phi - phi_th)^beta`` (``phi_th`` the
    threshold below which it fails; 0 for the plain form), the stimulus at
    ``t`` is the one whose ``psi`` lies the fraction ``t`` of the way from
    ``psi(lo)`` to ``psi(hi)``:
    ``phi = phi_th + ((lo - phi_th)^beta + t ((hi - phi_th)^beta - (lo - phi_th)^beta))^(1/beta)``;
    from the threshold up (``lo == phi_th``) that is
    ``phi_th + (hi - phi_th) t^(1/beta)``. Every use of the power law in the
    package (height levels, perceptual height mapping, data layers) goes
    through this function; the exponents are :data:`EXPONENTS`.

    Parameters
    ----------
    t : array-like, >= 0
        Position between the ends (0 at ``lo``, 1 at ``hi``; larger values
        extrapolate along the same law).
    lo, hi : float
        Stimuli at t = 0 and t = 1 (``phi_th <= lo <= hi``).
    beta : float
        Exponent (> 0).
    threshold : float
        ``phi_th``.
    """
    if not (beta > 0 and math.isfinite(beta)):
        raise InputError(f"the power law needs an exponent beta > 0 (got beta={beta})")
    if not threshold <= lo <= hi:
        raise InputError(f"the power law needs threshold <= lo <= hi (got threshold={threshold}, lo={lo}, hi={hi})")
    t = np.asarray(t, dtype=np.float64)
    if lo == threshold:
        return threshold + (hi - threshold) * np.power(t, 1.0 / beta)
    a, b = (lo - threshold) ** beta, (hi - threshold) ** beta
    return threshold + np.power(a + t * (b - a), 1.0 / beta)


def perceptual_scale(d, d0: float, phi0: float, beta: float, phi_th: float = 0.0):
    """Stimulus for data value ``d`` so that perceived steps are equal.

    Stevens' law ``psi = k (phi - phi_th)^beta`` inverted so that psi is linear
    in d (:func:`equal_steps` from the threshold up to ``phi0`` at ``d0``):
    ``phi = phi_th + (phi0 - phi_th) (d / d0)^(1/beta)`` for d > 0 and
    ``phi = 0`` for d = 0 (no stimulus). With ``phi_th = 0`` this is the plain
    form ``phi = phi0 (d / d0)^(1/beta)``.

    Parameters
    ----------
    d : array-like, >= 0
        Data values.
    d0, phi0 : float
        Reference pair: ``phi(d0) = phi0`` (d0 > 0).
    beta : float
        Exponent (> 0), e.g. :data:`EXPONENTS` ["bumpiness"] = 0.76.
    phi_th : float
        Detection threshold of the stimulus (0 <= phi_th < phi0).
    """
    if not (d0 > 0 and beta > 0 and math.isfinite(d0) and math.isfinite(beta)):
        raise InputError(f"perceptual scaling needs d0 > 0 and beta > 0 (got d0={d0}, beta={beta})")
    if not 0 <= phi_th < phi0 and not (phi0 == 0 and phi_th == 0):
        raise InputError(f"perceptual scaling needs 0 <= phi_th < phi0 (got phi_th={phi_th}, phi0={phi0})")
    d = np.asarray(d, dtype=np.float64)
    if np.any(d < 0):
        raise InputError("perceptual scaling takes data values >= 0")
    return np.where(d > 0, equal_steps(d / d0, phi_th, phi0, beta, phi_th), 0.0)


def perceived(phi, k: float, beta: float, phi_th: float = 0.0):
    """Perceived magnitude ``psi = k * max(phi - phi_th, 0)^beta`` (forward power law)."""
    phi = np.asarray(phi, dtype=np.float64)
    return k * np.power(np.maximum(phi - phi_th, 0.0), beta)


# ----------------------------------------------------------------- which channels
def needed_channels(device, mapping: MappingOptions, is_1d: bool = False) -> tuple[list, dict]:
    """Channels a table needs for this device and mapping.

    Returns
    -------
    kept : list of str
        Channel names, in :data:`shapedisplay.table.model.CHANNELS` order.
    left_out : dict
        Every other format channel -> the reason it is not stored.
    """
    from shapedisplay.table.model import CHANNELS

    outs = set(device.outputs)
    renders_friction = bool(outs & set(FRICTION_OUTPUTS))
    kept, left = [], {}
    for name in CHANNELS:
        reason = None
        if name == "normal_force":
            if not mapping.height:
                reason = f"mapping '{mapping.spec}' has no height term: N is constant n_base={mapping.n_base:g} N"
            elif not renders_friction:
                reason = f"device '{device.name}' outputs {sorted(outs)} do not render friction"
        elif name in ("breakaway_force", "kinetic_force"):
            reason = ("mu_s, mu_k are uniform over the surface: the runtime computes "
                      f"{'mu_s' if name == 'breakaway_force' else 'mu_k'}*N from normal_force")
        elif name in ("friction_scale", "burst_gain"):
            reason = "not produced by a height mapping (data layers only)"
        elif name in ("grad_x", "grad_y"):
            if mapping.slope_friction_gain <= 0:
                reason = "slope friction is off (slope_friction_gain = 0)"
            elif not renders_friction:
                reason = f"device '{device.name}' outputs {sorted(outs)} do not render friction"
            elif name == "grad_y" and is_1d:
                reason = "1-D source: no slope across the stroke"
        elif name in ("lateral_x", "lateral_y"):
            if mapping.lateral == "off":
                reason = "lateral cue is off in the mapping"
            elif "lateral" not in outs:
                reason = f"device '{device.name}' has no 'lateral' output (outputs: {sorted(outs)})"
            elif name == "lateral_y" and is_1d:
                reason = "1-D source: no lateral force across the stroke"
        elif name == "skin_stretch":
            if mapping.skin_stretch <= 0:
                reason = "skin stretch is off in the mapping"
            elif "skin_stretch" not in outs:
                reason = f"device '{device.name}' has no 'skin_stretch' output (outputs: {sorted(outs)})"
        else:  # a channel added to the format later
            reason = "not produced by this compiler"
        if reason is None:
            kept.append(name)
        else:
            left[name] = reason
    return kept, left


# ----------------------------------------------------------------- channels
class ForceChannels(dict):
    """``{name: ndarray (rows, cols) float64, SI}`` plus ``clamped``: per-channel clamping notes."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.clamped: dict = {}


def normal_force(hf: HeightField, device, mapping: MappingOptions, *, out: np.ndarray | None = None
                 ) -> tuple[np.ndarray, dict]:
    """Normal force N (rows, cols), newtons, clamped to the device range; and a clamping note.

    ``out``: a float64 array of the heights' shape to write N into (else a new one).
    """
    h = hf.heights
    beta = mapping.perceptual_exponent
    if out is not None and (out.shape != h.shape or out.dtype != np.float64):
        raise InputError(f"`out` must be a float64 array of shape {h.shape} (got {out.dtype} {out.shape})")
    if beta is None:
        n = np.multiply(h, mapping.n_gain, out=out)
    else:
        d0 = float(np.max(np.abs(h), initial=0.0))
        if d0 > 0:
            inc = perceptual_scale(np.abs(h), d0, mapping.n_gain * d0, beta,
                                   min(mapping.perceptual_threshold, mapping.n_gain * d0 * (1 - 1e-12)))
            n = np.copysign(inc, h, out=inc if out is None else out)
        else:
            n = np.zeros_like(h) if out is None else out
            n[...] = 0.0
    n += mapping.n_base
    lo, hi = device.normal_force_range
    return n, _clamp(n, lo, hi, "normal_force", "N")


def fit_to_force_range(hf: HeightField, device, mapping: MappingOptions) -> HeightField:
    """Scale the heights so that the normal force never leaves the device's range.

    With ``N = n_base + n_gain * h`` the heights are multiplied by the
    largest factor ``s <= 1`` that keeps every sample within
    ``device.normal_force_range`` (about height 0, so flat ground keeps
    ``n_base``). A field that already fits, or a mapping without the height
    term, is returned unchanged. The factor is recorded in
    ``meta["scale"]`` and stated in ``meta["notes"]``.

    Returns
    -------
    HeightField
        ``hf`` itself, or a copy on the same grid with scaled heights.
    """
    if not mapping.height or mapping.n_gain <= 0:
        return hf
    lo, hi = device.normal_force_range
    h = hf.heights
    hmin, hmax = float(h.min()), float(h.max())
    s = 1.0
    if hmax > 0 and mapping.n_base + mapping.n_gain * hmax > hi:
        s = min(s, (hi - mapping.n_base) / (mapping.n_gain * hmax))
    if hmin < 0 and mapping.n_base + mapping.n_gain * hmin < lo:
        s = min(s, (lo - mapping.n_base) / (mapping.n_gain * hmin))
    if s >= 1.0:
        return hf
    if s <= 0:
        raise InputError(f"cannot fit the heights into the device's normal force range {lo:g}..{hi:g} N: "
                         f"the base force n_base = {mapping.n_base:g} N lies outside it")
    s *= 1 - 1e-12                      # the top sample lands just inside the ceiling, not 1 ulp above it
    out = hf.with_heights(h * s)
    meta = out.meta
    sc = dict(meta.get("scale") or {"source_unit": "m", "m_per_unit": 1.0, "offset_m": 0.0, "rule": "metres"})
    sc["m_per_unit"] = sc["m_per_unit"] * s
    sc["offset_m"] = sc.get("offset_m", 0.0) * s
    sc["rule"] = sc.get("rule", "") + f", relief scaled x{s:.4g} to fit the device's {lo:g}..{hi:g} N force range"
    meta["scale"] = sc
    top = max(hmax, -hmin)
    meta["notes"] = list(meta.get("notes", [])) + [
        f"relief {hmin * 1e3:.4g}..{hmax * 1e3:.4g} mm would clamp at the device's force range {lo:g}..{hi:g} N "
        f"with n_gain {mapping.n_gain * 1e-3:g} N/mm; heights scaled x{s:.4g} to fit "
        f"(now {hmin * s * 1e3:.4g}..{hmax * s * 1e3:.4g} mm; give --n-gain or --height to choose the scale)"]
    meta["fitted_to_force_range"] = {"factor": s, "relief_m": top}
    return out


def _clamp(a: np.ndarray, lo: float, hi: float, name: str, unit: str) -> dict:
    """Clamp ``a`` in place to [lo, hi]; return a note of how much was clamped."""
    amin, amax = float(a.min()), float(a.max())
    below = int(np.count_nonzero(a < lo)) if amin < lo else 0
    above = int(np.count_nonzero(a > hi)) if amax > hi else 0
    if below or above:
        np.clip(a, lo, hi, out=a)
    return clamp_note(lo, hi, unit, amin, amax, below, above, a.size)


def clamp_note(lo: float, hi: float, unit: str, amin: float, amax: float, below: int, above: int,
               size: int) -> dict:
    """The report of a clamp to [lo, hi] of ``size`` values spanning ``amin..amax`` (``below``/``above`` clamped)."""
    return {"range": [lo, hi], "unit": unit, "below": below, "above": above,
            "fraction": (below + above) / size, "max_excess": max(lo - amin, amax - hi, 0.0),
            "raw_min": amin, "raw_max": amax}


def _check_lateral_peak(peak: float) -> None:
    if not math.isfinite(peak):   # |F|^2 overflowed: clipping would lose the direction (and give 0)
        raise InputError("lateral forces overflow float64 (|F| beyond 1e154 N); check the lateral gain "
                         "and the units of the heights and spacing")


def lateral_clip_note(fmax: float, count: int, peak: float, size: int) -> dict:
    """The report of lateral forces whose magnitude peaked at ``peak`` with ``count`` of ``size`` clipped
    to ``fmax`` (no limit if ``fmax`` <= 0); refuses an infinite peak."""
    _check_lateral_peak(peak)
    return {"range": [0.0, fmax if fmax > 0 else None], "unit": "N", "below": 0, "above": int(count),
            "fraction": int(count) / size, "max_excess": max(peak - fmax, 0.0) if fmax > 0 else 0.0,
            "raw_min": 0.0, "raw_max": float(peak), "rule": "magnitude clipped, direction kept"}


def lateral_force(gx: np.ndarray, gy: np.ndarray | None, device, mapping: MappingOptions,
                  n: np.ndarray | None = None, *, out=None) -> tuple[np.ndarray, np.ndarray | None, dict]:
    """Lateral cue ``F = -K grad h`` or ``-N grad h`` (newtons), magnitude clamped to the device.

    Parameters
    ----------
    gx, gy : ndarray (rows, cols)
        Slopes (``gy`` None for a 1-D field).
    n : ndarray (rows, cols) or None
        Normal force for the "normal" law (None: constant ``n_base``).
    out : (fx, fy) or None
        Output arrays; may be ``(gx, gy)`` to overwrite the slopes in place.

    Returns
    -------
    fx, fy, note
    """
    if mapping.lateral == "off":
        raise InputError("mapping has no lateral cue (lateral='off')")
    fx = np.empty_like(gx) if out is None else out[0]
    fy = None if gy is None else (np.empty_like(gy) if out is None else out[1])
    if mapping.lateral == "gradient":
        np.multiply(gx, -mapping.lateral_gain, out=fx)
        if gy is not None:
            np.multiply(gy, -mapping.lateral_gain, out=fy)
    else:
        load = -mapping.n_base if n is None else np.negative(n)
        np.multiply(gx, load, out=fx)
        if gy is not None:
            np.multiply(gy, load, out=fy)
        del load
    fmax = float(device.lateral_force_max)
    from shapedisplay.author.gradients import _flat
    flx, fly = _flat(fx), _flat(fy)
    if flx is not None and fly is not None and fx.size:
        from shapedisplay.author import kernels as _kernels
        cnt, peak = _kernels.clip_magnitude(flx, fly, fmax if fmax > 0 else math.inf)
        return fx, fy, lateral_clip_note(fmax, cnt, peak, fx.size)
    with np.errstate(over="ignore"):   # an overflow shows as an infinite peak, refused below
        m2 = np.multiply(fx, fx)
        if fy is not None:
            t = np.multiply(fy, fy)
            m2 += t
            del t
    peak = math.sqrt(float(m2.max(initial=0.0)))
    _check_lateral_peak(peak)
    note = {"range": [0.0, fmax if fmax > 0 else None], "unit": "N", "below": 0, "above": 0, "fraction": 0.0,
            "max_excess": 0.0, "raw_min": 0.0, "raw_max": peak, "rule": "magnitude clipped, direction kept"}
    if fmax > 0 and peak > fmax:
        cnt = int(np.count_nonzero(m2 > fmax * fmax))
        # factor min(1, fmax/|F|), exactly 1 where |F| <= fmax; fmax/|F| as in the kernel, not
        # sqrt(fmax^2/|F|^2): fmax^2 may underflow to 0 and 0/0 would be NaN (|F| = 0 gives inf -> 1)
        np.sqrt(m2, out=m2)
        with np.errstate(divide="ignore"):
            np.divide(fmax, m2, out=m2)
        np.minimum(m2, 1.0, out=m2)
        fx *= m2
        if fy is not None:
            fy *= m2
        note.update(above=cnt, fraction=cnt / fx.size, max_excess=peak - fmax)
    return fx, fy, note


def skin_stretch(n: np.ndarray | None, shape, device, mapping: MappingOptions) -> tuple[np.ndarray, dict]:
    """Skin-stretch target at breakaway ``delta_target * N / n_base`` (metres), clamped to the device."""
    if mapping.skin_stretch <= 0:
        raise InputError("mapping has no skin stretch (skin_stretch = 0)")
    if n is None or mapping.n_base <= 0:
        s = np.full(shape, mapping.skin_stretch)
    else:
        s = np.multiply(n, mapping.skin_stretch / mapping.n_base)
    hi = float(device.skin_stretch_max) if device.skin_stretch_max > 0 else math.inf
    return s, _clamp(s, 0.0, hi, "skin_stretch", "m")


def force_channels(hf: HeightField, device, mapping: MappingOptions, grad=None) -> ForceChannels:
    """Every channel this device and mapping need (see :func:`needed_channels`).

    Parameters
    ----------
    hf : HeightField
    device : DeviceProfile
    mapping : MappingOptions
    grad : (gx, gy) or None
        Precomputed (e.g. wall-limited) slopes; central differences if None.
        Not modified.

    Returns
    -------
    ForceChannels
        ``{name: ndarray (rows, cols) float64, SI}``; ``.clamped[name]`` says
        how much of each clamped channel hit the device limits.
    """
    kept, _ = needed_channels(device, mapping, hf.is_1d)
    out = ForceChannels()
    need_grad = any(k in kept for k in ("grad_x", "grad_y", "lateral_x", "lateral_y"))
    if need_grad and grad is None:
        from shapedisplay.author.gradients import gradient
        grad = gradient(hf, "central")
    n = None
    if mapping.height and (("normal_force" in kept) or mapping.lateral == "normal" or "skin_stretch" in kept):
        n, note = normal_force(hf, device, mapping)
        if "normal_force" in kept:
            out["normal_force"] = n
            out.clamped["normal_force"] = note
    if "grad_x" in kept:
        out["grad_x"] = np.array(grad[0], dtype=np.float64, copy=True)
    if "grad_y" in kept:
        out["grad_y"] = np.array(grad[1], dtype=np.float64, copy=True)
    if "lateral_x" in kept:
        fx, fy, note = lateral_force(grad[0], None if hf.is_1d else grad[1], device, mapping, n)
        out["lateral_x"] = fx
        if fy is not None and "lateral_y" in kept:
            out["lateral_y"] = fy
        out.clamped["lateral"] = note
    if "skin_stretch" in kept:
        s, note = skin_stretch(n, hf.shape, device, mapping)
        out["skin_stretch"] = s
        out.clamped["skin_stretch"] = note
    return out
