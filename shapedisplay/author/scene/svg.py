"""SVG mockups as scenes: a UI mockup from a design tool, read as the scene it shows.

The SVG is parsed with svgelements (optional extra: ``pip install
'shapedisplay[svg]'``), which resolves groups, transforms, units and CSS
lengths; this module turns the shapes that name a widget into the same data
a scene TOML holds (:func:`svg_scene_data`), which
:func:`shapedisplay.author.scene.spec.parse_scene` validates like any scene, and
writes that data as TOML (:func:`scene_toml`) for editing.

The attribute scheme
--------------------
* **Canvas.** The ``<svg>`` element's ``width`` and ``height`` give the
  physical size (``width="80mm"``; plain numbers or ``px`` are CSS pixels,
  96 per inch). Its ``data-*`` attributes set the rest of the scene:
  ``data-resolution`` (canvas sample spacing, default 0.5 mm),
  ``data-device`` (a bundled device name or a TOML path), ``data-name``,
  ``data-description``, and any ``[mapping]`` key with dashes for
  underscores (``data-n-base="1 N"``, ``data-n-gain="1 N/mm"``,
  ``data-direction="one-sided"``).
* **Widgets.** An element is a widget when it names a widget type: a
  ``data-widget="slider"`` attribute, else a class ``sd-slider`` (or just
  ``slider``), else an ``id`` that is a type or starts with one and a dash
  (``id="slider-volume"``). Other elements (text, decoration) are left out
  and counted. The ``id`` becomes the widget id.
* **Options.** Every other ``data-*`` attribute of a widget element is a
  widget key, dashes for underscores: ``data-height="1.5 mm"``,
  ``data-detents="5"``, ``data-state="on"``, ``data-value="0.25"``. Whole and
  decimal numbers become numbers, everything else stays text (units as in a
  scene file).
* **Geometry.** Boxed widgets (button, dent, slider, toggle, ...) take the
  element's bounding box after every transform: ``position`` is its
  lower-left corner and ``size`` its extent. A ``rect``'s ``rx``/``ry`` sets a
  button's or dent's ``corner_radius``; a ``circle`` or ``ellipse`` makes it
  round (radius half the smaller side). Line widgets (ridge, edge, groove)
  take a ``line``'s end points, or one widget per straight segment of a
  ``path`` or ``polyline`` (curves by their chord; ids ``ID-1``, ``ID-2``,
  ...), with ``width`` from ``stroke-width`` unless ``data-width`` is given.
  Explicit ``data-position``, ``data-size``, ``data-from``, ``data-to`` win.
* **Orientation.** SVG's y runs down the page, a scene's y up the screen:
  y is flipped about the canvas height, so the mockup and the scene look the
  same from above.
"""
from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

from shapedisplay.author.scene.fields import WIDGET_TYPE_NAMES
from shapedisplay.errors import FileFormatError, InputError, require

#: Widget types that are a line between two points rather than a box.
LINE_TYPES = ("ridge", "edge", "groove")
#: Widget types a rect's rx or a circle sets the corner radius of.
ROUNDED_TYPES = ("button", "dent", "well")
_ROOT_KEYS = {"resolution": ("canvas", "resolution"), "device": ("device", "profile"),
              "profile": ("device", "profile"), "name": ("scene", "name"), "description": ("scene", "description")}
_MM_PER_CSS_PX = 25.4 / 96
#: Deepest nesting of SVG elements read (design tools nest groups a few levels deep).
MAX_SVG_DEPTH = 64
#: Most elements in one SVG document (a settings screen has hundreds), counted before svgelements parses it.
MAX_SVG_ELEMENTS = 50_000
#: Most segments in one path, polyline or polygon (each becomes a widget on a line widget; see spec.MAX_WIDGETS),
#: counted from its ``d`` or ``points`` text before svgelements parses it.
MAX_PATH_SEGMENTS = 10_000
#: Numbers a path command takes per segment (``M`` takes 2 and its further pairs are line segments).
_PATH_ARGS = {"m": 2, "l": 2, "h": 1, "v": 1, "c": 6, "s": 4, "q": 4, "t": 2, "a": 7, "z": 0}
_PATH_COMMAND = re.compile(r"([MmZzLlHhVvCcSsQqTtAa])")
_PATH_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _mm(v: float) -> str:
    """A length in mm for a scene file, rounded to 1 nm (what the canvas grid can use)."""
    r = round(float(v), 6)
    return f"{r + 0.0:g}" if abs(r) < 1e15 else repr(r)


