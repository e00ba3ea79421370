"""SVG pictures (icons, logos, symbols): drawn to pixels by resvg, then read like a PNG.

Functions for turning an SVG picture -- an icon as icon libraries ship it:
a 24 x 24 ``viewBox``, black or ``currentColor`` paths and strokes on a
transparent background -- into an RGBA picture of shape (rows, cols), which
:func:`shapedisplay.author.imageio.read_picture` then reads like any PNG
(the shape of a one-colour icon is its alpha, see
:mod:`shapedisplay.author.imageio`). An SVG marked up as a UI mock-up is a
scene instead (:func:`shapedisplay.author.scene.svg.is_mockup` tells the two
apart); every other SVG is a picture.

The drawing is done by resvg (``pip install 'shapedisplay[svg]'``), which
runs no script and fetches nothing from the network, but reads the local
files an ``<image href>`` names. So the SVG is read here first, and refused
in one line naming the file and the element, if it holds

* a ``<script>`` or ``<foreignObject>`` element;
* an ``href`` or ``xlink:href`` that is neither ``#id`` (an element of the
  same file) nor a ``data:`` URI: a picture is read alone, never a file or
  URL it names;
* a ``data:`` URI that is not a PNG, JPEG, GIF or WebP picture (an SVG
  inside an SVG is not read: its own references would go unchecked), or a
  picture past the picture limits
  (:func:`~shapedisplay.author.heightfield.check_grid_size`).

That pass is the one that guards mock-ups
(:func:`shapedisplay.author.scene.svg.check_structure`: nesting depth,
element count with ``<use>`` copies, path segments; its XML parser refuses
entity expansion past its amplification limit and external entities); the
limits are in docs/limits.md.

What is drawn
-------------
Fills, strokes, transforms, ``fill-rule``, gradients, patterns, clip paths,
masks and opacity, as resvg draws them, at 96 CSS pixels an inch. Two things
are left out, so that the same file gives the same picture on every machine,
each with a :class:`VectorWarning` saying how many:

* **text**: no font is loaded (system fonts differ between machines); an
  icon's text should be converted to paths ("object to path" in Inkscape,
  "outline stroke/create outlines" in other editors);
* **filters** (blur, drop shadows, turbulence): not applied; an icon is felt
  by its fills and strokes, and a filter's cost per pixel has no bound.

Size and resolution
-------------------
:func:`svg_size` is the physical size the ``<svg>`` element states: its
``width`` and ``height`` in an absolute unit (``mm``, ``cm``, ``in``,
``pt``, ``pc``, ``Q``), or one of them with the other following the
``viewBox``. ``px`` and plain numbers are CSS pixels: without a size from
the caller, :func:`raster_plan` takes them at 96 an inch (the length a
browser shows at 100 %; a 24 px icon is 6.35 mm) and says so.

The raster (:func:`raster_size`) keeps the SVG's proportions (its
``width``/``height``, else its ``viewBox``) and is, in order of preference:

1. at least the caller's grid, ``pixels = (cols, rows)`` (a scene's image
   widget passes its box on the canvas grid), in both directions;
2. at least ``size / resolution`` samples (``compile --resolution``);
3. :data:`DEFAULT_RASTER_SIDE` (512) pixels along its longer side: 0.04 mm
   a sample on a 20 mm button.

The picture is then stretched over the size given, as any picture is.
"""
from __future__ import annotations

import base64
import binascii
import codecs
import io
import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

from shapedisplay.author.heightfield import check_grid_size
from shapedisplay.errors import FileFormatError, InputError, require

