"""Compare two friction-envelope tables: grid, channels, metadata.

:func:`diff_tables` returns a JSON-safe dict; :func:`format_diff` the lines
``shapedisplay diff A B`` prints. Channels are compared decoded to SI on
the whole canvas (background included), sample by sample: for each channel
the largest ``|b - a|``, where it is (row, col and x, y in mm), and the sum
of both tables' quantization bounds (a difference within it may be coding
alone). Metadata are compared key by key (nested keys joined with ``.``).
Tables compiled from scenes are also compared widget by widget
(:func:`widget_changes`): one line per widget that changed, in the
designer's words ("reset: normal force 3 → 1.5 N, ramp 5 → 10 mm",
"app-3: moved 4 mm right").
"""
from __future__ import annotations

import json

import numpy as np

#: Metadata keys not compared (they restate what the channel comparison shows, or vary run to run).
SKIP_META = ("report.stored_bytes", "report.bytes_saved", "report.ratio")


def _flatten(d, prefix="") -> dict:
    out = {}
    if isinstance(d, dict):
        for k, v in d.items():
            out.update(_flatten(v, f"{prefix}{k}."))
    else:
        out[prefix[:-1]] = d
    return out


def _short(v, n=60) -> str:
    s = json.dumps(v, allow_nan=True, default=str)
    return s if len(s) <= n else s[:n - 3] + "..."


#: Widget parameters (the compile report's, SI) that are lengths: printed in millimetres.
LENGTH_PARAMS = ("ramp", "corner_radius", "width", "track_width", "track_depth", "track_ramp", "thumb_size",
                 "detent_spacing", "detent_height", "detent_width", "knob_size")


def _report_widgets(table) -> dict:
    ws = ((table.meta.get("report") or {}).get("widgets") or []) if isinstance(table.meta, dict) else []
    return {w["id"]: w for w in ws if isinstance(w, dict) and isinstance(w.get("id"), str)}


def _n(v: float) -> str:
    return f"{v:.4g}"


def _moved(dx: float, dy: float) -> str:
    parts = []
    if abs(dx) > 1e-9:
        parts.append(f"{_n(abs(dx))} mm {'right' if dx > 0 else 'left'}")
    if abs(dy) > 1e-9:
        parts.append(f"{_n(abs(dy))} mm {'up' if dy > 0 else 'down'}")
    return "moved " + " and ".join(parts)


def widget_changes(a, b) -> list[dict]:
    """What changed per widget between two tables compiled from scenes (their compile reports).

    Returns ``[{"id", "changes": [text, ...], "line": "ID: change, change"}]``
    in B's widget order (removed widgets last): added or removed widgets, moves
    and resizes of the box (mm; y up), the strength as the normal force it
    gives (``mapping`` n_base + n_gain * height, N), lengths in mm and every
    other parameter as written. Tables without a widget report give ``[]``.
    """
    wa, wb = _report_widgets(a), _report_widgets(b)
    if not wa and not wb:
        return []

    def force(table, h):
        m = table.meta.get("mapping") or {}
        nb, ng = m.get("n_base"), m.get("n_gain")
        return nb + ng * h if isinstance(nb, (int, float)) and isinstance(ng, (int, float)) else None

    out = []
    for wid in list(wb) + [w for w in wa if w not in wb]:
        ch = []
        if wid not in wa:
            ch.append(f"added ({wb[wid].get('type')})")
        elif wid not in wb:
            ch.append("removed")
        else:
            x, y = wa[wid], wb[wid]
            if x.get("type") != y.get("type"):
                ch.append(f"type {x.get('type')} → {y.get('type')}")
            pa, pb = x.get("params") or {}, y.get("params") or {}
            for k in list(pb) + [k for k in pa if k not in pb]:
                va, vb = pa.get(k), pb.get(k)
                if va == vb or isinstance(va, (list, dict)) or isinstance(vb, (list, dict)):
                    continue
                if isinstance(va, (int, float)) and isinstance(vb, (int, float)) and not isinstance(va, bool):
                    if abs(va - vb) <= 1e-9 * max(abs(va), abs(vb), 1e-12):
                        continue
                    if k == "height" and force(a, va) is not None and force(b, vb) is not None:
                        ch.append(f"normal force {_n(force(a, va))} → {_n(force(b, vb))} N "
                                  f"(height {_n(va * 1e3)} → {_n(vb * 1e3)} mm)")
                    elif k in LENGTH_PARAMS:
                        ch.append(f"{k} {_n(va * 1e3)} → {_n(vb * 1e3)} mm")
                    else:
                        ch.append(f"{k} {_n(va)} → {_n(vb)}")
                else:
                    ch.append(f"{k} {'(none)' if va is None else va} → {'(none)' if vb is None else vb}")
            ba, bb = x.get("bbox_mm"), y.get("bbox_mm")
            if isinstance(ba, list) and isinstance(bb, list) and len(ba) == len(bb) == 4:
                sa, sb = (ba[2] - ba[0], ba[3] - ba[1]), (bb[2] - bb[0], bb[3] - bb[1])
                if max(abs(sa[0] - sb[0]), abs(sa[1] - sb[1])) > 1e-6:
                    ch.append(f"size {_n(sa[0])}x{_n(sa[1])} → {_n(sb[0])}x{_n(sb[1])} mm")
                    if max(abs(ba[0] - bb[0]), abs(ba[1] - bb[1])) > 1e-6:
                        ch.append(_moved(bb[0] - ba[0], bb[1] - ba[1]).replace("moved", "corner moved"))
                elif max(abs(ba[0] - bb[0]), abs(ba[1] - bb[1])) > 1e-6:
                    ch.append(_moved(bb[0] - ba[0], bb[1] - ba[1]))
        if ch:
            out.append({"id": wid, "changes": ch, "line": f"{wid}: {', '.join(ch)}"})
    return out


