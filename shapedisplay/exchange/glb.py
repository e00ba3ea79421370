"""glTF 2.0 binary (.glb) with haptic textures under the ``MPEG_haptic_material`` extension.

:func:`export_glb` (``shapedisplay export TABLE --format glb``) writes

* the height field as one triangle mesh: a vertex at every table sample
  centre, ``(x, y, h)`` in metres — x to the right, y up the screen, the
  height toward the viewer (+z), so a glTF viewer looking down -z sees the
  top view; heights come from N through the table's height mapping,
  ``h = (N - n_base) / n_gain`` (flat where the mapping is not linear in
  height); ``TEXCOORD_0`` puts each texel centre on its sample;
* three 16-bit grey PNG textures (image row 0 = largest y, the top view),
  each scaled to the full range, referenced from the file-level
  ``MPEG_haptic_material`` material and from the mesh:

  ========================  ====================================================
  ``stiffness``             normal force N, N (what pushes back on the finger)
  ``friction``              static friction coefficient mu_s at rest
  ``vibration``             burst amplitude per newton of breakaway force,
                            B * burst_gain, 1/N
  ========================  ====================================================

  Each texture item's ``extras`` gives the scale to SI:
  ``value = offset + scale * texel`` with ``unit``, ``quantity``, ``bits``,
  ``max_error``. The root ``extras.shapedisplay`` carries the table grid,
  mapping, device and checksum, so :func:`read_haptic_glb` (and ``compile
  model.glb``) can rebuild the table's channels.

glTF mandates metres; the file validates against the Khronos schema of the
extension (tests). Reading one back (``compile model.glb``) is
:mod:`shapedisplay.author.glb`'s. What a glb loses: see the project's exchange notes
(stick-slip dynamics, direction-dependent slope friction, lateral and
skin-stretch channels, toggle states other than the current one).
"""
from __future__ import annotations

import io
import json
import os
import struct
from pathlib import Path

import numpy as np

from shapedisplay.atomic import write_bytes
from shapedisplay.errors import InputError
from shapedisplay.author.glb import EXTENSION, MAX_TEXELS, TEXTURES
from shapedisplay.author.heightfield import picture_from_grid

#: Haptic texture -> (quantity, unit): the textures written, in this order.
#: Largest .glb read (bytes) and largest texture (pixels).

_FLOAT, _UINT = 5126, 5125


def _mapping(meta: dict):
    from shapedisplay.author.forces import MappingOptions
    mp = meta.get("mapping") if isinstance(meta, dict) else None
    return MappingOptions.from_json(mp) if isinstance(mp, dict) else None


def haptic_channels(table) -> dict:
    """The three texture quantities on the canvas, (rows, cols), SI, row r at y0 + r*dy."""
    from shapedisplay.exchange.export import device_of
    from shapedisplay.exchange.friction_png import quantity_map
    dev = device_of(table.meta)
    gain = table.dense("burst_gain") if "burst_gain" in table.channels else np.ones((table.grid.rows, table.grid.cols))
    return {"stiffness": quantity_map(table, "normal_force"), "friction": quantity_map(table, "mu"),
            "vibration": dev.burst.gain * gain}


def heights_of(table, n: np.ndarray) -> tuple[np.ndarray, str]:
    """Heights (m) from N through the table's mapping, and how they were found."""
    mp = _mapping(table.meta)
    try:
        return mp.height_of_force(n), f"h = (N - n_base) / n_gain, n_base {mp.n_base:g} N, n_gain {mp.n_gain:g} N/m"
    except (InputError, AttributeError):
        return np.zeros_like(n), "flat: the table's mapping is not linear in height"


def _png16(values: np.ndarray) -> tuple[bytes, dict]:
    from PIL import Image
    lo, hi = float(values.min()), float(values.max())
    scale = (hi - lo) / 65535 if hi > lo else 0.0
    grey = np.zeros(values.shape) if scale == 0 else np.rint((values - lo) / scale)
    img = picture_from_grid(np.clip(grey, 0, 65535).astype(np.uint16))
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")
    return buf.getvalue(), {"scale": scale, "offset": lo, "min": lo, "max": hi, "max_error": scale / 2,
                            "bits": 16, "rule": "value = offset + scale * texel"}


