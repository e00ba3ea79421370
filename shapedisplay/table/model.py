"""Friction-envelope tables: the compiled, versioned, checksummed container.

This module is on the runtime side: it imports nothing from the authoring
side, so a table file plus the runtime is all a device host needs.

Container
---------
An ``.npz`` (a zip of ``.npy`` arrays, readable with plain numpy) holding

* ``header`` — uint8 array of UTF-8 JSON (``json.loads(bytes(z["header"]))``);
* one flat array per stored channel, named after the channel, holding the
  quantized codes of every stored patch back to back.

The header gives the canvas ``grid`` (rows, cols, spacing and origin of the
sample centres, metres), the ``patches`` (shapes of the stored arrays), the
``blocks`` that place patches on the canvas (``[row0, col0, patch]``; blocks
never overlap; a patch used by several blocks is stored once), and per
channel its unit, dtype, ``scale``/``offset`` (value = offset + scale * code),
the worst-case quantization error and the ``background`` value used where no
block lies. A dense table is one block covering the canvas. The header also
carries the model and burst parameters, tick rate, velocity range, source
hashes, compile options and report, the ``format_version`` and a
``checksum`` (sha256 over the header without the checksum and every channel
array's dtype and bytes, in channel-name order).
"""
from __future__ import annotations

import copy
import hashlib
import io
import json
import math
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shapedisplay.atomic import atomic_path
from shapedisplay.table.container import NpzReader, parse_json, write_npz
from shapedisplay.errors import TableError, InputError, did_you_mean, unknown_key

FORMAT_NAME = "shapedisplay-friction-table"
FORMAT_VERSION = 1

#: Every channel the format knows: name -> (SI unit, meaning).
CHANNELS: dict[str, tuple[str, str]] = {
    "normal_force": ("N", "virtual normal force N"),
    "breakaway_force": ("N", "static friction limit mu_s*N where mu_s varies over the surface"),
    "kinetic_force": ("N", "kinetic friction mu_k*N where mu_k varies over the surface"),
    "friction_scale": ("1", "multiplier on mu_s and mu_k (data layers)"),
    "burst_gain": ("1", "multiplier on the burst gain B"),
    "grad_x": ("1", "surface slope dh/dx, for direction-dependent friction"),
    "grad_y": ("1", "surface slope dh/dy, for direction-dependent friction"),
    "lateral_x": ("N", "lateral-force cue along x"),
    "lateral_y": ("N", "lateral-force cue along y"),
    "skin_stretch": ("m", "skin-stretch target at breakaway"),
}

_DTYPES = {"uint8": np.uint8, "uint16": np.uint16, "float32": np.float32, "float64": np.float64}


@dataclass(frozen=True)
class Grid:
    """Canvas grid: sample (r, c) is at (x0 + c*dx, y0 + r*dy), metres."""

    rows: int
    cols: int
    dx: float
    dy: float
    x0: float = 0.0
    y0: float = 0.0

    def to_json(self) -> dict:
        return {"rows": self.rows, "cols": self.cols, "dx_m": self.dx, "dy_m": self.dy,
                "x0_m": self.x0, "y0_m": self.y0}

    @classmethod
    def from_json(cls, d: dict) -> "Grid":
        return cls(int(d["rows"]), int(d["cols"]), float(d["dx_m"]), float(d["dy_m"]),
                   float(d["x0_m"]), float(d["y0_m"]))


@dataclass(frozen=True)
class Quantization:
    """How a channel's values are coded: value = offset + scale * code."""

    dtype: str            # "uint8" | "uint16" | "float32" | "float64"
    scale: float = 1.0
    offset: float = 0.0
    max_error: float = 0.0  # worst-case |decoded - original|, channel unit

    def encode(self, values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=np.float64)
        if self.dtype in ("float32", "float64"):
            return values.astype(_DTYPES[self.dtype])
        top = np.iinfo(_DTYPES[self.dtype]).max
        if not self.scale > 0:
            return np.zeros(values.shape, dtype=_DTYPES[self.dtype])
        codes = np.subtract(values, self.offset)  # one float64 temporary, reused in place
        codes /= self.scale
        np.rint(codes, out=codes)
        np.clip(codes, 0, top, out=codes)
        return codes.astype(_DTYPES[self.dtype])

    def decode(self, codes: np.ndarray) -> np.ndarray:
        if self.dtype in ("float32", "float64"):
            return np.asarray(codes, dtype=np.float64)
        return self.offset + self.scale * np.asarray(codes, dtype=np.float64)


