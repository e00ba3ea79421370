"""Edits of a scene file that keep it the designer's file: the studio's canvas, inspector and palette.

Every change the page asks for is a list of operations on the scene text:

* ``{"op": "set", "widget": ID, "key": K, "value": V}`` sets one key of a
  widget (``None`` removes it); setting one strength key (``height``,
  ``force``, ``force_step``, ``level``; ``depth`` for sunk types) removes the
  widget's other strength keys, and ``position`` / ``center`` replace each other;
* ``{"op": "box", "widget": ID, "d": [dx0, dy0, dx1, dy1]}`` moves the edges
  of a widget's box by millimetres (all four equal: a move), snapped to the
  sample grid; a boxed widget gets ``position`` (or ``center``) and ``size``,
  a line (ridge, edge, groove) ``from`` / ``to`` (or ``at``) and ``width``;
* ``{"op": "add", "type": T}``, ``{"op": "duplicate", "widget": ID}``,
  ``{"op": "delete", "widget": ID}``: whole ``[[widget]]`` entries.

Values change through tomlkit, which rewrites only the value (a comment after
it, the spacing before it and every other line stay byte for byte); whole
widgets are cut and pasted as lines. :func:`validate` holds the result to the
rules ``shapedisplay check`` applies (the same messages), and the studio writes
nothing that breaks them. :func:`merge3` merges two versions of the file line
by line against the version both started from (a conflict keeps the disk's lines).
"""
from __future__ import annotations

import difflib
import hashlib
import math
import re
from pathlib import Path

from shapedisplay.errors import InputError

#: Palette: the widget types a page can add (image and mesh need a file: add them in the text),
#: with the keys a new one starts with besides id, type and its place.
NEW_WIDGET = {
    "button": {"size": (20, 20)}, "dent": {"size": (20, 14)}, "well": {"size": (20, 14)},
    "slider": {"size": (60, 12)}, "toggle": {"size": (24, 12)},
    "ridge": {"length": 40}, "edge": {"length": 40}, "groove": {"length": 40},
    "data": {"size": (20, 20), "extra": {"channel": "friction_scale", "values": [0.0, 1.0]}},
}
#: Offset of a duplicate from its original, millimetres (x right, y down the screen).
DUPLICATE_OFFSET_MM = 5.0

_ANY_HEADER = re.compile(r"^\s*\[")
_WIDGET_HEADER = re.compile(r"^\s*\[\[\s*widget\s*\]\]\s*(#.*)?$")
_COMMENT = re.compile(r"^\s*#")


def version_of(data: bytes) -> str:
    """The version of a scene file's bytes (the first 20 hex digits of their SHA-256)."""
    return hashlib.sha256(data).hexdigest()[:20]


def mm(v_m: float) -> str:
    """A length in metres as millimetres for the file: at most 4 decimals, no trailing zeros."""
    s = f"{round(v_m * 1e3, 4):.4f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


# --------------------------------------------------------------- reading the scene
def _toml():
    from shapedisplay.table.devices import toml_module
    return toml_module()


def widget_ids(data: dict) -> list:
    """Ids of the parsed scene's widgets in file order (a widget without ``id``: ``TYPE-INDEX``, as the loader)."""
    raw = data.get("widget", [])
    raw = [raw] if isinstance(raw, dict) else raw if isinstance(raw, list) else []
    return [str(w.get("id", f"{w.get('type', 'widget')}-{i}")) if isinstance(w, dict) else str(i)
            for i, w in enumerate(raw)]


#: The scenes :func:`validate` read last: (version of the text, path, device) -> Scene. An edit validates
#: its result once; the compile that follows and the next edit's placing read it from here.
_VALIDATED: dict = {}
_VALIDATED_KEEP = 4


def forget_validated() -> None:
    """Forget the scenes :func:`validate` kept (a file a scene names may have changed)."""
    _VALIDATED.clear()


def validated(data: bytes):
    """The scene :func:`validate` made of exactly these bytes (any path or device), or None."""
    v = version_of(data)
    return next((sc for (ver, _p, _d), sc in reversed(list(_VALIDATED.items())) if ver == v), None)