#: Largest SVG file read as a picture, bytes (icons are a few kB; an illustration with embedded pictures a few MB).
MAX_SVG_BYTES = 16 * 2 ** 20
#: Raster pixels along the longer side when neither a grid nor a resolution is known.
DEFAULT_RASTER_SIDE = 512
#: Most elements (``<use>`` copies included) times raster pixels drawn: 4096 elements at 512 x 512 pixels. resvg's
#: time grows with both, and it cannot be interrupted: a shape covering the raster costs about 1 ns a pixel opaque,
#: 40-90 ns translucent (docs/limits.md has the time at the limit).
MAX_RASTER_WORK = 2 ** 30
#: Vector formats shapedisplay does not read, by suffix: what they are, for the export advice.
VECTOR_FORMATS = {".pdf": "PDF", ".eps": "EPS", ".epsf": "EPS", ".ps": "PostScript", ".ai": "Adobe Illustrator",
                  ".emf": "EMF", ".wmf": "WMF", ".cdr": "CorelDRAW", ".dxf": "DXF", ".svgz": "gzip-compressed SVG"}
#: Pictures a ``data:`` URI may hold, by their first bytes, as Pillow names their format.
_DATA_PICTURES = ((b"\x89PNG\r\n\x1a\n", "PNG"), (b"\xff\xd8\xff", "JPEG"), (b"GIF87a", "GIF"), (b"GIF89a", "GIF"))
#: CSS units per CSS pixel at 96 an inch; the physical ones (all but px) make a stated size.
_PX_PER_UNIT = {"": 1.0, "px": 1.0, "mm": 96 / 25.4, "cm": 96 / 2.54, "in": 96.0, "pt": 96 / 72, "pc": 16.0,
                "q": 96 / 101.6}
_LENGTH = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z%]*)\s*$")
_ENCODING = re.compile(rb"^<\?xml[^>]*?encoding\s*=\s*[\"']([A-Za-z][A-Za-z0-9._-]*)[\"']")
#: A user stylesheet that switches every filter off (it outranks attributes and inline styles).
_NO_FILTERS = "* { filter: none !important; }"
_SVG_NS = "{http://www.w3.org/2000/svg}"
_M_PER_PX = 0.0254 / 96


class VectorWarning(UserWarning):
    """An SVG was drawn without a part of it (text, filters); the message says what and how many."""


@dataclass(frozen=True)
class _Scan:
    root: dict          # attributes of the <svg> element
    elements: int       # elements, <use> copies included
    texts: int          # <text> elements (not drawn)
    filters: int        # <filter> elements (not applied)
    filtered: int       # elements with a filter attribute or style (not applied)


# ----------------------------------------------------------------- formats not read
def refuse_vector_format(path, where: str) -> None:
    """Raise the export advice for a vector format shapedisplay does not read (.pdf, .eps, .ai, ...).

    Returns None for any other suffix, so a caller can go on to its own
    "unknown type" message. ``where`` starts the message ("source 'x.pdf'").
    """
    path = Path(os.fspath(path))
    suffix = path.suffix.lower()
    what = VECTOR_FORMATS.get(suffix)
    if what is None:
        return
    if suffix == ".svgz":
        raise InputError(f"{where}: a {what} file, which shapedisplay does not read; decompress it "
                         f"(gunzip -c '{path.name}' > '{path.stem}.svg') or export it as SVG or PNG")
    raise InputError(f"{where}: {suffix} ({what}) is a vector format shapedisplay does not read; "
                     f"export it as SVG or PNG")


# ----------------------------------------------------------------- reading the XML
def _read(path: Path, where: str) -> bytes:
    """The file's bytes, refused past MAX_SVG_BYTES (by its size first, and by what is read)."""
    if path.is_dir():
        raise FileFormatError(f"{where}: is a directory, not a file")
    try:
        size = path.stat().st_size
        data = b""
        if size <= MAX_SVG_BYTES:
            with open(path, "rb") as fh:
                data = fh.read(MAX_SVG_BYTES + 1)
    except FileNotFoundError:
        raise FileFormatError(f"{where}: no such file") from None
    except OSError as exc:
        raise FileFormatError(f"{where}: unreadable ({exc.strerror or exc})") from None
    if size > MAX_SVG_BYTES or len(data) > MAX_SVG_BYTES:
        raise FileFormatError(f"{where}: {max(size, len(data)) / 2 ** 20:.1f} MiB, more than the limit of "
                              f"{MAX_SVG_BYTES / 2 ** 20:g} MiB for an SVG picture (vector.MAX_SVG_BYTES, "
                              f"docs/limits.md); simplify it, or raise shapedisplay.author.vector.MAX_SVG_BYTES")
    return data


