"""Widget types: their keys, defaults and geometry (heights on a local grid).

Each widget type is one class in :data:`WIDGET_TYPES`. A type declares its
keys (kind and built-in default), turns the parsed keys into SI parameters
(:meth:`WidgetType.finish`, which sees the snapped size) and evaluates its
heights on the widget's own sample grid (:meth:`WidgetType.heights`) with
local coordinates ``u`` (along x, from the box corner) and ``v`` (along y).
A new widget type is one class plus one registry line.

Heights are metres; positive is raised (a bump: more normal force), negative
sunk (a dent). Tactile strength is given in the designer's language by one of

* ``height`` (``depth`` for dents and grooves): geometric height, mapped to
  force by the scene's ``n_gain`` (N = N1 + n_gain * h);
* ``force``: the normal force at the top (bottom for a dent), e.g. "2.5 N",
  or the range "0.5:2.5 N" whose low end must be the scene's N1;
* ``force_step``: the force difference to flat ground, e.g. "2 N";
* ``level``: perceived height in equal-feeling steps ``1..levels``; level
  ``i`` asks for ``level_force * (i / levels) ** (1 / beta)`` (Stevens' power
  law ``psi = k phi^beta`` with the bumpiness exponent, forces.equal_steps), so that
  each step feels equally larger than the one below.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from shapedisplay.author.forces import EXPONENTS, equal_steps
from shapedisplay.author.scene.fields import (MAX_LENGTH_M, Canvas, Ctx, OVERLAP_RULES, SceneError, Widget, choice, length, number,
                     pair, quantity, wrap_unit_errors)
from shapedisplay.author.shapes import WIDGET_EDGES, rounded_rect_distance

#: Published starting points: ramp spans of 10-30 mm were studied;
#: perception saturates above ~15 mm at 0.15 N/mm.
DEFAULT_RAMP = "10 mm"
EDGES = tuple(WIDGET_EDGES)           # "linear", "cosine", "tent" (author/shapes.py)
#: Largest box a widget may span on the canvas grid (samples), checked before its geometry is
#: built (a mesh is rasterised on the whole box, also where it reaches past the canvas).
MAX_WIDGET_SAMPLES = 4096 * 4096


# --------------------------------------------------------------- shapes
def edge_profile(t, kind: str):
    """Edge rise from 0 (outer edge, t=0) to 1 (top of the ramp, t>=1); ``kind`` one of :data:`EDGES`."""
    return WIDGET_EDGES[kind](t)


def inside_distance(u, v, W: float, H: float, r: float, is_1d: bool):
    """Distance from the edge of the rounded rectangle [0,W]x[0,H] (corner radius r), >0 inside."""
    if is_1d:
        return np.minimum(u, W - u) + 0.0 * v
    return -rounded_rect_distance(u - W / 2, v - H / 2, W / 2, H / 2, r)


def raised_cosine(r, radius: float):
    """(1 + cos(pi r / R)) / 2 inside r < R, 0 outside."""
    r = np.asarray(r, dtype=np.float64)
    return np.where(r < radius, 0.5 + 0.5 * np.cos(np.pi * np.minimum(r / radius, 1.0)), 0.0)


# --------------------------------------------------------------- strength
STRENGTH_KEYS = ("height", "force", "force_step", "level")
DEPTH_KEYS = ("depth", "force", "force_step", "level")


def resolve_strength(raw: dict, keys: tuple, sign: int, default: str, fp: str, w: "PlaceCtx") -> float:
    """Signed height in metres from one of the strength keys (see module doc)."""
    given = [k for k in keys if k in raw]
    if len(given) > 1:
        raise w.ctx.error(w.where, f"{fp}{given[1]}",
                          f"conflicts with `{fp}{given[0]}`: give only one of {', '.join(keys)}")
    n_base, n_gain = w.mapping.n_base, w.mapping.n_gain
    key = given[0] if given else keys[0]
    value = raw[key] if given else default
    path = f"{fp}{key}"
    if key in ("height", "depth"):
        return sign * length(value, path, w.ctx, w.where, nonneg=True)
    if n_gain <= 0:
        raise w.ctx.error(w.where, path, f"needs `mapping.n_gain` > 0 to turn a force into a height "
                                         f"(got n_gain={n_gain} N/m)")
    if key == "force":
        if isinstance(value, str) and ":" in value:
            lo, hi = _force_range(value, path, w)
            if abs(lo - n_base) > 1e-9:
                raise w.ctx.error(w.where, path, f"low end must be the scene's base force "
                                                 f"mapping.n_base = {n_base:g} N (got {value!r})")
            target = hi
        else:
            target = quantity(value, "N", path, w.ctx, w.where)
        step = target - n_base
        if step * sign < 0:
            what = "above" if sign > 0 else "below"
            raise w.ctx.error(w.where, path, f"must be {what} the base force {n_base:g} N for a "
                                             f"{w.type} (got {value!r})")
        return step / n_gain
    if key == "force_step":
        step = quantity(value, "N", path, w.ctx, w.where)
        if step < 0:
            raise w.ctx.error(w.where, path, f"must be a force >= 0 (got {value!r})")
        return sign * step / n_gain
    levels = w.levels["levels"]
    lv = number(value, path, w.ctx, w.where, lo=0, hi=levels)
    step = float(equal_steps(lv / levels, 0.0, w.levels["level_force"], EXPONENTS["bumpiness"]))
    return sign * step / n_gain


def _force_range(value, path, w):
    from shapedisplay.units import parse_pair
    return wrap_unit_errors(w.ctx, w.where, parse_pair, value, ":", "N", path)


# --------------------------------------------------------------- placing
class PlaceCtx:
    """What a widget type sees while finishing its parameters."""

    def __init__(self, ctx: Ctx, where: str, index: int, wtype: str, canvas: Canvas, mapping,
                 levels: dict, device):
        self.ctx, self.where, self.index, self.type = ctx, where, index, wtype
        self.canvas, self.mapping, self.levels, self.device = canvas, mapping, levels, device
        self.fp = f"widget[{index}]."

    def warn(self, msg: str) -> None:
        self.ctx.warn(self.where, msg)

    def error(self, key: str, msg: str) -> SceneError:
        return self.ctx.error(self.where, self.fp + key, msg)


COMMON_KEYS = {"id": "str", "type": "str", "label": "str", "overlap": "overlap"}
BOX_KEYS = {"position": "point", "center": "point", "size": "size"}


class WidgetType:
    """Base class: keys, placement and geometry of one widget type."""

    name = ""
    #: key -> kind; defaults live in :meth:`finish`.
    own_keys: dict = {}
    strength_keys: tuple = ()
    boxed = True          # has position/center + size
    states: tuple = ()    # alternative compiled states (toggle)
    data_layer = False    # drives a data channel, not height

    @property
    def keys(self) -> dict:
        k = dict(COMMON_KEYS)
        if self.boxed:
            k.update(BOX_KEYS)
        k.update(self.own_keys)
        return k

    # ---- box
    def extent(self, raw: dict, w: PlaceCtx) -> tuple[float, float, float, float]:
        """(x, y, width, height) of the box in metres (y, height 0 on a 1-D canvas)."""
        if "size" not in raw:
            eg = "30 mm" if w.canvas.is_1d else "30x16 mm"
            raise w.error("size", f"is required for a {self.name} (e.g. size = \"{eg}\")")
        sw, sh = self._size(raw["size"], w)
        if "position" in raw and "center" in raw:
            raise w.error("center", "cannot be given together with `position`; keep one")
        if "position" in raw:
            x, y = self._point(raw["position"], "position", w)
            if w.canvas.origin == "top-left":       # the top-left corner: the box lies below it
                y -= sh
        elif "center" in raw:
            cx, cy = self._point(raw["center"], "center", w)
            x, y = cx - sw / 2, cy - sh / 2
        else:
            raise w.error("position", "is required (the lower-left corner, e.g. position = \"10,20 mm\"; "
                                      "or center = \"x,y mm\")")
        return x, y, sw, sh

    def _size(self, value, w: PlaceCtx):
        if w.canvas.is_1d:
            if isinstance(value, list) or (isinstance(value, str) and "x" in value.replace("px", "")):
                raise w.error("size", f"must be a single length on a 1-D canvas (got {value!r})")
            return length(value, w.fp + "size", w.ctx, w.where, positive=True), 0.0
        sw, sh = pair(value, "x", w.fp + "size", w.ctx, w.where)
        if not (sw > 0 and sh > 0):
            raise w.error("size", f"must be two lengths > 0 (got {value!r})")
        return sw, sh

    def _point(self, value, key, w: PlaceCtx):
        if w.canvas.is_1d:
            if isinstance(value, list) or (isinstance(value, str) and "," in value):
                raise w.error(key, f"must be a single x on a 1-D canvas (got {value!r})")
            return length(value, w.fp + key, w.ctx, w.where), 0.0
        x, y = pair(value, ",", w.fp + key, w.ctx, w.where)
        if w.canvas.origin == "top-left":           # [canvas] origin: y measured down from the top edge
            y = w.canvas.height - y
        return x, y

    # ---- parameters and geometry
    def finish(self, raw: dict, W: float, H: float, w: PlaceCtx) -> dict:
        """Parse the type's own keys into SI parameters, given the snapped size."""
        return {}

    def heights(self, p: dict, u, v, W: float, H: float, is_1d: bool, state: str | None = None):
        """Heights (metres) at local coordinates ``u`` (1, ncols) and ``v`` (nrows, 1)."""
        raise NotImplementedError

    def data(self, p: dict, u, v, W: float, H: float, is_1d: bool):
        """(channel, values) of a data layer."""
        raise NotImplementedError

    def describe(self, p: dict) -> dict:
        """Designer-facing summary for reports (SI)."""
        return {k: v for k, v in p.items() if isinstance(v, (int, float, str))}