def _value(text: str):
    t = str(text).strip()
    if re.fullmatch(r"[-+]?\d+", t):
        return int(t)
    if _NUMBER.match(t):
        return float(t)
    if t in ("true", "false"):
        return t == "true"
    return t


def _physical(attr: str | None, px: float, where: str) -> float:
    """mm per SVG px from the root's width/height attribute (``80mm``, ``3in``, ``300``, ``300px``)."""
    if not attr or px <= 0:
        return _MM_PER_CSS_PX
    m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-z%]*)\s*", attr)
    if not m:
        raise FileFormatError(f"{where}: cannot read the size {attr!r} of the <svg> element")
    value, unit = float(m.group(1)), m.group(2) or "px"
    per = {"mm": 1.0, "cm": 10.0, "in": 25.4, "pt": 25.4 / 72, "pc": 25.4 / 6, "px": _MM_PER_CSS_PX, "q": 0.25}
    if unit not in per:
        raise FileFormatError(f"{where}: the <svg> size {attr!r} needs an absolute unit (mm, cm, in, pt, px)")
    return value * per[unit] / px


def _widget_type(attrs: dict, types) -> str | None:
    t = attrs.get("data-widget")
    if t is not None:
        return str(t).strip()
    for c in str(attrs.get("class", "")).split():
        name = c[3:] if c.startswith("sd-") else c
        if name in types:
            return name
    wid = str(attrs.get("id", ""))
    for name in sorted(types, key=len, reverse=True):
        if wid == name or wid.startswith(name + "-"):
            return name
    return None


#: Elements svgelements reads as shapes or groups: the ones that can name a widget.
_WIDGET_TAGS = ("g", "svg", "path", "rect", "circle", "ellipse", "line", "polyline", "polygon")
#: ``<svg data-*>`` keys only a mock-up carries (``data-name`` and ``data-description`` are common elsewhere).
_MOCKUP_ROOT_KEYS = tuple(f"data-{k}" for k in _ROOT_KEYS if k not in ("name", "description"))


def is_mockup(path) -> bool:
    """True if the SVG at ``path`` is a UI mock-up (a scene), False if it is a picture (an icon).

    A mock-up is marked up for shapedisplay: an element names a widget type
    (``data-widget``, a class ``sd-TYPE`` or ``TYPE``, an id ``TYPE`` or
    ``TYPE-...``; the rule :func:`svg_scene_data` makes widgets by), or the
    ``<svg>`` element sets ``data-resolution`` or ``data-device``. Any other
    SVG is a picture. One pass over the XML that stops at the first mark; a
    file that is missing or unreadable counts as a mock-up (its loader says
    why it cannot be read), one past :data:`MAX_SVG_ELEMENTS` elements without
    a mark as a picture (whose reader refuses it).
    """
    from xml.etree.ElementTree import ParseError, iterparse
    path = Path(os.fspath(path))
    try:
        fh = open(path, "rb")
    except OSError:
        return True
    with fh:
        try:
            for n, (_, el) in enumerate(iterparse(fh, events=("start",))):
                if n == 0:
                    if any(k in el.attrib for k in _MOCKUP_ROOT_KEYS):
                        return True
                elif el.tag.rsplit("}", 1)[-1] in _WIDGET_TAGS and _widget_type(el.attrib, WIDGET_TYPE_NAMES):
                    return True
                if n > MAX_SVG_ELEMENTS:
                    return False
                el.clear()
        except ParseError as exc:
            raise FileFormatError(f"SVG '{path}': cannot read the SVG ({exc})") from None
    return False


