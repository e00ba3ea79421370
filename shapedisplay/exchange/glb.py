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
extension (tests). What a glb loses: see the project's exchange notes
(stick-slip dynamics, direction-dependent slope friction, lateral and
skin-stretch channels, toggle states other than the current one).
"""
from __future__ import annotations

import io
import json
import math
import os
import struct
from pathlib import Path

import numpy as np

from shapedisplay.atomic import write_bytes
from shapedisplay.errors import FileFormatError, InputError
from shapedisplay.author.heightfield import grid_from_picture, picture_from_grid

EXTENSION = "MPEG_haptic_material"
#: Haptic texture -> (quantity, unit): the textures written, in this order.
TEXTURES = {"stiffness": ("normal_force", "N"), "friction": ("mu", "1"), "vibration": ("burst_amplitude_per_n", "1/N")}
#: Largest .glb read (bytes) and largest texture (pixels).
MAX_GLB_BYTES = 512 * 1024 * 1024
MAX_TEXELS = 64_000_000

_FLOAT, _UINT = 5126, 5125


def _mapping(meta: dict):
    from shapedisplay.author.forces import MappingOptions
    mp = meta.get("mapping") if isinstance(meta, dict) else None
    return MappingOptions.from_json(mp) if isinstance(mp, dict) else None


def haptic_channels(table) -> dict:
    """The three texture quantities on the canvas, (rows, cols), SI, row r at y0 + r*dy."""
    from shapedisplay.exchange.export import _device_of
    from shapedisplay.exchange.friction_png import quantity_map
    dev = _device_of(table.meta)
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
            "format": "shapedisplay-haptic-glb-1", "table_checksum": table.checksum(),
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
def read_glb(path: str | os.PathLike) -> tuple[dict, bytes]:
    """The JSON document and binary chunk of a .glb, sizes checked before reading."""
    path = Path(path)
    where = f"glb '{path}'"
    try:
        size = path.stat().st_size
        if size > MAX_GLB_BYTES:
            raise FileFormatError(f"{where}: {size} bytes exceed the {MAX_GLB_BYTES}-byte limit")
        data = path.read_bytes()
    except OSError as exc:
        raise FileFormatError(f"{where}: cannot read ({exc.strerror or exc})") from None
    if len(data) < 20 or data[:4] != b"glTF":
        raise FileFormatError(f"{where}: not a binary glTF (no 'glTF' magic)")
    version, total = struct.unpack_from("<II", data, 4)
    if version != 2 or total != len(data):
        raise FileFormatError(f"{where}: glTF version {version}, declared length {total} (file {len(data)} bytes)")
    off, chunks = 12, {}
    while off + 8 <= len(data):
        n, kind = struct.unpack_from("<I4s", data, off)
        if off + 8 + n > len(data):
            raise FileFormatError(f"{where}: chunk {kind!r} of {n} bytes runs past the end of the file")
        chunks.setdefault(kind, data[off + 8:off + 8 + n])
        off += 8 + n               # chunk lengths include their padding to 4 bytes
    if b"JSON" not in chunks:
        raise FileFormatError(f"{where}: no JSON chunk")
    try:
        doc = json.loads(chunks[b"JSON"].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FileFormatError(f"{where}: JSON chunk is not valid JSON ({exc})") from None
    if not isinstance(doc, dict):
        raise FileFormatError(f"{where}: JSON chunk must be an object")
    return doc, chunks.get(b"BIN\0", b"")


def has_haptic_textures(path) -> bool:
    """True when ``path`` is a .glb written with shapedisplay's haptic textures."""
    if Path(path).suffix.lower() != ".glb":
        return False
    doc, _ = read_glb(path)
    return EXTENSION in (doc.get("extensions") or {}) and \
        isinstance((doc.get("extras") or {}).get("shapedisplay"), dict)


def refuse_geometry_options(path, **given) -> None:
    """Refuse geometry options (``size``, ``resolution``, ``up`` ...) for a glb whose textures set the grid."""
    for name, value in given.items():
        if value is not None:
            raise InputError(f"`--{name.replace('_', '-')}` does not apply to '{path}': its haptic textures set "
                             f"the grid")