def _root(data: bytes, where: str) -> dict:
    """Attributes of the root element, which must be ``<svg>`` (the XML past it is not read)."""
    from xml.etree.ElementTree import ParseError, iterparse
    try:
        for _, el in iterparse(io.BytesIO(data), events=("start",)):
            if el.tag not in ("svg", _SVG_NS + "svg"):
                raise FileFormatError(f"{where}: not an SVG (its root element is <{el.tag.rsplit('}', 1)[-1]}>)")
            return dict(el.attrib)
    except ParseError as exc:
        raise FileFormatError(f"{where}: cannot read the SVG ({exc})") from None
    raise FileFormatError(f"{where}: not an SVG (no element)")


def _scan(data: bytes, where: str) -> _Scan:
    """One pass over the XML: the structure limits, then what a picture may not hold (module docstring)."""
    from shapedisplay.author.scene.svg import check_structure

    found = {"n": 0, "texts": 0, "filters": 0, "filtered": 0, "root": None}

    def visit(el) -> None:
        found["n"] += 1
        tag = el.tag.rsplit("}", 1)[-1]
        if found["root"] is None:
            if el.tag not in ("svg", _SVG_NS + "svg"):
                raise FileFormatError(f"{where}: not an SVG (its root element is <{tag}>)")
            found["root"] = dict(el.attrib)
        name = f"<{tag}> '{el.get('id')}'" if el.get("id") else f"<{tag}> number {found['n']}"
        if tag in ("script", "foreignObject"):
            raise FileFormatError(f"{where}: {name} is refused: an SVG picture may hold no "
                                  f"{'script' if tag == 'script' else 'foreign (HTML) content'}; remove it")
        for key, value in el.attrib.items():
            if key.rsplit("}", 1)[-1] == "href":
                _check_reference(value, name, where)
        if tag in ("text", "filter"):
            found[tag + "s"] += 1
        style = el.get("style", "")
        if el.get("filter", "none").strip() != "none" or re.search(r"(^|;)\s*filter\s*:\s*(?!none)", style):
            found["filtered"] += 1

    elements = check_structure(io.BytesIO(data), where, visit)
    if found["root"] is None:
        raise FileFormatError(f"{where}: not an SVG (no element)")
    return _Scan(found["root"], elements, found["texts"], found["filters"], found["filtered"])


def _check_reference(value: str, name: str, where: str) -> None:
    ref = value.strip()
    if ref.startswith("#"):
        return
    if ref[:5].lower() == "data:":
        _check_data_picture(ref, name, where)
        return
    shown = ref if len(ref) <= 80 else ref[:77] + "..."
    raise FileFormatError(f"{where}: {name} refers to '{shown}'; an SVG picture is read alone: only '#id' references "
                          f"and data: URIs are followed (inline what it names, or embed a picture as a data: URI)")


