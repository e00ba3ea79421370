"""Grayscale PNG and ``.npy`` height-map files, read and written with zlib + numpy.

Functions for dealing with single-channel height images as integer arrays
of shape (rows, cols). Only what a height map needs is supported:

* PNG colour type 0 (grayscale) with bit depth 8 or 16, not interlaced, any
  mix of the five PNG row filters (None, Sub, Up, Average, Paeth). RGB,
  palette, alpha and 1/2/4-bit images are refused with a message saying so.
* ``.npy`` arrays of shape (rows, cols) or (cols,), integer or float.

The image size is read from the PNG header and checked against
:data:`shapedisplay.heightfield.MAX_SAMPLES` *before* any pixel data is
decompressed, so an oversized (or hostile) file is refused without
exhausting memory. Pixel data is inflated with an output limit equal to the
size the header announces. CRCs of every chunk are checked.

The row filters None/Sub/Up are undone with numpy; Average and Paeth, which
depend on the pixel just decoded to their left, are undone by a small numba
kernel (compiled once, cached on disk).
"""
from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np

from .atomic import atomic_path
from .errors import FileFormatError, InputError
from .heightfield import check_grid_size

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: What this reader accepts, quoted in every refusal.
SUPPORTED = "8- or 16-bit grayscale PNG (colour type 0, not interlaced)"
_COLOR_NAMES = {0: "grayscale", 2: "RGB", 3: "palette", 4: "grayscale+alpha", 6: "RGBA"}
FILTER_NAMES = ("none", "sub", "up", "average", "paeth")