def choose_quantization(values: np.ndarray, dtype: str = "auto", max_error: float | None = None) -> Quantization:
    """Pick a coding for ``values``.

    ``dtype`` "uint8"/"uint16" spreads the codes over [min, max] (worst-case
    error scale/2; when the range straddles zero, zero gets a code of its own
    so it decodes exactly); "float32"/"float64" keep floats; "auto" takes the
    smallest integer width whose worst-case error is <= ``max_error`` and
    falls back to float32 when none is.
    """
    v = np.asarray(values, dtype=np.float64)
    lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 0.0)
    if not (math.isfinite(lo) and math.isfinite(hi)):   # NaN propagates into min/max
        raise InputError(f"channel values must be finite to be quantized (got range {lo!r}..{hi!r})")
    if dtype == "auto":
        if max_error is None or max_error <= 0:
            raise InputError(f"`max_error` must be > 0 for automatic quantization (got {max_error!r})")
        for cand in ("uint8", "uint16"):
            q = choose_quantization(v, cand)
            if q.max_error <= max_error:
                return q
        dtype = "float32"
    if dtype in ("float32", "float64"):
        big = float(np.max(np.abs(v), initial=0.0))
        # half an ulp relative (2^-24), and at least half the smallest subnormal (2^-150)
        eps = 0.0 if dtype == "float64" or big == 0 else max(big * 2.0 ** -24, 2.0 ** -150)
        return Quantization(dtype, 1.0, 0.0, eps)
    if dtype not in _DTYPES:
        raise unknown_key("quantization dtype", dtype, list(_DTYPES) + ["auto"])
    top = np.iinfo(_DTYPES[dtype]).max
    scale = (hi - lo) / top if hi > lo else 0.0
    offset = lo + 0.0   # -0.0 -> 0.0: the header stores the offset as JSON, which reads -0.0 back as 0.0
    if lo < 0.0 < hi:
        # Signed channels (slopes, lateral forces): put zero exactly on a code so
        # that flat ground decodes to 0, not to a small bias.
        k = min(max(int(round(-lo / (hi - lo) * top)), 1), top - 1)
        scale = max(-lo / k, hi / (top - k))
        offset = -(k * scale)
    q = Quantization(dtype, scale, offset, 0.0)
    err = float(np.max(np.abs(q.decode(q.encode(v)) - v), initial=0.0)) if v.size else 0.0
    return Quantization(dtype, scale, offset, max(err, scale / 2 if scale > 0 else 0.0))


