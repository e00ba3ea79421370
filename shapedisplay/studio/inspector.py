"""What the studio's inspector shows: every key of each widget type, its unit and choices, and the values.

:func:`schema` lists per widget type the keys the scene loader accepts
(``WidgetType.keys``, the legibility keys and the reaction keys of
docs/reactive.md), each with the unit the page
writes after a bare number, the choices of a choice key and whether it is one
of the type's strength keys (height / force / force_step / level; depth for
sunk types: writing one removes the others). :func:`widget_values` gives each
widget's keys as the file writes them and what it inherits from ``[defaults]``.
"""
from __future__ import annotations

#: Unit the page appends to a bare number, by key kind (widgets.WidgetType.keys).
UNITS = {"len": "mm", "force": "N", "point": "mm", "size": "mm", "lenrange": "mm", "forcerange": "N"}
#: Choices of the choice keys, by (type, key), then by key.
CHOICES = {
    ("slider", "edge"): ("linear", "cosine"), ("toggle", "edge"): ("linear", "cosine"),
    "track": ("groove", "ridge"), "orientation": ("auto", "horizontal", "vertical"), "state": ("off", "on"),
    "profile": ("cosine", "linear"), "scaling": ("perceptual", "linear"),
}
#: Hints shown beside a key (its meaning or its form).
HINTS = {
    "level": "of [defaults] levels", "value": "0..1", "detents": "count, spacing or off",
    "position": "x,y of the lower-left corner", "center": "x,y", "size": "width x height",
    "from": "x,y", "to": "x,y", "contrast": "e.g. 3 jnd", "distinct_from": "widget ids",
    "overlap": "max | min | add | over",
    "press": "e.g. 2 N release 1.2 N, or off", "click": "e.g. burst 0.5 10ms, drop 50% 20ms, or off",
    "movable": "dragged by a pressed finger", "motion": "e.g. 20 mm/s +x, or keyframes",
}
#: Kind, unit and choices of the reaction keys (author/scene/reactions.py): a bare number of `press` is newtons.
REACTION_KINDS = {"press": ("force", "N", None), "click": ("str", "", None), "movable": ("bool", "", ("true", "false")),
                  "motion": ("str", "", None)}


def _choices(wtype: str, key: str):
    from shapedisplay.author.scene.fields import OVERLAP_RULES
    from shapedisplay.author.scene.widgets import EDGES
    if key == "overlap":
        return tuple(OVERLAP_RULES)
    if (wtype, key) in CHOICES:
        return CHOICES[(wtype, key)]
    if key == "edge":
        return tuple(EDGES)
    if key == "channel":
        if wtype == "data":
            from shapedisplay.author.scene.widgets import DATA_CHANNELS
            return tuple(DATA_CHANNELS)
        return None                                      # an image's channel: free text (imageio.CHANNELS)
    return CHOICES.get(key)


def schema() -> dict:
    """``{type: {"keys": [{key, kind, unit, choices, strength, hint}], "strength": [...], "boxed": bool}}``."""
    from shapedisplay.author.scene.reactions import FIXED_TYPES, REACTION_KEYS
    from shapedisplay.author.scene.spec import PERCEPTION_KEYS
    from shapedisplay.author.scene.widgets import WIDGET_TYPES
    out = {}
    for name, wt in WIDGET_TYPES.items():
        keys = []
        for key, kind in wt.keys.items():
            if key in ("type",):
                continue
            keys.append({"key": key, "kind": kind, "unit": UNITS.get(kind, ""), "choices": _choices(name, key),
                         "strength": key in wt.strength_keys, "hint": HINTS.get(key, "")})
        for key in PERCEPTION_KEYS:
            keys.append({"key": key, "kind": "str", "unit": "", "choices": None, "strength": False,
                         "hint": HINTS.get(key, "")})
        for key in REACTION_KEYS:                       # docs/reactive.md: how the widget reacts
            if key in ("movable", "motion") and name in FIXED_TYPES:
                continue
            kind, unit, choices = REACTION_KINDS[key]
            keys.append({"key": key, "kind": kind, "unit": unit, "choices": choices, "strength": False,
                         "hint": HINTS.get(key, "")})
        out[name] = {"keys": keys, "strength": list(wt.strength_keys), "boxed": wt.boxed}
    return out


def _plain(v):
    """A TOML value as JSON (dates and times as text)."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    if isinstance(v, (str, int, float, bool)) or v is None:
        return v
    return str(v)


_PARSED: list = [None, None]            # the last text read here and its data (the state reads it twice)


def _parsed(text: str):
    from shapedisplay.studio.edits import _toml
    if _PARSED[0] != text:
        try:
            data = _toml().loads(text)
        except Exception:
            data = None
        _PARSED[:] = [text, data]
    return _PARSED[1]


def canvas_origin(text: str) -> str:
    """The scene text's ``[canvas] origin`` (``bottom-left`` when absent or unreadable)."""
    data = _parsed(text)
    canvas = data.get("canvas") if isinstance(data, dict) else None
    v = canvas.get("origin", "bottom-left") if isinstance(canvas, dict) else "bottom-left"
    return v if v in ("bottom-left", "top-left") else "bottom-left"


def widget_values(text: str) -> list:
    """Per widget of the scene text: ``{id, type, values, inherited}`` (as written; inherited from [defaults])."""
    from shapedisplay.studio.edits import widget_ids
    data = _parsed(text)
    if not isinstance(data, dict):
        return []
    raw = data.get("widget", [])
    raw = [raw] if isinstance(raw, dict) else raw if isinstance(raw, list) else []
    defaults = data.get("defaults") if isinstance(data.get("defaults"), dict) else {}
    out = []
    for wid, w in zip(widget_ids(data), raw):
        if not isinstance(w, dict):
            continue
        t = w.get("type")
        inherited = {k: v for k, v in defaults.items() if not isinstance(v, dict)}
        if isinstance(t, str) and isinstance(defaults.get(t), dict):
            inherited.update(defaults[t])
        out.append({"id": wid, "type": t if isinstance(t, str) else None, "values": _plain(w),
                    "inherited": _plain({k: v for k, v in inherited.items() if k not in w})})
    return out