def glb_document(table) -> tuple[dict, bytes]:
    """The glTF JSON and binary chunk of :func:`export_glb`."""
    g = table.grid
    rows, cols = g.rows, g.cols
    if rows * cols > MAX_TEXELS:
        raise InputError(f"glb export: {cols} x {rows} samples exceed the {MAX_TEXELS:,}-texel limit")
    chans = haptic_channels(table)
    h, how = heights_of(table, chans["stiffness"])
    r, c = np.mgrid[0:rows, 0:cols]
    pos = np.stack([g.x0 + c * g.dx, g.y0 + r * g.dy, h], axis=-1).reshape(-1, 3).astype(np.float32)
    uv = np.stack([(c + 0.5) / cols, (rows - 1 - r + 0.5) / rows], axis=-1).reshape(-1, 2).astype(np.float32)
    if rows > 1 and cols > 1:
        i = (r[:-1, :-1] * cols + c[:-1, :-1]).ravel()
        tri = np.stack([i, i + 1, i + cols + 1, i, i + cols + 1, i + cols], axis=-1).reshape(-1, 3)
    else:                                  # a 1-D table: a strip one sample wide, extruded by one spacing
        raise InputError("glb export needs a 2-D table (at least 2 x 2 samples); a 1-D table has no surface")
    idx = tri.astype(np.uint32).ravel()

    blobs, views = [], []

    def add(data: bytes, target=None):
        off = sum(len(b) for b in blobs)
        pad = (-off) % 4
        if pad:
            blobs.append(b"\0" * pad)
            off += pad
        blobs.append(data)
        v = {"buffer": 0, "byteOffset": off, "byteLength": len(data)}
        if target:
            v["target"] = target
        views.append(v)
        return len(views) - 1

    v_pos = add(pos.astype("<f4").tobytes(), 34962)
    v_uv = add(uv.astype("<f4").tobytes(), 34962)
    v_idx = add(idx.astype("<u4").tobytes(), 34963)
    accessors = [
        {"bufferView": v_pos, "componentType": _FLOAT, "count": int(pos.shape[0]), "type": "VEC3",
         "min": pos.min(axis=0).astype(float).tolist(), "max": pos.max(axis=0).astype(float).tolist()},
        {"bufferView": v_uv, "componentType": _FLOAT, "count": int(uv.shape[0]), "type": "VEC2"},
        {"bufferView": v_idx, "componentType": _UINT, "count": int(idx.size), "type": "SCALAR"},
    ]
    images, textures, haptic = [], [], {}
    for k, (name, (quantity, unit)) in enumerate(TEXTURES.items()):
        png, scale = _png16(chans[name])
        images.append({"bufferView": add(png), "mimeType": "image/png", "name": name})
        textures.append({"source": k, "sampler": 0, "name": name})
        haptic[name] = [{"texture": {"index": k, "texCoord": 0}, "type": "High_Resolution",
                         "extras": dict(scale, quantity=quantity, unit=unit)}]
    binary = b"".join(blobs)
    binary += b"\0" * ((-len(binary)) % 4)
    mp = table.meta.get("mapping", {}) if isinstance(table.meta, dict) else {}
    doc = {
        "asset": {"version": "2.0", "generator": "shapedisplay"},
        "extensionsUsed": [EXTENSION],
        "extensions": {EXTENSION: {"materials": [dict(haptic, name="shapedisplay table")]}},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "surface"}],
        "meshes": [{"name": "surface", "primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1},
                                                       "indices": 2, "material": 0, "mode": 4}],
                    "extensions": {EXTENSION: {"hapticMaterialIndex": 0}}}],
        "materials": [{"name": "surface", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0],
                                                                  "metallicFactor": 0.0, "roughnessFactor": 0.9},
                       "doubleSided": True}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
        "images": images,
        "textures": textures,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary)}],
        "extras": {"shapedisplay": {
            "format": "shapedisplay-haptic-glb-1", "table_checksum": table.checksum,
            "grid": g.to_json(), "heights": how, "mapping": mp,
            "device": table.meta.get("device") if isinstance(table.meta, dict) else None,
            "orientation": "x right, y up the screen, height +z (metres); textures are the top view "
                           "(image row 0 = largest y)"}},
    }
    return doc, binary


def glb_bytes(doc: dict, binary: bytes) -> bytes:
    js = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")
    js += b" " * ((-len(js)) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(js), b"JSON") + js
            + struct.pack("<I4s", len(binary), b"BIN\0") + binary)


def export_glb(table, path: str | os.PathLike) -> Path:
    """Write ``table`` as a .glb with haptic textures (module docs), atomically."""
    doc, binary = glb_document(table)
    write_bytes(path, glb_bytes(doc, binary))
    return Path(path)


# ------------------------------------------------------------------ reading
