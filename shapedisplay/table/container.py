"""Bounded reading of ``.npz`` containers (tables and traces) and their JSON.

Every path that reads a table or a trace — a file, uploaded bytes, the
preview, the device emulator and the C engine it feeds — goes through
:class:`NpzReader`. It never lets a file decide how much memory is spent:

* the zip's central directory is checked first: at most ``max_entries``
  entries, each named ``<name>.npy`` for a name the caller expects, no name
  twice, no encryption flag, compression stored or deflate only;
* an entry is read as a stream, never more than its cap: the declared size
  must fit the cap, and the decompressed bytes must match the declared size
  (a zip bomb stops at the cap, however many bytes it would inflate to);
* a ``.npy`` header is parsed by a strict pattern (not evaluated): version
  1–3, at most :data:`NPY_HEADER_MAX` bytes, a dtype the caller allows, C
  order, a shape whose element count fits the caller's cap (Python integers:
  no overflow), and a byte count equal to what the zip declares;
* JSON is read with a size cap and a nesting-depth cap checked before it is
  parsed, and ``NaN``/``Infinity`` are refused.

:func:`write_npz` writes such containers (what ``numpy.savez_compressed``
writes, with a compression chosen per entry for speed: see there).

Anything wrong raises :class:`~shapedisplay.errors.TableError` (or the
``error`` class given) naming the file, the entry, the rule and the value.
This module is on the runtime side and imports only numpy.
"""
from __future__ import annotations

import io
import json
import os
import re
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np

from shapedisplay.errors import TableError

#: Largest ``.npy`` header accepted, bytes (numpy writes 64–128).
NPY_HEADER_MAX = 4096
#: Deepest nesting of JSON arrays/objects accepted.
JSON_MAX_DEPTH = 32
#: Chunk read from a zip entry at a time, bytes.
_CHUNK = 1 << 20
#: Exceptions the standard library's zip, zlib and struct code raise on damaged input.
_DAMAGE = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, struct.error, EOFError, OSError,
           ValueError, NotImplementedError, RuntimeError, OverflowError, KeyError, IndexError,
           UnicodeDecodeError)

_NPY_MAGIC = b"\x93NUMPY"
_NPY_HEADER = re.compile(
    r"\{'descr': '(?P<descr>[<>|=][a-zA-Z]\d{1,3})', 'fortran_order': (?P<fortran>False|True), "
    r"'shape': \((?P<shape>(?:\d{1,19}, ?)*\d{0,19})\), \}[ ]*\n?$")
_JSON_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


#: Entries up to this many bytes are deflated at zlib's default level, as ``numpy.savez_compressed`` does.
SMALL_ENTRY = 1 << 20
#: zlib level of a large deflated entry: the fastest deflate, as the files are written while a user waits.
LARGE_LEVEL = 1
#: A large entry is stored uncompressed if deflate (level 1) keeps more than this fraction of a sample of it.
STORE_ABOVE_RATIO = 0.7
_SAMPLES = 8
_SAMPLE_BYTES = 1 << 15


def entry_compression(data) -> tuple[int, int | None]:
    """How :func:`write_npz` stores one entry: ``(zipfile compress type, zlib level)``.

    Small entries (<= :data:`SMALL_ENTRY` bytes): deflate at zlib's default
    level 6. Large ones: deflate at level 1 (3-5x faster than level 6 on
    smooth maps, about 1.5-2x the bytes), or stored when deflating
    :data:`_SAMPLES` evenly spaced 32 KiB pieces keeps more than
    :data:`STORE_ABOVE_RATIO` of them: codes of a noisy map hardly compress,
    and deflating them only to find that out costs time. Both are plain zip
    methods that any zip or ``numpy.load`` reads.
    """
    view = memoryview(data).cast("B")
    n = len(view)
    if n <= SMALL_ENTRY:
        return zipfile.ZIP_DEFLATED, 6
    step = (n - _SAMPLE_BYTES) // (_SAMPLES - 1)
    packed = sum(len(zlib.compress(view[i * step:i * step + _SAMPLE_BYTES], LARGE_LEVEL)) for i in range(_SAMPLES))
    if packed > STORE_ABOVE_RATIO * _SAMPLES * _SAMPLE_BYTES:
        return zipfile.ZIP_STORED, None
    return zipfile.ZIP_DEFLATED, LARGE_LEVEL