def validate(text: str, path: Path, device=None):
    """The scene of ``text`` as ``shapedisplay check`` reads it (files confined to the scene's folder).

    Raises the loader's error (its message names the widget and the key). A text validated
    a moment ago is not read again (only while the files it names are unchanged is that safe,
    so the cache holds the last few texts only and the studio recompiles when a file changes).
    """
    key = (version_of(text.encode("utf-8")), str(path), id(device) if device is not None else None)
    if key in _VALIDATED:
        return _VALIDATED[key]
    scene = _validate(text, path, device)
    _VALIDATED[key] = scene
    while len(_VALIDATED) > _VALIDATED_KEEP:
        _VALIDATED.pop(next(iter(_VALIDATED)))
    return scene


def _validate(text: str, path: Path, device=None):
    from shapedisplay.author.scene.spec import check_toml_nesting, parse_scene
    from shapedisplay.errors import FileFormatError
    tomllib = _toml()
    where = f"scene '{path}'"
    check_toml_nesting(text, where)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"{where}: invalid TOML ({exc})") from None
    return parse_scene(data, str(path), Path(path).resolve().parent, device=device, confine=True)


def check_toml(text: str, path) -> None:
    """Refuse text that is not TOML (the message says where, as the loader's)."""
    from shapedisplay.errors import FileFormatError
    tomllib = _toml()
    try:
        tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"scene '{path}': invalid TOML ({exc})") from None


# --------------------------------------------------------------- applying operations
def apply_ops(text: str, ops: list, path: Path, device=None) -> tuple[str, str | None]:
    """``text`` with ``ops`` applied, and the id to select afterwards (an added or duplicated widget).

    Each operation sees the result of the one before; the result is validated
    (:func:`validate`): a change that breaks a rule raises its message and nothing is written.
    """
    if not isinstance(ops, list) or not ops or len(ops) > 100:
        raise InputError("`ops` must be a list of 1..100 operations")
    select = None
    for op in ops:
        if not isinstance(op, dict) or not isinstance(op.get("op"), str):
            raise InputError(f"each operation must be an object with an `op` (got {str(op)[:60]!r})")
        kind = op["op"]
        if kind == "set":
            text = set_key(text, _wid(op), op.get("key"), op.get("value"))
            select = _wid(op)
        elif kind == "box":
            d = op.get("d")
            if not (isinstance(d, list) and len(d) == 4 and all(_finite(v) for v in d)):
                raise InputError("`box` needs `d`: four numbers [dx0, dy0, dx1, dy1] in millimetres")
            text = move_box(text, _wid(op), [float(v) for v in d], path, device)
            select = _wid(op)
        elif kind == "add":
            text, select = add_widget(text, op.get("type"), path, device)
        elif kind == "duplicate":
            text, select = duplicate_widget(text, _wid(op), path, device)
        elif kind == "delete":
            text = delete_widget(text, _wid(op))
            select = None
        else:
            raise InputError(f"unknown operation {kind!r}; valid: set, box, add, duplicate, delete")
    validate(text, path, device)
    return text, select


def _wid(op) -> str:
    w = op.get("widget")
    if not isinstance(w, str) or not w:
        raise InputError(f"operation {op.get('op')!r} needs `widget`: a widget id")
    return w


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _index(data: dict, wid: str) -> int:
    ids = widget_ids(data)
    if wid not in ids:
        from shapedisplay.errors import did_you_mean
        raise InputError(f"the scene has no widget '{wid}'{did_you_mean(wid, ids)}")
    if not isinstance(data.get("widget"), list):
        raise InputError("the scene's widgets are not [[widget]] tables; edit them in the text")
    return ids.index(wid)


def _document(text: str):
    import tomlkit
    doc = tomlkit.parse(text)
    if tomlkit.dumps(doc) != text:           # tomlkit would reformat this file: leave it to the text editor
        raise InputError("this scene's layout cannot be kept by the TOML editor; edit it in the text")
    return doc


