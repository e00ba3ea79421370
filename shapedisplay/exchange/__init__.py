"""Exchange formats: tables and played strokes in the formats other tools read.

Table exports (:func:`export_table`, ``shapedisplay export TABLE --format F``):

======================  ==========================================================
``json``                dense SI channels, metadata, widget map and toggle states
``c``                   C99 header for firmware, enough on its own (toggles,
                        widget map, every runtime constant, ``NAME_bind``)
``bin``                 binary table image: flat, little-endian, CRC-32; the C
                        runtime loads it in place (docs/table-image.md)
======================  ==========================================================

Every export is written atomically and reads only the verified table.
"""
from __future__ import annotations

import os
from pathlib import Path

from ..errors import unknown_key

#: Export format -> "module:function" (imported only when used).
EXPORTERS = {
    "json": "shapedisplay.export:export_json",
    "c": "shapedisplay.export:export_c",
    "bin": "shapedisplay.runtime.image:export_image",
}
FORMATS = tuple(EXPORTERS)


def export_table(table, path: str | os.PathLike, fmt: str, name: str | None = None) -> Path:
    """Export ``table`` to ``path`` in format ``fmt`` (a key of :data:`EXPORTERS`).

    ``name`` is the C symbol prefix (format ``c`` only; default the file stem).
    """
    import importlib
    if fmt not in EXPORTERS:
        raise unknown_key("export format", fmt, FORMATS)
    mod, func = EXPORTERS[fmt].split(":")
    fn = getattr(importlib.import_module(mod), func)
    return fn(table, path, name) if fmt == "c" else fn(table, path)
