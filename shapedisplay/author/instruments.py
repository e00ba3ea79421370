"""Instrument height data with its units: AFM/SPM text exports and Gwyddion Simple Field (``.gsf``) files.

A scanning-probe instrument saves a height image together with what it
means: how many pixels, the physical size of the scan, the unit of the
heights. :func:`load_scan` reads both forms below into a
:class:`~shapedisplay.author.heightfield.HeightField` in metres, with the
size and the z unit taken from the file (options that say the same are
accepted, options that contradict the file are refused, naming both).

Text exports (``.txt``)
-----------------------
A header of ``key : value`` or ``key = value`` lines, each optionally behind
``#``, ``;`` or ``%``, then the grid: one row of numbers a line, separated
by spaces, tabs, commas or semicolons (with semicolons, or with tabs or
spaces between numbers that each hold one comma, a comma is a decimal
comma). The header ends at a marker line (``Start of Data:``, ``# Data:``,
``[Data]``) or at the first line of numbers. Keys are matched without case,
punctuation or a bracketed unit (``Width (px)``, ``X Length [nm]``):

* columns: ``Image Width``, ``Width (px)``, ``XRes``, ``Samples per line``,
  ``Columns``, ...; rows: ``Image Height``, ``YRes``, ``Lines``, ``Rows``,
  ...; both: ``Pixels``. ``Width``/``Height`` are pixel counts when the
  value is a bare whole number and lengths when it has a unit;
* physical size: ``Real Width``/``Real Height``, ``XReal``/``YReal``,
  ``X Length``/``Y Length``, ``X Range``, ``Scan Size`` (one length: a
  square scan), with the unit in the value (``10.00 µm``, ``1e-5 m``,
  ``10000 nm``) or on an ``XY Unit`` / ``Lateral Unit`` line;
* z unit: ``Z Unit``, ``Z Units``, ``Value Units``, ``Height Unit``.

Lengths are m, cm, mm, µm (written ``µm``, ``μm``, ``um`` or ``~m``), nm,
pm or Å (``Å``, ``A``, ``Angstrom``). Gwyddion's ASCII export (``# Channel:
Height``, ``# Width: 10.000 µm``, ``# Height: 10.000 µm``, ``# Value units:
m``, then the grid) is this form: its width and height are lengths and the
pixel counts are the grid's; its units are SI, so ``A`` is an ampere there
(a current channel, refused). A grid of one value a line is read row by row
when the header gives both pixel counts.

Gwyddion Simple Field (``.gsf``)
--------------------------------
The magic line ``Gwyddion Simple Field 1.0``, ``Name = Value`` lines
(``XRes`` and ``YRes`` mandatory; ``XReal``, ``YReal``, ``XYUnits``,
``ZUnits``, ``Title``, ... optional), 1 to 4 NUL bytes that bring the data
to a multiple of 4 bytes, then ``XRes * YRes`` little-endian float32 values
row by row. The file must be exactly that long.

Both forms: row 0 of the grid is the top edge of the top view (the largest
y), as in pictures (:func:`~shapedisplay.author.heightfield.grid_from_picture`).
The grid's size is checked against the header and against
:func:`~shapedisplay.author.heightfield.check_grid_size` before it is read;
NaN or infinite values and ragged rows are refused with their row and column.
"""
from __future__ import annotations

import io
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shapedisplay.errors import FileFormatError, InputError
from shapedisplay.author.heightfield import (HeightField, check_grid_size, check_spacing, fit_range, parse_size,
                                             grid_from_picture, height_range as _height_range, height_scale)

#: Suffixes of instrument files (:func:`load_scan`).
SCAN_SUFFIXES = (".txt", ".gsf")
#: Lines of a text export read before its grid must have begun.
MAX_HEADER_LINES = 200
#: Longest header line of a text export, bytes.
MAX_LINE_BYTES = 4096
#: Largest text export read, bytes (some 50 million numbers); a larger scan travels as .gsf.
MAX_TEXT_BYTES = 2 ** 29
#: Longest header of a .gsf file, bytes.
MAX_GSF_HEADER_BYTES = 65536
#: First line of a .gsf file.
GSF_MAGIC = b"Gwyddion Simple Field 1.0\n"

#: Length units of instrument files, metres per unit (after :func:`length_unit` spelled them).
LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "nm": 1e-9, "pm": 1e-12, "Å": 1e-10}
_UNIT_WORDS = {"meter": "m", "meters": "m", "metre": "m", "metres": "m", "micron": "um", "microns": "um",
               "micrometer": "um", "micrometers": "um", "micrometre": "um", "micrometres": "um",
               "nanometer": "nm", "nanometers": "nm", "nanometre": "nm", "nanometres": "nm",
               "angstrom": "Å", "angstroms": "Å", "ang": "Å", "a": "Å"}
_PIXEL_UNITS = ("px", "pix", "pixel", "pixels", "samples", "points", "lines")

# Header keys, as matched: lower case, punctuation to spaces, a bracketed unit taken out.
_COLS = {"image width", "xres", "x res", "x pixels", "pixels x", "x samples", "samples per line", "samples line",
         "points per line", "columns", "number of columns", "cols", "pixel width", "width pixels", "x points"}