def _type_of(data: dict, i: int):
    from shapedisplay.author.scene.widgets import WIDGET_TYPES
    t = data["widget"][i].get("type")
    return WIDGET_TYPES.get(t) if isinstance(t, str) else None


#: Keys that replace each other: writing one removes the others.
EXCLUSIVE = (("position", "center"),)


def set_key(text: str, wid: str, key, value) -> str:
    """Set (or with ``value`` None remove) ``key`` of widget ``wid``; only that value's text changes."""
    data = _toml().loads(text)
    return _set_at(text, data, _index(data, wid), wid, key, value)


def _set_at(text: str, data: dict, i: int, wid: str, key, value) -> str:
    """:func:`set_key` on the ``i``-th [[widget]] entry (``wid`` names it in messages)."""
    from shapedisplay.author.scene.reactions import REACTION_KEYS
    from shapedisplay.author.scene.spec import PERCEPTION_KEYS
    wt = _type_of(data, i)
    valid = (list(wt.keys) if wt else []) + list(PERCEPTION_KEYS) + list(REACTION_KEYS)
    if not isinstance(key, str) or key not in valid:
        from shapedisplay.errors import did_you_mean
        raise InputError(f"widget '{wid}': unknown key {key!r}{did_you_mean(str(key), valid)}; "
                         f"valid: {', '.join(sorted(valid))}")
    if key in ("type",):
        raise InputError("a widget's type is changed in the text (its keys differ)")
    if value is not None and not isinstance(value, (str, int, float, bool, list)):
        raise InputError(f"`{key}` must be a string, a number or a list (got {type(value).__name__})")
    quick = _set_line(text, data, i, key, value)
    if quick is not None:
        return quick
    doc = _document(text)
    tbl = doc["widget"][i]
    drop = []
    if wt is not None and key in wt.strength_keys and value is not None:
        drop += [k for k in wt.strength_keys if k != key] + ["contrast"]
    if wt is not None and key == "contrast" and value is not None:
        drop += list(wt.strength_keys)
    for group in EXCLUSIVE:
        if key in group and value is not None:
            drop += [k for k in group if k != key]
    for k in drop:
        if k in tbl:
            del tbl[k]
    if value is None:
        if key in tbl:
            del tbl[key]
    elif key not in tbl or not _same(tbl[key], value):
        tbl[key] = value
    import tomlkit
    return tomlkit.dumps(doc)


_VALUE = re.compile(r'''("(?:[^"\\\n]|\\.)*"|'[^'\n]*'|[-+0-9.a-zA-Z_:]+)''')


def _set_line(text: str, data: dict, i: int, key: str, value):
    """``text`` with the value of an existing one-line ``key = value`` of widget ``i`` replaced in place,
    or None where that is not certain (a new key, a removal, a key that replaces others, a value over
    several lines): then tomlkit does it. The result is checked to parse to ``data`` with that one value
    changed."""
    from shapedisplay.author.scene.widgets import WIDGET_TYPES
    wt = WIDGET_TYPES.get(data["widget"][i].get("type"))
    if value is None or isinstance(value, (list, bool)) or key not in data["widget"][i] or key == "contrast":
        return None
    if wt is not None and (key in wt.strength_keys or any(key in g for g in EXCLUSIVE)):
        others = [k for k in (*wt.strength_keys, "contrast", *(k for g in EXCLUSIVE if key in g for k in g))
                  if k != key]
        if any(k in data["widget"][i] for k in others):
            return None
    try:
        lines, blocks = _blocks(text, data)
    except InputError:
        return None
    _start, h, end = blocks[i]
    pat = re.compile(rf"^(\s*{re.escape(key)}\s*=\s*)")
    hits = [k for k in range(h + 1, end) if pat.match(lines[k])]
    if len(hits) != 1:
        return None
    line = lines[hits[0]]
    head = pat.match(line).group(1)
    m = _VALUE.match(line, len(head))
    rest = line[m.end():] if m else ""
    if m is None or rest.strip() and not rest.strip().startswith("#"):
        return None
    if isinstance(value, str):
        import json
        literal = json.dumps(value, ensure_ascii=False)
    else:
        literal = repr(value) if isinstance(value, float) else str(value)
    out = "".join(lines[:hits[0]]) + head + literal + rest + "".join(lines[hits[0] + 1:])
    import copy
    expect = copy.deepcopy(data)
    expect["widget"][i][key] = value
    try:
        if _toml().loads(out) != expect:
            return None
    except Exception:
        return None
    return out