def _check_data_picture(ref: str, name: str, where: str) -> None:
    """A ``data:`` URI must hold a PNG, JPEG, GIF or WebP picture within the picture limits (read from its header)."""
    head, sep, payload = ref[5:].partition(",")
    what = f"{where}: {name}'s data: URI"
    if not sep:
        raise FileFormatError(f"{what} has no ',' before its data")
    try:
        if head.lower().endswith(";base64"):
            raw = base64.b64decode(re.sub(r"\s+", "", payload), validate=True)
        else:
            from urllib.parse import unquote_to_bytes
            raw = unquote_to_bytes(payload)
    except (binascii.Error, ValueError) as exc:
        raise FileFormatError(f"{what} is not valid base64 ({exc})") from None
    fmt = next((f for magic, f in _DATA_PICTURES if raw.startswith(magic)), None)
    if fmt is None and raw[:4] == b"RIFF" and raw[8:12] == b"WEBP":
        fmt = "WEBP"
    if fmt is None:
        raise FileFormatError(f"{what} holds no PNG, JPEG, GIF or WebP picture (an SVG inside an SVG is not read: "
                              f"inline its elements)")
    from PIL import Image
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)     # the grid limits are checked next
            with Image.open(io.BytesIO(raw), formats=(fmt,)) as im:
                cols, rows = im.size
    except Image.DecompressionBombError as exc:
        raise InputError(f"{what}: refused before decoding: {exc}") from None
    except Exception as exc:  # UnidentifiedImageError, SyntaxError, OSError: a broken header
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"{what}: not a picture Pillow can read ({msg})") from None
    check_grid_size(rows, cols, f"{what} ({fmt})", "embed a smaller picture")


def _text(data: bytes, where: str) -> str:
    """The SVG as text for resvg: by its byte-order mark, else its XML declaration, else UTF-8."""
    if data.startswith(codecs.BOM_UTF8):
        encoding = "utf-8-sig"
    elif data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        encoding = "utf-16"
    else:
        m = _ENCODING.match(data)
        encoding = m.group(1).decode("ascii") if m else "utf-8"
    try:
        return data.decode(encoding)
    except (LookupError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"{where}: cannot decode its text as {encoding} ({exc}); save it as UTF-8") from None


# ----------------------------------------------------------------- size
def _length_px(text, what: str, where: str):
    """(CSS pixels, physical?) of a ``width``/``height`` attribute; None if missing or relative (%, em)."""
    if text is None:
        return None
    m = _LENGTH.match(str(text))
    if not m:
        raise FileFormatError(f"{where}: cannot read the <svg> {what} {text!r}")
    value, unit = float(m.group(1)), m.group(2).lower()
    if unit not in _PX_PER_UNIT:
        return None                                   # %, em, ex, vw...: relative to what is not there
    if not (math.isfinite(value) and value > 0):
        raise FileFormatError(f"{where}: the <svg> {what} must be a length > 0 (got {text!r})")
    return value * _PX_PER_UNIT[unit], unit not in ("", "px")


def _view_box(text):
    try:
        x, y, w, h = (float(v) for v in re.split(r"[\s,]+", str(text).strip()))
    except (TypeError, ValueError):
        return None
    return (w, h) if all(math.isfinite(v) for v in (w, h)) and w > 0 and h > 0 else None


def _intrinsic(root: dict, where: str):
    """((width, height) CSS px: the drawn proportions, (width, height) metres or None: the stated size)."""
    w = _length_px(root.get("width"), "width", where)
    h = _length_px(root.get("height"), "height", where)
    vb = _view_box(root.get("viewBox")) if root.get("viewBox") is not None else None
    if w and h:
        aspect = (w[0], h[0])
    elif w and vb:
        aspect = (w[0], w[0] * vb[1] / vb[0])
    elif h and vb:
        aspect = (h[0] * vb[0] / vb[1], h[0])
    elif vb:
        aspect = vb
    else:
        aspect = (w[0] if w else 100.0, h[0] if h else 100.0)     # resvg's size without width, height or viewBox
    stated = [d for d in (w, h) if d is not None]
    physical = None
    if stated and all(is_length for _, is_length in stated) and (len(stated) == 2 or vb):
        physical = (aspect[0] * _M_PER_PX, aspect[1] * _M_PER_PX)
    return aspect, physical


def svg_size(path) -> tuple[float, float] | None:
    """The physical size the SVG states, ``(width, height)`` metres, or None (px, unitless, relative or missing).

    ``width="20mm" height="20mm"``, ``2cm``, ``1in``, ``72pt``, or one of
    them with a ``viewBox`` giving the other; see the module docstring.
    """
    path = Path(os.fspath(path))
    where = f"SVG '{path}'"
    return _intrinsic(_root(_read(path, where), where), where)[1]