_ROWS = {"image height", "yres", "y res", "y pixels", "pixels y", "y samples", "lines", "number of lines", "rows",
         "number of rows", "pixel height", "height pixels", "y points", "lines per frame"}
_SQUARE = {"pixels", "number of pixels", "samples"}
_WIDTH = {"real width", "xreal", "x real", "x length", "x range", "x scan size", "x scan range", "scan width",
          "physical width", "width real", "x extent"}
_HEIGHT = {"real height", "yreal", "y real", "y length", "y range", "y scan size", "y scan range", "scan height",
           "physical height", "height real", "y extent"}
_BOTH = {"scan size", "scan range", "real size"}
#: Width/height keys that are pixel counts with a bare whole number and lengths with a unit.
_EITHER_W = {"width", "x size", "image width", "breite", "largeur"}     # Gwyddion's export, in its languages
_EITHER_H = {"height", "y size", "image height", "höhe", "hohe", "hoehe", "hauteur"}
_XY_UNIT = {"xy unit", "xy units", "xyunit", "xyunits", "lateral unit", "lateral units", "x unit", "x units",
            "length unit", "length units", "distance unit", "distance units"}
_Z_UNIT = {"z unit", "z units", "zunit", "zunits", "value unit", "value units", "height unit", "height units",
           "data unit", "data units"}
_TITLE = {"channel", "title", "channel name", "data channel", "kanal", "canal"}
_MARKERS = {"start of data", "data", "begin data", "data start", "begin of data", "data begin", "data section"}

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_QTY = re.compile(rf"\s*({_NUM})\s*(~m|(?![x×](?:[\s\d.+-]|$))[^\W\d_]+)?\s*")   # a number, a unit
_BRACKET = re.compile(r"[(\[]([^)\]]*)[)\]]")


@dataclass(frozen=True)
class Scan:
    """What an instrument file holds, before any option: the grid and the units the file states.

    Parameters
    ----------
    values : ndarray of shape (rows, cols), float32 or float64
        Finite heights in the file's unit, picture order (row 0 = top edge).
    size_m : (width, height) metres, or None
        Physical size of the whole scan, None when the file does not state it.
    size_text : str
        How the file states its size, for messages ("Real Width 10.00 µm x Real Height 7.5 µm"), or
        why it states none ("no XYUnits line"; "" for a text export without size lines).
    z_unit : str or None
        Unit of ``values`` (a key of :data:`LENGTH_UNITS`), None when the file states none.
    z_text : str
        How the file states its z unit ("Z Unit nm").
    description : str
        The form of the file and its channel ("Gwyddion Simple Field, Title 'Topography'").
    notes : list of str
        What was read, converted or left unused.
    """

    values: np.ndarray
    size_m: tuple[float, float] | None
    size_text: str
    z_unit: str | None
    z_text: str
    description: str
    notes: list = field(default_factory=list)


# ----------------------------------------------------------------- units
def length_unit(text: str, si: bool = False) -> str | None:
    """The key of :data:`LENGTH_UNITS` that ``text`` spells ("μm", "µm", "um", "~m" -> "um"), or None.

    ``si``: the file writes SI unit symbols (Gwyddion), where ``A`` is the
    ampere, not the ångström: refused, as every unit that is not a length.
    """
    u = text.strip().replace("μ", "u").replace("µ", "u").replace("\u212b", "Å")
    if u.startswith("~"):                      # Nanoscope writes ~m for µm
        u = "u" + u[1:]
    if si and u == "A":
        return None
    if u in LENGTH_UNITS:
        return u
    low = u.lower()
    if low in LENGTH_UNITS and low != "m":                # "NM", "Um"; not "M"
        return low
    return _UNIT_WORDS.get(low)


def _unit_or_refuse(text: str, what: str, si: bool) -> str:
    u = length_unit(text, si)
    if u is None:
        why = "an ampere in Gwyddion's SI units (a current channel)" if si and text.strip() == "A" else "not a length"
        raise FileFormatError(f"{what}: unit {text.strip()!r} is {why}; a height map needs lengths "
                              f"({', '.join(LENGTH_UNITS)})")
    return u


def _len_text(*values: float) -> str:
    """``1e-5, 7.5e-6`` -> ``'10 x 7.5 um'``: lengths in the unit of the largest."""
    big = max(abs(v) for v in values)
    for f, p in ((1.0, "m"), (1e-3, "mm"), (1e-6, "um"), (1e-9, "nm"), (1e-12, "pm")):
        if big >= f or p == "pm":
            return " x ".join(f"{v / f:.6g}" for v in values) + f" {p}"
    raise AssertionError("unreachable")


# ----------------------------------------------------------------- text exports
def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")           # Windows instrument software writes µ as 0xB5


def _norm_key(key: str) -> tuple[str, str]:
    """``'Width (px)'`` -> ``('width', 'px')``: the key as matched, and a unit in brackets."""
    hint = ""
    m = _BRACKET.search(key)
    if m:
        hint = m.group(1).strip()
        key = key[:m.start()] + " " + key[m.end():]
    return " ".join(re.sub(r"[\W_]+", " ", key.lower()).split()), hint