def _same(item, value) -> bool:
    plain = item.unwrap() if hasattr(item, "unwrap") else item
    return type(plain) is type(value) and plain == value


def _placed(text: str, wid: str, path: Path, device):
    """(scene, widget) of ``text`` as the loader places it (the box snapped to the grid, not clipped)."""
    scene = validate(text, path, device)
    return scene, scene.widget(wid)


def _snap(v: float, s: float) -> float:
    return round(v / s) * s


def move_box(text: str, wid: str, d_mm: list, path: Path, device=None) -> str:
    """Move the edges of widget ``wid``'s box by ``d_mm`` = [dx0, dy0, dx1, dy1] mm, on the sample grid."""
    scene, w = _placed(text, wid, path, device)
    s = w.spacing
    one_d = scene.canvas.is_1d
    x0, y0 = w.col0 * s, w.row0 * s
    x1, y1 = x0 + (w.ncols - 1) * s, y0 + (0 if one_d else (w.nrows - 1) * s)
    d = [_snap(v * 1e-3, s) for v in d_mm]
    nx0, ny0, nx1, ny1 = x0 + d[0], y0 + d[1], x1 + d[2], y1 + d[3]
    if nx1 - nx0 < s:                         # a handle dragged past the opposite edge stops a sample short
        nx0, nx1 = (nx1 - s, nx1) if d[0] != d[2] and d[0] != 0 else (nx0, nx0 + s)
    if not one_d and ny1 - ny0 < s:
        ny0, ny1 = (ny1 - s, ny1) if d[1] != d[3] and d[1] != 0 else (ny0, ny0 + s)
    if one_d:
        ny0 = ny1 = 0.0
    data = _toml().loads(text)
    i = _index(data, wid)
    raw = data["widget"][i]
    wt = _type_of(data, i)
    sets: dict = {}
    if wt is not None and not wt.boxed:
        sets = _line_keys(raw, w, (x0, y0, x1, y1), (nx0, ny0, nx1, ny1), scene, path)
    else:
        W, H = nx1 - nx0, ny1 - ny0
        if "center" in raw:
            cx, cy = (nx0 + nx1) / 2, _file_y(scene, (ny0 + ny1) / 2)
            sets["center"] = f"{mm(cx)} mm" if one_d else f"{mm(cx)},{mm(cy)} mm"
        else:
            corner = ny1 if scene.canvas.origin == "top-left" else ny0     # the corner `position` names
            sets["position"] = f"{mm(nx0)} mm" if one_d else f"{mm(nx0)},{mm(_file_y(scene, corner))} mm"
        oW, oH = w.size
        if abs(W - oW) > 1e-9 or abs(H - oH) > 1e-9:
            sets["size"] = f"{mm(W)} mm" if one_d else f"{mm(W)}x{mm(H)} mm"
    for k, v in sets.items():
        if k in raw and _same_length_text(raw[k], v, k, scene, path):
            continue
        text = set_key(text, wid, k, v)
    return text


def _file_y(scene, y: float) -> float:
    """A y of the table (up from the bottom edge) as the file writes it (``[canvas] origin``), and back."""
    return scene.canvas.height - y if scene.canvas.origin == "top-left" else y


def _same_length_text(old, new: str, key: str, scene, path) -> bool:
    """True if the file's value ``old`` states the same lengths as ``new`` (so it is left as written)."""
    from shapedisplay.author.scene.fields import Ctx, length, pair
    ctx = Ctx(str(path), Path(path).parent, dpi=scene.canvas.dpi)
    try:
        if key == "size" and not scene.canvas.is_1d:
            a, b = pair(old, "x", key, ctx), pair(new, "x", key, ctx)
        elif key in ("position", "center", "from", "to") and not scene.canvas.is_1d:
            a, b = pair(old, ",", key, ctx), pair(new, ",", key, ctx)
        else:
            a, b = (length(old, key, ctx),), (length(new, key, ctx),)
    except Exception:
        return False
    return all(abs(p - q) <= 1e-9 for p, q in zip(a, b))