def _edge_keys(w: PlaceCtx, raw: dict, default_edge: str = "linear"):
    edge = choice(raw.get("edge", default_edge), EDGES, w.fp + "edge", w.ctx, w.where)
    ramp = length(raw.get("ramp", DEFAULT_RAMP), w.fp + "ramp", w.ctx, w.where, positive=True)
    return edge, ramp


def _limit_ramp(ramp: float, edge: str, half: float, w: PlaceCtx, what: str = "ramp") -> float:
    if edge == "tent":
        return half
    if ramp > half + 1e-12:
        w.warn(f"`{what}` {ramp * 1e3:g} mm is longer than half the widget ({half * 1e3:g} mm); "
               f"shortened to {half * 1e3:g} mm so the full height is reached (use edge = \"tent\" "
               f"for a peak without plateau)")
        return half
    return ramp


def _sunk(keys: dict) -> dict:
    """The keys of a sunk variant (dent, groove): ``depth`` in place of ``height``."""
    return {("depth" if k == "height" else k): kind for k, kind in keys.items()}


class Button(WidgetType):
    """Raised rounded rectangle: flat top, edges rising over ``ramp`` with profile ``edge``."""

    name = "button"
    sign = 1
    strength_keys = STRENGTH_KEYS
    default_strength = "2 mm"
    own_keys = {"height": "len", "force": "force", "force_step": "force", "level": "num",
                "ramp": "len", "edge": "choice", "corner_radius": "len"}

    def finish(self, raw, W, H, w):
        edge, ramp = _edge_keys(w, raw)
        half = W / 2 if w.canvas.is_1d else min(W, H) / 2
        r = length(raw.get("corner_radius", "2 mm"), w.fp + "corner_radius", w.ctx, w.where, nonneg=True)
        if not w.canvas.is_1d and r > half:
            w.warn(f"`corner_radius` {r * 1e3:g} mm exceeds half the smaller side; using {half * 1e3:g} mm")
            r = half
        keys = self.strength_keys
        h = resolve_strength(raw, keys, self.sign, self.default_strength, w.fp, w)
        return {"height": h, "edge": edge, "ramp": _limit_ramp(ramp, edge, half, w), "corner_radius": r}

    def heights(self, p, u, v, W, H, is_1d, state=None):
        d = inside_distance(u, v, W, H, p["corner_radius"], is_1d)
        return np.where(d > 0, p["height"] * edge_profile(d / p["ramp"], p["edge"]), 0.0)