#: Largest size zipfile writes without zip64 records (``zipfile.ZIP64_LIMIT``).
_ZIP64_LIMIT = (1 << 31) - 1


def write_npz(fh, arrays: dict) -> None:
    """Write ``arrays`` ({name: ndarray}) to the binary file object ``fh`` as an ``.npz``.

    Each entry ``NAME.npy`` holds the array in ``.npy`` format exactly as
    ``numpy.save`` writes it, compressed as :func:`entry_compression`
    chooses, by the standard library's ``zipfile`` and ``zlib``. Entry times
    are fixed (1980-01-01), so equal arrays give equal bytes.
    :class:`NpzReader` and ``numpy.load`` read the result.

    The array bytes stream from the array into the zip entry a chunk at a
    time (no ``.npy`` copy of the array in memory); the bytes are those of
    ``ZipFile.writestr`` on the whole ``numpy.save`` output (the tests
    compare them). Only ``zipfile``'s public API sets the levels: the zip's
    own method and level (deflate, :data:`LARGE_LEVEL`) apply to the large
    deflated entries, opened by name; the others are opened as a
    ``ZipInfo`` of their method (stored, or deflate at zlib's default
    level, 6).
    """
    with zipfile.ZipFile(fh, "w", zipfile.ZIP_DEFLATED, allowZip64=True, compresslevel=LARGE_LEVEL) as zf:
        for name, a in arrays.items():
            a = np.ascontiguousarray(a)
            if a.dtype.hasobject:
                raise ValueError(f"entry '{name}': object arrays cannot be stored")
            data = a.reshape(-1).view(np.uint8)
            method, level = entry_compression(data)
            head = io.BytesIO()
            np.lib.format.write_array_header_1_0(head, np.lib.format.header_data_from_array_1_0(a))
            if method == zipfile.ZIP_DEFLATED and level == LARGE_LEVEL:
                entry = f"{name}.npy"                   # the zip's method and level; time 1980-01-01
            else:                                       # stored, or deflate at zlib's default level (6)
                entry = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
                entry.compress_type = method
            # zip64 records where writestr would put them (decided from the size before any byte)
            with zf.open(entry, "w", force_zip64=(head.tell() + data.size) * 1.05 > _ZIP64_LIMIT) as dest:
                dest.write(head.getbuffer())
                for i in range(0, data.size, _CHUNK):
                    dest.write(data[i:i + _CHUNK])