def _cells_table(line: str):
    """The byte translation that turns a line of numbers into space-separated numbers, or None.

    ``None`` when the line is not a row of numbers. Separators: whitespace,
    ``,`` or ``;``; a decimal comma with ``;`` or whitespace separators.
    """
    body = line.strip()
    if not body or body[0] in "#;%":
        return None
    candidates = []
    words = body.split()
    if ";" in body:
        candidates.append(bytes.maketrans(b";,", b" ."))
    elif "," in body and "." not in body and len(words) > 1 and all(w.count(",") == 1 and w[0] != ","
                                                                     and w[-1] != "," for w in words):
        candidates.append(bytes.maketrans(b",", b"."))          # tab/space separated with decimal commas
    candidates += [bytes.maketrans(b",;", b"  ")]
    for table in candidates:
        cells = body.encode("latin-1", "replace").translate(table).split()
        if cells and all(_is_number(c) for c in cells):
            return table
    return None


def _is_number(cell: bytes) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


class _Header:
    """Key/value lines of a text export; :meth:`resolve` turns them into sizes and units."""

    def __init__(self, where: str):
        self.where = where
        self.items: list[tuple[str, str, str, str]] = []     # (key as matched, bracket unit, key, value)
        self.unused: list[str] = []

    def add(self, text: str) -> bool:
        """Take one header line; True when it marks the start of the data."""
        body = text.strip()
        while body[:1] in ("#", ";", "%") and body:
            body = body[1:].lstrip()
        if not body:
            return False
        if body[0] == "[" and body[-1] == "]":            # [Section]
            return _norm_key(body[1:-1])[0] in _MARKERS
        cut = [i for i in (body.find(":"), body.find("=")) if i > 0]
        if not cut:
            return _norm_key(body)[0] in _MARKERS
        key, value = body[:min(cut)].strip(), body[min(cut) + 1:].strip()
        nkey, hint = _norm_key(key)
        if nkey in _MARKERS and not value:
            return True
        self.items.append((nkey, hint, key, value))
        return False

    def resolve(self) -> dict:
        """``{"cols", "rows", "dims_text", "size_m", "size_text", "z_unit", "z_text", "title", "si"}``."""
        keys = {k for k, *_ in self.items}
        si = "channel" in keys and "value units" in keys          # Gwyddion's ASCII export: SI units
        got: dict = {}
        texts: dict = {}

        def put(name, value, text):
            if name in got and not math.isclose(got[name], value, rel_tol=1e-9):
                raise FileFormatError(f"{self.where}: the header gives two values for the {name.replace('_', ' ')}: "
                                      f"'{texts[name]}' and '{text}'")
            got.setdefault(name, value)
            texts.setdefault(name, text)

        xy = [(f"{key} {value}", value) for k, _, key, value in self.items if k in _XY_UNIT]
        xy_unit = None
        for text, value in xy:
            u = _unit_or_refuse(value, f"{self.where}: '{text}'", si)
            if xy_unit is not None and u != xy_unit:
                raise FileFormatError(f"{self.where}: the header gives two lateral units: '{xy[0][0]}' and '{text}'")
            xy_unit = u
        z_unit = z_text = None
        for k, _, key, value in self.items:
            if k in _Z_UNIT:
                u = _unit_or_refuse(value, f"{self.where}: '{key} {value}'", si)
                if z_unit is not None and u != z_unit:
                    raise FileFormatError(f"{self.where}: the header gives two z units: '{z_text}' and "
                                          f"'{key} {value}'")
                z_unit, z_text = u, f"{key} {value}"
        title = next((value for k, _, _, value in self.items if k in _TITLE), "")
        for k, hint, key, value in self.items:
            text = f"{key} {value}"
            if k in _XY_UNIT or k in _Z_UNIT or k in _TITLE:
                continue
            counts = k in _COLS or k in _ROWS or k in _SQUARE
            lengths = k in _WIDTH or k in _HEIGHT or k in _BOTH
            either = k in _EITHER_W or k in _EITHER_H
            if not (counts or lengths or either):
                self.unused.append(key)
                continue
            q = _quantities(value, hint)
            if q is None:
                raise FileFormatError(f"{self.where}: '{text}' is not one or two numbers with a unit")
            units = {u for _, u in q}
            if either:
                pixel = units <= set(_PIXEL_UNITS) | {""} and (units != {""} or (len(q) == 1 and q[0][0].isdigit()))
                counts, lengths = pixel, not pixel
            if counts:
                if not units <= set(_PIXEL_UNITS) | {""}:
                    raise FileFormatError(f"{self.where}: '{text}' must be a pixel count (got unit "
                                          f"{sorted(units - set(_PIXEL_UNITS))[0]!r})")
                n = [_count(v, text, self.where) for v, _ in q]
                if k in _SQUARE:
                    put("columns", n[0], text)
                    put("rows", n[-1], text)
                else:
                    put("columns" if (k in _COLS or k in _EITHER_W) else "rows", n[0], text)
                continue
            if "" in units and xy_unit is None:
                raise FileFormatError(f"{self.where}: '{text}' has no unit and the header has no XY Unit line; "
                                      f"lengths are never guessed")
            if "" in units:
                text += f" ({xy[0][0]})"
            v = [float(x) * LENGTH_UNITS[_unit_or_refuse(u, f"{self.where}: '{text}'", si) if u else xy_unit]
                 for x, u in q]
            if not all(math.isfinite(x) and x > 0 for x in v):
                raise FileFormatError(f"{self.where}: '{text}' must be a length > 0")
            if k in _BOTH:
                put("width", v[0], text)
                put("height", v[-1], text)
            else:
                put("width" if (k in _WIDTH or k in _EITHER_W) else "height", v[0], text)
        if ("width" in got) != ("height" in got):
            have = "width" if "width" in got else "height"
            raise FileFormatError(f"{self.where}: the header gives the physical {have} ('{texts[have]}') but not the "
                                  f"{'height' if have == 'width' else 'width'}")
        size = (got["width"], got["height"]) if "width" in got else None
        size_text = (texts["width"] if texts.get("width") == texts.get("height")
                     else f"{texts['width']} x {texts['height']}") if size else ""
        dims = [texts[n] for n in ("columns", "rows") if n in texts]
        return {"cols": got.get("columns"), "rows": got.get("rows"), "dims_text": ", ".join(dict.fromkeys(dims)),
                "size_m": size, "size_text": size_text, "z_unit": z_unit, "z_text": z_text or "", "title": title,
                "si": si}