@dataclass
class FrictionTable:
    """A friction-envelope table in memory.

    ``codes[name]`` is the flat code array of channel ``name`` over every
    patch; ``patch_shapes`` gives each patch's (rows, cols) and ``blocks``
    places patches on the canvas as ``(row0, col0, patch)``. Values decode
    with ``quant[name]``; samples outside every block take ``background[name]``.
    """

    grid: Grid
    patch_shapes: list           # [(rows, cols), ...]
    blocks: list                 # [(row0, col0, patch), ...]
    codes: dict                  # name -> flat ndarray of codes (all patches)
    quant: dict                  # name -> Quantization
    background: dict             # name -> float (SI)
    meta: dict = field(default_factory=dict)  # model, burst, tick rate, source, report...
    _dense_cache: dict = field(default_factory=dict, repr=False, compare=False)

    # -------------------------------------------------------------- building
    @classmethod
    def from_dense(cls, grid: Grid, channels: dict, quant: dict, meta: dict | None = None) -> "FrictionTable":
        """One block covering the canvas. ``channels[name]`` has shape (rows, cols), SI."""
        return cls.from_patches(grid, [((0, 0), channels)], quant, {n: 0.0 for n in channels}, meta)

    @classmethod
    def from_codes(cls, grid: Grid, codes: dict, quant: dict, background: dict | None = None,
                   meta: dict | None = None) -> "FrictionTable":
        """One block covering the canvas from channels already coded with ``quant``.

        ``codes[name]`` has shape (rows, cols) and the dtype of ``quant[name]``.
        Lets a compiler code one channel at a time instead of holding every
        float64 channel at once.
        """
        names = sorted(quant)
        for name in names:
            if name not in CHANNELS:
                raise unknown_key("channel", name, CHANNELS)
            c = np.asarray(codes[name])
            if c.shape != (grid.rows, grid.cols) or c.dtype != np.dtype(_DTYPES[quant[name].dtype]):
                raise InputError(f"codes of channel '{name}' must be {quant[name].dtype} of shape "
                                 f"{(grid.rows, grid.cols)} (got {c.dtype} {c.shape})")
        flat = {n: np.ascontiguousarray(codes[n]).reshape(-1) for n in names}
        bg = {n: float((background or {}).get(n, 0.0)) for n in names}
        t = cls(grid, [(grid.rows, grid.cols)], [(0, 0, 0)], flat, dict(quant), bg, copy.deepcopy(meta or {}))
        t._check_layout()
        return t

    @classmethod
    def from_patches(cls, grid: Grid, placed: list, quant: dict, background: dict,
                     meta: dict | None = None) -> "FrictionTable":
        """Build from ``placed = [((row0, col0), {name: array}), ...]``.

        Patches with identical coded contents are stored once.
        """
        names = sorted(quant)
        for name in names:
            if name not in CHANNELS:
                raise unknown_key("channel", name, CHANNELS)
        shapes, blocks, chunks, seen = [], [], {n: [] for n in names}, {}
        for (r0, c0), chans in placed:
            missing = set(names) - set(chans)
            if missing:
                raise InputError(f"patch at row {r0}, col {c0} lacks channels {sorted(missing)}")
            arrs = {n: np.atleast_2d(np.asarray(chans[n], dtype=np.float64)) for n in names}
            for n, a in arrs.items():
                if not np.isfinite(a).all():
                    raise InputError(f"patch at row {r0}, col {c0}: channel '{n}' must be finite "
                                     f"({int(np.count_nonzero(~np.isfinite(a)))} NaN/inf values)")
            shape = next(iter(arrs.values())).shape
            if r0 < 0 or c0 < 0 or r0 + shape[0] > grid.rows or c0 + shape[1] > grid.cols:
                raise InputError(f"patch {shape} at row {r0}, col {c0} lies outside the {grid.cols} x {grid.rows}-sample canvas")
            coded = {n: quant[n].encode(arrs[n]).ravel() for n in names}
            key = hashlib.sha256(repr(shape).encode() + b"".join(coded[n].tobytes() for n in names)).hexdigest()
            if key not in seen:
                seen[key] = len(shapes)
                shapes.append(tuple(int(s) for s in shape))
                for n in names:
                    chunks[n].append(coded[n])
            blocks.append((int(r0), int(c0), seen[key]))
        codes = {n: (np.concatenate(chunks[n]) if chunks[n] else np.zeros(0, _DTYPES[quant[n].dtype]))
                 for n in names}
        t = cls(grid, shapes, blocks, codes, dict(quant), {n: float(background.get(n, 0.0)) for n in names},
                copy.deepcopy(meta or {}))
        t._check_layout()
        return t

    # -------------------------------------------------------------- queries
    @property
    def channels(self) -> list[str]:
        return sorted(self.codes)

    @property
    def is_1d(self) -> bool:
        return self.grid.rows == 1

    def require(self, *names: str) -> None:
        """Raise if any of ``names`` is not stored."""
        missing = [n for n in names if n not in self.codes]
        if missing:
            raise TableError(f"table lacks channel(s) {missing} needed here; it holds {self.channels}")

    def patch_offsets(self) -> np.ndarray:
        sizes = [r * c for r, c in self.patch_shapes]
        return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)

    def packed(self, name: str):
        """Flat form for compiled lookups.

        Returns
        -------
        blocks : ndarray (n_blocks, 5) int64 — row0, col0, rows, cols, offset
        data : ndarray (n_values,) float64 — decoded values, SI
        background : float
        """
        self.require(name)
        off = self.patch_offsets()
        blk = np.array([[r0, c0, *self.patch_shapes[p], off[p]] for r0, c0, p in self.blocks],
                       dtype=np.int64).reshape(-1, 5)
        return blk, self.quant[name].decode(self.codes[name]), self.background[name]

    def dense(self, name: str) -> np.ndarray:
        """Decoded channel on the whole canvas, shape (rows, cols), float64, SI."""
        if name not in self._dense_cache:
            blk, data, bg = self.packed(name)
            out = np.full((self.grid.rows, self.grid.cols), bg, dtype=np.float64)
            for r0, c0, nr, nc, off in blk:
                out[r0:r0 + nr, c0:c0 + nc] = data[off:off + nr * nc].reshape(nr, nc)
            out.setflags(write=False)
            self._dense_cache[name] = out
        return self._dense_cache[name]

    def sample(self, name: str, x, y=None) -> np.ndarray:
        """Bilinear value of channel ``name`` at positions (x, y), metres.

        Outside the canvas the edge value is held (coordinates are clamped to
        the outermost sample centres). A 1-D table ignores ``y``.
        """
        g = self.grid
        vals = self.dense(name)
        x = np.asarray(x, dtype=np.float64)
        fc = np.clip((x - g.x0) / g.dx, 0.0, g.cols - 1)
        c0 = np.minimum(np.floor(fc).astype(np.int64), max(g.cols - 2, 0))
        tx = fc - c0
        c1 = np.minimum(c0 + 1, g.cols - 1)
        if g.rows == 1 or y is None:
            row = vals[0]
            return row[c0] * (1 - tx) + row[c1] * tx
        y = np.asarray(y, dtype=np.float64)
        fr = np.clip((y - g.y0) / g.dy, 0.0, g.rows - 1)
        r0 = np.minimum(np.floor(fr).astype(np.int64), max(g.rows - 2, 0))
        ty = fr - r0
        r1 = np.minimum(r0 + 1, g.rows - 1)
        return ((vals[r0, c0] * (1 - tx) + vals[r0, c1] * tx) * (1 - ty)
                + (vals[r1, c0] * (1 - tx) + vals[r1, c1] * tx) * ty)

    @property
    def stored_bytes(self) -> int:
        """Bytes of channel data actually stored (codes of every unique patch)."""
        return int(sum(a.nbytes for a in self.codes.values()))

    @property
    def dense_bytes(self) -> int:
        """Bytes of a dense float32 table of every format channel on this canvas."""
        return int(self.grid.rows * self.grid.cols * len(CHANNELS) * 4)

    # -------------------------------------------------------------- header
    def header(self) -> dict:
        h = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "grid": self.grid.to_json(),
            "patches": [list(s) for s in self.patch_shapes],
            "blocks": [list(b) for b in self.blocks],
            "channels": {
                n: {"unit": CHANNELS[n][0], "dtype": q.dtype, "scale": q.scale, "offset": q.offset,
                    "max_error": q.max_error, "background": self.background[n]}
                for n, q in sorted(self.quant.items())
            },
        }
        h.update(self.meta)
        return h

    @classmethod
    def from_repeated_row(cls, grid: Grid, codes: dict, quant: dict, background: dict | None = None,
                          meta: dict | None = None) -> "FrictionTable":
        """One row of codes stored once and placed on every row of the canvas (an extruded profile).

        ``codes[name]`` has shape (cols,) and the dtype of ``quant[name]``;
        the table has one block per row, built without a patch per row.
        """
        names = sorted(quant)
        for name in names:
            if name not in CHANNELS:
                raise unknown_key("channel", name, CHANNELS)
            c = np.asarray(codes[name])
            if c.shape != (grid.cols,) or c.dtype != np.dtype(_DTYPES[quant[name].dtype]):
                raise InputError(f"codes of channel '{name}' must be {quant[name].dtype} of shape "
                                 f"{(grid.cols,)} (got {c.dtype} {c.shape})")
        flat = {n: np.ascontiguousarray(codes[n]) for n in names}
        bg = {n: float((background or {}).get(n, 0.0)) for n in names}
        t = cls(grid, [(1, grid.cols)], [(r, 0, 0) for r in range(grid.rows)], flat, dict(quant), bg,
                copy.deepcopy(meta or {}))
        t._check_layout()
        return t

    @property
    def checksum(self) -> str:
        """The table's SHA-256 over its header and stored codes, as ``inspect --json`` prints it (hex)."""
        return _checksum(self.header(), self.codes)

    def _check_layout(self) -> None:
        g = self.grid
        if g.rows < 1 or g.cols < 1 or not (g.dx > 0 and g.dy > 0):
            raise TableError(f"table grid is invalid: {g}")
        n_vals = int(self.patch_offsets()[-1])
        for n, a in self.codes.items():
            if a.ndim != 1 or a.size != n_vals:
                raise TableError(f"channel '{n}' holds {a.size} values; the patches need {n_vals}")
        # one block cannot overlap another (and the map of occupied samples would cost a canvas of memory)
        occupied = np.zeros((g.rows, g.cols), dtype=bool) if g.rows * g.cols <= 1 << 26 and len(self.blocks) > 1 \
            else None
        for r0, c0, p in self.blocks:
            if not 0 <= p < len(self.patch_shapes):
                raise TableError(f"block at ({r0}, {c0}) names patch {p}; only {len(self.patch_shapes)} exist")
            nr, nc = self.patch_shapes[p]
            if r0 < 0 or c0 < 0 or r0 + nr > g.rows or c0 + nc > g.cols:
                raise TableError(f"block at ({r0}, {c0}) of {nr}x{nc} lies outside the canvas")
            if occupied is not None:
                if occupied[r0:r0 + nr, c0:c0 + nc].any():
                    raise TableError(f"block at ({r0}, {c0}) overlaps another block")
                occupied[r0:r0 + nr, c0:c0 + nc] = True

    # -------------------------------------------------------------- files
    def save(self, path: str | os.PathLike) -> Path:
        """Write atomically to ``path`` (.npz). Returns the path.

        The table is first checked by the reader's rules (:func:`check_readable`):
        a table :meth:`load` would refuse is not written.
        """
        path = Path(path)
        arrays = self._arrays(str(path))
        with atomic_path(path, suffix=".npz") as tmp:
            with open(tmp, "wb") as fh:
                write_npz(fh, arrays)
        return path

    def to_bytes(self) -> bytes:
        """The bytes of the table file (.npz) that :meth:`save` writes (checked as :meth:`save` does)."""
        buf = io.BytesIO()
        write_npz(buf, self._arrays("<bytes>"))
        return buf.getvalue()

    def _arrays(self, where: str = "<bytes>") -> dict:
        """The entries of the table file: ``header`` (JSON with its checksum) and each channel, little-endian.

        Raises :class:`TableError` if the reader would refuse them (``where`` names the file).
        """
        header = self.header()
        header["checksum"] = _checksum(header, self.codes)
        text = json.dumps(header, sort_keys=True).encode()
        check_readable(text, self.codes, where)
        arrays = {"header": np.frombuffer(text, dtype=np.uint8)}
        for n, a in self.codes.items():
            arrays[n] = a.astype(a.dtype.newbyteorder("<"), copy=False)
        return arrays

    @classmethod
    def load(cls, path: str | os.PathLike) -> "FrictionTable":
        """Read and verify a table; raise :class:`TableError` on any defect."""
        path = Path(path)
        if path.is_dir():
            raise TableError(f"table '{path}': is a directory, not a table file")
        if not path.is_file():
            raise TableError(f"table '{path}': no such file")
        try:
            with open(path, "rb") as fh:
                magic = fh.read(4)
        except OSError as exc:
            raise TableError(f"table '{path}': unreadable ({exc.strerror or exc})") from None
        if magic != b"PK\x03\x04":
            raise TableError(f"table '{path}': not a table (.npz zip archive); it starts with {magic!r}")
        return cls._from_npz(path, f"table '{path}'", str(path))

    @classmethod
    def from_bytes(cls, data: bytes, where: str = "uploaded table", max_bytes: int | None = None) -> "FrictionTable":
        """Read and verify a table from the bytes of a table file (e.g. an upload).

        ``max_bytes`` caps the channel data it may hold (a device's table memory).
        """
        return cls._from_npz(bytes(data), where, where, max_bytes)

    @classmethod
    def _from_npz(cls, source, label: str, where: str, max_bytes: int | None = None) -> "FrictionTable":
        """The one bounded reader of table files: every cap is known before a byte is inflated.

        The header is read first (at most :data:`HEADER_MAX_BYTES`, JSON depth
        capped); its grid and channel dtypes give each channel array's cap
        (:func:`stored_values_cap` values of the declared dtype, and
        ``max_bytes`` in all); then the checksum, the schema of every header
        value and the finiteness of every float channel are checked.
        """
        budget = MAX_TABLE_BYTES if max_bytes is None else min(int(max_bytes), MAX_TABLE_BYTES)
        with NpzReader(source, label, None, max_entries=1 + len(CHANNELS)) as z:
            if "header" not in z:
                raise TableError(f"{label}: no 'header' entry; not a shapedisplay table")
            unknown = sorted(set(z.entries) - {"header", *CHANNELS})
            if unknown:
                raise TableError(f"{label}: unexpected entry '{unknown[0]}'; a table holds 'header' and "
                                 f"channel arrays only")
            header = z.read_json("header", HEADER_MAX_BYTES)
            cap, dtypes = array_caps(header, label)
            arrays, spent = {}, 0
            for name in sorted(z.entries):
                if name == "header":
                    continue
                if name not in dtypes:
                    raise TableError(f"{label}: entry '{name}' is not a channel of the header "
                                     f"(channels: {', '.join(sorted(dtypes)) or 'none'})")
                code = np.dtype(_DTYPES[dtypes[name]]).str[1:]
                limit = min(cap, max(0, budget - spent) // np.dtype(code).itemsize)
                arrays[name] = z.read_array(name, (code,), limit, ndim=1)
                spent += arrays[name].nbytes
        return cls.from_header(header, arrays, where)

    @classmethod
    def from_header(cls, header: dict, arrays: dict, where: str = "table") -> "FrictionTable":
        """Verify a parsed header and its channel arrays; build the table.

        Raises :class:`TableError` (one line naming ``where``, the key, the
        rule and the value) for a wrong format or version, a checksum
        mismatch, a header value of the wrong type, range or finiteness, a
        non-finite float channel, or a layout that does not fit the grid.
        """
        if not isinstance(header, dict):
            raise TableError(f"table '{where}': header must be a JSON object (got {type(header).__name__})")
        if header.get("format") != FORMAT_NAME:
            raise TableError(f"table '{where}': format is {_short(header.get('format'))}, expected {FORMAT_NAME!r}")
        ver = header.get("format_version")
        if ver != FORMAT_VERSION or isinstance(ver, bool):
            raise TableError(f"table '{where}': format_version must be {FORMAT_VERSION} (got {_short(ver)})")
        stored = header.get("checksum")
        body = {k: v for k, v in header.items() if k != "checksum"}
        try:
            actual = _checksum(body, arrays)
        except (TypeError, ValueError) as exc:     # a key or value JSON cannot write back
            raise TableError(f"table '{where}': header cannot be checksummed ({exc})") from None
        if stored != actual:
            raise TableError(f"table '{where}': checksum mismatch (stored {_short(stored)}, computed {actual}); "
                             f"file is corrupt")
        try:
            grid, patches, blocks, quant, background, codes = _parse_layout(header, arrays)
            check_meta(body)
        except TableError as exc:
            raise TableError(f"table '{where}': {exc}") from None
        meta = {k: v for k, v in body.items()
                if k not in ("format", "format_version", "grid", "patches", "blocks", "channels")}
        t = cls(grid, patches, blocks, codes, quant, background, meta)
        try:
            t._check_layout()
            check_meta_refs(t)
        except TableError as exc:
            raise TableError(f"table '{where}': {exc}") from None
        return t

    # -------------------------------------------------------------- exports
    def to_json(self) -> dict:
        """Dense export: grid and every stored channel at the sample centres, SI, row-major."""
        return {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "checksum": self.checksum,
            "grid": self.grid.to_json(),
            "channels": {n: {"unit": CHANNELS[n][0], "max_error": self.quant[n].max_error,
                             "values": self.dense(n).tolist()} for n in self.channels},
            "meta": self.meta,
        }

    def summary(self) -> dict:
        """Sizes, channels and ranges for ``inspect``."""
        return {
            "format_version": FORMAT_VERSION,
            "checksum": self.checksum,
            "grid": self.grid.to_json(),
            "is_1d": self.is_1d,
            "channels": {n: {"unit": CHANNELS[n][0], "dtype": self.quant[n].dtype,
                             "max_error": self.quant[n].max_error,
                             "min": float(self.dense(n).min()), "max": float(self.dense(n).max())}
                         for n in self.channels},
            "patches": len(self.patch_shapes),
            "blocks": len(self.blocks),
            "stored_bytes": self.stored_bytes,
            "dense_bytes": self.dense_bytes,
            "meta": self.meta,
        }


#: Largest canvas a table file may declare (same bound as a height field).
MAX_CANVAS_SAMPLES = 16384 * 16384
#: Stored values a table may hold per channel, as a multiple of its canvas: placed
#: patches never overlap (at most one canvas) and toggles store their other states.
STORED_PER_CANVAS = 8
#: Most bytes of channel data a table file may make the reader hold (all channels).
MAX_TABLE_BYTES = 1 << 30
#: Largest header accepted, bytes of JSON.
HEADER_MAX_BYTES = 8 << 20
#: Largest magnitude of a coordinate or spacing in a table header, metres (a display is
#: centimetres wide; a kilometre is beyond any device and keeps every product finite).
MAX_COORDINATE_M = 1e3
_META_DICTS = ("device", "mapping", "source", "compile", "report", "scene")
_CHANNEL_KEYS = ("background", "dtype", "max_error", "offset", "scale", "unit")


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_dtype(v) -> bool:
    return isinstance(v, str) and v in _DTYPES


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _number(d: dict, key: str, where: str, lo: float = -math.inf, hi: float = math.inf, *,
            lo_open: bool = False) -> float:
    v = d.get(key)
    if not _is_num(v):
        raise TableError(f"header '{where}.{key}' must be a finite number (got {_short(v)})")
    if v < lo or v > hi or (lo_open and v == lo):
        rule = f"{'>' if lo_open else '>='} {lo:g}" if hi == math.inf else f"within {lo:g}..{hi:g}"
        raise TableError(f"header '{where}.{key}' must be {rule} (got {v!r})")
    return float(v)


def _int_list(value, n: int, what: str) -> tuple:
    if not (isinstance(value, list) and len(value) == n and all(_is_int(v) and 0 <= v < 2 ** 31 for v in value)):
        raise TableError(f"{what} must be {n} non-negative integers (got {_short(value)})")
    return tuple(value)


def _object(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise TableError(f"header '{where}' must be an object (got {_short(value)})")
    return value


def _grid(header: dict) -> Grid:
    g = _object(header.get("grid"), "grid")
    for key in ("rows", "cols"):
        v = g.get(key)
        if not (_is_int(v) and v >= 1):
            raise TableError(f"header 'grid.{key}' must be an integer >= 1 (got {_short(v)})")
    if g["rows"] * g["cols"] > MAX_CANVAS_SAMPLES:
        raise TableError(f"grid of {g['cols']} x {g['rows']} samples exceeds the limit of {MAX_CANVAS_SAMPLES}")
    dx = _number(g, "dx_m", "grid", 0.0, MAX_COORDINATE_M, lo_open=True)
    dy = _number(g, "dy_m", "grid", 0.0, MAX_COORDINATE_M, lo_open=True)
    x0 = _number(g, "x0_m", "grid", -MAX_COORDINATE_M, MAX_COORDINATE_M)
    y0 = _number(g, "y0_m", "grid", -MAX_COORDINATE_M, MAX_COORDINATE_M)
    if abs(x0) + dx * g["cols"] > 2 * MAX_COORDINATE_M or abs(y0) + dy * g["rows"] > 2 * MAX_COORDINATE_M:
        raise TableError(f"header 'grid' spans beyond {2 * MAX_COORDINATE_M:g} m (got {_short(g)})")
    return Grid(g["rows"], g["cols"], dx, dy, x0, y0)


def stored_values_cap(grid: Grid) -> int:
    """Most values one channel array of a table on ``grid`` may hold."""
    return min(MAX_CANVAS_SAMPLES, STORED_PER_CANVAS * grid.rows * grid.cols)


def check_readable(header_json: bytes, codes: dict, where: str) -> None:
    """Check a table's header (JSON bytes) and channel arrays by the rules its reader applies.

    The writer's half of :meth:`FrictionTable._from_npz`: the same header
    size, depth and finiteness caps (:func:`~shapedisplay.table.container.parse_json`),
    the same per-channel and total array caps (:func:`array_caps`) and the
    same schema (:meth:`FrictionTable.from_header`). Raises
    :class:`TableError` naming the table ``where``, the key, the rule and the
    value, with "not written" added.
    """
    label = f"table '{where}'"
    try:
        if len(header_json) > HEADER_MAX_BYTES:
            raise TableError(f"{label}, entry 'header': {len(header_json)} elements exceed the limit of "
                             f"{HEADER_MAX_BYTES}")
        header = parse_json(header_json, f"{label}, entry 'header'")
        cap, dtypes = array_caps(header, label)
        spent = 0
        for name, a in codes.items():
            if a.size > cap:
                raise TableError(f"{label}, entry '{name}': {a.size} elements exceed the limit of {cap}")
            spent += a.nbytes
        if spent > MAX_TABLE_BYTES:
            raise TableError(f"{label}: channels hold {spent} bytes, beyond the limit of {MAX_TABLE_BYTES}")
        FrictionTable.from_header(header, codes, where)
    except TableError as exc:
        raise TableError(f"{exc}; not written (the table reader would refuse it)") from None


def array_caps(header: dict, label: str) -> tuple[int, dict]:
    """Per-channel element cap and declared dtypes, from the header alone (before any array is read)."""
    if not isinstance(header, dict):
        raise TableError(f"{label}: header must be a JSON object (got {type(header).__name__})")
    try:
        if header.get("format") != FORMAT_NAME:
            raise TableError(f"format is {_short(header.get('format'))}, expected {FORMAT_NAME!r}")
        grid = _grid(header)
        channels = _object(header.get("channels"), "channels")
        dtypes = {}
        for n, c in channels.items():
            if n not in CHANNELS:
                raise TableError(f"unknown channel '{_short(n)[1:-1]}'{did_you_mean(n, CHANNELS)}")
            if not isinstance(c, dict) or not _is_dtype(c.get("dtype")):
                got = c.get("dtype") if isinstance(c, dict) else c
                raise TableError(f"channel '{n}': dtype must be one of {list(_DTYPES)} (got {_short(got)})")
            dtypes[n] = c["dtype"]
    except TableError as exc:
        raise TableError(f"{label}: {exc}") from None
    return stored_values_cap(grid), dtypes


def _parse_layout(header: dict, arrays: dict):
    """Grid, patches, blocks and channels of a header whose checksum matched; every value checked."""
    for key in ("grid", "patches", "blocks", "channels"):
        if key not in header:
            raise TableError(f"header key '{key}' is missing")
    grid = _grid(header)
    cap = stored_values_cap(grid)
    if not isinstance(header["patches"], list) or len(header["patches"]) > cap:
        raise TableError(f"header 'patches' must be a list of at most {cap} shapes (got {_short(header['patches'])})")
    if not isinstance(header["blocks"], list) or len(header["blocks"]) > grid.rows * grid.cols:
        raise TableError(f"header 'blocks' must be a list of at most {grid.rows * grid.cols} blocks "
                         f"(got {_short(header['blocks'])})")
    patches = [_int_list(s, 2, "each patch shape") for s in header["patches"]]
    blocks = [_int_list(b, 3, "each block [row0, col0, patch]") for b in header["blocks"]]
    n_vals = sum(r * c for r, c in patches)
    if n_vals > cap:
        raise TableError(f"patches hold {n_vals} values; at most {cap} fit a {grid.cols} x {grid.rows}-sample table")
    channels = header["channels"]
    if not isinstance(channels, dict):
        raise TableError(f"'channels' must be an object (got {type(channels).__name__})")
    quant, background, codes = {}, {}, {}
    for n, c in channels.items():
        if n not in CHANNELS:
            raise TableError(f"unknown channel '{n}'{did_you_mean(n, CHANNELS)}")
        where = f"channels.{n}"
        c = _object(c, where)
        if sorted(c) != list(_CHANNEL_KEYS):
            raise TableError(f"header '{where}' must have exactly the keys {list(_CHANNEL_KEYS)} (got {sorted(c)})")
        if not _is_dtype(c["dtype"]):
            raise TableError(f"channel '{n}': dtype must be one of {list(_DTYPES)} (got {_short(c['dtype'])})")
        if c["unit"] != CHANNELS[n][0]:
            raise TableError(f"header '{where}.unit' must be {CHANNELS[n][0]!r} (got {_short(c['unit'])})")
        for key in ("scale", "offset", "max_error", "background"):
            if not _is_num(c[key]):
                raise TableError(f"channel '{n}': scale, offset, max_error and background must be finite "
                                 f"numbers (got {key}={_short(c[key])})")
        scale = _number(c, "scale", where, 0.0)
        offset = c["offset"] + 0.0
        max_error = _number(c, "max_error", where, 0.0)
        if n not in arrays:
            raise TableError(f"channel '{n}' has no array in the file")
        a = arrays[n]
        if not isinstance(a, np.ndarray) or a.dtype != np.dtype(_DTYPES[c["dtype"]]):
            got = a.dtype if isinstance(a, np.ndarray) else type(a).__name__
            raise TableError(f"channel '{n}': array dtype is {got}, the header says {c['dtype']}")
        if a.ndim != 1 or a.size != n_vals:
            raise TableError(f"channel '{n}' holds {a.size} values; the patches need {n_vals}")
        if c["dtype"] in ("float32", "float64"):
            bad = int(a.size - np.count_nonzero(np.isfinite(a)))
            if bad:
                raise TableError(f"channel '{n}': values must be finite ({bad} NaN/inf of {a.size})")
            top = float(np.max(np.abs(a), initial=0.0))
        else:
            top = float(np.iinfo(a.dtype).max)
        if not (math.isfinite(offset + scale * top) and math.isfinite(offset - scale * top)):
            raise TableError(f"channel '{n}': decoded values overflow (offset {offset!r} + scale {scale!r} "
                             f"x code {top:g})")
        quant[n] = Quantization(c["dtype"], scale, offset, max_error)
        background[n] = c["background"] + 0.0
        codes[n] = a
    extra = sorted(set(arrays) - set(channels))
    if extra:
        raise TableError(f"array '{extra[0]}' is not a channel of the header")
    return grid, patches, blocks, quant, background, codes


# ------------------------------------------------------------------ header schema
#: The header's ``mapping`` (what the authoring side's ``MappingOptions.to_json()`` writes: its fields and
#: ``spec``): key -> kind as :func:`~shapedisplay.table.devices.header_kinds` derives it. The table side does
#: not import the authoring side, so the list lives here; tests/test_one_home.py holds it to the dataclass.
MAPPING_KINDS = {"height": "bool", "n_base": "number", "n_gain": "number", "slope_friction_gain": "number",
                 "lateral": "str", "lateral_gain": "number", "skin_stretch": "number",
                 "perceptual_exponent": "number?", "perceptual_threshold": "number", "spec": "str"}
#: Kind -> (test of a value, what the value must be) for the kinds checked by type alone.
_KIND_TESTS = {"str": (lambda v: isinstance(v, str), "a string"),
               "bool": (lambda v: isinstance(v, bool), "true or false"),
               "number?": (lambda v: v is None or _is_num(v), "a finite number or null"),
               "names": (lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v), "a list of strings")}


def _check_kinds(d: dict, where: str, kinds: dict, strict: bool = True) -> None:
    """Check header object ``d`` (at ``where``) value by value against ``kinds``; unknown keys refused if ``strict``."""
    for key, v in d.items():
        kind, at = kinds.get(key), f"{where}.{key}"
        if kind is None:
            if strict:
                raise TableError(f"header '{where}' has unknown key {_short(key)}")
        elif isinstance(kind, dict):
            _check_kinds(_object(v, at), at, kind)
        elif kind == "number":
            _number(d, key, where)
        elif kind == "object":
            _object(v, at)
        else:
            test, what = _KIND_TESTS.get(kind) or (
                lambda v: isinstance(v, list) and len(v) == kind and all(_is_num(x) for x in v),
                f"{kind} finite numbers")
            if not test(v):
                raise TableError(f"header '{at}' must be {what} (got {_short(v)})")


def _device_schema(d: dict) -> None:
    # runtime side; imported here to keep `import table` light
    from shapedisplay.table.devices import DeviceProfile, header_kinds
    _check_kinds(d, "device", header_kinds(DeviceProfile))
    try:
        DeviceProfile.from_json(d)
    except (InputError, TypeError, ValueError) as exc:
        raise TableError(f"header 'device' is not a valid device profile ({exc})") from None


def _mapping_schema(m: dict) -> None:
    _check_kinds(m, "mapping", MAPPING_KINDS, strict=False)     # keys a newer writer adds pass (plain JSON)
    b = m.get("perceptual_exponent")
    if b is not None and not b > 0:
        raise TableError(f"header 'mapping.perceptual_exponent' must be a number > 0 or null (got {_short(b)})")


def _scene_schema(sc: dict) -> None:
    widgets = sc.get("widgets", [])
    if not isinstance(widgets, list):
        raise TableError(f"header 'scene.widgets' must be a list (got {_short(widgets)})")
    for i, w in enumerate(widgets):
        w = _object(w, f"scene.widgets[{i}]")
        box = w.get("bbox_m")
        if not (isinstance(box, list) and len(box) == 4 and all(_is_num(v) for v in box)):
            raise TableError(f"header 'scene.widgets[{i}].bbox_m' must be 4 finite numbers (got {_short(box)})")
        for key in ("id", "type", "label"):
            if key in w and not isinstance(w[key], str):
                raise TableError(f"header 'scene.widgets[{i}].{key}' must be a string (got {_short(w[key])})")
    toggles = _object(sc.get("toggles", {}), "scene.toggles")
    for tid, t in toggles.items():
        where = f"scene.toggles.{tid}"
        t = _object(t, where)
        states = _object(t.get("states"), f"{where}.states")
        if not (_is_int(t.get("block")) and t["block"] >= 0):
            raise TableError(f"header '{where}.block' must be a block index (got {_short(t.get('block'))})")
        if not all(_is_int(p) and p >= 0 for p in states.values()):
            raise TableError(f"header '{where}.states' must map each state to a patch index (got {_short(states)})")
        if not isinstance(t.get("state"), str) or t["state"] not in states:
            raise TableError(f"header '{where}.state' must be one of its states {sorted(states)} "
                             f"(got {_short(t.get('state'))})")


def check_meta(header: dict) -> None:
    """Check the type, range and finiteness of every header value outside the layout.

    Known sections (``device``, ``mapping``, ``scene``, ``tick_rate_hz``,
    ``velocity_range_m_s``) have a schema of their own; every other value
    (the report, compile options, source, keys a newer writer adds) must be
    plain JSON whose numbers are all finite.
    """
    for key in _META_DICTS:
        if key in header and not isinstance(header[key], dict):
            raise TableError(f"'{key}' must be an object (got {_short(header[key])})")
    if "device" in header:
        _device_schema(header["device"])
    if "mapping" in header:
        _mapping_schema(header["mapping"])
    if "scene" in header:
        _scene_schema(header["scene"])
    if "tick_rate_hz" in header:
        _number(header, "tick_rate_hz", "header", 0.0, lo_open=True)
    if "velocity_range_m_s" in header:
        v = header["velocity_range_m_s"]
        if not (isinstance(v, list) and len(v) == 2 and all(_is_num(x) and x >= 0 for x in v) and v[0] <= v[1]):
            raise TableError(f"header 'velocity_range_m_s' must be 2 finite numbers 0 <= low <= high "
                             f"(got {_short(v)})")
    for key, v in header.items():
        if not is_finite_json(v):
            raise TableError(f"header '{key}' holds a NaN or infinite number")


def check_meta_refs(table: "FrictionTable") -> None:
    """Indices the header's scene section gives (toggle blocks and state patches) exist."""
    toggles = (table.meta.get("scene") or {}).get("toggles", {})
    for tid, t in toggles.items():
        if t["block"] >= len(table.blocks):
            raise TableError(f"header 'scene.toggles.{tid}.block' is {t['block']}; the table has "
                             f"{len(table.blocks)} blocks")
        for st, p in t["states"].items():
            if p >= len(table.patch_shapes) or table.patch_shapes[p] != table.patch_shapes[
                    table.blocks[t["block"]][2]]:
                raise TableError(f"header 'scene.toggles.{tid}.states.{st}' names patch {p}, which does not "
                                 f"exist or has another shape than its block")


def _checksum(header: dict, arrays: dict) -> str:
    d = hashlib.sha256()
    d.update(json.dumps({k: v for k, v in header.items() if k != "checksum"}, sort_keys=True).encode())
    for n in sorted(arrays):
        a = np.asarray(arrays[n])
        d.update(n.encode() + b"\0" + a.dtype.newbyteorder("<").str.encode() + b"\0")
        d.update(np.ascontiguousarray(a.astype(a.dtype.newbyteorder("<"), copy=False)).reshape(-1).view(np.uint8))
    return "sha256:" + d.hexdigest()


def is_finite_json(obj) -> bool:
    """True if no number anywhere in ``obj`` is NaN or infinite (or an integer beyond a float)."""
    if isinstance(obj, float):
        return math.isfinite(obj)
    if isinstance(obj, int) and not isinstance(obj, bool):
        return abs(obj) < 2 ** 1023
    if isinstance(obj, dict):
        return all(is_finite_json(v) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return all(is_finite_json(v) for v in obj)
    return True