def _line_keys(raw: dict, w, old: tuple, new: tuple, scene, path) -> dict:
    """``from`` / ``to`` / ``width`` (``at`` on a 1-D canvas) of a line widget whose box goes from ``old`` to ``new``."""
    from shapedisplay.author.scene.fields import Ctx, pair
    ctx = Ctx(str(path), Path(path).parent, dpi=scene.canvas.dpi)
    wd = w.params["width"]
    out = {}
    if scene.canvas.is_1d:
        cx = (new[0] + new[2]) / 2
        out["at"] = f"{mm(cx)} mm"
        nw = new[2] - new[0]
        if abs(nw - (old[2] - old[0])) > 1e-9:
            out["width"] = f"{mm(nw)} mm"
        return out
    ends = [pair(raw[k], ",", k, ctx) for k in ("from", "to")]
    ends = [(x, _file_y(scene, y)) for x, y in ends]              # in the table's frame (y up)
    new_wd = wd
    mapped = [[0.0, 0.0], [0.0, 0.0]]
    for axis in (0, 1):
        o0, o1, n0, n1 = old[axis], old[axis + 2], new[axis], new[axis + 2]
        lo, hi = min(e[axis] for e in ends), max(e[axis] for e in ends)
        if hi - lo > 1e-12:                      # the ends spread along this axis: map them with the box
            nlo, nhi = lo + (n0 - o0), max(hi + (n1 - o1), lo + (n0 - o0))
            for k, e in enumerate(ends):
                mapped[k][axis] = nlo + (e[axis] - lo) * (nhi - nlo) / (hi - lo)
        else:                                    # the line runs across this axis: its extent is the width
            for k, e in enumerate(ends):
                mapped[k][axis] = e[axis] + ((n0 + n1) - (o0 + o1)) / 2
            if abs((n1 - n0) - (o1 - o0)) > 1e-9:
                new_wd = max(n1 - n0, w.spacing)
    out["from"] = f"{mm(mapped[0][0])},{mm(_file_y(scene, mapped[0][1]))} mm"
    out["to"] = f"{mm(mapped[1][0])},{mm(_file_y(scene, mapped[1][1]))} mm"
    if abs(new_wd - wd) > 1e-9:
        out["width"] = f"{mm(new_wd)} mm"
    return out


# --------------------------------------------------------------- whole widgets
_TOKENS = re.compile(r'''"{3}(?:[^\\]|\\.)*?"{3,5}|'{3}.*?'{3,5}|"(?:[^"\\\n]|\\.)*"|'[^'\n]*'|\#[^\n]*|[\[\]{}]''', re.S)


def _outside_values(text: str, lines: list) -> list:
    """Per line: True if it starts outside any value (not within an array, an inline table or a
    multi-line string), where a table header can stand."""
    import bisect
    starts, pos = [], 0
    for ln in lines:
        starts.append(pos)
        pos += len(ln)
    depth_at, in_string = [0] * len(lines), set()
    depth, li = 0, 0
    for m in _TOKENS.finditer(text):
        while li < len(lines) and starts[li] <= m.start():
            depth_at[li] = depth
            li += 1
        tok = m.group()
        if tok in ("[", "{"):
            depth += 1
        elif tok in ("]", "}"):
            depth -= 1
        elif tok.startswith(('"""', "'''")):
            first = bisect.bisect_right(starts, m.start()) - 1
            last = bisect.bisect_right(starts, m.end() - 1) - 1
            in_string.update(range(first + 1, last + 1))
    while li < len(lines):
        depth_at[li] = depth
        li += 1
    return [depth_at[j] == 0 and j not in in_string for j in range(len(lines))]