class Dent(Button):
    """Sunk rounded rectangle (a well): ``depth`` below flat ground."""

    name = "dent"
    sign = -1
    strength_keys = DEPTH_KEYS
    default_strength = "1 mm"
    own_keys = _sunk(Button.own_keys)


class Well(Dent):
    name = "well"


def _orientation(raw: dict, W: float, H: float, w: PlaceCtx) -> tuple[bool, float, float]:
    """(vertical, length L along the widget, cross size C) from ``orientation`` auto|horizontal|vertical.

    ``auto`` runs along the longer side; a 1-D canvas only has horizontal widgets.
    """
    orient = choice(raw.get("orientation", "auto"), ("auto", "horizontal", "vertical"),
                    w.fp + "orientation", w.ctx, w.where)
    if w.canvas.is_1d:
        if orient == "vertical":
            raise w.error("orientation", "must be horizontal on a 1-D canvas (got 'vertical')")
        return False, W, H
    vertical = orient == "vertical" or (orient == "auto" and H > W)
    return (vertical, H, W) if vertical else (vertical, W, H)


class Slider(WidgetType):
    """Track (groove or ridge) along the long axis, a thumb bump, optional detents.

    Keys: ``track`` groove|ridge, ``track_width``, ``track_depth`` (height of a
    ridge track), ``track_ramp``, ``value`` (0..1, thumb position), ``thumb_size``
    (diameter), thumb strength ``height``/``force``/``force_step``/``level``,
    ``detents`` (a count, e.g. 5, or a spacing, e.g. "10 mm", or "off"; see
    :func:`_detents` for where they sit), ``detent_height``,
    ``detent_width``, ``orientation`` auto|horizontal|vertical.
    """

    name = "slider"
    strength_keys = STRENGTH_KEYS
    own_keys = {"height": "len", "force": "force", "force_step": "force", "level": "num",
                "track": "choice", "track_width": "len", "track_depth": "len", "track_ramp": "len",
                "value": "num", "thumb_size": "len", "detents": "detents", "detent_height": "len",
                "detent_width": "len", "orientation": "choice", "edge": "choice"}

    def finish(self, raw, W, H, w):
        fp, ctx, where = w.fp, w.ctx, w.where
        vertical, L, C = _orientation(raw, W, H, w)
        track = choice(raw.get("track", "groove"), ("groove", "ridge"), fp + "track", ctx, where)
        edge = choice(raw.get("edge", "cosine"), ("linear", "cosine"), fp + "edge", ctx, where)
        if w.canvas.is_1d:
            tw = 0.0
        else:
            tw = length(raw.get("track_width", f"{0.5 * C * 1e3!r} mm"), fp + "track_width", ctx, where, positive=True)
            if tw > C + 1e-12:
                raise w.error("track_width", f"must fit the widget's {C * 1e3:g} mm cross size "
                                             f"(got {raw.get('track_width')!r})")
        td = length(raw.get("track_depth", "0.5 mm"), fp + "track_depth", ctx, where, nonneg=True)
        half = L / 2 if w.canvas.is_1d else min(tw, L) / 2
        tr = length(raw.get("track_ramp", f"{min(half, 2e-3) * 1e3!r} mm"), fp + "track_ramp", ctx, where,
                    positive=True)
        tr = _limit_ramp(tr, edge, half, w, "track_ramp")
        value = number(raw.get("value", 0.5), fp + "value", ctx, where, lo=0.0, hi=1.0)
        default_thumb = min(C, 12e-3, L) if not w.canvas.is_1d else min(10e-3, L / 2)
        ts = length(raw.get("thumb_size", f"{default_thumb * 1e3!r} mm"), fp + "thumb_size", ctx, where, positive=True)
        if ts > L + 1e-12:
            raise w.error("thumb_size", f"must not exceed the slider length {L * 1e3:g} mm "
                                        f"(got {raw.get('thumb_size', f'{ts * 1e3:g} mm')!r})")
        ts = min(ts, L)
        th = resolve_strength(raw, self.strength_keys, 1, "1.5 mm", fp, w)
        spacing, n_det = _detents(raw.get("detents", "off"), L, w)
        dh = length(raw.get("detent_height", "0.3 mm"), fp + "detent_height", ctx, where, nonneg=True)
        dw = length(raw.get("detent_width", "1 mm"), fp + "detent_width", ctx, where, positive=True)
        if spacing:
            res = w.device.resolution_m
            felt = max(0, math.ceil(L / res - 1e-9) - 1)
            if spacing < res:
                w.warn(f"`detents` every {spacing * 1e3:g} mm gives {n_det} detents, more than can be felt "
                       f"apart at the device's {res * 1e3:g} mm resolution (at most {felt} on "
                       f"{L * 1e3:g} mm; use a spacing >= {res * 1e3:g} mm)")
            if spacing < 2 * w.canvas.spacing or dw < 2 * w.canvas.spacing:
                w.warn(f"detents ({spacing * 1e3:g} mm apart, {dw * 1e3:g} mm wide) are finer than two "
                       f"canvas samples ({2 * w.canvas.spacing * 1e3:g} mm) and will alias; refine "
                       f"canvas.resolution or widen them")
            if dw > spacing:
                w.warn(f"`detent_width` {dw * 1e3:g} mm exceeds the detent spacing {spacing * 1e3:g} mm; "
                       f"neighbouring detents merge")
        return {"vertical": vertical, "track": track, "track_width": tw, "track_depth": td,
                "track_ramp": tr, "edge": edge, "value": value, "thumb_size": ts, "height": th,
                "detent_spacing": spacing, "detents": n_det, "detent_height": dh, "detent_width": dw}

    def thumb_center(self, p, L):
        R = p["thumb_size"] / 2
        return R + p["value"] * (L - 2 * R)

    def heights(self, p, u, v, W, H, is_1d, state=None):
        if p["vertical"]:
            u, v, W, H = v, u, H, W
        L = W
        sign = -1.0 if p["track"] == "groove" else 1.0
        if is_1d:
            band = inside_distance(u, v, W, H, 0.0, True)
            vc = v
        else:
            tw = p["track_width"]
            band = inside_distance(u, v - (H - tw) / 2, W, tw, tw / 2, False)
            vc = H / 2
        mask = np.where(band > 0, edge_profile(band / p["track_ramp"], p["edge"]), 0.0)
        r = np.abs(u - self.thumb_center(p, L)) if is_1d else np.hypot(u - self.thumb_center(p, L), v - vc)
        thumb = p["height"] * raised_cosine(r, p["thumb_size"] / 2)
        if p.get("thumb_part"):
            # a thumb that follows the finger (docs/reactive.md) is a part of its own: the table's block holds
            # the track ("rest" draws both, for previews), the part the thumb alone ("thumb")
            if state == "thumb":
                return thumb + 0.0 * (u + v)
            if state != "rest":
                thumb = 0.0 * thumb
        h = sign * p["track_depth"] * mask
        h = h + thumb
        if p["detents"]:
            det = np.zeros(np.broadcast(u, v).shape)
            for k in range(1, p["detents"] + 1):
                det = np.maximum(det, raised_cosine(np.abs(u - k * p["detent_spacing"]) + 0 * v,
                                                    p["detent_width"] / 2))
            h = h + p["detent_height"] * det * mask
        out = h + 0.0 * (u + v)
        return out  # (rows, cols) whichever way the widget runs


