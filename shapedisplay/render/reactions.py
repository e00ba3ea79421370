"""Reactive widgets of a scene table as the engine plays them (docs/reactive.md).

A scene table lists its reactive widgets in ``table.meta["scene"]["reactions"]``
(written by the scene compiler): per widget its kind (button, toggle, slider,
object, surface), its box, the press threshold and release level, the click
(drive and friction transient), a toggle's two state patches, the patch of a
moving part (a slider's thumb, a movable object, a scrolling or keyframed
surface), a slider's track and detents, and a surface's motion. This module
turns that list into the engine's records (:data:`~.layouts.REACT_DEF`,
:data:`~.layouts.REACT_KEY`), the reaction section of a table image and the
arrays of a firmware header, and names the events the engine reports.

Meta entry of one widget (SI units; keys absent where they do not apply)::

    {"id": "toggle", "widget": 1, "kind": "toggle", "box_m": [x0, y0, x1, y1],
     "press_n": 2.0, "release_n": 1.0,
     "click": {"gain": 0.5, "hz": 300.0, "time_s": 0.01, "drop": 0.5, "drop_s": 0.02},
     "part": {"row0": r, "col0": c, "patch": p},
     "slider": {"axis": 0, "track0_m": .., "track_len_m": .., "thumb_m": .., "thumb_r_m": .., "cross_m": ..,
                "detent0_m": .., "detent_step_m": .., "detents": n, "value_step": 0.01},
     "motion": {"velocity_m_s": [vx, vy]}   or   {"keys": [[t_s, dx_m, dy_m], ...], "loop_s": 0.0}}

A toggle's patches come from ``table.meta["scene"]["toggles"][id]`` (its
first state is state 0).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from shapedisplay.errors import TableError
from shapedisplay.render.layouts import EVENT_KINDS, REACT_DEF, REACT_KEY, REACT_KINDS

#: Click drive frequency when a table names none (Hz): the burst carrier of the published device.
DEFAULT_CLICK_HZ = 300.0


class ReactionEvent(NamedTuple):
    """One reaction event: ``kind`` (one of :data:`~.layouts.EVENT_KINDS`), the widget's id, the time of its
    tick (s) and its value (toggle: the new state's index; value: the slider's value 0..1; click: the
    detent number, 0 for a press click; grab and drop of a slider: its value)."""

    kind: str
    widget: str
    t: float
    value: float


def _scene(table) -> dict:
    s = table.meta.get("scene") if isinstance(table.meta, dict) else None
    return s if isinstance(s, dict) else {}


def reactions_meta(table) -> list:
    """The table's reactive widgets as its meta lists them (empty without a scene or reactions)."""
    r = _scene(table).get("reactions") or []
    if not isinstance(r, list) or not all(isinstance(e, dict) for e in r):
        raise TableError("table meta: scene.reactions must be a list of tables")
    return r


def _num(entry: dict, key: str, default=None, where: str = "") -> float:
    v = entry.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise TableError(f"table meta: reaction {where}: `{key}` must be a finite number (got {v!r})")
    return float(v)


