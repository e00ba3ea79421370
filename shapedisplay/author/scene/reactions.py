"""Scene keys of reactive widgets and moving surfaces: parsing, and what the compiler stores for the engine.

Keys any widget may carry (docs/reactive.md)::

    press = "2 N"                          # threshold of the press force (N along z); released below half of
    press = "2 N release 1.2 N"            #   it, or below the level given; "off": does not react
    click = "burst 0.5 10ms, drop 50% 20ms"  # the click: a drive burst (amplitude, length) and/or a friction
                                           #   drop (fraction of N, recovery time); "off": none
    movable = true                         # a press on it grabs it; it follows the finger until released
    motion = "10 mm/s +y"                  # its content scrolls through its box (DIR one of +x -x +y -y)
    motion = ["0 s: 0,0 mm", "0.5 s: 12,0 mm", "2 s: 12,0 mm", "loop 3 s"]   # keyframes: it moves as a whole

Buttons and toggles react to a firm press without any key (:data:`DEFAULT_PRESS`, with the default click
of their type); a slider's thumb follows the finger when the slider has a ``press`` key (its thumb is then
stored as a part of its own); other widgets react when they have ``press``, ``movable`` or ``motion``.
A widget that moves (``movable``, ``motion``) is not drawn into the table's blocks: it is stored as a
patch of its own that the engine adds where the widget has moved (a slider's thumb likewise).
"""
from __future__ import annotations

import math
import re

from shapedisplay.author.scene.fields import Ctx, SceneError, length, pair, quantity

REACTION_KEYS = ("press", "click", "movable", "motion")
#: Widget types that react to a firm press without any key.
PRESS_BY_DEFAULT = ("button", "toggle")
#: The press threshold of a widget without a ``press`` key (a firm press: people explore a surface with about
#: 1.3 N, Provancher and Sylvester 2009); released below half of it.
DEFAULT_PRESS = "2 N"
#: The click of each kind of reactive widget without a ``click`` key.
DEFAULT_CLICK = {"button": "burst 0.5 10ms, drop 50% 20ms", "toggle": "burst 0.5 10ms, drop 50% 20ms",
                 "slider": "burst 0.3 5ms, drop 30% 10ms", "object": "off", "surface": "off"}
#: Widget types that cannot move (they react on their own terms: a toggle flips, a slider's thumb slides).
FIXED_TYPES = ("toggle", "slider")
#: Keyframes a scene may hold in all (the engine's SD_MAX_KEYS).
MAX_KEYS = 64
#: Change of a slider's value that makes a `value` event while its thumb is dragged.
VALUE_STEP = 0.05

_PRESS = re.compile(r"^\s*(\S+(?:\s*N)?)\s*(?:release\s+(\S+(?:\s*N)?))?\s*$", re.I)
_BURST = re.compile(r"^burst\s+([0-9.eE+-]+)(?:\s+(\S+))?$", re.I)
_DROP = re.compile(r"^drop\s+([0-9.eE+-]+)\s*%(?:\s+(\S+))?$", re.I)
_VELOCITY = re.compile(r"^\s*(.+?)\s+([+-])([xy])\s*$")
_KEY = re.compile(r"^\s*([^:]+):\s*(.+?)\s*$")
_LOOP = re.compile(r"^\s*loop(?:\s+(.+?))?\s*$", re.I)


def reaction_keys(raw: dict, wt, i: int, where: str, ctx: Ctx, is_1d: bool) -> tuple[dict, dict | None]:
    """``raw`` without the reaction keys, and their values parsed (None when the widget has none)."""
    if not any(k in raw for k in REACTION_KEYS):
        return raw, None
    fp = f"widget[{i}]."
    got: dict = {}
    if "press" in raw:
        got["press"] = parse_press(raw["press"], fp + "press", ctx, where)
    if "click" in raw:
        got["click"] = parse_click(raw["click"], fp + "click", ctx, where)
    if "movable" in raw:
        if not isinstance(raw["movable"], bool):
            raise ctx.error(where, fp + "movable", f"must be true or false (got {raw['movable']!r})")
        got["movable"] = raw["movable"]
    if "motion" in raw:
        got["motion"] = parse_motion(raw["motion"], fp + "motion", ctx, where, is_1d)
    moves = got.get("movable") or "motion" in got
    if moves and wt.name in FIXED_TYPES:
        key = "movable" if got.get("movable") else "motion"
        raise ctx.error(where, fp + key, f"cannot make a {wt.name} move (a toggle flips, a slider's thumb follows the "
                                         f"finger); move a button, dent, image, mesh, ridge or data layer")
    if got.get("movable") and "motion" in got:
        raise ctx.error(where, fp + "motion", "cannot be given with `movable = true`: a widget either moves by "
                                              "itself or is dragged")
    return {k: v for k, v in raw.items() if k not in REACTION_KEYS}, got