def raster_size(aspect: tuple[float, float], pixels: tuple[int, int] | None = None) -> tuple[int, int]:
    """``(cols, rows)`` of the raster of a drawing with proportions ``aspect`` (width, height).

    ``pixels``: at least this many columns and rows (the drawing keeps its
    proportions, so one side may get more); None: :data:`DEFAULT_RASTER_SIDE`
    along the longer side. Each side is at least 1 pixel.
    """
    aw, ah = aspect
    scale = DEFAULT_RASTER_SIDE / max(aw, ah) if pixels is None else max(pixels[0] / aw, pixels[1] / ah)

    def side(v: float) -> int:
        v *= scale
        return 1 if v < 1 else int(round(v)) if v < 2 ** 62 else 2 ** 62
    return side(aw), side(ah)


def _pixels(pixels) -> tuple[int, int] | None:
    if pixels is None:
        return None
    try:
        cols, rows = (int(v) for v in pixels)
        ok = cols >= 1 and rows >= 1 and all(float(v) == int(v) for v in pixels)
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise InputError(f"`pixels` must be (cols, rows), two whole numbers >= 1 (got {pixels!r})")
    return cols, rows


def _check_raster(cols: int, rows: int, elements: int, where: str) -> None:
    """The raster within the picture limits and the drawing work within MAX_RASTER_WORK, before drawing."""
    from PIL import Image
    fix = "draw it coarser (a larger resolution or a smaller size)"
    check_grid_size(rows, cols, f"{where} drawn as pixels", fix)
    if Image.MAX_IMAGE_PIXELS and cols * rows > 2 * Image.MAX_IMAGE_PIXELS:       # Pillow refuses that PNG too
        raise InputError(f"{where}: a raster of {cols} x {rows} = {cols * rows} pixels is more than Pillow reads "
                         f"(2 x PIL.Image.MAX_IMAGE_PIXELS = {2 * Image.MAX_IMAGE_PIXELS}); {fix}")
    work = elements * cols * rows
    if work > MAX_RASTER_WORK:
        raise InputError(f"{where}: drawing {elements} elements at {cols} x {rows} pixels is {work:.3g} "
                         f"element-pixels, more than the limit of {MAX_RASTER_WORK:.3g} (vector.MAX_RASTER_WORK, "
                         f"docs/limits.md); {fix}, simplify the SVG, or raise "
                         f"shapedisplay.author.vector.MAX_RASTER_WORK")


# ----------------------------------------------------------------- drawing
def rasterise_svg(path, *, pixels=None):
    """Draw an SVG picture as an RGBA picture (resvg), after the checks of the module docstring.

    Parameters
    ----------
    path : path-like
        The ``.svg`` file.
    pixels : (cols, rows) or None
        The least raster (the caller's sample grid); None:
        :data:`DEFAULT_RASTER_SIDE` pixels along the longer side. The raster
        keeps the SVG's proportions (:func:`raster_size`).

    Returns
    -------
    PIL.Image.Image
        Mode RGBA, 8 bits a channel, not premultiplied; (0, 0, 0, 0) where
        nothing is drawn. Row 0 is the top edge of the drawing.

    Raises
    ------
    FileFormatError
        Missing, unreadable or broken file; a script, foreign content or a
        reference to another file; a structure limit.
    InputError
        A raster beyond the picture limits or :data:`MAX_RASTER_WORK`.
    MissingDependencyError
        resvg-py is not installed.
    """
    resvg = require("resvg_py", "svg", "Reading SVG pictures")
    path = Path(os.fspath(path))
    where = f"SVG '{path}'"
    data = _read(path, where)
    scan = _scan(data, where)
    cols, rows = raster_size(_intrinsic(scan.root, where)[0], _pixels(pixels))
    _check_raster(cols, rows, scan.elements, where)
    text = _text(data, where)
    try:
        png = resvg.svg_to_bytes(svg_string=text, width=cols, height=rows, dpi=96.0, skip_system_fonts=True,
                                 style_sheet=_NO_FILTERS)
    except ValueError as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"{where}: resvg cannot draw it ({msg})") from None
    if scan.texts:
        warnings.warn(f"{where}: {scan.texts} <text> element(s) not drawn (no fonts are loaded, so that every machine "
                      f"draws the same); convert the text to paths", VectorWarning, stacklevel=2)
    if scan.filters or scan.filtered:
        warnings.warn(f"{where}: filters not applied ({scan.filters} <filter> element(s), {scan.filtered} element(s) "
                      f"with a filter): blur and shadows are not felt; an icon is its fills and strokes",
                      VectorWarning, stacklevel=2)
    from PIL import Image
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)       # its size was checked above
        im = Image.open(io.BytesIO(png))
        im.load()
    return im if im.mode == "RGBA" else im.convert("RGBA")


