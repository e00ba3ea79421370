"""The widget map and toggle states of a scene table, as the firmware and JSON exports carry them.

A scene table (``table.meta["scene"]``) places each widget in one block of
the table; a toggle's block points at the patch of its current state, and
every other state is stored as an extra patch. These functions turn that
into plain lists that the C header and the JSON export both write:

* :func:`widget_map` — per widget its id, type, bounding box (metres, x to
  the right, y up the screen) and the blocks that hold it (for hit-testing);
* :func:`toggle_states` — per toggle its block, the initial state and each
  state's patch with the offset of its first value in the flat code arrays
  (switching a state = writing that offset into the block's ``offset``).

Tables that are not compiled from a scene have no widgets and no toggles.
"""
from __future__ import annotations

import math

from shapedisplay.errors import TableError


def _scene(table) -> dict:
    s = table.meta.get("scene") if isinstance(table.meta, dict) else None
    return s if isinstance(s, dict) else {}


def toggle_states(table) -> list[dict]:
    """Toggles of ``table`` in id order.

    Returns
    -------
    list of dict
        ``{"id", "block", "state" (initial), "states": [{"name", "patch", "offset"}]}``;
        ``offset`` indexes the flat code arrays (``blocks[block][4]`` in the C header).
    """
    toggles = _scene(table).get("toggles") or {}
    if not isinstance(toggles, dict):
        raise TableError(f"table meta scene.toggles must be a mapping (got {type(toggles).__name__})")
    offsets = table.patch_offsets()
    out = []
    for tid in sorted(toggles):
        t = toggles[tid]
        try:
            bi = int(t["block"])
            states = {str(k): int(v) for k, v in dict(t["states"]).items()}
            initial = str(t["state"])
        except (KeyError, TypeError, ValueError) as exc:
            raise TableError(f"table meta: toggle '{tid}' needs block, states and state ({exc})") from None
        if not 0 <= bi < len(table.blocks):
            raise TableError(f"table meta: toggle '{tid}' block {bi} is outside the table's "
                             f"{len(table.blocks)} blocks")
        shape = table.patch_shapes[table.blocks[bi][2]]
        rows = []
        for name, p in states.items():
            if not 0 <= p < len(table.patch_shapes) or tuple(table.patch_shapes[p]) != tuple(shape):
                raise TableError(f"table meta: toggle '{tid}' state '{name}' names patch {p}, which is not a "
                                 f"stored patch of the block's shape {tuple(shape)}")
            rows.append({"name": name, "patch": p, "offset": int(offsets[p])})
        if initial not in states:
            raise TableError(f"table meta: toggle '{tid}' state '{initial}' is not one of {sorted(states)}")
        out.append({"id": str(tid), "block": bi, "state": initial, "states": rows})
    return out


def widget_boxes(table) -> tuple:
    """``((id, (x0, y0, x1, y1)), ...)`` of the table's scene widgets, metres, in scene order (empty without a scene).

    Only the boxes: what names the widget under a point (a played event's
    ``widget``). A table rebuilt on another layout (dense, resampled) keeps
    its widgets' boxes even where its blocks no longer match the scene's.
    """
    out = []
    for w in _scene(table).get("widgets") or []:
        wid = str(w.get("id"))
        bbox = [float(v) for v in w.get("bbox_m", ())]
        if len(bbox) != 4 or not all(math.isfinite(v) for v in bbox):
            raise TableError(f"table meta: widget '{wid}' needs a finite bbox_m [x0, y0, x1, y1] (got {bbox!r})")
        out.append((wid, tuple(bbox)))
    return tuple(out)


def widget_map(table) -> list[dict]:
    """Widgets of ``table`` in scene order.

    Returns
    -------
    list of dict
        ``{"id", "type", "bbox_m": [x0, y0, x1, y1], "blocks": [i, ...], "toggle": index or None}``;
        ``toggle`` is the widget's index in :func:`toggle_states`.
    """
    scene = _scene(table)
    widgets = scene.get("widgets") or []
    report = table.meta.get("report", {}) if isinstance(table.meta, dict) else {}
    block_of = {w.get("id"): w.get("block") for w in (report.get("widgets") or []) if isinstance(w, dict)}
    toggles = {t["id"]: i for i, t in enumerate(toggle_states(table))}
    out = []
    for w, (wid, box) in zip(widgets, widget_boxes(table)):
        bbox = list(box)
        b = block_of.get(wid)
        blocks = [int(b)] if isinstance(b, int) and 0 <= b < len(table.blocks) else []
        out.append({"id": wid, "type": str(w.get("type")), "bbox_m": bbox, "blocks": blocks,
                    "toggle": toggles.get(wid)})
    return out