def parse_press(value, fp: str, ctx: Ctx, where: str):
    """``"2 N"`` / ``"2 N release 1.2 N"`` / ``"off"`` -> ``(threshold N, release N)`` or None."""
    if value in ("off", False):
        return None
    m = _PRESS.match(value) if isinstance(value, str) else None
    if m is None:
        raise ctx.error(where, fp, f"must be a force such as \"2 N\", \"2 N release 1.2 N\" or \"off\" (got {value!r})")
    thr = quantity(m.group(1), "N", fp, ctx, where)
    rel = quantity(m.group(2), "N", fp, ctx, where) if m.group(2) else thr / 2
    if not 0 < thr <= 100:
        raise ctx.error(where, fp, f"must be a threshold within 0..100 N, above 0 (got {value!r})")
    if not 0 <= rel < thr:
        raise ctx.error(where, fp, f"release level must be below the threshold and >= 0 (got {value!r})")
    return thr, rel


def parse_click(value, fp: str, ctx: Ctx, where: str) -> dict:
    """``"burst 0.5 10ms, drop 50% 20ms"`` (either part alone, or ``"off"``) -> the click's numbers."""
    out = {"gain": 0.0, "time_s": 0.0, "drop": 0.0, "drop_s": 0.0}
    if value in ("off", False):
        return out
    if not isinstance(value, str):
        raise ctx.error(where, fp, f"must be text such as \"burst 0.5 10ms, drop 50% 20ms\" or \"off\" (got {value!r})")
    for part in (p.strip() for p in value.split(",")):
        mb, md = _BURST.match(part), _DROP.match(part)
        if mb:
            a = float(mb.group(1))
            t = quantity(mb.group(2), "s", fp, ctx, where) if mb.group(2) else 0.010
            if not (0 < a <= 1 and 0 < t <= 1):
                raise ctx.error(where, fp, f"burst amplitude must be within 0..1 (full scale) and its length "
                                           f"0..1 s (got {part!r})")
            out["gain"], out["time_s"] = a, t
        elif md:
            d = float(md.group(1)) / 100
            t = quantity(md.group(2), "s", fp, ctx, where) if md.group(2) else 0.020
            if not (0 < d <= 1 and 0 < t <= 1):
                raise ctx.error(where, fp, f"drop must be within 0..100 % and its recovery 0..1 s (got {part!r})")
            out["drop"], out["drop_s"] = d, t
        else:
            raise ctx.error(where, fp, f"cannot read {part!r}: write \"burst A [T]\" (A 0..1 full scale), "
                                       f"\"drop P% [T]\", both joined by ',', or \"off\" (got {value!r})")
    return out