class NpzReader:
    """An ``.npz`` (zip of ``.npy``) opened with bounds, from a path or bytes.

    Parameters
    ----------
    source : path or bytes
        The file, or its bytes (an upload).
    label : str
        How messages name it: ``"table 't.npz'"``, ``"uploaded table"``.
    names : collection of str or None
        Array names the caller knows; any other entry is refused. None: any
        ``NAME.npy`` (the caller checks the names).
    max_entries : int
        Most entries the zip may hold.
    error : type
        Exception class raised (a :class:`TableError` subclass or sibling).
    """

    def __init__(self, source, label: str, names, max_entries: int, error=TableError):
        self.label = label
        self.error = error
        self._names = None if names is None else set(names)
        if isinstance(source, (bytes, bytearray, memoryview)):
            fh = io.BytesIO(bytes(source))
        else:
            try:
                fh = open(Path(os.fspath(source)), "rb")
            except OSError as exc:
                raise error(f"{label}: unreadable ({exc.strerror or exc})") from None
        self._fh = fh
        try:
            self._zip = zipfile.ZipFile(fh)
            infos = self._zip.infolist()
        except _DAMAGE as exc:
            fh.close()
            raise error(f"{label}: unreadable or truncated .npz zip archive ({_why(exc)})") from None
        self.entries: dict[str, zipfile.ZipInfo] = {}
        try:
            if len(infos) > max_entries:
                raise error(f"{label}: holds {len(infos)} zip entries; at most {max_entries} are allowed")
            for info in infos:
                self._check_entry(info)
        except BaseException:
            self.close()
            raise

    def _check_entry(self, info: zipfile.ZipInfo) -> None:
        label, name = self.label, info.filename
        stem = name[:-4] if name.endswith(".npy") else None
        if stem is None or len(name) > 128 or (self._names is not None and stem not in self._names):
            expected = f"{', '.join(sorted(self._names))} (.npy)" if self._names is not None else "NAME.npy"
            raise self.error(f"{label}: unexpected zip entry {_short_name(name)}; expected {expected}")
        if stem in self.entries:
            raise self.error(f"{label}: zip entry {_short_name(name)} appears twice")
        if info.flag_bits & 0x1:
            raise self.error(f"{label}: zip entry {name!r} is encrypted; tables are never encrypted")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise self.error(f"{label}: zip entry {name!r} uses compression method {info.compress_type}; "
                             f"only stored (0) and deflate (8) are allowed")
        self.entries[stem] = info

    # ------------------------------------------------------------ context
    def close(self) -> None:
        try:
            self._zip.close()
        finally:
            self._fh.close()

    def __enter__(self) -> "NpzReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __contains__(self, name: str) -> bool:
        return name in self.entries

    # ------------------------------------------------------------ arrays
    def read_array(self, name: str, dtypes, max_items: int, *, shape=None, ndim=None) -> np.ndarray:
        """Read entry ``name`` as an array, spending at most what its cap allows.

        Parameters
        ----------
        dtypes : collection of str
            Allowed numpy dtype strings without byte order (``"u1"``, ``"f4"``,
            ``"U64"``); stored byte order must be little-endian or none.
        max_items : int
            Most elements accepted.
        shape : tuple, optional
            Exact shape required.
        ndim : int, optional
            Exact number of dimensions required.

        Returns
        -------
        ndarray, native byte order, read-only.
        """
        where = f"{self.label}, entry '{name}'"
        info = self.entries.get(name)
        if info is None:
            raise self.error(f"{self.label}: no '{name}' entry")
        try:
            with self._zip.open(info) as f:
                head = _read_exact(f, 10)
                if len(head) < 10 or head[:6] != _NPY_MAGIC:
                    raise self.error(f"{where}: not a .npy array (starts with {head[:8]!r})")
                major = head[6]
                if major == 1:
                    hlen = struct.unpack("<H", head[8:10])[0]
                    extra = b""
                elif major in (2, 3):
                    extra = _read_exact(f, 2)
                    hlen = struct.unpack("<I", head[8:10] + extra)[0]
                else:
                    raise self.error(f"{where}: .npy version must be 1, 2 or 3 (got {major})")
                if hlen > NPY_HEADER_MAX:
                    raise self.error(f"{where}: .npy header of {hlen} bytes exceeds {NPY_HEADER_MAX}")
                text = _read_exact(f, hlen)
                if len(text) != hlen:
                    raise self.error(f"{where}: truncated .npy header")
                m = _NPY_HEADER.match(text.decode("latin1"))
                if not m:
                    raise self.error(f"{where}: .npy header is not in numpy's form "
                                     f"({text[:60].decode('latin1')!r})")
                descr = m.group("descr")
                if descr[0] == ">" or descr[1:] not in set(dtypes):
                    raise self.error(f"{where}: dtype must be one of {sorted(dtypes)} little-endian "
                                     f"(got {descr!r})")
                if m.group("fortran") == "True":
                    raise self.error(f"{where}: Fortran-ordered arrays are not accepted")
                dims = tuple(int(s) for s in m.group("shape").replace(" ", "").split(",") if s)
                if shape is not None and dims != tuple(shape):
                    raise self.error(f"{where}: shape must be {tuple(shape)} (got {dims})")
                if ndim is not None and len(dims) != ndim:
                    raise self.error(f"{where}: must have {ndim} dimension(s) (got shape {dims})")
                count = 1
                for d in dims:
                    count *= d
                if count > max_items:
                    raise self.error(f"{where}: {count} elements exceed the limit of {max_items}")
                dtype = np.dtype(descr)
                nbytes = count * dtype.itemsize
                declared = info.file_size - 10 - len(extra) - hlen
                if declared != nbytes:
                    raise self.error(f"{where}: holds {declared} data bytes; shape {dims} of {descr} "
                                     f"needs {nbytes}")
                data = _read_exact(f, nbytes)
                if len(data) != nbytes or f.read(1):
                    raise self.error(f"{where}: data is {len(data)} bytes, {nbytes} expected (truncated)")
        except self.error:
            raise
        except _DAMAGE as exc:
            raise self.error(f"{where}: unreadable or truncated ({_why(exc)})") from None
        arr = np.frombuffer(data, dtype=dtype).reshape(dims)
        if dtype.byteorder not in ("=", "|") and not dtype.isnative:
            arr = arr.astype(dtype.newbyteorder("="))
        return arr

    def read_json(self, name: str, max_bytes: int, max_depth: int = JSON_MAX_DEPTH):
        """Read entry ``name`` (a uint8 ``.npy`` of UTF-8 JSON) with a size and depth cap."""
        raw = self.read_array(name, ("u1", "i1"), max_bytes, ndim=1)
        return parse_json(raw.tobytes(), f"{self.label}, entry '{name}'", max_depth, self.error)


