"""Where in a scene file an error points: its line number, for the studio's editor.

Scene errors name the place the way the file is written: a TOML syntax error
says "at line 12, column 5"; a validation error names the widget
(``widget[3] 'app-4'``) and the field in backticks (```size```,
```canvas.size```, ```defaults.button.ramp```). :func:`error_line` maps
such a message back to the line that holds the field, by reading the text's
table headers and keys (one line per key; the studio does not need a full TOML
parser for this, and a value spanning several lines still starts on the key's
line).
"""
from __future__ import annotations

import re

_HEADER = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.\-\" ]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\"]+(?:\s*\.\s*[A-Za-z0-9_\-\"]+)*)\s*=")
_AT_LINE = re.compile(r"at line (\d+)")
_WIDGET = re.compile(r"widget\[(\d+)\]")
_FIELD = re.compile(r"`([^`]+)`")


def key_lines(text: str) -> dict:
    """Map each key of a TOML text to its 1-based line.

    Keys are ``(section, index, dotted_key)``: ``section`` is the dotted table
    name (``""`` at the top), ``index`` the position of an array-of-tables
    entry (``[[widget]]`` number 0, 1, ...) or None for a plain table. Table
    headers themselves are stored with the key ``""``.
    """
    lines: dict = {}
    section, index = "", None
    counts: dict = {}
    for no, raw in enumerate(text.splitlines(), start=1):
        m = _HEADER.match(raw)
        if m and not _KEY.match(raw):
            name = m.group(2).replace('"', "").replace(" ", "")
            if m.group(1) == "[[":
                index = counts.get(name, 0)
                counts[name] = index + 1
            else:
                index = None
            section = name
            lines.setdefault((section, index, ""), no)
            continue
        k = _KEY.match(raw)
        if k:
            key = re.sub(r"\s*\.\s*", ".", k.group(1)).replace('"', "")
            lines.setdefault((section, index, key), no)
    return lines


def error_line(text: str, message: str) -> int | None:
    """The 1-based line of ``text`` that the scene error ``message`` points at, or None."""
    m = _AT_LINE.search(message)
    if m:
        return int(m.group(1))
    lines = key_lines(text)
    w = _WIDGET.search(message)
    fields = [re.sub(r"^widget\[\d+\]\.", "", f) for f in _FIELD.findall(message) if not f.startswith("[")]
    field = fields[0] if fields else ""
    if w:
        i = int(w.group(1))
        for cand in _suffixes(field):
            if ("widget", i, cand) in lines:
                return lines[("widget", i, cand)]
        # a value the widget took from [defaults] or [defaults.TYPE]
        inherited = sorted(no for (sec, idx, key), no in lines.items()
                           if idx is None and sec.split(".")[0] == "defaults" and key == field)
        if field and inherited:
            return inherited[-1]
        return lines.get(("widget", i, ""))
    if field:
        parts = field.split(".")
        # longest table name first: `defaults.button.ramp` is key `ramp` of [defaults.button]
        for cut in range(len(parts) - 1, -1, -1):
            sec, key = ".".join(parts[:cut]), ".".join(parts[cut:])
            if (sec, None, key) in lines:
                return lines[(sec, None, key)]
        if (field, None, "") in lines:          # the error names a whole table
            return lines[(field, None, "")]
    return None


def _suffixes(field: str):
    """`a.b.c` -> `a.b.c`, `b.c`, `c` (a widget field may be named with or without its prefix)."""
    parts = field.split(".") if field else []
    for k in range(len(parts)):
        yield ".".join(parts[k:])