def _blocks(text: str, data: dict) -> tuple[list, list]:
    """(lines, [(start, header, end)] per [[widget]]): a block runs from the comment lines just above its
    header to the line before the next block or table (trailing blank lines included)."""
    lines = text.splitlines(keepends=True)
    free = _outside_values(text, lines)
    heads = [k for k, ln in enumerate(lines) if free[k] and _WIDGET_HEADER.match(ln)]
    if len(heads) != len(widget_ids(data)):
        raise InputError("the scene's [[widget]] headers cannot be told apart in the text; edit it in the text")

    def lead(h):                                 # the comment lines directly above header h
        k = h
        while k > 0 and _COMMENT.match(lines[k - 1]):
            k -= 1
        return k

    out = []
    for n, h in enumerate(heads):
        start = lead(h)
        nxt = next((k for k in range(h + 1, len(lines)) if free[k] and _ANY_HEADER.match(lines[k])), len(lines))
        end = lead(nxt) if nxt < len(lines) else len(lines)
        out.append((start, h, max(end, h + 1)))
    return lines, out


def delete_widget(text: str, wid: str) -> str:
    """``text`` without widget ``wid``'s lines (its header, keys and the comments just above it)."""
    data = _toml().loads(text)
    i = _index(data, wid)
    lines, blocks = _blocks(text, data)
    start, _h, end = blocks[i]
    return "".join(lines[:start] + lines[end:])


def _insert_block(text: str, data: dict, after: int | None, body: str) -> str:
    """``body`` (a [[widget]] entry) inserted after widget ``after``'s block (None: after the last one)."""
    lines, blocks = _blocks(text, data)
    at = blocks[after if after is not None else -1][2] if blocks else len(lines)
    head = lines[:at]
    while head and not head[-1].strip():         # the block's trailing blank lines go after the new entry
        head.pop()
    tail = lines[len(head):at]
    if head and not head[-1].endswith("\n"):
        head[-1] += "\n"
    return "".join(head) + "\n" + body + ("".join(tail) if tail else ("\n" if at < len(lines) else "")) \
        + "".join(lines[at:])


def _free_id(base: str, taken: list) -> str:
    m = re.match(r"^(.*?)(\d+)$", base)
    stem, n = (m.group(1), int(m.group(2))) if m else (base + "-", 1)
    while f"{stem}{n}" in taken:
        n += 1
    return f"{stem}{n}"


def add_widget(text: str, wtype, path: Path, device=None) -> tuple[str, str]:
    """``text`` with a new widget of type ``wtype`` in the middle of the canvas, and its id."""
    if wtype not in NEW_WIDGET:
        raise InputError(f"the palette adds {', '.join(NEW_WIDGET)} (got {wtype!r}); "
                         "an image or mesh widget needs a file: add it in the text")
    data = _toml().loads(text)
    scene = validate(text, path, device)
    c = scene.canvas
    s = c.spacing
    spec = NEW_WIDGET[wtype]
    wid = _free_id(f"{wtype}-1", widget_ids(data))
    cx, cy = _snap(c.width / 2, s), _snap(c.height / 2, s)
    keys = [("id", wid), ("type", wtype)]
    if "length" in spec:
        half = min(spec["length"] * 1e-3, c.width * 0.8) / 2
        if c.is_1d:
            keys.append(("at", f"{mm(cx)} mm"))
        else:
            fy = mm(_file_y(scene, cy))
            keys += [("from", f"{mm(_snap(cx - half, s))},{fy} mm"), ("to", f"{mm(_snap(cx + half, s))},{fy} mm")]
    else:
        W = min(spec["size"][0] * 1e-3, c.width * 0.8)
        H = min(spec["size"][1] * 1e-3, c.height * 0.8)
        x0, y0 = _snap(cx - W / 2, s), _snap(cy - H / 2, s)
        W, H = max(_snap(W, s), s), max(_snap(H, s), s)
        keys += ([("position", f"{mm(x0)} mm"), ("size", f"{mm(W)} mm")] if c.is_1d else
                 [("position", f"{mm(x0)},{mm(_file_y(scene, y0 + H if c.origin == 'top-left' else y0))} mm"),
                  ("size", f"{mm(W)}x{mm(H)} mm")])
    keys += list(spec.get("extra", {}).items())
    import tomlkit
    body = "[[widget]]\n" + "".join(f"{k} = {tomlkit.item(v).as_string()}\n" for k, v in keys)
    has = isinstance(data.get("widget"), list) and data["widget"]
    if not has:
        out = text + ("" if text.endswith("\n") or not text else "\n") + ("\n" if text.strip() else "") + body
    else:
        out = _insert_block(text, data, None, body)
    return out, wid