def _quantities(value: str, hint: str = "") -> list[tuple[str, str]] | None:
    """``'10 x 7.5 µm'`` -> ``[('10', 'µm'), ('7.5', 'µm')]``: one or two numbers, each with its unit.

    A number without a unit takes the unit written after the other one, else
    ``hint`` (a unit in the key's brackets), else ``''``. None when the value
    is anything else.
    """
    out, pos = [], 0
    while pos < len(value) and len(out) < 3:
        m = _QTY.match(value, pos)
        if not m:
            return None
        out.append((m.group(1), m.group(2) or ""))
        pos = m.end()
        if pos < len(value) and value[pos] in "x×*,":
            pos += 1
            if pos >= len(value):
                return None
    if not 1 <= len(out) <= 2:
        return None
    last = next((u for _, u in reversed(out) if u), hint.strip())
    return [(n, u or last) for n, u in out]


def _count(text: str, line: str, where: str) -> int:
    try:
        n = int(text.lstrip("+"))
    except ValueError:
        raise FileFormatError(f"{where}: '{line}' must be a whole number of pixels") from None
    if n < 1:
        raise FileFormatError(f"{where}: '{line}' must be at least 1 pixel")
    return n


def read_text_export(path) -> Scan:
    """Read an instrument text export: header of ``key : value`` lines, then a grid of numbers.

    Parameters
    ----------
    path : path-like
        The export (module docs for the keys and separators understood).

    Returns
    -------
    Scan
        ``values`` float64 (rows, cols) in the file's z unit, picture order.

    Raises
    ------
    FileFormatError
        A header without a grid within :data:`MAX_HEADER_LINES` lines, a
        binary file, a value that is not a number, NaN or infinite, ragged
        rows, a grid that disagrees with the header's pixel counts, a unit
        that is not a length. InputError: a grid beyond the size limits.
    """
    path = Path(os.fspath(path))
    where = f"scan '{path}'"
    total = _file_size(path, where)
    if total > MAX_TEXT_BYTES:
        raise InputError(f"{where}: a text export of {total} bytes exceeds the limit of {MAX_TEXT_BYTES} "
                         f"(shapedisplay.author.instruments.MAX_TEXT_BYTES); export the scan as .gsf")
    header = _Header(where)
    line_no, table = 0, None
    with path.open("rb") as f:
        while True:
            raw = f.readline(MAX_LINE_BYTES + 1)
            if not raw:
                raise FileFormatError(f"{where}: no grid of numbers after the header ({line_no} lines)")
            line_no += 1
            if b"\0" in raw:
                raise FileFormatError(f"{where}: line {line_no} holds NUL bytes: a binary file, not a text export")
            text = _decode(raw)
            long = len(raw) > MAX_LINE_BYTES and not raw.endswith(b"\n")
            table = _cells_table(text.rsplit(None, 1)[0] if long else text)   # a long line: its last cell is cut
            if table is not None:
                first = line_no
                f.seek(-len(raw), os.SEEK_CUR)
                break
            if long:
                raise FileFormatError(f"{where}: line {line_no} is longer than {MAX_LINE_BYTES} bytes and is not a "
                                      f"row of numbers")
            if header.add(text):
                first = line_no + 1
                break
            if line_no >= MAX_HEADER_LINES:
                raise FileFormatError(f"{where}: no grid of numbers within the first {MAX_HEADER_LINES} lines "
                                      f"(shapedisplay.author.instruments.MAX_HEADER_LINES)")
        data = f.read()
    h = header.resolve()
    if b"\0" in data:
        raise FileFormatError(f"{where}: the grid holds NUL bytes: a binary file, not a text export")
    values = _parse_grid(data, table, first, h, where)
    notes = []
    if header.unused:
        notes.append("header lines not used: " + ", ".join(header.unused[:8])
                     + (f" and {len(header.unused) - 8} more" if len(header.unused) > 8 else ""))
    desc = ("Gwyddion ASCII export" if h["si"] else "instrument text export") + \
        (f", {h['title']!r}" if h["title"] else "")
    return Scan(values, h["size_m"], h["size_text"], h["z_unit"], h["z_text"], desc, notes)