def svg_scene_data(path, notes: list | None = None, origins: dict | None = None) -> dict:
    """The scene data (as parsed TOML would hold it) of an SVG mockup; see the module docstring.

    Parameters
    ----------
    path : path-like
        The ``.svg`` file.
    notes : list, optional
        Receives one line per thing left out (elements without a widget type).
    origins : dict, optional
        Receives, per scene field path (``device.profile``, ``widget[3].file``), the attribute
        it was read from (``<svg data-device>``), for messages about it.

    Returns
    -------
    dict
        ``{"scene": ..., "canvas": ..., "device": ..., "mapping": ..., "widget": [...]}``
        with lengths as strings in mm.
    """
    se = require("svgelements", "svg", "Reading SVG mockups")
    path = Path(os.fspath(path))
    where = f"SVG mockup '{path}'"
    if not path.is_file():
        raise FileFormatError(f"{where}: no such file")
    check_structure(path, where)
    try:
        svg = se.SVG.parse(str(path), reify=True)
    except Exception as exc:  # svgelements raises ParseError, ValueError, ... for broken files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"{where}: cannot read the SVG ({msg})") from None
    root = svg.values.get("attributes", {})
    width_px, height_px = float(svg.width or 0), float(svg.height or 0)
    if not (width_px > 0 and height_px > 0):
        raise FileFormatError(f"{where}: the <svg> element needs a width and a height (the canvas size)")
    k = _physical(root.get("width"), width_px, where)
    W, H = width_px * k, height_px * k
    data: dict = {"scene": {"name": path.stem}, "canvas": {"size": f"{_mm(W)}x{_mm(H)} mm"}}
    for key, value in root.items():
        if not key.startswith("data-"):
            continue
        name = key[5:].replace("-", "_")
        sec, field = _ROOT_KEYS.get(name, ("mapping", name))
        data.setdefault(sec, {})[field] = _value(value)
        if origins is not None:
            origins[f"{sec}.{field}"] = f"<svg {key}>"

    def xy(px, py):    # SVG px (y down) -> scene mm (y up)
        return px * k, H - py * k

    widgets, seen, skipped = [], set(), 0

    def add(widget: dict, wid: str, attrs: dict) -> None:
        if origins is not None:
            for key in attrs:
                if key.startswith("data-") and key != "data-widget":
                    origins[f"widget[{len(widgets)}].{key[5:].replace('-', '_')}"] = f"element '{wid}' {key}"
        widgets.append(widget)
    for el in svg.elements():
        if el is svg:
            continue
        if isinstance(el, se.Text):
            skipped += 1
            continue
        if not isinstance(el, (se.Shape, se.Group)):
            continue
        attrs = el.values.get("attributes", {})
        wtype = _widget_type(attrs, WIDGET_TYPE_NAMES)
        if wtype is None:
            if isinstance(el, se.Shape):
                skipped += 1
            continue
        wid = str(attrs.get("id") or f"{wtype}-{len(widgets)}")
        opts = {}
        for key, value in attrs.items():
            if key.startswith("data-") and key != "data-widget":
                opts[key[5:].replace("-", "_")] = _value(value)
        bbox = el.bbox()
        if bbox is None:
            raise InputError(f"{where}: element '{wid}' ({wtype}) has no geometry")
        x0, y1 = xy(bbox[0], bbox[1])
        x1, y0 = xy(bbox[2], bbox[3])
        if wtype in LINE_TYPES:
            if "width" not in opts and el.values.get("stroke-width") not in (None, "") and \
                    "stroke-width" in attrs:
                opts["width"] = f"{_mm(float(el.stroke_width) * k)} mm"
            if "from" in opts or "to" in opts:
                add({"id": wid, "type": wtype, **opts}, wid, attrs)
                continue
            segs = _segments(el, se)
            if not segs:
                raise InputError(f"{where}: element '{wid}' ({wtype}) has no line to follow")
            for i, (a, b) in enumerate(segs):
                (ax, ay), (bx, by) = xy(a.x, a.y), xy(b.x, b.y)
                sid = wid if len(segs) == 1 else f"{wid}-{i + 1}"
                add({"id": sid, "type": wtype, "from": f"{_mm(ax)},{_mm(ay)} mm",
                     "to": f"{_mm(bx)},{_mm(by)} mm", **opts}, wid, attrs)
            continue
        w = {"id": wid, "type": wtype}
        if "position" not in opts and "center" not in opts:
            w["position"] = f"{_mm(x0)},{_mm(y0)} mm"
        if "size" not in opts:
            w["size"] = f"{_mm(x1 - x0)}x{_mm(y1 - y0)} mm"
        if wtype in ROUNDED_TYPES and "corner_radius" not in opts:
            if isinstance(el, (se.Circle, se.Ellipse)):
                w["corner_radius"] = f"{_mm(min(x1 - x0, y1 - y0) / 2)} mm"
            elif isinstance(el, se.Rect) and (float(el.rx or 0) > 0 or float(el.ry or 0) > 0):
                r = min(float(el.rx or el.ry), float(el.ry or el.rx)) * k
                w["corner_radius"] = f"{_mm(r)} mm"
        w.update(opts)
        add(w, wid, attrs)
        seen.add(wid)
    if skipped and notes is not None:
        notes.append(f"{skipped} element(s) without a widget type left out (text, decoration)")
    if not widgets:
        raise InputError(f"{where}: no element names a widget type (data-widget=\"button\", class \"sd-button\" "
                         f"or an id such as \"button-ok\"); types: {', '.join(sorted(WIDGET_TYPE_NAMES))}")
    data["widget"] = widgets
    return data