def duplicate_widget(text: str, wid: str, path: Path, device=None) -> tuple[str, str]:
    """``text`` with a copy of widget ``wid`` (a new id, moved by DUPLICATE_OFFSET_MM), and the copy's id."""
    data = _toml().loads(text)
    i = _index(data, wid)
    lines, blocks = _blocks(text, data)
    _start, h, end = blocks[i]
    body = lines[h:end]
    while body and (not body[-1].strip() or _COMMENT.match(body[-1])):
        body.pop()
    if body and not body[-1].endswith("\n"):
        body[-1] += "\n"
    new_id = _free_id(wid, widget_ids(data))
    out = _insert_block(text, data, i, "".join(body))
    out = _set_at(out, _toml().loads(out), i + 1, new_id, "id", new_id)      # the copy, not the original
    scene, w = _placed(out, new_id, path, device)
    x0, y0, x1, y1 = w.bbox
    off = DUPLICATE_OFFSET_MM
    dx = off if x1 + off * 1e-3 <= scene.canvas.width + 1e-12 else -off
    dy = 0.0 if scene.canvas.is_1d else (-off if y0 - off * 1e-3 >= -1e-12 else off)
    return move_box(out, new_id, [dx, dy, dx, dy], path, device), new_id


# --------------------------------------------------------------- merging two versions
def _changes(base: list, other: list) -> list:
    sm = difflib.SequenceMatcher(None, base, other, autojunk=False)
    return [(i1, i2, other[j1:j2]) for tag, i1, i2, j1, j2 in sm.get_opcodes() if tag != "equal"]


def merge3(base: str, mine: str, disk: str) -> tuple[str, list]:
    """Merge the page's ``mine`` and the file's ``disk``, both edited from ``base``, line by line.

    Returns (text, conflicts): the disk's text with every change of ``mine``
    that touches lines the disk did not change; where both changed the same
    lines the disk's lines stay and ``conflicts`` lists them
    (``{"line": n, "mine": text, "disk": text}``, n 1-based in the base).
    """
    b, m, d = (s.splitlines(keepends=True) for s in (base, mine, disk))
    changes = sorted([(i1, i2, rep, "m") for i1, i2, rep in _changes(b, m)] +
                     [(i1, i2, rep, "d") for i1, i2, rep in _changes(b, d)], key=lambda c: (c[0], c[1]))
    out, pos, conflicts, k = [], 0, [], 0
    while k < len(changes):
        group = [changes[k]]
        hi = changes[k][1]
        k += 1
        while k < len(changes) and (changes[k][0] < hi or changes[k][0] == group[0][0]):
            group.append(changes[k])
            hi = max(hi, changes[k][1])
            k += 1
        lo = group[0][0]
        out += b[pos:lo]
        sides = {c[3] for c in group}
        if len(sides) == 1 or all((c[0], c[1], c[2]) == (group[0][0], group[0][1], group[0][2]) for c in group):
            seg, at = [], lo
            for c in group if len(sides) == 1 else group[:1]:
                seg += b[at:c[0]] + c[2]
                at = c[1]
            out += seg + b[at:hi]
        else:                                    # both sides changed these lines: keep the disk's
            seg, at = [], lo
            for c in (c for c in group if c[3] == "d"):
                seg += b[at:c[0]] + c[2]
                at = c[1]
            out += seg + b[at:hi]
            conflicts.append({"line": lo + 1,
                              "mine": "".join(x for c in group if c[3] == "m" for x in c[2]) or "(removed)",
                              "disk": "".join(x for c in group if c[3] == "d" for x in c[2]) or "(removed)"})
        pos = hi
    out += b[pos:]
    return "".join(out), conflicts