def _parse_grid(data: bytes, table, first: int, h: dict, where: str) -> np.ndarray:
    """The grid of a text export (``data``: the file from line ``first`` on): sizes checked first.

    ``table`` is the separators of the first row (:func:`_cells_table`), or
    None after a marker line. Lines are streamed to the parser, never split
    up front, so a hostile file costs no more than its bytes.
    """
    start = 0
    for skipped in range(MAX_HEADER_LINES + 1):            # after a marker line: find the first row
        if table is not None:
            break
        end = data.find(b"\n", start)
        line = data[start:] if end < 0 else data[start:end]
        table = _cells_table(_decode(line))
        if table is None:
            if line.strip() and not line.lstrip().startswith(b"#"):
                raise FileFormatError(f"{where}: line {first + skipped}: {_decode(line).strip()[:40]!r} is not a row "
                                      f"of numbers")
            if end < 0:
                raise FileFormatError(f"{where}: no grid of numbers after the header")
            start = end + 1
    else:
        raise FileFormatError(f"{where}: no row of numbers within {MAX_HEADER_LINES} lines after the header")
    row1 = first + data.count(b"\n", 0, start)             # the line of the first row
    end = data.find(b"\n", start)
    cols0 = len((data[start:] if end < 0 else data[start:end]).translate(table).split(b"#")[0].split())
    lines = data.count(b"\n", start) + (not data.endswith(b"\n"))         # rows at most
    hc, hr = h["cols"], h["rows"]
    if hc is not None and hr is not None:
        check_grid_size(hr, hc, where, "crop or resample the scan")
    one_column = cols0 == 1 and hc not in (None, 1) and hr is not None
    if one_column:                                          # one value a line, row by row
        if not hc * hr <= lines <= hc * hr + MAX_HEADER_LINES:
            raise FileFormatError(f"{where}: the header says {hc} x {hr} pixels ({h['dims_text']}), the grid holds "
                                  f"one value a line on {lines} lines")
    else:
        check_grid_size(lines, cols0, where, "crop or resample the scan")
        if hc is not None and cols0 != hc:
            raise FileFormatError(f"{where}: the header says {hc} columns ({h['dims_text']}), the grid's first row "
                                  f"(line {row1}) holds {cols0} values")
        if hr is not None and lines < hr:
            raise FileFormatError(f"{where}: the header says {hr} rows ({h['dims_text']}), the grid has {lines} lines")
    text = data.translate(table)
    del data
    try:
        values = np.loadtxt((line.decode("latin-1") for line in io.BytesIO(text)), dtype=np.float64, comments="#",
                            ndmin=2)
    except ValueError:
        raise _grid_error(text, first, where) from None
    if one_column:
        if values.size != hc * hr:
            raise FileFormatError(f"{where}: the header says {hc} x {hr} pixels ({h['dims_text']}), the grid holds "
                                  f"{values.size} values, one a line")
        values = values.reshape(hr, hc)
    rows, cols = values.shape
    if hr is not None and rows != hr:
        raise FileFormatError(f"{where}: the header says {hr} rows ({h['dims_text']}), the grid has {rows}")
    if hc is None and cols in (2, 3) and rows >= 4 * cols and _point_list(values):
        raise FileFormatError(f"{where}: {rows} lines of {cols} numbers with a steadily growing column: a list of "
                              f"points ({'x y z' if cols == 3 else 'x z'} a line), not a grid of heights; export the "
                              f"scan as a matrix (one row of the map a line)")
    if rows * cols < 2:
        raise FileFormatError(f"{where}: {cols} x {rows} values; a height map needs at least 2 samples")
    bad = ~np.isfinite(values)
    if bad.any():
        r, c = (int(i) for i in np.argwhere(bad)[0])
        line = "" if one_column else f" (line {_line_of_row(text, r, first)})"
        raise FileFormatError(f"{where}: grid row {r + 1}{line}, column {c + 1} holds {values[r, c]}; heights must be "
                              f"finite ({int(bad.sum())} NaN/inf values)")
    return values


