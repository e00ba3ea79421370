"""A .glb with shapedisplay's haptic textures as a source: read its textures back and compile them.

:mod:`shapedisplay.exchange.glb` writes such files (``export --format glb``);
this module reads them: :func:`has_haptic_textures` tells one from a plain
mesh, :func:`read_haptic_glb` gives the three textures as SI arrays on the
table grid and :func:`compile_haptic_glb` rebuilds a table from them
(``compile model.glb``). Every size is checked before it is allocated.
"""
from __future__ import annotations

import io
import json
import math
import os
import struct
from pathlib import Path

import numpy as np

from shapedisplay.errors import FileFormatError, InputError
from shapedisplay.author.heightfield import grid_from_picture

EXTENSION = "MPEG_haptic_material"
#: texture name -> (quantity, unit)
TEXTURES = {"stiffness": ("normal_force", "N"), "friction": ("mu", "1"), "vibration": ("burst_amplitude_per_n", "1/N")}
MAX_GLB_BYTES = 512 * 1024 * 1024
MAX_TEXELS = 64_000_000


def _mapping(meta: dict):
    from shapedisplay.author.forces import MappingOptions
    mp = meta.get("mapping") if isinstance(meta, dict) else None
    return MappingOptions.from_json(mp) if isinstance(mp, dict) else None


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


def refuse_geometry_options(path, flags: dict | None = None, **given) -> None:
    """Refuse geometry options (``size``, ``resolution``, ``up`` ...) for a glb whose textures set the grid.

    ``flags`` spells an option as the caller wrote it (default: its name).
    """
    for name, value in given.items():
        if value is not None:
            flag = (flags or {}).get(name, name)
            raise InputError(f"`{flag}` does not apply to '{path}': its haptic textures set the grid")


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