def check_structure(path, where: str, visit=None) -> int:
    """Refuse, in one pass of the XML before svgelements reads it, what would make it slow or deep.

    ``path`` is the file, or a binary file object holding its bytes;
    ``visit(element)``, if given, sees each element as it opens (its
    attributes read, its children not yet). Returns the number of elements,
    the copies ``<use>`` elements make included. The XML parser (expat)
    refuses a document whose entities expand past its amplification limit
    (a "billion laughs"), and defines no external entity.

    Nesting past MAX_SVG_DEPTH (svgelements walks groups recursively), more
    than MAX_SVG_ELEMENTS elements, or a ``path``, ``polyline`` or
    ``polygon`` of more than MAX_PATH_SEGMENTS segments (counted from its
    text: svgelements builds objects per segment, and each segment of a
    ridge, edge or groove is a widget). Each ``<use>`` counts the elements it
    copies (svgelements builds every copy, and copies of copies): a few
    hundred uses of a large group are refused here, not after the parse.
    """
    from xml.etree.ElementTree import ParseError, iterparse
    depth = elements = 0
    frames = [[0, []]]                       # per open element: [elements in its subtree, <use> targets inside]
    subtree: dict = {}                       # id -> (elements, <use> targets) of that element's subtree
    try:
        for event, el in iterparse(path if hasattr(path, "read") else str(path), events=("start", "end")):
            if event == "end":
                depth -= 1
                count, uses = frames.pop()
                if el.get("id"):
                    subtree[el.get("id")] = (count, uses)
                frames[-1][0] += count
                frames[-1][1].extend(uses)
                el.clear()                    # the pass keeps no tree
                continue
            depth += 1
            elements += 1
            frames.append([1, []])
            if el.tag.rsplit("}", 1)[-1] == "use":
                href = el.get("href") or el.get("{http://www.w3.org/1999/xlink}href") or ""
                if href.startswith("#"):
                    frames[-1][1].append(href[1:])
            if depth > MAX_SVG_DEPTH:
                raise FileFormatError(f"{where}: elements nest more than {MAX_SVG_DEPTH} levels deep, beyond the "
                                      f"limit of {MAX_SVG_DEPTH} (svg.MAX_SVG_DEPTH, docs/limits.md)")
            if elements > MAX_SVG_ELEMENTS:
                raise FileFormatError(f"{where}: more than {MAX_SVG_ELEMENTS} elements, the limit "
                                      f"(svg.MAX_SVG_ELEMENTS, docs/limits.md); flatten or remove decoration, "
                                      f"or raise shapedisplay.author.scene.svg.MAX_SVG_ELEMENTS")
            tag = el.tag.rsplit("}", 1)[-1]
            if tag in ("path", "polyline", "polygon"):
                n = _path_segment_count(el.get("d", "")) if tag == "path" else \
                    _points_segment_count(el.get("points", ""), closed=tag == "polygon")
                if n > MAX_PATH_SEGMENTS:
                    name = f"'{el.get('id')}'" if el.get("id") else f"number {elements}"
                    raise FileFormatError(f"{where}: <{tag}> {name} has {n} segments, more than the limit of "
                                          f"{MAX_PATH_SEGMENTS} (svg.MAX_PATH_SEGMENTS, docs/limits.md); simplify "
                                          f"the path, or raise shapedisplay.author.scene.svg.MAX_PATH_SEGMENTS")
            if visit is not None:
                visit(el)
    except ParseError as exc:
        raise FileFormatError(f"{where}: cannot read the SVG ({exc})") from None
    total = elements + _copies(frames[0][1], subtree, where)
    if total > MAX_SVG_ELEMENTS:
        raise FileFormatError(f"{where}: {total} elements with the copies its <use> elements make, more than the "
                              f"limit of {MAX_SVG_ELEMENTS} (svg.MAX_SVG_ELEMENTS, docs/limits.md); use fewer copies, "
                              f"or raise shapedisplay.author.scene.svg.MAX_SVG_ELEMENTS")
    return total


