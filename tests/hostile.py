"""Helpers shared by the hostile-input tests: a small table, its parts, and writers of edited copies.

The checksum is recomputed here by the rule the table module documents
(sha256 over the header's JSON without the checksum, sorted keys, then per
channel in name order: name, NUL, little-endian dtype string, NUL, the bytes),
independently of the module's own function.
"""
from __future__ import annotations

import hashlib
import io
import json
import zipfile

import numpy as np

from shapedisplay.author.compile import CompileOptions, compile_heightfield
from shapedisplay.author.forces import MappingOptions
from shapedisplay.author.heightfield import HeightField


def small_table():
    """A 6 x 10 table with a uint8 normal force and float32 lateral and slope channels."""
    yy, xx = np.mgrid[0:6, 0:10]
    h = 1e-3 * np.exp(-((xx - 5.0) ** 2 + (yy - 3.0) ** 2) / 6.0)
    hf = HeightField(h, 1e-3, 1e-3)
    mapping = MappingOptions(lateral="gradient", lateral_gain=0.5, slope_friction_gain=0.2)
    return compile_heightfield(hf, mapping=mapping, options=CompileOptions(quantize="float32")).table


def table_bytes(table) -> bytes:
    """The bytes of ``table`` saved as a file (np.savez_compressed, as FrictionTable.save writes)."""
    header = table.header()
    header["checksum"] = documented_checksum(header, table.codes)
    return npz_bytes(header, table.codes, compressed=True)


def documented_checksum(header: dict, arrays: dict) -> str:
    d = hashlib.sha256()
    d.update(json.dumps({k: v for k, v in header.items() if k != "checksum"}, sort_keys=True).encode())
    for name in sorted(arrays):
        a = np.asarray(arrays[name])
        le = a.dtype.newbyteorder("<")
        d.update(name.encode() + b"\0" + le.str.encode() + b"\0")
        d.update(a.astype(le, copy=False).tobytes())
    return "sha256:" + d.hexdigest()


def npz_bytes(header, arrays: dict, compressed: bool = False, header_text: str | None = None) -> bytes:
    """An .npz of a header (JSON, or ``header_text`` verbatim) and arrays."""
    text = header_text if header_text is not None else json.dumps(header, sort_keys=True)
    buf = io.BytesIO()
    save = np.savez_compressed if compressed else np.savez
    save(buf, header=np.frombuffer(text.encode("utf-8", "surrogatepass"), dtype=np.uint8), **arrays)
    return buf.getvalue()


def npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr)
    return buf.getvalue()


def zip_of(entries: list[tuple[str, bytes]], method: int = zipfile.ZIP_DEFLATED) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", method) as z:
        for name, data in entries:
            z.writestr(name, data)
    return buf.getvalue()


def zip_bomb(path, table, inflated_bytes: int, entry: str = "normal_force", mode: str = "data") -> None:
    """Write a table whose ``entry`` inflates to ``inflated_bytes`` of zeros (compressed ~1000:1).

    ``mode`` "data": the .npy header declares the true (small) shape, the zip entry
    is huge; "shape": the .npy header declares the huge shape as well.
    """
    header = table.header()
    header["checksum"] = documented_checksum(header, table.codes)
    arrays = dict(table.codes)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("header.npy", npy_bytes(np.frombuffer(json.dumps(header).encode(), np.uint8)))
        for name, a in arrays.items():
            if name != entry:
                z.writestr(f"{name}.npy", npy_bytes(a))
                continue
            a = np.asarray(a)
            n = a.size if mode == "data" else inflated_bytes // a.itemsize
            head = npy_bytes(np.zeros(0, a.dtype))
            head = head.replace(b"(0,)", f"({n},)".encode())
            head = _repad(head)
            info = zipfile.ZipInfo(f"{name}.npy")
            info.compress_type = zipfile.ZIP_DEFLATED
            with z.open(info, "w", force_zip64=True) as f:
                f.write(head)
                zeros = bytes(1 << 20)
                left = inflated_bytes
                while left > 0:
                    f.write(zeros[:min(left, len(zeros))])
                    left -= len(zeros)


def _repad(npy: bytes) -> bytes:
    """Re-pad a version-1 .npy header after its text changed length (numpy aligns data to 64 bytes)."""
    hlen = int.from_bytes(npy[8:10], "little")
    text = npy[10:10 + hlen].rstrip(b" \n")
    total = 10 + len(text) + 1
    pad = (-total) % 64
    text = text + b" " * pad + b"\n"
    return npy[:8] + len(text).to_bytes(2, "little") + text + npy[10 + hlen:]