def reaction_records(table) -> tuple[np.ndarray, np.ndarray]:
    """The engine's records of the table's reactive widgets.

    Returns
    -------
    defs : ndarray (n,), :data:`~.layouts.REACT_DEF`
    keys : ndarray (k,), :data:`~.layouts.REACT_KEY`, every moving part's keyframes back to back

    Raises :class:`TableError` for a malformed meta entry (the engine checks
    the records again when it loads them). An entry whose toggle block or
    moving part does not fit the table's layout (a table rebuilt on another
    layout, dense or resampled, keeps its scene's meta) is left out: that
    widget plays as its blocks show it, without reacting.
    """
    entries = reactions_meta(table)
    defs = np.zeros(len(entries), REACT_DEF)
    keys: list = []
    if not entries:
        return defs, np.zeros(0, REACT_KEY)
    offsets = table.patch_offsets()
    toggles = _scene(table).get("toggles") or {}
    keep = np.ones(len(entries), bool)
    for i, e in enumerate(entries):
        wid = str(e.get("id", i))
        d = defs[i]
        kind = e.get("kind")
        if kind not in REACT_KINDS[1:]:
            raise TableError(f"table meta: reaction '{wid}': kind must be one of {', '.join(REACT_KINDS[1:])} "
                             f"(got {kind!r})")
        d["kind"] = REACT_KINDS.index(kind)
        d["widget"] = int(_num(e, "widget", where=wid))
        box = e.get("box_m")
        if not (isinstance(box, list) and len(box) == 4):
            raise TableError(f"table meta: reaction '{wid}': box_m must be [x0, y0, x1, y1] (got {box!r})")
        d["x0"], d["y0"], d["x1"], d["y1"] = (float(v) for v in box)
        d["press_n"] = _num(e, "press_n", 0.0, wid)
        d["release_n"] = _num(e, "release_n", 0.0, wid)
        ck = e.get("click") or {}
        d["click_gain"] = _num(ck, "gain", 0.0, wid)
        d["click_hz"] = _num(ck, "hz", DEFAULT_CLICK_HZ, wid)
        d["click_s"] = _num(ck, "time_s", 0.0, wid)
        d["drop"] = _num(ck, "drop", 0.0, wid)
        d["drop_s"] = _num(ck, "drop_s", 0.0, wid)
        d["block"] = -1
        if kind == "toggle":
            t = toggles.get(wid)
            if not isinstance(t, dict) or not isinstance(t.get("states"), dict) or len(t["states"]) != 2:
                raise TableError(f"table meta: toggle '{wid}' reacts but has no two stored states in scene.toggles")
            names = list(t["states"])
            bi = int(t["block"])
            shapes = [tuple(table.patch_shapes[int(p)]) if 0 <= int(p) < len(table.patch_shapes) else None
                      for p in t["states"].values()]
            if not 0 <= bi < len(table.blocks) or any(sh != tuple(table.patch_shapes[table.blocks[bi][2]])
                                                      for sh in shapes):
                keep[i] = False                 # not this table's layout: the toggle does not flip
                continue
            d["block"] = bi
            d["offset_a"], d["offset_b"] = (int(offsets[int(t["states"][n])]) for n in names)
            d["state0"] = names.index(t["state"]) if t.get("state") in names else 0
        part = e.get("part")
        if part:
            p = int(part["patch"])
            if not 0 <= p < len(table.patch_shapes):
                keep[i] = False                 # not this table's layout: nothing moves
                continue
            d["part_row0"], d["part_col0"] = int(part["row0"]), int(part["col0"])
            d["part_rows"], d["part_cols"] = (int(v) for v in table.patch_shapes[p])
            d["part_offset"] = int(offsets[p])
        sl = e.get("slider")
        if sl:
            d["axis"] = int(_num(sl, "axis", 0, wid))
            for f, k in (("track0", "track0_m"), ("track_len", "track_len_m"), ("thumb_c", "thumb_m"),
                         ("thumb_r", "thumb_r_m"), ("cross_c", "cross_m"), ("detent0", "detent0_m"),
                         ("detent_step", "detent_step_m")):
                d[f] = _num(sl, k, 0.0, wid)
            d["n_detents"] = int(_num(sl, "detents", 0, wid))
            d["value_step"] = _num(sl, "value_step", 0.01, wid)
        mo = e.get("motion")
        if mo:
            if "velocity_m_s" in mo:
                d["wrap"] = 1
                d["vx"], d["vy"] = (float(v) for v in mo["velocity_m_s"])
            else:
                ks = mo.get("keys") or []
                d["key0"], d["n_keys"] = len(keys), len(ks)
                keys += [tuple(float(v) for v in k) for k in ks]
                d["loop_s"] = _num(mo, "loop_s", 0.0, wid)
    defs = defs[keep]
    if not keep.all() and keys:                 # keyframes of the entries kept, renumbered
        kept = []
        for d in defs:
            k0, n = int(d["key0"]), int(d["n_keys"])
            d["key0"] = len(kept)
            kept += keys[k0:k0 + n]
        keys = kept
    return defs, np.array(keys, REACT_KEY) if keys else np.zeros(0, REACT_KEY)


def widget_ids(table) -> list:
    """The table's scene widget ids in scene order: an event's ``widget`` number indexes this list."""
    return [str(w.get("id")) for w in (_scene(table).get("widgets") or []) if isinstance(w, dict)]


def events_of(records: np.ndarray, ids, t0: float, tick_rate: float) -> list:
    """:class:`ReactionEvent` tuples of REACT_EVENT ``records`` (ticks from ``t0`` at ``tick_rate``)."""
    out = []
    for r in records:
        k, w = int(r["kind"]), int(r["widget"])
        out.append(ReactionEvent(EVENT_KINDS[k - 1] if 1 <= k <= len(EVENT_KINDS) else "?",
                                 ids[w] if 0 <= w < len(ids) else str(w),
                                 t0 + int(r["tick"]) / tick_rate, float(r["value"])))
    return out