def _copies(targets: list, subtree: dict, where: str) -> int:
    """Elements the ``<use>`` elements with these targets add (copies of copies included), capped past the limit.

    A ``<use>`` whose target contains a ``<use>`` of itself (directly or not) is refused: it never ends.
    """
    memo: dict = {}

    def size(ref: str, open_refs: tuple) -> int:
        if ref in open_refs:
            raise FileFormatError(f"{where}: <use> of '#{ref}' copies itself (a <use> inside '#{ref}' leads back "
                                  f"to it)")
        if ref not in memo:
            count, uses = subtree.get(ref, (0, []))
            n = count
            for u in uses:
                n += size(u, open_refs + (ref,))
                if n > MAX_SVG_ELEMENTS:
                    break
            memo[ref] = n
        return memo[ref]

    total = 0
    for ref in targets:
        total += size(ref, ())
        if total > MAX_SVG_ELEMENTS:
            break
    return total


def _path_segment_count(d: str) -> int:
    """Segments (lines, curves, arcs, closes) a path's ``d`` text draws, counted without building them.

    Each command's numbers are split into segments by the count it takes
    (``C`` 6, ``L`` 2, ``H`` 1, ...); the first pair of a ``M`` is a move,
    its further pairs lines. A short last group counts as one segment; arc
    flags written without spaces (``a1 1 0 01 5 5``) read as fewer numbers.
    So the count is at most one a command above what is drawn, never below
    by more than one an arc.
    """
    n = 0
    parts = _PATH_COMMAND.split(d)
    for cmd, args in zip(parts[1::2], parts[2::2]):
        per = _PATH_ARGS[cmd.lower()]
        if per == 0:
            n += 1
            continue
        k = -(-len(_PATH_NUMBER.findall(args)) // per)        # ceil: a short last group is still drawn as one
        n += max(0, k - 1) if cmd in "Mm" else k
    return n


def _points_segment_count(points: str, closed: bool) -> int:
    k = -(-len(_PATH_NUMBER.findall(points)) // 2)
    return max(0, k - 1) + (1 if closed and k > 1 else 0)


def _segments(el, se) -> list:
    """Straight segments (start, end) of a line, polyline or path (curves by their chord), SVG px."""
    if isinstance(el, se.SimpleLine):
        return [(se.Point(el.x1, el.y1), se.Point(el.x2, el.y2))]
    shape = el if isinstance(el, se.Path) else se.Path(el)
    out = []
    for s in shape.segments():
        if isinstance(s, se.Move) or s.start is None or s.end is None:
            continue
        if math.hypot(s.end.x - s.start.x, s.end.y - s.start.y) > 0:
            out.append((s.start, s.end))
    return out


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    return json.dumps(str(v), ensure_ascii=False)


def scene_toml(data: dict, source: str = "") -> str:
    """TOML text of scene ``data`` (as :func:`svg_scene_data` returns): the scene file to edit."""
    lines = []
    if source:
        lines += [f"# Scene imported from the SVG mockup {source}", "#", "#   shapedisplay compile THIS.toml -o t.npz", ""]
    for sec in ("scene", "canvas", "device", "mapping"):
        if data.get(sec):
            lines.append(f"[{sec}]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in data[sec].items()]
            lines.append("")
    for w in data.get("widget", []):
        lines.append("[[widget]]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in w.items()]
        lines.append("")
    return "\n".join(lines)
