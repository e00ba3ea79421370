"""The flat binary table image: a friction-envelope table as firmware and WebAssembly load it.

One little-endian byte string, versioned and closed by a CRC-32, that the C
runtime (``engine/sd_image.c``) validates and binds in place — no parsing
into new memory, no allocation: firmware receiving a table over the serial
link, the WebAssembly module in the studio and the device emulator all load
it this way. The layout is documented field by field in ``docs/table-image.md``;
:data:`HEADER` below is its one definition on the Python side.

The image carries everything the renderer needs: the grid, the blocks that
place stored patches on the canvas, a coarse tile index of the blocks (O(1)
lookup), every stored renderer channel's codes with scale/offset/background,
the renderer settings resolved from the table's device profile and mapping
(pad, friction, burst, tick and audio rates), the reactive widgets of a
scene table (version 2: :mod:`shapedisplay.render.reactions`) and the table file's own JSON
header, so :func:`read_image` gives back the same
:class:`~shapedisplay.table.model.FrictionTable` (same checksum). A table
without reactive widgets is written as version 1, byte for byte as before;
both versions are read.
"""
from __future__ import annotations

import json
import os
import struct
import zlib
from pathlib import Path

import numpy as np

from shapedisplay.atomic import write_bytes
from shapedisplay.errors import TableError
from shapedisplay.table.container import parse_json
from shapedisplay.table.model import HEADER_MAX_BYTES, FrictionTable, array_caps
# the image's channel slots, in order, are the renderer's (C's SD_SLOT_*): part of the format, so
# reordering them needs a new VERSION (layouts imports no compiled kernel)
from shapedisplay.render.layouts import SLOTS

MAGIC = b"SDTI"
#: The version written for a table with reactive widgets (its header ends in the reaction section's place);
#: a table without them is written as version 1. Both are read.
VERSION = 2
VERSIONS = (1, 2)
#: Largest image the runtime accepts (bytes); sizes are 32-bit fields.
MAX_IMAGE_BYTES = 1 << 30
#: Tiles of the block index: at most this many, and at most 4 per block (plus one).
MAX_TILES = 4096

#: Renderer settings stored in the image, in order (SI units); the C enum SD_IP_* follows it.
PARAMS = ("pad_mass_kg", "pad_stiffness_n_per_m", "pad_damping_ns_per_m", "burst_gain", "max_stick_period_s",
          "mu_s", "mu_k", "slope_friction_gain", "skin_stretch_target_m", "tick_rate_hz", "audio_rate_hz",
          "burst_carrier_hz", "burst_rise_s", "burst_decay_s", "normal_force_n")
N_PARAMS = 16                      # 15 used, 1 reserved (0.0)
_DTYPE_CODES = {"uint8": 0, "uint16": 1, "float32": 2, "float64": 3}
_DTYPE_NAMES = {v: k for k, v in _DTYPE_CODES.items()}
_ABSENT = 0xFFFFFFFF

# Fixed header: (name, struct format), little-endian, no padding; 8-byte fields start 8-aligned.
HEADER = (
    ("magic", "4s"), ("version", "H"), ("header_size", "H"), ("image_size", "I"), ("flags", "I"),
    ("rows", "i"), ("cols", "i"), ("n_blocks", "i"), ("n_values", "i"), ("slot_mask", "I"),
    ("tile_rows", "i"), ("tile_cols", "i"), ("tiles_y", "i"), ("tiles_x", "i"), ("max_tile_blocks", "i"),
    ("n_tile_entries", "i"), ("meta_len", "I"),
    ("dx", "d"), ("dy", "d"), ("x0", "d"), ("y0", "d"),
    *((f"param_{i}", "d") for i in range(N_PARAMS)),
    # per renderer slot (SLOTS order): code type (0 u8, 1 u16, 2 f32, 3 f64, 0xFFFFFFFF absent), byte
    # offset of its n_values codes, and value = offset + scale * code, background outside every block
    *((f"{name}_{k}", f) for name in SLOTS
      for k, f in (("dtype", "I"), ("data_off", "I"), ("scale", "d"), ("offset", "d"), ("background", "d"))),
    ("blocks_off", "I"), ("tile_start_off", "I"), ("tile_list_off", "I"), ("meta_off", "I"),
)
_FMT = "<" + "".join(f for _, f in HEADER)
HEADER_SIZE = struct.calcsize(_FMT)          # 560: version 1
#: Version 2 appends the reaction section's place: its offset, the REACT_DEF records and REACT_KEY keyframes
#: it holds (records back to back, then the keyframes), and 4 reserved bytes (0).
HEADER_V2 = (("react_off", "I"), ("n_react", "I"), ("n_react_keys", "I"), ("reserved", "I"))
_FMT_V2 = "<" + "".join(f for _, f in HEADER_V2)
HEADER_SIZE_V2 = HEADER_SIZE + struct.calcsize(_FMT_V2)   # 576