def _detents(value, L: float, w: "PlaceCtx") -> tuple[float, int]:
    """(spacing m, count) of a slider's detents from ``detents`` = "off", a count or a spacing.

    The rule: detent k sits at ``k * spacing`` from the start of the track,
    k = 1, 2, ...; the ends of the track (where it ramps) never get one. A
    count N gives ``spacing = L / (N + 1)``: N detents and N + 1 equal gaps.
    A spacing that does not divide L leaves a shorter last gap (warned); a
    spacing as long as the track leaves no detent (an error).
    """
    fp = w.fp + "detents"
    if value in ("off", False, 0):
        return 0.0, 0
    if isinstance(value, int) and not isinstance(value, bool) or isinstance(value, str) and value.strip().isdigit():
        n = int(value)
        if not 1 <= n <= 1000:
            raise w.error("detents", f"as a count must be 1..1000 (got {value!r})")
        return L / (n + 1), n
    if isinstance(value, float):
        raise w.error("detents", f"must be a whole count (e.g. 5) or a spacing with its unit (e.g. \"10 mm\"), "
                                 f"or \"off\" (got {value!r})")
    spacing = length(value, fp, w.ctx, w.where, positive=True)
    n = max(0, math.ceil(L / spacing - 1e-9) - 1)
    if n == 0:
        raise w.error("detents", f"spacing {spacing * 1e3:g} mm leaves no detent on the {L * 1e3:g} mm track "
                                 f"(detents sit at whole spacings from its start, never at its ends); use a "
                                 f"shorter spacing or a count such as detents = 5 (got {value!r})")
    last = L - n * spacing
    if abs(last - spacing) > 1e-6 * spacing:
        w.warn(f"`detents` every {spacing * 1e3:g} mm do not divide the {L * 1e3:g} mm track: {n} detents, the last "
               f"gap is {last * 1e3:.4g} mm; detents = {n} spaces them evenly ({L / (n + 1) * 1e3:.4g} mm apart)")
    return spacing, n