def read_haptic_glb(path) -> dict:
    """The haptic textures of a .glb as SI arrays on the table grid.

    Returns
    -------
    dict with ``grid`` (:class:`~shapedisplay.table.model.Grid`), ``channels``
    {stiffness, friction, vibration: ndarray (rows, cols), row r at y0 + r*dy},
    ``scales`` {name: extras}, ``mapping`` and ``device`` (dicts or None),
    ``heights`` (ndarray from the mesh's z on the same grid).
    """
    from PIL import Image

    from shapedisplay.table.model import Grid
    doc, binary = read_glb(path)
    where = f"glb '{path}'"
    ext = (doc.get("extensions") or {}).get(EXTENSION)
    info = (doc.get("extras") or {}).get("shapedisplay")
    if not isinstance(ext, dict) or not isinstance(info, dict):
        raise FileFormatError(f"{where}: no {EXTENSION} material with shapedisplay scales in extras")
    try:
        grid = Grid.from_json(info["grid"])
    except (KeyError, TypeError, ValueError) as exc:
        raise FileFormatError(f"{where}: extras.shapedisplay.grid is malformed ({exc})") from None
    if not (0 < grid.rows * grid.cols <= MAX_TEXELS and grid.dx > 0 and grid.dy > 0
            and all(math.isfinite(v) for v in (grid.dx, grid.dy, grid.x0, grid.y0))):
        raise FileFormatError(f"{where}: grid {grid} is out of range")
    mats = ext.get("materials")
    if not (isinstance(mats, list) and mats and isinstance(mats[0], dict)):
        raise FileFormatError(f"{where}: {EXTENSION}.materials must list at least one material")
    views = doc.get("bufferViews") or []

    def view_bytes(i):
        try:
            v = views[i]
            a, n = int(v.get("byteOffset", 0)), int(v["byteLength"])
        except (IndexError, KeyError, TypeError, ValueError):
            raise FileFormatError(f"{where}: bufferView {i!r} is malformed") from None
        if a < 0 or n < 0 or a + n > len(binary):
            raise FileFormatError(f"{where}: bufferView {i} ({a}+{n}) lies outside the {len(binary)}-byte buffer")
        return binary[a:a + n]

    channels, scales = {}, {}
    for name in TEXTURES:
        items = mats[0].get(name)
        if not items:
            continue
        item = items[0]
        sc = item.get("extras") or {}
        try:
            tex = doc["textures"][item["texture"]["index"]]
            img = doc["images"][tex["source"]]
            scale, offset = float(sc["scale"]), float(sc["offset"])
        except (KeyError, IndexError, TypeError, ValueError) as exc:
            raise FileFormatError(f"{where}: {name} texture or its extras scale is malformed ({exc})") from None
        if not (math.isfinite(scale) and math.isfinite(offset) and scale >= 0):
            raise FileFormatError(f"{where}: {name} scale {scale!r}/offset {offset!r} must be finite, scale >= 0")
        blob = view_bytes(img.get("bufferView"))
        try:
            with Image.open(io.BytesIO(blob)) as im:
                if im.size != (grid.cols, grid.rows):
                    raise FileFormatError(f"{where}: {name} texture is {im.size[0]} x {im.size[1]} px, the grid "
                                          f"{grid.cols} x {grid.rows} samples")
                texel = np.array(im)
        except FileFormatError:
            raise
        except Exception as exc:   # Pillow raises several types for damaged images
            raise FileFormatError(f"{where}: {name} texture is not a readable PNG ({exc})") from None
        channels[name] = offset + scale * grid_from_picture(texel).astype(np.float64)
        scales[name] = sc
    if "stiffness" not in channels:
        raise FileFormatError(f"{where}: no stiffness texture (the normal force) to compile from")
    return {"grid": grid, "channels": channels, "scales": scales, "mapping": info.get("mapping"),
            "device": info.get("device")}


def compile_haptic_glb(path, device=None, mapping=None, options=None):
    """Compile a .glb with haptic textures (``compile model.glb``).

    The stiffness texture gives N on the texture grid; heights follow from
    N through the height mapping (the file's own, ``mapping`` overrides it),
    so the compiled N reproduces the texture within its quantization. A
    friction texture that varies becomes the ``friction_scale`` channel
    (mu / the device's mu_s), a vibration texture that varies the
    ``burst_gain`` channel (amplitude / the device's B).

    Returns
    -------
    CompileResult
    """
    from shapedisplay.author.compile import CompileOptions, compile_heightfield
    from shapedisplay.table.devices import DeviceProfile, load_device
    from shapedisplay.author.forces import MappingOptions
    from shapedisplay.author.heightfield import HeightField
    from shapedisplay.table.model import FrictionTable, choose_quantization
    got = read_haptic_glb(path)
    g = got["grid"]
    if mapping is None:
        mapping = MappingOptions.from_json(got["mapping"]) if isinstance(got["mapping"], dict) else MappingOptions()
    if device is None:
        device = DeviceProfile.from_json(got["device"]) if isinstance(got["device"], dict) else load_device(None)
    elif not isinstance(device, DeviceProfile):
        device = load_device(device)
    options = options or CompileOptions()
    n = got["channels"]["stiffness"]
    h = mapping.height_of_force(n)
    hf = HeightField(h, g.dx, g.dy, g.x0, g.y0, source=f"glb {path} (stiffness texture through the height mapping)")
    res = compile_heightfield(hf, device, mapping, options)
    extra = {}
    mu = got["channels"].get("friction")
    if mu is not None and float(mu.max() - mu.min()) > got["scales"]["friction"].get("max_error", 0) * 2:
        extra["friction_scale"] = mu / device.friction.mu_s
    vib = got["channels"].get("vibration")
    if vib is not None and device.burst.gain > 0 and \
            float(vib.max() - vib.min()) > got["scales"]["vibration"].get("max_error", 0) * 2:
        extra["burst_gain"] = vib / device.burst.gain
    if not extra:
        res.report["glb_textures"] = "stiffness used (N); friction and vibration uniform: device values"
        return res
    t = res.table
    dense = {name: t.dense(name) for name in t.channels}
    quant = dict(t.quant)
    for name, v in extra.items():
        dense[name] = v
        quant[name] = choose_quantization(v, "uint16")
    table = FrictionTable.from_dense(t.grid, dense, quant, t.meta)
    res.report["glb_textures"] = ("stiffness used (N); " + ", ".join(
        f"{k} from the {'friction' if k == 'friction_scale' else 'vibration'} texture" for k in extra))
    table.meta["report"] = res.report
    return type(res)(table, res.report)