def _align(n: int, a: int = 8) -> int:
    return (n + a - 1) // a * a


def settings(table: FrictionTable, device=None) -> dict:
    """The renderer settings of ``table`` (names of :data:`PARAMS`), as a Renderer resolves them."""
    from shapedisplay.render.settings import constant_normal_force, device_for_table, mapping_settings
    dev = device_for_table(table, device)
    kmu, sst = mapping_settings(table, dev)
    p, f, b = dev.pad, dev.friction, dev.burst
    values = (p.mass, p.stiffness, p.damping, b.gain, b.max_stick_period_s, f.mu_s, f.mu_k, kmu, sst,
              dev.tick_rate_hz, dev.audio_rate_hz, b.carrier_hz, b.rise_s, b.decay_s,
              constant_normal_force(table) or 0.0)
    return {n: float(v) for n, v in zip(PARAMS, values)}


def tile_index(rows: int, cols: int, blocks: np.ndarray):
    """Coarse index of the blocks: the canvas cut into tiles of ``tile_rows x tile_cols`` samples,
    each tile listing the blocks that overlap it.

    Returns ``(tile_rows, tile_cols, tiles_y, tiles_x, start, entries)`` with ``start`` of
    ``tiles_y * tiles_x + 1`` uint32 (tile ``i`` lists ``entries[start[i]:start[i+1]]``). The tile
    count is at most ``min(MAX_TILES, 4 * n_blocks + 1)``; the tile edge is the smallest that fits.
    """
    budget = max(1, min(MAX_TILES, 4 * len(blocks) + 1))
    edge = 1
    while -(-rows // edge) * -(-cols // edge) > budget:
        edge *= 2
    tr, tc = min(edge, rows), min(edge, cols)
    ty, tx = -(-rows // tr), -(-cols // tc)
    lists = [[] for _ in range(ty * tx)]
    for b, (r0, c0, nr, nc, _) in enumerate(blocks.tolist()):
        for i in range(r0 // tr, (r0 + nr - 1) // tr + 1):
            for j in range(c0 // tc, (c0 + nc - 1) // tc + 1):
                lists[i * tx + j].append(b)
    start = np.zeros(ty * tx + 1, "<u4")
    start[1:] = np.cumsum([len(lst) for lst in lists])
    entries = np.array([b for lst in lists for b in lst], "<u4")
    return tr, tc, ty, tx, start, entries


def to_image(table: FrictionTable, device=None) -> bytes:
    """The binary image of ``table`` (module docs); raises :class:`TableError` if it cannot hold it."""
    if not isinstance(table, FrictionTable):
        raise TableError(f"`table` must be a FrictionTable (got {type(table).__name__})")
    g = table.grid
    prm = settings(table, device)
    off = table.patch_offsets()
    n_values = int(off[-1])
    blocks = np.array([[r0, c0, *table.patch_shapes[i], off[i]] for r0, c0, i in table.blocks],
                      dtype="<i4").reshape(-1, 5)
    tr, tc, ty, tx, start, entries = tile_index(g.rows, g.cols, blocks)
    header_json = table.header()
    header_json["checksum"] = table.checksum
    meta = json.dumps(header_json, sort_keys=True, allow_nan=False).encode("utf-8")
    from shapedisplay.render.reactions import reaction_records
    react, keys = reaction_records(table)
    version, head_size = (VERSION, HEADER_SIZE_V2) if react.size or keys.size else (1, HEADER_SIZE)

    pos = head_size
    blocks_off, pos = pos, _align(pos + blocks.nbytes)
    tile_start_off, pos = pos, _align(pos + start.nbytes)
    tile_list_off, pos = pos, _align(pos + entries.nbytes)
    chan_words, chan_data, mask = [], [], 0
    for s, name in enumerate(SLOTS):
        if name not in table.channels:
            chan_words += [_ABSENT, 0, 0.0, 0.0, 0.0]
            continue
        q = table.quant[name]
        codes = np.asarray(table.codes[name])
        le = codes.astype(codes.dtype.newbyteorder("<"), copy=False).tobytes()
        mask |= 1 << s
        chan_words += [_DTYPE_CODES[q.dtype], pos, float(q.scale), float(q.offset), float(table.background[name])]
        chan_data.append((pos, le))
        pos = _align(pos + len(le))
    react_bytes = react.astype(react.dtype.newbyteorder("<")).tobytes() + keys.astype(keys.dtype.newbyteorder("<")).tobytes()
    react_off, pos = pos, _align(pos + len(react_bytes))
    meta_off, pos = pos, _align(pos + len(meta), 4)
    size = pos + 4
    if size > MAX_IMAGE_BYTES:
        raise TableError(f"table image would be {size} bytes; the format holds at most {MAX_IMAGE_BYTES}")
    head = struct.pack(_FMT, MAGIC, version, head_size, size, 0, g.rows, g.cols, len(blocks), n_values, mask,
                       tr, tc, ty, tx, int(np.diff(start).max()) if start.size > 1 else 0, int(entries.size),
                       len(meta), g.dx, g.dy, g.x0, g.y0,
                       *[prm[n] for n in PARAMS], *[0.0] * (N_PARAMS - len(PARAMS)),
                       *chan_words, blocks_off, tile_start_off, tile_list_off, meta_off)
    buf = bytearray(size)
    buf[:HEADER_SIZE] = head
    if version == 2:
        buf[HEADER_SIZE:HEADER_SIZE_V2] = struct.pack(_FMT_V2, react_off, react.size, keys.size, 0)
        buf[react_off:react_off + len(react_bytes)] = react_bytes
    buf[blocks_off:blocks_off + blocks.nbytes] = blocks.tobytes()
    buf[tile_start_off:tile_start_off + start.nbytes] = start.tobytes()
    buf[tile_list_off:tile_list_off + entries.nbytes] = entries.tobytes()
    for at, data in chan_data:
        buf[at:at + len(data)] = data
    buf[meta_off:meta_off + len(meta)] = meta
    struct.pack_into("<I", buf, size - 4, zlib.crc32(bytes(buf[:size - 4])) & 0xFFFFFFFF)
    return bytes(buf)


def export_image(table: FrictionTable, path: str | os.PathLike, device=None) -> Path:
    """Write the binary image of ``table`` to ``path`` atomically; returns the path."""
    write_bytes(path, to_image(table, device))
    return Path(path)


def parse_header(data: bytes, where: str = "table image") -> dict:
    """Check the frame of an image (size, magic, version, CRC) and return its header fields."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise TableError(f"{where}: image must be bytes (got {type(data).__name__})")
    data = bytes(data)
    if len(data) < HEADER_SIZE + 4:
        raise TableError(f"{where}: {len(data)} bytes is shorter than the {HEADER_SIZE + 4}-byte minimum image")
    if data[:4] != MAGIC:
        raise TableError(f"{where}: not a shapedisplay table image (starts with {data[:4]!r}, expected {MAGIC!r})")
    h = dict(zip((name for name, _ in HEADER), struct.unpack_from(_FMT, data)))
    if h["version"] not in VERSIONS:
        raise TableError(f"{where}: image version must be one of {', '.join(map(str, VERSIONS))} (got {h['version']})")
    want = HEADER_SIZE if h["version"] == 1 else HEADER_SIZE_V2
    if h["header_size"] != want or h["image_size"] != len(data) or len(data) < want + 4:
        raise TableError(f"{where}: image_size field says {h['image_size']} bytes, header {h['header_size']}; "
                         f"got {len(data)} bytes with a {want}-byte header (truncated or padded)")
    if h["version"] >= 2:
        h.update(zip((name for name, _ in HEADER_V2), struct.unpack_from(_FMT_V2, data, HEADER_SIZE)))
    else:
        h.update(react_off=0, n_react=0, n_react_keys=0, reserved=0)
    (crc,) = struct.unpack_from("<I", data, len(data) - 4)
    actual = zlib.crc32(data[:-4]) & 0xFFFFFFFF
    if crc != actual:
        raise TableError(f"{where}: CRC mismatch (stored {crc:08x}, computed {actual:08x}); image is corrupt")
    return h


def read_image(data: bytes, where: str = "table image") -> FrictionTable:
    """The :class:`FrictionTable` an image was made from, verified (frame, CRC, table checksum)."""
    h = parse_header(data, where)
    data = bytes(data)
    mo, ml = h["meta_off"], h["meta_len"]
    if not (h["header_size"] <= mo and mo + ml <= len(data) - 4):
        raise TableError(f"{where}: meta section {mo}+{ml} lies outside the {len(data)}-byte image")
    if ml > HEADER_MAX_BYTES:
        raise TableError(f"{where}: meta section of {ml} bytes exceeds the limit of {HEADER_MAX_BYTES}")
    # the same bounded rules as a table file: JSON depth capped, NaN/Infinity refused, every header
    # value checked by FrictionTable.from_header below
    header = parse_json(data[mo:mo + ml], f"{where}, meta section")
    if not isinstance(header, dict) or not isinstance(header.get("channels"), dict):
        raise TableError(f"{where}: meta section lacks the table header")
    n_values = h["n_values"]
    try:
        cap, _ = array_caps(header, where)
    except TableError:
        cap = 0                      # from_header names the fault; no array is read beyond the frame
    if not 0 <= n_values <= cap:
        raise TableError(f"{where}: n_values is {n_values}; the header's grid allows 0..{cap}")
    _check_binary_matches_header(h, header, where)
    arrays = {}
    for name, spec in header["channels"].items():
        if name not in SLOTS or not isinstance(spec, dict) or spec.get("dtype") not in _DTYPE_CODES:
            raise TableError(f"{where}: channel {name!r} cannot be stored in an image")
        code, at = h[f"{name}_dtype"], h[f"{name}_data_off"]
        if code != _DTYPE_CODES[spec["dtype"]]:
            raise TableError(f"{where}: channel {name!r} has dtype code {code} in the image, "
                             f"{spec['dtype']!r} in its header")
        dt = np.dtype(spec["dtype"]).newbyteorder("<")
        end = at + n_values * dt.itemsize
        if not (HEADER_SIZE <= at and end <= len(data) - 4):
            raise TableError(f"{where}: channel {name!r} data {at}..{end} lies outside the image")
        arrays[name] = np.frombuffer(data, dt, n_values, at).astype(dt.newbyteorder("="))
    table = FrictionTable.from_header(header, arrays, where)
    _check_reactions_match(h, data, table, where)
    return table


def _check_reactions_match(h: dict, data: bytes, table: FrictionTable, where: str) -> None:
    """The reaction section the engine reads must be the records the table's meta gives."""
    from shapedisplay.render.reactions import reaction_records
    react, keys = reaction_records(table)
    if (h["n_react"], h["n_react_keys"]) != (react.size, keys.size):
        raise TableError(f"{where}: the reaction section holds {h['n_react']} widgets and {h['n_react_keys']} keyframes; "
                         f"the table's meta lists {react.size} and {keys.size}")
    if react.size or keys.size:
        want = react.astype(react.dtype.newbyteorder("<")).tobytes() + keys.astype(keys.dtype.newbyteorder("<")).tobytes()
        at = h["react_off"]
        if not (h["header_size"] <= at and at + len(want) <= len(data) - 4) or data[at:at + len(want)] != want:
            raise TableError(f"{where}: the reaction section differs from the reactions of the table's meta")


def _check_binary_matches_header(h: dict, header: dict, where: str) -> None:
    """The binary fields the C runtime reads must say what the checked JSON header says."""
    import math
    g = header.get("grid") if isinstance(header.get("grid"), dict) else {}
    pairs = [("rows", h["rows"], g.get("rows")), ("cols", h["cols"], g.get("cols")), ("dx", h["dx"], g.get("dx_m")),
             ("dy", h["dy"], g.get("dy_m")), ("x0", h["x0"], g.get("x0_m")), ("y0", h["y0"], g.get("y0_m"))]
    for name, spec in header["channels"].items():
        if name in SLOTS and isinstance(spec, dict):
            pairs += [(f"{name}_{k}", h[f"{name}_{k}"], spec.get(k)) for k in ("scale", "offset", "background")]
    for name, binary, text in pairs:
        if not (isinstance(text, (int, float)) and not isinstance(text, bool) and binary == text):
            raise TableError(f"{where}: binary field {name} = {binary!r} differs from the header's {text!r}")
    for i in range(N_PARAMS):
        v = h[f"param_{i}"]
        if not math.isfinite(v):
            raise TableError(f"{where}: renderer setting {PARAMS[i] if i < len(PARAMS) else i} must be finite "
                             f"(got {v!r})")


def is_image(data: bytes) -> bool:
    """True if ``data`` starts like a table image (the magic; nothing verified)."""
    return bytes(data[:4]) == MAGIC


def load_table_or_image(path: str | os.PathLike) -> tuple[FrictionTable, bytes]:
    """Read a table file (.npz) or a binary table image from ``path``, verified; returns the
    table and the file's bytes (what a device upload sends)."""
    path = Path(path)
    if path.is_file():
        try:
            with open(path, "rb") as fh:
                head = fh.read(4)
        except OSError as exc:
            raise TableError(f"table '{path}': unreadable ({exc.strerror or exc})") from None
        if head == MAGIC:
            size = path.stat().st_size
            if size > MAX_IMAGE_BYTES:
                raise TableError(f"table image '{path}': {size} bytes exceeds the {MAX_IMAGE_BYTES}-byte limit")
            data = path.read_bytes()
            return read_image(data, f"table image '{path}'"), data
    table = FrictionTable.load(path)
    return table, path.read_bytes()