def diff_tables(a, b) -> dict:
    """Differences between tables ``a`` and ``b`` (:class:`~shapedisplay.table.model.FrictionTable`).

    Returns
    -------
    dict with ``identical`` (bool), ``checksums`` [a, b], ``grid`` {same, a, b},
    ``channels`` {name: {only_in} or {max_abs_diff, at_row_col, at_mm, a_value,
    b_value, coding_bound, within_coding}}, ``meta`` [{key, a, b}].
    """
    ga, gb = a.grid.to_json(), b.grid.to_json()
    same_grid = ga == gb
    out = {"checksums": [a.checksum, b.checksum], "grid": {"same": same_grid, "a": ga, "b": gb},
           "channels": {}, "meta": []}
    for name in sorted(set(a.channels) | set(b.channels)):
        if name not in b.channels:
            out["channels"][name] = {"only_in": "a"}
            continue
        if name not in a.channels:
            out["channels"][name] = {"only_in": "b"}
            continue
        if not same_grid and (ga["rows"], ga["cols"]) != (gb["rows"], gb["cols"]):
            out["channels"][name] = {"not_compared": "the grids differ in size"}
            continue
        va, vb = a.dense(name), b.dense(name)
        d = np.abs(vb - va)
        r, c = np.unravel_index(int(np.argmax(d)), d.shape)
        bound = float(a.quant[name].max_error + b.quant[name].max_error)
        out["channels"][name] = {
            "max_abs_diff": float(d[r, c]), "at_row_col": [int(r), int(c)],
            "at_mm": [(a.grid.x0 + c * a.grid.dx) * 1e3, (a.grid.y0 + r * a.grid.dy) * 1e3],
            "a_value": float(va[r, c]), "b_value": float(vb[r, c]), "coding_bound": bound,
            "within_coding": bool(d[r, c] <= bound), "differing_samples": int(np.count_nonzero(d))}
    fa, fb = _flatten(a.meta), _flatten(b.meta)
    for k in sorted(set(fa) | set(fb)):
        if k in SKIP_META:
            continue
        if fa.get(k, "<absent>") != fb.get(k, "<absent>"):
            out["meta"].append({"key": k, "a": fa.get(k, "<absent>"), "b": fb.get(k, "<absent>")})
    out["widgets"] = widget_changes(a, b)
    out["identical"] = (out["checksums"][0] == out["checksums"][1]) or (
        same_grid and not out["meta"] and all(v.get("max_abs_diff") == 0.0 for v in out["channels"].values()))
    return out


def format_diff(d: dict, name_a: str = "A", name_b: str = "B") -> str:
    """Readable lines of :func:`diff_tables`."""
    if d["identical"]:
        return f"{name_a} and {name_b} are identical (checksum {d['checksums'][0]})"
    lines = [f"{name_a}: checksum {d['checksums'][0]}", f"{name_b}: checksum {d['checksums'][1]}"]
    if d.get("widgets"):
        lines.append("widgets:")
        lines += [f"  {w['line']}" for w in d["widgets"]]
    g = d["grid"]
    if g["same"]:
        lines.append(f"grid: same ({g['a']['cols']} x {g['a']['rows']} samples)")
    else:
        for k in g["a"]:
            if g["a"][k] != g["b"][k]:
                lines.append(f"grid {k}: {g['a'][k]!r} -> {g['b'][k]!r}")
    lines.append("channels:")
    for name, c in d["channels"].items():
        if "only_in" in c:
            lines.append(f"  {name:<16} only in {name_a if c['only_in'] == 'a' else name_b}")
        elif "not_compared" in c:
            lines.append(f"  {name:<16} not compared: {c['not_compared']}")
        elif c["max_abs_diff"] == 0:
            lines.append(f"  {name:<16} identical")
        else:
            x, y = c["at_mm"]
            lines.append(f"  {name:<16} max |diff| {c['max_abs_diff']:.6g} at row {c['at_row_col'][0]}, col "
                         f"{c['at_row_col'][1]} (x {x:.4g} mm, y {y:.4g} mm): {c['a_value']:.6g} -> "
                         f"{c['b_value']:.6g}; {c['differing_samples']} samples differ"
                         + ("; within the coding bound" if c["within_coding"] else
                            f"; beyond the coding bound {c['coding_bound']:.3g}"))
    if d["meta"]:
        lines.append("metadata:")
        for m in d["meta"]:
            lines.append(f"  {m['key']}: {_short(m['a'])} -> {_short(m['b'])}")
    else:
        lines.append("metadata: same")
    return "\n".join(lines)