def too_deep(text: str, tokens: re.Pattern, limit: int) -> int | None:
    """Offset in ``text`` of the first bracket that opens a level deeper than ``limit``, or None.

    ``tokens`` matches the brackets ``[]{}`` and whatever must be skipped whole (strings, comments); a
    scan without recursion, so it runs before a recursive parser would meet the nesting."""
    depth = 0
    for m in tokens.finditer(text):
        tok = m.group()
        if tok in ("[", "{"):
            depth += 1
            if depth > limit:
                return m.start()
        elif tok in ("]", "}"):
            depth = max(depth - 1, 0)
    return None


def parse_json(data: bytes, where: str, max_depth: int = JSON_MAX_DEPTH, error=TableError):
    """Parse UTF-8 JSON whose nesting is at most ``max_depth``; NaN/Infinity refused."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{where}: not UTF-8 text (byte {exc.start})") from None
    if too_deep(text, _JSON_TOKENS, max_depth) is not None:
        raise error(f"{where}: JSON nests deeper than {max_depth} levels")

    def constant(name):
        raise _NonFinite(name)

    try:
        return json.loads(text, parse_constant=constant)
    except _NonFinite as exc:
        raise error(f"{where}: numbers must be finite (got {exc})") from None
    except (ValueError, RecursionError) as exc:
        raise error(f"{where}: not valid JSON ({_why(exc)})") from None


class _NonFinite(ValueError):
    pass


def _read_exact(f, n: int) -> bytes:
    """Read up to ``n`` bytes in chunks (a damaged stream may end early)."""
    if n <= _CHUNK:
        return f.read(n)
    parts, left = [], n
    while left > 0:
        b = f.read(min(left, _CHUNK))
        if not b:
            break
        parts.append(b)
        left -= len(b)
    return b"".join(parts)


def _short_name(name: str) -> str:
    return repr(name if len(name) <= 60 else name[:57] + "...")


def _why(exc: BaseException) -> str:
    text = " ".join(str(exc).split())[:120]
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
