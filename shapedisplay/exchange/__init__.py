"""Exchange formats: tables and played strokes in the formats other tools read.

Table exports (:func:`export_table`, ``shapedisplay export TABLE --format F``):

======================  ==========================================================
``json``                dense SI channels, metadata, widget map and toggle states
``c``                   C99 header for firmware, enough on its own (toggles,
                        widget map, every runtime constant, ``NAME_bind``)
``bin``                 binary table image: flat, little-endian, CRC-32; the C
                        runtime loads it in place (docs/table-image.md)
``glb``                 glTF 2.0 binary: the surface as a mesh, stiffness (N),
                        friction (mu) and vibration (B) as 16-bit textures
                        under ``MPEG_haptic_material`` (:mod:`.glb`)
``friction-png``        8/16-bit grey PNG of mu, N or mu_s*N (top view) and a
                        sidecar JSON of the scale (:mod:`.friction_png`)
======================  ==========================================================

Every export is written atomically and reads only the verified table.
"""
from __future__ import annotations

import os
from pathlib import Path

from shapedisplay.errors import InputError, unknown_key

#: Export format -> ("module:function", options it takes); modules are imported only when used.
EXPORTERS = {
    "json": ("shapedisplay.exchange.export:export_json", ()),
    "c": ("shapedisplay.exchange.export:export_c", ("name",)),
    "bin": ("shapedisplay.render.image:export_image", ()),
    "friction-png": ("shapedisplay.exchange.friction_png:export_friction_png", ("quantity", "bits")),
    "glb": ("shapedisplay.exchange.glb:export_glb", ()),
}
FORMATS = tuple(EXPORTERS)


def export_table(table, path: str | os.PathLike, fmt: str, name: str | None = None, **options) -> Path:
    """Export ``table`` to ``path`` in format ``fmt`` (a key of :data:`EXPORTERS`).

    ``name`` is the C symbol prefix (format ``c``; default the file stem);
    ``options`` are the format's own (friction-png: ``quantity``, ``bits``).
    An option given to a format that does not take it is refused.
    """
    import importlib
    if fmt not in EXPORTERS:
        raise unknown_key("export format", fmt, FORMATS)
    target, takes = EXPORTERS[fmt]
    given = {k: v for k, v in dict(options, name=name).items() if v is not None}
    for k in given:
        if k not in takes:
            users = [f for f, (_, t) in EXPORTERS.items() if k in t]
            raise InputError(f"`--{k}` applies to --format {' or '.join(users)}, not to --format {fmt}")
    mod, func = target.split(":")
    return getattr(importlib.import_module(mod), func)(table, path, **given)