class Toggle(WidgetType):
    """Two-state switch: a shallow well with a knob bump at one end (off) or the other (on).

    Both states are compiled; the table places the initial ``state`` and
    stores the other as an alternative patch (see :func:`select_state`).
    """

    name = "toggle"
    strength_keys = STRENGTH_KEYS
    states = ("off", "on")
    own_keys = {"height": "len", "force": "force", "force_step": "force", "level": "num",
                "state": "choice", "track_depth": "len", "ramp": "len", "knob_size": "len",
                "orientation": "choice", "edge": "choice"}

    def finish(self, raw, W, H, w):
        fp, ctx, where = w.fp, w.ctx, w.where
        vertical, L, C = _orientation(raw, W, H, w)
        state = choice(raw.get("state", "off"), self.states, fp + "state", ctx, where)
        edge = choice(raw.get("edge", "cosine"), ("linear", "cosine"), fp + "edge", ctx, where)
        half = L / 2 if w.canvas.is_1d else min(L, C) / 2
        ramp = length(raw.get("ramp", f"{min(half, 2e-3) * 1e3!r} mm"), fp + "ramp", ctx, where, positive=True)
        ramp = _limit_ramp(ramp, edge, half, w)
        td = length(raw.get("track_depth", "0.3 mm"), fp + "track_depth", ctx, where, nonneg=True)
        default_knob = 0.8 * (min(C, L / 2) if not w.canvas.is_1d else L / 2)
        ks = length(raw.get("knob_size", f"{default_knob * 1e3!r} mm"), fp + "knob_size", ctx, where, positive=True)
        if ks > L / 2 + 1e-12:
            raise w.error("knob_size", f"must not exceed half the toggle length, {L / 2 * 1e3:g} mm "
                                       f"(got {raw.get('knob_size')!r})")
        kh = resolve_strength(raw, self.strength_keys, 1, "1.5 mm", fp, w)
        return {"vertical": vertical, "state": state, "edge": edge, "ramp": ramp, "track_depth": td,
                "knob_size": ks, "height": kh}

    def heights(self, p, u, v, W, H, is_1d, state=None):
        if p["vertical"]:
            u, v, W, H = v, u, H, W
        state = state or p["state"]
        d = inside_distance(u, v, W, H, min(W, H) / 2 if not is_1d else 0.0, is_1d)
        h = np.where(d > 0, -p["track_depth"] * edge_profile(d / p["ramp"], p["edge"]), 0.0)
        uc = W / 4 if state == "off" else 3 * W / 4
        r = np.abs(u - uc) + 0 * v if is_1d else np.hypot(u - uc, v - H / 2)
        out = h + p["height"] * raised_cosine(r, p["knob_size"] / 2)
        return out  # (rows, cols) whichever way the widget runs


class Ridge(WidgetType):
    """A raised line from ``from`` to ``to`` (``width`` across, ``profile`` cosine|linear).

    On a 1-D canvas a ridge crosses the strip at ``at``.
    """

    name = "ridge"
    sign = 1
    boxed = False
    strength_keys = STRENGTH_KEYS
    default_strength = "0.5 mm"
    own_keys = {"from": "point", "to": "point", "at": "len", "width": "len", "profile": "choice",
                "height": "len", "force": "force", "force_step": "force", "level": "num"}

    def extent(self, raw, w):
        wd = length(raw.get("width", "2 mm"), w.fp + "width", w.ctx, w.where, positive=True)
        if w.canvas.is_1d:
            if "at" not in raw:
                raise w.error("at", f"is required for a {self.name} on a 1-D canvas (e.g. at = \"40 mm\")")
            if "from" in raw or "to" in raw:
                raise w.error("from", "is for 2-D canvases; on a 1-D canvas give `at`")
            x = length(raw["at"], w.fp + "at", w.ctx, w.where)
            return x - wd / 2, 0.0, wd, 0.0
        if "at" in raw:
            raise w.error("at", "is for 1-D canvases; on a 2-D canvas give `from` and `to`")
        for k in ("from", "to"):
            if k not in raw:
                raise w.error(k, f"is required for a {self.name} (e.g. from = \"10,20 mm\", to = \"60,20 mm\")")
        (ax, ay), (bx, by) = self._point(raw["from"], "from", w), self._point(raw["to"], "to", w)
        x0, y0 = min(ax, bx) - wd / 2, min(ay, by) - wd / 2
        return x0, y0, abs(bx - ax) + wd, abs(by - ay) + wd

    def finish(self, raw, W, H, w):
        wd = length(raw.get("width", "2 mm"), w.fp + "width", w.ctx, w.where, positive=True)
        prof = choice(raw.get("profile", "cosine"), ("cosine", "linear"), w.fp + "profile", w.ctx, w.where)
        h = resolve_strength(raw, self.strength_keys, self.sign, self.default_strength, w.fp, w)
        if w.canvas.is_1d:
            a = b = (wd / 2, 0.0)
        else:
            (ax, ay), (bx, by) = self._point(raw["from"], "from", w), self._point(raw["to"], "to", w)
            ox, oy = min(ax, bx) - wd / 2, min(ay, by) - wd / 2
            a, b = (ax - ox, ay - oy), (bx - ox, by - oy)
        return {"width": wd, "profile": prof, "height": h, "a": a, "b": b}

    def describe(self, p):
        d = super().describe(p)
        d.update({"from_local_m": list(p["a"]), "to_local_m": list(p["b"])})
        return d

    def heights(self, p, u, v, W, H, is_1d, state=None):
        (ax, ay), (bx, by) = p["a"], p["b"]
        if is_1d:
            dist = np.abs(u - ax) + 0 * v
        else:
            ex, ey = bx - ax, by - ay
            ll = ex * ex + ey * ey
            t = np.clip(((u - ax) * ex + (v - ay) * ey) / ll, 0.0, 1.0) if ll > 0 else 0.0 * u
            dist = np.hypot(u - (ax + t * ex), v - (ay + t * ey))
        half = p["width"] / 2
        prof = edge_profile(1.0 - dist / half, p["profile"])
        return np.where(dist < half, p["height"] * prof, 0.0)


class Edge(Ridge):
    """Alias of ridge: a raised line marking an edge."""

    name = "edge"


class Groove(Ridge):
    """A sunk line: ``depth`` below flat ground."""

    name = "groove"
    sign = -1
    strength_keys = DEPTH_KEYS
    own_keys = _sunk(Ridge.own_keys)