# ----------------------------------------------------------------- reading
def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read an 8- or 16-bit grayscale PNG.

    Parameters
    ----------
    path : path-like
        The PNG file.

    Returns
    -------
    ndarray of shape (rows, cols), uint8 or uint16
        Gray values; full scale is 255 (8-bit) or 65535 (16-bit).

    Raises
    ------
    FileFormatError
        missing/unreadable/corrupt file, unsupported colour type or bit depth,
        interlacing, bad CRC, truncated or oversized pixel data.
    InputError
        the header announces an image too large to hold in memory.
    """
    path = Path(path)
    data = _read_file(path, "image")
    if not data.startswith(PNG_SIGNATURE):
        raise FileFormatError(f"image '{path}': not a PNG file (bad signature); supported: {SUPPORTED}, or .npy")
    pos = len(PNG_SIGNATURE)
    ihdr = None
    idat: list[bytes] = []
    seen_iend = False
    while pos < len(data):
        if pos + 8 > len(data):
            raise FileFormatError(f"image '{path}': truncated PNG chunk header at byte {pos}")
        length, ctype = struct.unpack(">I4s", data[pos:pos + 8])
        end = pos + 12 + length
        if end > len(data):
            raise FileFormatError(f"image '{path}': truncated PNG chunk {ctype!r} (needs {length} bytes)")
        body = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:end])
        if zlib.crc32(ctype + body) & 0xFFFFFFFF != crc:
            raise FileFormatError(f"image '{path}': CRC mismatch in PNG chunk {ctype.decode('latin-1')!r}; file is corrupt")
        if ctype == b"IHDR":
            ihdr = _parse_ihdr(body, path)
        elif ctype == b"IDAT":
            if ihdr is None:
                raise FileFormatError(f"image '{path}': IDAT before IHDR; file is corrupt")
            idat.append(body)
        elif ctype == b"IEND":
            seen_iend = True
            break
        elif ctype == b"PLTE" or (ctype[0] & 0x20) == 0 and ctype not in (b"IHDR", b"IDAT", b"IEND"):
            # a critical chunk this reader does not know
            raise FileFormatError(f"image '{path}': unsupported critical PNG chunk {ctype!r}; supported: {SUPPORTED}")
        pos = end
    if ihdr is None:
        raise FileFormatError(f"image '{path}': no IHDR chunk; file is corrupt")
    if not idat:
        raise FileFormatError(f"image '{path}': no pixel data (IDAT); file is truncated")
    if not seen_iend:
        raise FileFormatError(f"image '{path}': no IEND chunk; file is truncated")
    width, height, depth = ihdr
    bpp = depth // 8
    stride = width * bpp
    expected = height * (stride + 1)
    raw = _inflate(b"".join(idat) if len(idat) > 1 else idat[0], expected, path)
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(height, stride + 1)
    ftypes = rows[:, 0]
    if ftypes.max(initial=0) > 4:
        r = int(np.argmax(ftypes > 4))
        raise FileFormatError(f"image '{path}': row {r} has unknown PNG filter type {int(ftypes[r])}; file is corrupt")
    pix = unfilter(rows[:, 1:], ftypes, bpp)
    if depth == 16:
        return pix.view(">u2").astype(np.uint16)
    return pix


def _read_file(path: Path, what: str) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise FileFormatError(f"{what} '{path}': no such file") from None
    except IsADirectoryError:
        raise FileFormatError(f"{what} '{path}': is a directory, not a file") from None
    except OSError as exc:
        raise FileFormatError(f"{what} '{path}': unreadable ({exc.strerror or exc})") from None


def _parse_ihdr(body: bytes, path: Path) -> tuple[int, int, int]:
    if len(body) != 13:
        raise FileFormatError(f"image '{path}': IHDR has {len(body)} bytes, expected 13; file is corrupt")
    width, height, depth, color, comp, filt, interlace = struct.unpack(">IIBBBBB", body)
    if color != 0:
        raise FileFormatError(
            f"image '{path}': colour type {color} ({_COLOR_NAMES.get(color, 'unknown')}) is not supported; "
            f"supported: {SUPPORTED}")
    if depth not in (8, 16):
        raise FileFormatError(f"image '{path}': bit depth {depth} is not supported; supported: {SUPPORTED}")
    if comp != 0 or filt != 0:
        raise FileFormatError(f"image '{path}': unknown PNG compression/filter method ({comp}, {filt}); file is corrupt")
    if interlace != 0:
        raise FileFormatError(f"image '{path}': interlaced (Adam7) PNG is not supported; supported: {SUPPORTED}")
    if width == 0 or height == 0:
        raise FileFormatError(f"image '{path}': empty image ({width}x{height} pixels)")
    check_grid_size(height, width, f"image '{path}'")
    return width, height, depth


def _inflate(blob: bytes, expected: int, path: Path) -> bytes:
    d = zlib.decompressobj()
    try:
        out = d.decompress(blob, expected)
    except zlib.error as exc:
        raise FileFormatError(f"image '{path}': corrupt compressed pixel data ({exc})") from None
    if len(out) < expected:
        raise FileFormatError(
            f"image '{path}': pixel data holds {len(out)} bytes, the header needs {expected}; file is truncated")
    if d.unconsumed_tail and d.decompress(d.unconsumed_tail, 1):
        raise FileFormatError(f"image '{path}': more pixel data than the header announces; file is corrupt")
    return out


def unfilter(filtered: np.ndarray, ftypes: np.ndarray, bpp: int) -> np.ndarray:
    """Undo PNG row filters.

    Parameters
    ----------
    filtered : ndarray of shape (rows, stride), uint8
        Filtered scanlines without their filter-type byte.
    ftypes : ndarray of shape (rows,), uint8
        Filter type of each row (0 None, 1 Sub, 2 Up, 3 Average, 4 Paeth).
    bpp : int
        Bytes per pixel (1 for 8-bit gray, 2 for 16-bit gray).

    Returns
    -------
    ndarray of shape (rows, stride), uint8
        Raw scanline bytes.
    """
    ftypes = np.asarray(ftypes)
    if np.any(ftypes >= 3):
        return _unfilter_kernel()(np.ascontiguousarray(filtered), ftypes.astype(np.uint8), bpp)
    out = np.empty_like(filtered)
    nrow, stride = filtered.shape
    prior = np.zeros(stride, dtype=np.uint8)
    for r in range(nrow):
        line, t = filtered[r], ftypes[r]
        cur = out[r]
        if t == 0:
            cur[:] = line
        elif t == 2:
            np.add(line, prior, out=cur)
        else:  # Sub: running sum per byte lane, modulo 256
            np.cumsum(line.reshape(-1, bpp), axis=0, dtype=np.uint8, out=cur.reshape(-1, bpp))
        prior = cur
    return out


_KERNEL = None


def _unfilter_kernel():
    """Numba kernel for all five filters (needed for Average and Paeth rows)."""
    global _KERNEL
    if _KERNEL is None:
        import numba

        @numba.njit(cache=True, nogil=True)
        def _unfilter_all(filt, ftypes, bpp):  # pragma: no cover - compiled
            nrow, stride = filt.shape
            out = np.empty((nrow, stride), dtype=np.uint8)
            for r in range(nrow):
                t = ftypes[r]
                for i in range(stride):
                    x = np.int32(filt[r, i])
                    a = np.int32(out[r, i - bpp]) if i >= bpp else np.int32(0)
                    b = np.int32(out[r - 1, i]) if r > 0 else np.int32(0)
                    if t == 0:
                        v = x
                    elif t == 1:
                        v = x + a
                    elif t == 2:
                        v = x + b
                    elif t == 3:
                        v = x + (a + b) // 2
                    else:
                        c = np.int32(out[r - 1, i - bpp]) if (r > 0 and i >= bpp) else np.int32(0)
                        p = a + b - c
                        pa = abs(p - a)
                        pb = abs(p - b)
                        pc = abs(p - c)
                        if pa <= pb and pa <= pc:
                            pred = a
                        elif pb <= pc:
                            pred = b
                        else:
                            pred = c
                        v = x + pred
                    out[r, i] = np.uint8(v & 0xFF)
            return out

        _KERNEL = _unfilter_all
    return _KERNEL


def png_info(path: str | os.PathLike) -> dict:
    """Size and bit depth from the PNG header alone: {"cols", "rows", "bit_depth"}."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(33)
    except FileNotFoundError:
        raise FileFormatError(f"image '{path}': no such file") from None
    except OSError as exc:
        raise FileFormatError(f"image '{path}': unreadable ({exc.strerror or exc})") from None
    if len(head) < 33 or not head.startswith(PNG_SIGNATURE) or head[12:16] != b"IHDR":
        raise FileFormatError(f"image '{path}': not a PNG file; supported: {SUPPORTED}, or .npy")
    width, height, depth = _parse_ihdr(head[16:29], path)
    return {"cols": width, "rows": height, "bit_depth": depth}