def _point_list(values: np.ndarray) -> bool:
    """True when one of the first two columns is a coordinate: it never decreases (or never increases) and
    steps through evenly spaced values (a raster's x or y, repeated along each line), which no column of
    measured heights does; or, of two columns, the first strictly grows or falls (a profile's x)."""
    if values.shape[1] == 2:
        d = np.diff(values[:, 0])
        if np.all(d > 0) or np.all(d < 0):
            return True
    for c in range(min(2, values.shape[1] - 1)):
        col = values[:, c]
        d = np.diff(col)
        if np.ptp(col) > 0 and (np.all(d >= 0) or np.all(d <= 0)):
            steps = np.diff(np.unique(col))
            if steps.size and np.ptp(steps) <= 1e-3 * np.abs(steps).max():
                return True
    return False


def _data_rows(text: bytes):
    """(index of the line, cells) of each row of numbers in ``text``, streamed."""
    for i, line in enumerate(io.BytesIO(text)):
        cells = line.split(b"#")[0].split()
        if cells:
            yield i, cells


def _line_of_row(text: bytes, row: int, first: int) -> int:
    for n, (i, _) in enumerate(_data_rows(text)):
        if n == row:
            return first + i
    return first


def _grid_error(text: bytes, first: int, where: str) -> FileFormatError:
    """The first cell that is not a number, or the first ragged row (the slow path, after the parser failed)."""
    width = None
    for n, (i, cells) in enumerate(_data_rows(text)):
        for c, cell in enumerate(cells):
            if not _is_number(cell):
                return FileFormatError(f"{where}: grid row {n + 1} (line {first + i}), column {c + 1}: "
                                       f"{_decode(cell)[:24]!r} is not a number")
        if width is None:
            width = len(cells)
        elif len(cells) != width:
            return FileFormatError(f"{where}: grid row {n + 1} (line {first + i}) holds {len(cells)} values, row 1 "
                                   f"holds {width}; every row must hold as many (ragged rows)")
    return FileFormatError(f"{where}: the grid is not a table of numbers")


# ----------------------------------------------------------------- Gwyddion Simple Field
def read_gsf(path) -> Scan:
    """Read a Gwyddion Simple Field file (``.gsf``; module docs for the layout).

    Returns
    -------
    Scan
        ``values`` float32 (YRes, XRes) in ``ZUnits``, picture order; the
        size from ``XReal``/``YReal`` in ``XYUnits`` (None without them: the
        format's default of 1 is not a size).

    Raises
    ------
    FileFormatError
        A wrong magic line, a header without its NUL padding, a header line
        that is not ``Name = Value``, missing or bad ``XRes``/``YRes``, a
        file whose length is not header + padding + 4 x XRes x YRes, NaN or
        infinite values. InputError: a grid beyond the size limits.
    """
    path = Path(os.fspath(path))
    where = f"scan '{path}'"
    total = _file_size(path, where)
    with path.open("rb") as f:
        magic = f.read(len(GSF_MAGIC))
        if magic != GSF_MAGIC:
            sonar = b"GSF-v" in magic + f.read(64)      # the sonar Generic Sensor Format shares the suffix
            raise FileFormatError(
                f"{where}: a Generic Sensor Format (sonar bathymetry) file, not a Gwyddion Simple Field; "
                f"shapedisplay reads the SPM format (first line 'Gwyddion Simple Field 1.0')" if sonar else
                f"{where}: not a Gwyddion Simple Field file (its first line must be 'Gwyddion Simple Field 1.0'; "
                f"got {magic[:26]!r})")
        block = f.read(MAX_GSF_HEADER_BYTES)
        end = block.find(b"\0")
        if end < 0:
            raise FileFormatError(
                f"{where}: the file ends before the NUL bytes that close its header (truncated)"
                if len(block) < MAX_GSF_HEADER_BYTES else
                f"{where}: no NUL byte closes the header within {MAX_GSF_HEADER_BYTES} bytes "
                f"(shapedisplay.author.instruments.MAX_GSF_HEADER_BYTES)")
        head = len(GSF_MAGIC) + end
        pad = 4 - head % 4
        if block[end:end + pad] != b"\0" * pad:
            raise FileFormatError(f"{where}: the header ({head} bytes) must be closed by {pad} NUL bytes that bring "
                                  f"the data to a multiple of 4 bytes (got {block[end:end + pad]!r})")
        fields = _gsf_fields(block[:end], where)
        xres, yres = (_gsf_count(fields, k, where) for k in ("XRes", "YRes"))
        check_grid_size(yres, xres, where, "crop or resample the scan")
        want = head + pad + 4 * xres * yres
        if total != want:
            raise FileFormatError(f"{where}: the file holds {total} bytes; header {head} + padding {pad} + "
                                  f"4 x XRes {xres} x YRes {yres} = {want} "
                                  f"({'truncated' if total < want else 'bytes after the data'})")
        f.seek(head + pad)
        values = np.fromfile(f, dtype="<f4", count=xres * yres)
    if values.size != xres * yres:
        raise FileFormatError(f"{where}: the data ends after {values.size} of {xres * yres} values (truncated)")
    values = values.reshape(yres, xres)
    if xres * yres < 2:
        raise FileFormatError(f"{where}: XRes {xres} x YRes {yres}; a height map needs at least 2 samples")
    bad = ~np.isfinite(values)
    if bad.any():
        r, c = (int(i) for i in np.argwhere(bad)[0])
        raise FileFormatError(f"{where}: row {r + 1} (from the top), column {c + 1} holds {values[r, c]}; heights "
                              f"must be finite ({int(bad.sum())} NaN/inf values)")
    notes, size = [], None
    unit = fields.get("XYUnits")
    if "XReal" in fields and "YReal" in fields and unit is not None:
        u = _unit_or_refuse(unit, f"{where}: 'XYUnits = {unit}'", si=True)
        w, h = (_gsf_length(fields, k, u, where) for k in ("XReal", "YReal"))
        size, size_text = (w, h), f"XReal {fields['XReal']} {unit} x YReal {fields['YReal']} {unit}"
    else:                                        # the format's default XReal of 1 is not a size
        size_text = "no XYUnits line" if "XReal" in fields and "YReal" in fields else "no XReal and YReal lines"
    z_unit = z_text = None
    if "ZUnits" in fields:
        z_text = f"ZUnits {fields['ZUnits']}"
        z_unit = _unit_or_refuse(fields["ZUnits"], f"{where}: 'ZUnits = {fields['ZUnits']}'", si=True)
    offsets = [k for k in ("XOffset", "YOffset") if _gsf_float(fields, k, where, 0.0) != 0.0]
    if offsets:
        notes.append(f"{' and '.join(offsets)} not used: the table's corner is at (0, 0)")
    title = fields.get("Title", "")
    return Scan(values, size, size_text, z_unit, z_text or "",
                "Gwyddion Simple Field" + (f", Title {title!r}" if title else ""), notes)