def raster_plan(path, size, resolution, pixels, flags: dict | None = None):
    """The size and the least raster of an SVG read as a height map (:func:`shapedisplay.author.sources.load_image`).

    Parameters
    ----------
    path : path-like
        The ``.svg`` file.
    size : (width, height) m, str "20x20mm", or None
        The picture's physical size; None: the size the SVG states
        (:func:`svg_size`), or else its size in CSS pixels (1/96 in each,
        the length a browser shows at 100 %; a 24 px icon is 6.35 mm).
    resolution : float (m), str, or None
        Sample spacing wanted: the raster has at least ``size / resolution``
        samples.
    pixels : (cols, rows) or None
        The least raster, taking precedence over ``resolution``.
    flags : dict, optional
        How the caller spells ``size`` and ``resolution`` in messages.

    Returns
    -------
    ((width, height), (cols, rows) or None, note or None)
        Metres; the least raster for :func:`rasterise_svg` (None: the default);
        a note when the size came from CSS pixels.
    """
    from shapedisplay.units import parse_pair, parse_quantity

    path = Path(os.fspath(path))
    where = f"SVG '{path}'"
    flag = (lambda name: (flags or {}).get(name, name))
    note = None
    if size is None:
        root = _root(_read(path, where), where)
        aspect, size = _intrinsic(root, where)
        if size is None:                       # CSS pixels: 1 px = 1/96 in, the length a browser draws at 100 %
            size = (aspect[0] * _M_PER_PX, aspect[1] * _M_PER_PX)
            note = (f"size {size[0] * 1e3:.4g} x {size[1] * 1e3:.4g} mm: the SVG's {aspect[0]:g} x {aspect[1]:g} px "
                    f"at CSS 96 px/in (give `{flag('size')}` to choose another)")
    elif isinstance(size, str):
        size = parse_pair(size, "x", "m", flag("size"))
    try:
        w, h = (float(v) for v in size)
    except (TypeError, ValueError):
        raise InputError(f"`{flag('size')}` must be (width, height) in metres (got {size!r})") from None
    if not (math.isfinite(w) and math.isfinite(h) and w > 0 and h > 0):
        raise InputError(f"`{flag('size')}` must be positive (got width={w} m, height={h} m)")
    least = _pixels(pixels)
    if least is None and resolution is not None:
        s = parse_quantity(resolution, "m", flag("resolution")) if isinstance(resolution, str) else float(resolution)
        if not (math.isfinite(s) and s > 0):
            raise InputError(f"`{flag('resolution')}` must be a finite length > 0 (got {resolution!r})")
        least = tuple(max(1, int(round(v / s))) if v / s < 2 ** 62 else 2 ** 62 for v in (w, h))
    return (w, h), least, note


__all__ = ["DEFAULT_RASTER_SIDE", "MAX_RASTER_WORK", "MAX_SVG_BYTES", "VECTOR_FORMATS", "VectorWarning",
           "raster_plan", "raster_size", "rasterise_svg", "refuse_vector_format", "svg_size"]