# ----------------------------------------------------------------- writing
def _filter_rows(raw: np.ndarray, ftypes: np.ndarray, bpp: int) -> np.ndarray:
    """Apply PNG filters to raw scanlines (vectorised: filters read raw bytes only)."""
    kinds = np.unique(ftypes)
    out = np.empty_like(raw)
    for t in kinds:
        sel = slice(None) if len(kinds) == 1 else (ftypes == t)
        x = raw[sel]
        if t == 0:
            out[sel] = x
            continue
        left = np.zeros_like(x)
        left[:, bpp:] = x[:, :-bpp]
        up = np.zeros_like(raw)
        up[1:] = raw[:-1]
        up = up[sel]
        if t == 1:
            out[sel] = x - left                       # uint8 arithmetic wraps modulo 256
        elif t == 2:
            out[sel] = x - up
        elif t == 3:
            out[sel] = x - ((left.astype(np.int16) + up) // 2).astype(np.uint8)
        else:
            upleft = np.zeros_like(raw)
            upleft[1:, bpp:] = raw[:-1, :-bpp]
            a, b, c = left.astype(np.int16), up.astype(np.int16), upleft[sel].astype(np.int16)
            p = a + b - c
            pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
            pred = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
            out[sel] = x - pred.astype(np.uint8)
    return out


def _chunk(ctype: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + ctype + body + struct.pack(">I", zlib.crc32(ctype + body) & 0xFFFFFFFF)


def encode_png(gray: np.ndarray, filter_type: int | str | np.ndarray = "up", level: int = 6,
               text: dict | None = None) -> bytes:
    """Encode a grayscale image as PNG bytes.

    Parameters
    ----------
    gray : ndarray of shape (rows, cols), uint8 or uint16
        Gray values (bit depth follows the dtype).
    filter_type : int, name, or ndarray of shape (rows,)
        PNG filter for every row (0-4 or "none", "sub", "up", "average",
        "paeth"), or one per row.
    level : int
        zlib compression level 0-9.
    text : dict, optional
        ``{keyword: value}`` written as PNG ``tEXt`` chunks (Latin-1).
    """
    gray = np.asarray(gray)
    if gray.ndim != 2 or gray.size == 0:
        raise InputError(f"`gray` must be a non-empty 2-D array (got shape {gray.shape})")
    if gray.dtype == np.uint8:
        depth, raw = 8, gray
    elif gray.dtype == np.uint16:
        depth, raw = 16, gray.astype(">u2").view(np.uint8).reshape(gray.shape[0], -1)
    else:
        raise InputError(f"`gray` must be uint8 or uint16 (got {gray.dtype})")
    rows, cols = gray.shape
    if isinstance(filter_type, str):
        if filter_type not in FILTER_NAMES:
            from .errors import unknown_key
            raise unknown_key("PNG filter", filter_type, FILTER_NAMES)
        filter_type = FILTER_NAMES.index(filter_type)
    ftypes = np.broadcast_to(np.asarray(filter_type, dtype=np.uint8), (rows,))
    if ftypes.max() > 4:
        raise InputError(f"`filter_type` must be 0-4 (got {int(ftypes.max())})")
    filtered = _filter_rows(raw, ftypes, depth // 8)
    scan = np.empty((rows, filtered.shape[1] + 1), dtype=np.uint8)
    scan[:, 0] = ftypes
    scan[:, 1:] = filtered
    ihdr = struct.pack(">IIBBBBB", cols, rows, depth, 0, 0, 0, 0)
    texts = b"".join(_chunk(b"tEXt", str(k).encode("latin-1") + b"\0" + str(v).encode("latin-1"))
                     for k, v in (text or {}).items())
    return (PNG_SIGNATURE + _chunk(b"IHDR", ihdr) + texts + _chunk(b"IDAT", zlib.compress(scan.tobytes(), level))
            + _chunk(b"IEND", b""))


def write_png(path: str | os.PathLike, gray: np.ndarray, filter_type: int | str | np.ndarray = "up",
              level: int = 6) -> Path:
    """Write a grayscale PNG atomically (see :func:`encode_png`). Returns the path."""
    data = encode_png(gray, filter_type, level)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path


# ----------------------------------------------------------------- npy
def read_npy(path: str | os.PathLike) -> np.ndarray:
    """Read a ``.npy`` height array of shape (rows, cols) or (cols,).

    The shape is checked from the file header before the data is read.
    Returns the stored array (integer or float dtype; bool and complex are
    refused).
    """
    path = Path(path)
    try:
        fh = open(path, "rb")
    except FileNotFoundError:
        raise FileFormatError(f"array '{path}': no such file") from None
    except OSError as exc:
        raise FileFormatError(f"array '{path}': unreadable ({exc.strerror or exc})") from None
    with fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        except (ValueError, OSError, SyntaxError) as exc:
            raise FileFormatError(f"array '{path}': not a .npy file ({exc})") from None
        if len(shape) not in (1, 2):
            raise FileFormatError(f"array '{path}': heights must have shape (rows, cols) or (cols,) (got {shape})")
        if dtype.kind not in "uif":
            raise FileFormatError(f"array '{path}': dtype {dtype} is not supported; use an integer or float array")
        rows, cols = (1, shape[0]) if len(shape) == 1 else shape
        check_grid_size(rows, cols, f"array '{path}'")
        fh.seek(0)
        try:
            arr = np.load(fh, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise FileFormatError(f"array '{path}': truncated or corrupt ({exc})") from None
    return arr