def _gsf_fields(raw: bytes, where: str) -> dict:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{where}: the header is not UTF-8 text (byte {exc.start + len(GSF_MAGIC)})") from None
    lines = text.split("\n")
    if len(lines) > MAX_HEADER_LINES + 1:
        raise FileFormatError(f"{where}: the header has {len(lines)} lines, more than {MAX_HEADER_LINES} "
                              f"(shapedisplay.author.instruments.MAX_HEADER_LINES)")
    fields: dict = {}
    for n, line in enumerate(lines, 2):
        if not line.strip():
            continue
        if "=" not in line:
            raise FileFormatError(f"{where}: header line {n} is not 'Name = Value' (got {line.strip()[:40]!r})")
        key, value = (s.strip() for s in line.split("=", 1))
        if key in fields and fields[key] != value:
            raise FileFormatError(f"{where}: header line {n} gives {key} again ({fields[key]!r}, then {value!r})")
        fields[key] = value
    return fields


def _gsf_count(fields: dict, key: str, where: str) -> int:
    if key not in fields:
        raise FileFormatError(f"{where}: the header lacks the mandatory '{key} = N' line")
    v = fields[key]
    if not v.isdigit() or int(v) < 1:
        raise FileFormatError(f"{where}: {key} must be a whole number >= 1 (got {v!r})")
    return int(v)


def _gsf_float(fields: dict, key: str, where: str, default: float) -> float:
    if key not in fields:
        return default
    try:
        v = float(fields[key])
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise FileFormatError(f"{where}: {key} must be a finite number (got {fields[key]!r})")
    return v


def _gsf_length(fields: dict, key: str, unit: str, where: str) -> float:
    v = _gsf_float(fields, key, where, math.nan)
    if not v > 0:
        raise FileFormatError(f"{where}: {key} must be a length > 0 (got {fields[key]!r})")
    return v * LENGTH_UNITS[unit]


def _file_size(path: Path, where: str) -> int:
    if not path.is_file():
        raise FileFormatError(f"{where}: no such file")
    return path.stat().st_size


# ----------------------------------------------------------------- height field
def read_scan(path) -> Scan:
    """Read an instrument file by its suffix: ``.txt`` (:func:`read_text_export`) or ``.gsf`` (:func:`read_gsf`)."""
    suffix = Path(os.fspath(path)).suffix.lower()
    if suffix == ".gsf":
        return read_gsf(path)
    if suffix == ".txt":
        return read_text_export(path)
    raise InputError(f"scan '{path}': unknown suffix {suffix!r}; instrument files: {', '.join(SCAN_SUFFIXES)}")


