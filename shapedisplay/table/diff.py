"""Compare two friction-envelope tables: grid, channels, metadata.

:func:`diff_tables` returns a JSON-safe dict; :func:`format_diff` the lines
``shapedisplay diff A B`` prints. Channels are compared decoded to SI on
the whole canvas (background included), sample by sample: for each channel
the largest ``|b - a|``, where it is (row, col and x, y in mm), and the sum
of both tables' quantization bounds (a difference within it may be coding
alone). Metadata are compared key by key (nested keys joined with ``.``).
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
    out["identical"] = (out["checksums"][0] == out["checksums"][1]) or (
        same_grid and not out["meta"] and all(v.get("max_abs_diff") == 0.0 for v in out["channels"].values()))
    return out


def format_diff(d: dict, name_a: str = "A", name_b: str = "B") -> str:
    """Readable lines of :func:`diff_tables`."""
    if d["identical"]:
        return f"{name_a} and {name_b} are identical (checksum {d['checksums'][0]})"
    lines = [f"{name_a}: checksum {d['checksums'][0]}", f"{name_b}: checksum {d['checksums'][1]}"]
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