def parse_motion(value, fp: str, ctx: Ctx, where: str, is_1d: bool) -> dict:
    """``"10 mm/s +x"`` -> ``{"velocity_m_s": [vx, vy]}``; a list of keyframes -> ``{"keys": [[t, dx, dy], ...],
    "loop_s": period or 0}``."""
    if isinstance(value, str):
        m = _VELOCITY.match(value)
        if m is None:
            raise ctx.error(where, fp, f"must be \"V DIR\" such as \"10 mm/s +y\" (DIR one of +x -x +y -y) or a list "
                                       f"of keyframes [\"0 s: 0,0 mm\", ...] (got {value!r})")
        v = quantity(m.group(1), "m/s", fp, ctx, where)
        if not 0 < v <= 1:
            raise ctx.error(where, fp, f"speed must be within 0..1 m/s, above 0 (got {value!r})")
        if is_1d and m.group(3) == "y":
            raise ctx.error(where, fp, f"can only be +x or -x on a 1-D canvas (got {value!r})")
        sign = 1.0 if m.group(2) == "+" else -1.0
        return {"velocity_m_s": [sign * v, 0.0] if m.group(3) == "x" else [0.0, sign * v]}
    if not isinstance(value, list) or not value or not all(isinstance(k, str) for k in value):
        raise ctx.error(where, fp, f"must be \"V DIR\" or a list of keyframes such as [\"0 s: 0,0 mm\", "
                                   f"\"1 s: 10,0 mm\"] (got {value!r})")
    keys, loop = [], 0.0
    for n, text in enumerate(value):
        lm = _LOOP.match(text)
        if lm:
            if n != len(value) - 1:
                raise ctx.error(where, fp, f"\"loop\" must be the last entry (got {value!r})")
            loop = quantity(lm.group(1), "s", fp, ctx, where) if lm.group(1) else None
            continue
        km = _KEY.match(text)
        if km is None:
            raise ctx.error(where, fp, f"keyframe {text!r} must read \"T: X,Y mm\" (time, then the displacement "
                                       f"from where the widget is placed)")
        t = quantity(km.group(1), "s", fp, ctx, where)
        if is_1d:
            dx, dy = length(km.group(2), fp, ctx, where), 0.0
        else:
            dx, dy = pair(km.group(2), ",", fp, ctx, where)
        if not 0 <= t <= 1e6 or (keys and t < keys[-1][0]):
            raise ctx.error(where, fp, f"keyframe times must be >= 0 and not decrease (got {text!r})")
        keys.append([t, dx, dy])
    if not keys:
        raise ctx.error(where, fp, f"needs at least one keyframe \"T: X,Y mm\" (got {value!r})")
    if loop is None:
        loop = keys[-1][0]
    if loop and loop < keys[-1][0]:
        raise ctx.error(where, fp, f"loop period must not end before the last keyframe ({keys[-1][0]:g} s) "
                                   f"(got {value!r})")
    if len(keys) > MAX_KEYS:
        raise ctx.error(where, fp, f"holds {len(keys)} keyframes, more than the engine's {MAX_KEYS}")
    return {"keys": keys, "loop_s": float(loop)}


def finish_reactions(widgets, asked: dict, ctx: Ctx, device) -> dict:
    """Every reactive widget's reaction: ``{id: {"kind", "press_n", "release_n", "click", "motion"}}``.

    ``asked`` holds the parsed keys per widget id (:func:`reaction_keys`). Marks the placed widgets that
    move (``params["part"]``) and the sliders whose thumb moves (``params["thumb_part"]``).
    """
    out: dict = {}
    n_keys = 0
    carrier = float(getattr(getattr(device, "burst", None), "carrier_hz", 300.0) or 300.0)
    for w in widgets:
        got = asked.get(w.id) or {}
        if got.get("movable"):
            kind = "object"
        elif "motion" in got:
            kind = "surface"
        elif w.type in PRESS_BY_DEFAULT:
            kind = w.type
        elif w.type == "slider" and "press" in got:
            kind = "slider"
        elif "press" in got:
            kind = "button"
        else:
            continue
        fp = f"widget[{w.index}].press"
        if "press" in got:
            press = got["press"]                         # None: "off"
        elif kind in PRESS_BY_DEFAULT or kind == "object":
            press = parse_press(DEFAULT_PRESS, fp, ctx, w.where)
        else:
            press = None
        if press is None and kind in ("button", "toggle", "slider"):
            continue                                     # press = "off": the widget does not react
        if press is None and kind == "object":
            raise ctx.error(w.where, fp, "cannot be \"off\" on a movable widget: a press grabs it")
        click = got.get("click") or parse_click(DEFAULT_CLICK[kind], f"widget[{w.index}].click", ctx, w.where)
        entry = {"kind": kind, "press_n": press[0] if press else 0.0, "release_n": press[1] if press else 0.0,
                 "click": dict(click, hz=carrier)}
        if "motion" in got:
            entry["motion"] = got["motion"]
            n_keys += len(got["motion"].get("keys", ()))
        if kind in ("object", "surface"):
            w.params["part"] = True
        if kind == "slider":
            w.params["thumb_part"] = True
        out[w.id] = entry
    if n_keys > MAX_KEYS:
        raise SceneError(f"scene '{ctx.path}': the moving widgets hold {n_keys} keyframes together, more than the "
                         f"engine's {MAX_KEYS}")
    return out