def load_scan(path, size=None, height_range=None, *, resolution=None, channel=None, z_units=None,
              flags: dict | None = None) -> HeightField:
    """Height field from an instrument file, with the size and z unit the file states.

    Parameters
    ----------
    path : path-like
        A text export (``.txt``) or a Gwyddion Simple Field file (``.gsf``).
    size : (width, height) m or str "10x10um", optional
        Physical size of the whole scan. Must equal the file's when it
        states one (to 1 part in 10^6); needed when it does not.
    height_range : (low, high) m or str "0:2mm", optional
        The data's min..max fitted onto this range; None keeps the file's
        heights, converted from its z unit to metres.
    resolution : float (m) or str, optional
        Pixel size (dx = dy) instead of ``size``; must match the file's.
    channel : None
        Refused: an instrument file holds one height channel.
    z_units : {"m", "mm", "um", "nm", ...}, optional
        Unit of the heights (:data:`LENGTH_UNITS`); must equal the file's
        when it states one, needed when it does not (unless ``height_range``).
    flags : dict, optional
        How the caller spells an option in messages (``{"size": "--size"}``).

    Returns
    -------
    HeightField
        Shape (rows, cols) of the grid; pixel (r, c) of the file at
        ``x = (c + 0.5) dx``, ``y = (rows - r - 0.5) dy``. ``meta``: ``kind``
        "scan", ``file``, ``size_m``, ``scale`` (file unit -> metres),
        ``notes``, ``instrument``.
    """
    path = Path(os.fspath(path))
    where = f"scan '{path}'"
    flag = (flags or {}).get
    if channel is not None:
        raise InputError(f"`{flag('channel', 'channel')}` applies to colour pictures, not to {where} "
                         f"(an instrument file holds one height channel)")
    if size is not None:
        w, h = parse_size(size, flag("size", "size"))
    if resolution is not None:
        r = _length_m(resolution, flag("resolution", "resolution"))
    if size is not None and resolution is not None:
        raise InputError(f"{where}: give `{flag('size', 'size')}` or `{flag('resolution', 'resolution')}`, not both "
                         f"(got {_len_text(w, h)} and {_len_text(r)})")
    scan = read_scan(path)
    rows, cols = scan.values.shape
    if scan.size_m is not None:                 # the file's size; an option may only repeat it
        fw, fh = scan.size_m
        if size is not None and not (math.isclose(w, fw, rel_tol=1e-6) and math.isclose(h, fh, rel_tol=1e-6)):
            raise InputError(f"`{flag('size', 'size')}` {_len_text(w, h)} contradicts '{path}' ({scan.size_text})")
        if resolution is not None and not (math.isclose(r, fw / cols, rel_tol=1e-6)
                                           and math.isclose(r, fh / rows, rel_tol=1e-6)):
            px = _len_text(fw / cols) if math.isclose(fw / cols, fh / rows, rel_tol=1e-6) else \
                _len_text(fw / cols, fh / rows)
            raise InputError(f"`{flag('resolution', 'resolution')}` {_len_text(r)} contradicts '{path}' "
                             f"({scan.size_text}: {px} a pixel over {cols} x {rows} pixels)")
        w, h = fw, fh
    elif resolution is not None:
        w, h = cols * r, rows * r
    elif size is None:
        raise InputError(f"{where} does not state its physical size "
                         f"({scan.size_text or 'no Real Width / Scan Size / XReal line'}); give "
                         f"`{flag('size', 'size')}` (width x height, e.g. 10x10um) or "
                         f"`{flag('resolution', 'resolution')}`")
    dx, dy = w / cols, h / rows
    unit = scan.z_unit
    if z_units is not None:
        given = length_unit(str(z_units))
        if given is None:
            raise InputError(f"`{flag('z_units', 'z_units')}` must be a length unit ({', '.join(LENGTH_UNITS)}) "
                             f"(got {z_units!r})")
        if unit is not None and LENGTH_UNITS[given] != LENGTH_UNITS[unit]:
            raise InputError(f"`{flag('z_units', 'z_units')}` {z_units} contradicts '{path}' ({scan.z_text})")
        unit = unit or given
    hr = None if height_range is None else _height_range(height_range)
    values = grid_from_picture(scan.values)
    if hr is not None:
        heights, a, b, rule = fit_range(values, hr, where, unit=unit or "")
        scale = height_scale(unit or "file unit", a, b, rule)
    elif unit is None:
        raise InputError(f"{where} does not state the unit of its heights (no Z Unit / ZUnits line); give "
                         f"`{flag('z_units', 'z_units')}` (e.g. nm) or `{flag('height', 'height_range')}`")
    else:
        per = LENGTH_UNITS[unit]
        heights = values.astype(np.float64)
        heights *= per
        scale = height_scale(unit, per, 0.0, f"data in {unit}" + (f" ({scan.z_text})" if scan.z_text else ""))
    notes = [f"size {_len_text(w, h)} from the file ({scan.size_text})" if scan.size_m is not None else
             f"size {_len_text(w, h)} from the options"] + list(scan.notes)
    desc = f"{path.name} {cols}x{rows} px ({scan.description}), {_len_text(w, h)}"
    if hr is not None:
        desc += f", h {hr[0] * 1e3:g}..{hr[1] * 1e3:g} mm"
    elif unit is not None:
        desc += f", z in {unit}"
    return HeightField(heights, dx, dy, 0.5 * dx, 0.5 * dy, desc,
                       {"kind": "scan", "file": str(path), "size_m": [w, h],
                        "height_range_m": None if hr is None else list(hr), "scale": scale, "notes": notes,
                        "instrument": scan.description, "z_unit": unit})


def _length_m(value, name: str) -> float:
    from shapedisplay.units import parse_quantity
    if isinstance(value, str):
        return check_spacing(parse_quantity(value, "m", name), name)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"`{name}` must be a length in metres or a string with its unit (got {value!r})") from None
    return check_spacing(v, name)