def _resample(values: np.ndarray, u, v, W: float, H: float, is_1d: bool, centred: bool = False):
    """Bilinear look-up of ``values`` (rows, cols) spread over [0,W]x[0,H] at (u, v).

    ``centred``: samples are pixel centres (pixel c covers [c, c+1] * W/cols,
    as images and meshes are loaded); otherwise the first and last samples sit
    on the box edges (inline data).
    """
    a = np.asarray(values, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    rows, cols = a.shape

    def frac(t, extent, n):
        if n < 2 or extent <= 0:
            return 0.0 * t
        f = t / extent * n - 0.5 if centred else t / extent * (n - 1)
        return np.clip(f, 0, n - 1)

    fc = frac(u, W, cols)
    if is_1d or rows == 1:
        fr = 0.0 * v + (rows - 1) / 2.0
    else:
        fr = frac(v, H, rows)
    fc, fr = np.broadcast_arrays(fc, fr)
    c0 = np.minimum(np.floor(fc).astype(np.int64), max(cols - 2, 0))
    r0 = np.minimum(np.floor(fr).astype(np.int64), max(rows - 2, 0))
    c1, r1 = np.minimum(c0 + 1, cols - 1), np.minimum(r0 + 1, rows - 1)
    tx, ty = fc - c0, fr - r0
    return ((a[r0, c0] * (1 - tx) + a[r0, c1] * tx) * (1 - ty)
            + (a[r1, c0] * (1 - tx) + a[r1, c1] * tx) * ty)


def _file(raw, key, w: PlaceCtx, what: str) -> Path:
    if key not in raw:
        raise w.error(key, f"is required for a{'n' if what[0] in 'aeiou' else ''} {what} (e.g. {key} = \"terrain.png\")")
    p = w.ctx.file(w.where, w.fp + key, raw[key])
    if not p.is_file():
        raise w.error(key, f"names a missing {what} file (got {str(raw[key])!r}, looked for '{p}')")
    return p


class Image(WidgetType):
    """A height map (any picture, an SVG icon, or .npy) stretched over the widget box, seen from above.

    ``channel`` picks the channel of a colour picture (luminance, r, g, b, a,
    or normal to integrate a normal map; see :mod:`shapedisplay.author.imageio`).
    ``height = "0:2 mm"``: gray 0 to full scale maps to this range (float data:
    their range is fitted onto it); or
    ``force = "0.5:2.5 N"``, the normal-force range (low end = mapping n_base
    unless the height range is meant to start below flat ground).
    """

    name = "image"
    own_keys = {"file": "file", "height": "lenrange", "force": "forcerange", "channel": "choice"}

    def finish(self, raw, W, H, w):
        path = _file(raw, "file", w, "image")
        if "height" in raw and "force" in raw:
            raise w.error("force", "conflicts with `height`: give only one")
        if "force" in raw:
            lo, hi = _force_range(raw["force"], w.fp + "force", w)
            g = w.mapping.n_gain
            if g <= 0:
                raise w.error("force", f"needs mapping.n_gain > 0 (got {g} N/m)")
            lo, hi = w.mapping.height_of_force(lo), w.mapping.height_of_force(hi)
        else:
            from shapedisplay.units import parse_pair
            lo, hi = wrap_unit_errors(w.ctx, w.where, parse_pair, raw.get("height", "0:2mm"), ":", "m", w.fp + "height")
            if not (abs(lo) <= MAX_LENGTH_M and abs(hi) <= MAX_LENGTH_M):
                raise w.error("height", f"must be lengths within {MAX_LENGTH_M:g} m of 0 (got {raw.get('height')!r})")
        if hi < lo:
            raise w.error("height", f"range must run low:high (got {raw.get('height', raw.get('force'))!r})")
        from shapedisplay.author.sources import load_image
        try:
            channel = None
            if "channel" in raw:
                from shapedisplay.author.imageio import CHANNELS
                channel = choice(raw["channel"], CHANNELS, w.fp + "channel", w.ctx, w.where)
            box, s = (W, H if H > 0 else W), w.canvas.spacing       # an SVG is drawn with a pixel a canvas sample
            hf = load_image(path, box, (lo, hi), channel=channel, pixels=tuple(int(round(v / s)) + 1 for v in box))
        except SceneError:
            raise
        except Exception as exc:  # ShapeDisplayError subclasses from the loader
            from shapedisplay.errors import ShapeDisplayError
            if isinstance(exc, ShapeDisplayError):
                raise SceneError(f"scene '{w.ctx.path}': {w.where}: `{w.fp}file`: {exc}") from None
            raise
        return {"file": str(path), "height_range": (lo, hi), "values": np.asarray(hf.heights)}

    def describe(self, p):
        return {"file": p["file"], "height_range_m": list(p["height_range"]),
                "source_shape": list(p["values"].shape)}

    def heights(self, p, u, v, W, H, is_1d, state=None):
        return _resample(p["values"], u, v, W, H, is_1d, centred=True)


#: Mesh formats that may name other files (OBJ: mtllib and textures; glTF: buffers and images).
MESH_SUFFIXES_WITH_REFERENCES = (".obj", ".gltf", ".glb")


def check_mesh_confined(path: Path, where: str) -> None:
    """Refuse a mesh that may name other files when trimesh would read them outside the mesh's folder.

    trimesh 5 keeps the files a mesh names (an OBJ's ``mtllib`` and textures,
    glTF buffers and images) inside the mesh's own folder; trimesh 4 reads
    ``../`` names anywhere. A confined read (the studio) needs the former.
    """
    if Path(path).suffix.lower() not in MESH_SUFFIXES_WITH_REFERENCES:
        return
    try:
        import trimesh
    except ImportError:
        return                              # the mesh reader reports the missing extra
    major = int(str(trimesh.__version__).split(".")[0])
    if major < 5:
        raise SceneError(f"{where}: a {Path(path).suffix} mesh may name other files, and trimesh "
                         f"{trimesh.__version__} would read them outside the folder; the studio needs "
                         f"trimesh>=5 for it: pip install -U 'trimesh>=5'")


class Mesh(WidgetType):
    """A 3D model (STL/OBJ/PLY/...) whose top surface is placed in the box.

    ``units`` of the model file ("mm" default), ``up`` axis, ``height_scale``
    multiplies the heights. The footprint is stretched to ``size``: the mesh
    is rasterised on the widget's own sample grid (one sample per canvas
    sample of the box, the first and last on the footprint's edges), so each
    canvas sample reads the model's surface at exactly its place in the box.
    On a 1-D canvas the centre line of the footprint is used.
    """

    name = "mesh"
    own_keys = {"file": "file", "units": "str", "up": "str", "height_scale": "num"}

    def finish(self, raw, W, H, w):
        path = _file(raw, "file", w, "mesh")
        if w.ctx.confine:
            check_mesh_confined(path, f"scene '{w.ctx.path}': {w.where}: `{w.fp}file`")
        scale = number(raw.get("height_scale", 1.0), w.fp + "height_scale", w.ctx, w.where, lo=0.0)
        from shapedisplay.author.mesh import mesh_to_heightfield
        from shapedisplay.errors import ShapeDisplayError
        s = w.canvas.spacing
        cols = int(round(W / s)) + 1
        rows = 3 if w.canvas.is_1d else int(round(H / s)) + 1   # 1-D: the middle row is the centre line
        try:
            hf = mesh_to_heightfield(path, grid=(rows, cols), up=str(raw.get("up", "z")),
                                     units=str(raw.get("units", "mm")), background=0.0)
        except ShapeDisplayError as exc:
            raise SceneError(f"scene '{w.ctx.path}': {w.where}: `{w.fp}file`: {exc}") from None
        return {"file": str(path), "values": np.asarray(hf.heights) * scale, "height_scale": scale}

    def describe(self, p):
        return {"file": p["file"], "height_scale": p["height_scale"], "source_shape": list(p["values"].shape)}

    def heights(self, p, u, v, W, H, is_1d, state=None):
        return _resample(p["values"], u, v, W, H, is_1d, centred=False)   # edge-aligned grid


DATA_CHANNELS = ("friction_scale", "burst_gain")
#: Default stimulus range of each data channel (multiplier on mu / on burst gain B).
DATA_RANGES = {"friction_scale": (0.8, 1.5), "burst_gain": (0.5, 2.0)}
#: Haptic dimension of each data channel: its power-law exponent is forces.EXPONENTS[dimension].
DATA_DIMENSIONS = {"friction_scale": "friction", "burst_gain": "vibration"}


class Data(WidgetType):
    """A free data layer: a scalar field driving its own haptic dimension.

    ``channel`` friction_scale|burst_gain; the field from ``values`` (inline
    list or 2-D list, rows along y) or ``file`` (.npy, .csv or gray PNG),
    stretched over the box with its first and last samples on the box edges
    (bilinear in between); ``data_range``
    "lo:hi" (default: the field's min:max); ``range`` "lo:hi" of the stimulus
    (multiplier); ``scaling`` perceptual (power law with ``exponent``, default
    per dimension: friction 1.26, vibration 0.6) or linear; ``threshold``
    (stimulus below which the power law fails, threshold-corrected form).
    """

    name = "data"
    data_layer = True
    own_keys = {"channel": "choice", "values": "array", "file": "file", "data_range": "range",
                "range": "range", "scaling": "choice", "exponent": "num", "threshold": "num"}

    def finish(self, raw, W, H, w):
        fp, ctx, where = w.fp, w.ctx, w.where
        if "channel" not in raw:
            raise w.error("channel", f"is required for a data layer; one of {', '.join(DATA_CHANNELS)}")
        ch = choice(raw["channel"], DATA_CHANNELS, fp + "channel", ctx, where)
        if ("values" in raw) == ("file" in raw):
            raise w.error("values", "give exactly one of `values` (inline numbers) or `file`")
        if "values" in raw:
            try:
                arr = np.asarray(raw["values"], dtype=np.float64)
            except (TypeError, ValueError):
                raise w.error("values", "must be a list of numbers or a list of equal-length rows") from None
        else:
            arr = _load_data_file(_file(raw, "file", w, "data"), w)
        if arr.ndim not in (1, 2) or arr.size < 2:
            raise w.error("values" if "values" in raw else "file",
                          f"must hold a 1-D or 2-D field of at least 2 numbers (got shape {arr.shape})")
        if not np.isfinite(arr).all():
            raise w.error("values" if "values" in raw else "file", "must be finite (found NaN or inf)")
        dlo, dhi = (float(arr.min()), float(arr.max()))
        if "data_range" in raw:
            dlo, dhi = _num_range(raw["data_range"], fp + "data_range", w)
        lo, hi = DATA_RANGES[ch]
        if "range" in raw:
            lo, hi = _num_range(raw["range"], fp + "range", w)
        if lo < 0 or hi < 0:
            raise w.error("range", f"must be multipliers >= 0 (got {raw.get('range')!r})")
        scaling = choice(raw.get("scaling", "perceptual"), ("perceptual", "linear"), fp + "scaling", ctx, where)
        beta = number(raw.get("exponent", EXPONENTS[DATA_DIMENSIONS[ch]]), fp + "exponent", ctx, where, lo=1e-3)
        th = number(raw.get("threshold", 0.0), fp + "threshold", ctx, where, lo=0.0)
        if scaling == "perceptual" and th > min(lo, hi):
            raise w.error("threshold", f"must be <= the low end of `range` ({min(lo, hi):g}) (got {th:g})")
        t = (arr - dlo) / (dhi - dlo) if dhi > dlo else np.zeros_like(arr)
        if scaling == "perceptual":
            t = np.clip(t, 0.0, 1.0)
            vals = equal_steps(t, lo, hi, beta, th) if hi >= lo else equal_steps(1 - t, hi, lo, beta, th)
        else:
            vals = lo + np.clip(t, 0, 1) * (hi - lo)
        return {"channel": ch, "values": vals, "range": (lo, hi), "data_range": (dlo, dhi),
                "scaling": scaling, "exponent": beta, "threshold": th}

    def describe(self, p):
        return {"channel": p["channel"], "range": list(p["range"]), "data_range": list(p["data_range"]),
                "scaling": p["scaling"], "exponent": p["exponent"], "source_shape": list(p["values"].shape)}

    def heights(self, p, u, v, W, H, is_1d, state=None):
        return np.zeros(np.broadcast(u, v).shape)

    def data(self, p, u, v, W, H, is_1d):
        return p["channel"], _resample(p["values"], u, v, W, H, is_1d)


def _num_range(value, path, w):
    if isinstance(value, list) and len(value) == 2:
        return (number(value[0], path, w.ctx, w.where), number(value[1], path, w.ctx, w.where))
    if not isinstance(value, str) or value.count(":") != 1:
        raise w.ctx.error(w.where, path, f"must look like 'low:high' (got {value!r})")
    a, b = value.split(":")
    return number(a.strip(), path, w.ctx, w.where), number(b.strip(), path, w.ctx, w.where)


def _load_data_file(path: Path, w: PlaceCtx) -> np.ndarray:
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            return np.asarray(np.load(path, allow_pickle=False), dtype=np.float64)
        if suffix in (".csv", ".txt"):
            return np.loadtxt(path, delimiter="," if suffix == ".csv" else None, ndmin=1)
    except (OSError, ValueError) as exc:
        raise w.error("file", f"is unreadable ({exc})") from None
    if suffix == ".png":
        from shapedisplay.author.sources import load_image
        hf = load_image(path, (1.0, 1.0), (0.0, 1.0))
        return np.asarray(hf.heights)
    raise w.error("file", f"must be .npy, .csv, .txt or .png (got '{path.name}')")


WIDGET_TYPES: dict[str, WidgetType] = {t.name: t for t in (
    Button(), Dent(), Well(), Slider(), Toggle(), Ridge(), Edge(), Groove(), Image(), Mesh(), Data())}


def place_widget(wt: WidgetType, raw: dict, index: int, wid: str, canvas: Canvas, mapping,
                 levels: dict, device, ctx: Ctx) -> Widget:
    """Validate one widget, snap its box to the grid, clip it to the canvas."""
    where = f"widget[{index}] '{wid}'"
    w = PlaceCtx(ctx, where, index, wt.name, canvas, mapping, levels, device)
    overlap = choice(raw.get("overlap", "max"), OVERLAP_RULES, w.fp + "overlap", ctx, where)
    x, y, sw, sh = wt.extent(raw, w)
    s = canvas.spacing
    col0 = int(round(x / s))
    ncols = max(int(round(sw / s)) + 1, 2)
    if canvas.is_1d:
        row0, nrows = 0, 1
    else:
        row0 = int(round(y / s))
        nrows = max(int(round(sh / s)) + 1, 2)
    if ncols * nrows > MAX_WIDGET_SAMPLES:
        raise ctx.error(where, f"widget[{index}].{'size' if wt.boxed else 'from'}",
                        f"gives a box of {ncols} x {nrows} = {ncols * nrows} samples on the "
                        f"{s * 1e3:g} mm grid, more than the limit of {MAX_WIDGET_SAMPLES} (got {sw * 1e3:g} x "
                        f"{sh * 1e3:g} mm)")
    W, H = (ncols - 1) * s, (0.0 if canvas.is_1d else (nrows - 1) * s)
    moved = max(abs(col0 * s - x), abs(row0 * s - y), abs(W - sw), abs(H - sh))
    if moved > 1e-3 * s:
        w.warn(f"box snapped to the {s * 1e3:g} mm grid (moved by up to {moved * 1e3:.3g} mm)")
    c_end, r_end = col0 + ncols - 1, row0 + nrows - 1
    if c_end < 0 or col0 > canvas.cols - 1 or r_end < 0 or row0 > canvas.rows - 1:
        raise ctx.error(where, f"widget[{index}].{'position' if wt.boxed else 'from'}",
                        f"puts the widget entirely outside the {canvas.width * 1e3:g} x {canvas.height * 1e3:g} mm "
                        f"canvas (box x {col0 * s * 1e3:g}..{c_end * s * 1e3:g} mm, "
                        f"y {row0 * s * 1e3:g}..{r_end * s * 1e3:g} mm)")
    cut = {"left": max(0, -col0) * s, "right": max(0, c_end - (canvas.cols - 1)) * s,
           "bottom": max(0, -row0) * s, "top": max(0, r_end - (canvas.rows - 1)) * s}
    clipped = any(v > 0 for v in cut.values())
    if clipped:
        parts = ", ".join(f"{k} by {v * 1e3:g} mm" for k, v in cut.items() if v > 0)
        w.warn(f"reaches outside the canvas ({parts}); clipped to the canvas")
    params = wt.finish(raw, W, H, w)
    box = (max(row0, 0), max(col0, 0), min(r_end, canvas.rows - 1), min(c_end, canvas.cols - 1))
    return Widget(wid, wt.name, index, params, col0, row0, ncols, nrows, s, overlap, clipped,
                  str(raw.get("label", "")), box, "overlap" in raw)