# --------------------------------------------------------------- what the compiler stores
def part_rect(w, reach: int, rows: int, cols: int) -> tuple[int, int, int, int]:
    """Canvas rectangle (r0, c0, r1, c1) of a widget's moving part: the widget's box, or a slider's thumb square,
    grown by the gradient's reach (clipped to the canvas)."""
    r0, c0, r1, c1 = w.box
    if w.params.get("thumb_part"):
        p, s = w.params, w.spacing
        W, H = w.size
        L = H if p["vertical"] else W
        R = p["thumb_size"] / 2
        along = R + p["value"] * (L - 2 * R)
        k = int(math.ceil(R / s)) + 1
        if p["vertical"]:
            ca, cc = w.row0 + along / s, w.col0 + W / 2 / s
            r0, r1 = max(r0, int(math.floor(ca)) - k), min(r1, int(math.ceil(ca)) + k)
            c0, c1 = max(c0, int(math.floor(cc)) - k), min(c1, int(math.ceil(cc)) + k)
        else:
            ca = w.col0 + along / s
            c0, c1 = max(c0, int(math.floor(ca)) - k), min(c1, int(math.ceil(ca)) + k)
            if rows > 1:
                cc = w.row0 + H / 2 / s
                r0, r1 = max(r0, int(math.floor(cc)) - k), min(r1, int(math.ceil(cc)) + k)
    return (max(r0 - reach, 0), max(c0 - reach, 0), min(r1 + reach, rows - 1), min(c1 + reach, cols - 1))


def slider_meta(w) -> dict:
    """A slider's track, thumb and detents in canvas metres (the engine's slider record)."""
    p, s = w.params, w.spacing
    W, H = w.size
    vertical = bool(p["vertical"])
    L = H if vertical else W
    R = p["thumb_size"] / 2
    origin = (w.row0 if vertical else w.col0) * s
    cross = (w.col0 * s + W / 2) if vertical else (w.row0 * s + H / 2)
    return {"axis": 1 if vertical else 0, "track0_m": origin + R, "track_len_m": max(L - 2 * R, 1e-9),
            "thumb_m": origin + R + p["value"] * (L - 2 * R), "thumb_r_m": R, "cross_m": cross,
            "detent0_m": origin + p["detent_spacing"], "detent_step_m": p["detent_spacing"] or 1.0,
            "detents": int(p["detents"]), "value_step": VALUE_STEP}


def reaction_entries(scene, table, parts: dict) -> list:
    """The table meta's ``scene.reactions`` (render/reactions.py reads it): one entry per reactive widget in scene
    order; ``parts`` maps a widget id to ``(row0, col0, patch)`` of its moving part."""
    out = []
    index = {w.id: k for k, w in enumerate(scene.widgets)}
    for w in scene.widgets:
        r = scene.reactions.get(w.id) if getattr(scene, "reactions", None) else None
        if not r:
            continue
        x0, y0, x1, y1 = w.bbox
        e = {"id": w.id, "widget": index[w.id], "kind": r["kind"], "box_m": [x0, y0, x1, y1],
             "press_n": r["press_n"], "release_n": r["release_n"], "click": dict(r["click"])}
        if w.id in parts:
            r0, c0, patch = parts[w.id]
            e["part"] = {"row0": int(r0), "col0": int(c0), "patch": int(patch)}
        if r["kind"] == "slider":
            e["slider"] = slider_meta(w)
        if "motion" in r:
            e["motion"] = r["motion"]
        out.append(e)
    return out
