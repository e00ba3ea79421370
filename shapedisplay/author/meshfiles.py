"""Mesh files checked before trimesh parses them: sizes, truncation and polygons, each bounded by a limit.

A mesh file's cost can lie far beyond its size (a truncated STL reads as
empty, an 80,000-vertex polygon rasterises for most of a minute): the checks
here read only what the header or one pass over the mapped file gives, and
refuse with one line naming the limit (docs/limits.md).
"""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from shapedisplay.errors import FileFormatError

#: Largest mesh file read, bytes, checked before the file is parsed.
MAX_MESH_BYTES = 512 * 1024 * 1024
#: Most triangles a binary STL may declare in its header (10 M triangles = 500 MB of STL).
MAX_MESH_TRIANGLES = 10_000_000
#: Largest magnitude of a vertex coordinate, file units: the footprint, areas and normals are
#: products of up to four coordinates, finite in float64 below this (an STL's float32 stays under 3.4e38).
MAX_COORDINATE = 1e60
#: Most vertices of one OBJ face (polygon), checked before trimesh splits it into a fan of
#: triangles: each slice of a fan spans the polygon, and rasterising them costs the polygon's
#: area per vertex (80,000 vertices: 47.5 s).
MAX_FACE_VERTICES = 4096
#: Most records of a PLY triangle-strip element (a scanner writes one strip, or one per row of the scan):
#: each record is read on its own, so the count bounds the reading time.
MAX_PLY_STRIPS = 1_000_000



def _check_stl(path: Path) -> None:
    """Detect truncated STL files, which trimesh reads as empty without complaint."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(84)
    if len(head) >= 84:
        (n,) = struct.unpack("<I", head[80:84])
        if size == 84 + 50 * n:
            if n > MAX_MESH_TRIANGLES:
                raise FileFormatError(f"mesh '{path}': {n} triangles exceed the limit of {MAX_MESH_TRIANGLES}")
            return  # consistent binary STL
    if head[:5].lower() == b"solid":
        with open(path, "rb") as f:
            f.seek(max(0, size - 512))
            tail = f.read().lower()
        if b"endsolid" in tail:
            return  # ASCII STL with its closing line
        if b"facet" in head.lower() or size < 84:
            raise FileFormatError(f"mesh '{path}': ASCII STL is truncated (no closing 'endsolid' line)")
    if len(head) < 84:
        raise FileFormatError(f"mesh '{path}': binary STL is truncated ({size} bytes, the header alone is 84)")
    raise FileFormatError(
        f"mesh '{path}': binary STL is truncated or corrupt: header says {n} triangles "
        f"({84 + 50 * n} bytes) but the file has {size} bytes"
    )


def _refuse_face(path: Path, n: int, where: str) -> None:
    raise FileFormatError(
        f"mesh '{path}': face {where} has {n} vertices, beyond the limit of {MAX_FACE_VERTICES} a face "
        f"(shapedisplay.author.meshfiles.MAX_FACE_VERTICES); triangulate the polygon in a modelling program first")


def _check_text_faces(path: Path, data, prefix: bytes, skip_tokens: int) -> None:
    """Long face lines of a text mesh (OBJ ``f ...``, OFF and ASCII PLY ``N i1 i2 ...``), found by one regex pass.

    Only lines long enough to hold :data:`MAX_FACE_VERTICES` vertices (two
    bytes each at least) are split: about 3 ms per MB of file.
    """
    import itertools
    import re
    face = rb"[ \t]*" + prefix + rb"[^\n]{%d,}" % (2 * MAX_FACE_VERTICES - 1)
    first = re.compile(face).match(data)
    for match in itertools.chain([first] if first else [], re.compile(rb"\n" + face).finditer(data)):
        tokens = match.group().split()
        if prefix:                                    # OBJ: every token after 'f' is a vertex
            n = len(tokens) - skip_tokens
        else:                                         # OFF / PLY: the first token counts the vertices
            try:
                n = int(tokens[0])
            except ValueError:
                continue
        if n > MAX_FACE_VERTICES:
            start = match.start() + (data[match.start():match.start() + 1] == b"\n")
            line = data[:start].count(b"\n") + 1
            _refuse_face(path, n, f"on line {line}")


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def _check_binary_ply_faces(path: Path, data, header_end: int, elements: list, order: str) -> None:
    """Vertex counts of a binary PLY's faces, read with numpy where every face has the same layout."""
    pos = header_end
    for name, count, props in elements:
        lists = [p for p in props if p[0] == "list"]
        if name != "face":
            if lists:                     # variable-size records before the faces: leave the check to the reader
                return
            pos += count * sum(np.dtype(_PLY_TYPES.get(p[1], "u1")).itemsize for p in props)
            continue
        if len(props) != 1 or not lists or count == 0:
            return
        _, ctype, itype = lists[0]
        if ctype not in _PLY_TYPES or itype not in _PLY_TYPES:
            return
        cdt = np.dtype(_PLY_TYPES[ctype]).newbyteorder(order)
        count_fmt = order + cdt.char                 # struct reads single counts (no view kept on the map)
        isz = np.dtype(_PLY_TYPES[itype]).itemsize
        if pos + cdt.itemsize > len(data):
            return
        k = struct.unpack_from(count_fmt, data, pos)[0]
        if k > MAX_FACE_VERTICES:
            _refuse_face(path, k, "#0")
        stride = cdt.itemsize + k * isz
        if k >= 0 and pos + count * stride <= len(data):
            rec = np.dtype({"names": ["n"], "formats": [cdt], "itemsize": stride})
            view = np.frombuffer(data, rec, count, pos)
            uniform = bool(np.all(view["n"] == k))
            del view                                  # the map closes only once no view is left
            if uniform:                               # every face has k vertices: nothing beyond the limit
                return
        for i in range(count):                        # mixed polygon sizes: walk the records
            if pos + cdt.itemsize > len(data):
                return
            n = struct.unpack_from(count_fmt, data, pos)[0]
            if n > MAX_FACE_VERTICES:
                _refuse_face(path, n, f"#{i}")
            pos += cdt.itemsize + max(n, 0) * isz
        return


def _ply_header(data) -> tuple[str, list, int] | None:
    """A PLY header's format, its elements ``(name, count, properties)`` and where the data starts (or None)."""
    end = data.find(b"end_header", 0, 1 << 16)
    if end < 0:
        return None
    header = bytes(data[:end]).decode("ascii", "replace").split("\n")
    fmt = next((ln.split()[1] for ln in header if ln.startswith("format ") and len(ln.split()) > 1), "")
    elements: list = []
    for ln in header:
        t = ln.split()
        if len(t) >= 3 and t[0] == "element" and t[2].isdigit():
            elements.append((t[1], int(t[2]), []))
        elif len(t) >= 3 and t[0] == "property" and elements:
            elements[-1][2].append(("list", t[2], t[3]) if t[1] == "list" and len(t) >= 5 else ("scalar", t[1]))
    return fmt, elements, data.find(b"\n", end) + 1


def ply_elements(path: Path) -> dict:
    """Element name -> count of a PLY file's header (empty when there is no header to read)."""
    with open(path, "rb") as fh:
        head = _ply_header(fh.read(1 << 16))
    return {} if head is None else {name: count for name, count, _ in head[1]}


def _check_faces(path: Path) -> None:
    """Refuse a polygon of more than :data:`MAX_FACE_VERTICES` vertices (OBJ, OFF, PLY) before trimesh reads it.

    trimesh splits a polygon into a fan of triangles; each slice of the fan
    spans the polygon, and rasterising them costs the polygon's area per
    vertex (an 80,000-vertex OBJ face: 47.5 s; an 800,000-vertex OFF face: 17 s).
    """
    import mmap
    suffix = path.suffix.lower()
    if suffix not in (".obj", ".off", ".ply") or path.stat().st_size == 0:
        return
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as data:
        if suffix == ".obj":
            return _check_text_faces(path, data, rb"f[ \t]", 1)
        if suffix == ".off":
            return _check_text_faces(path, data, b"", 0)
        head = _ply_header(data)
        if head is None:
            return                        # not a PLY header trimesh can read either: its error names it
        fmt, elements, header_end = head
        if fmt == "ascii":
            return _check_text_faces(path, data, b"", 0)
        if fmt in ("binary_little_endian", "binary_big_endian") and header_end > 0:
            _check_binary_ply_faces(path, data, header_end, elements, "<" if fmt.endswith("little_endian") else ">")


def check_mesh_file(path: Path, suffix: str) -> None:
    """Every check that applies to ``path`` before it is parsed: readable, size, STL truncation, polygon sizes."""
    if not path.is_file():
        raise FileFormatError(f"mesh '{path}': file not found")
    if not os.access(path, os.R_OK):
        raise FileFormatError(f"mesh '{path}': file is not readable (permission denied)")
    size = path.stat().st_size
    if size == 0:
        raise FileFormatError(f"mesh '{path}': file is empty (0 bytes)")
    if size > MAX_MESH_BYTES:
        raise FileFormatError(f"mesh '{path}': {size} bytes exceed the limit of {MAX_MESH_BYTES} (simplify the mesh)")
    if suffix == ".stl":
        _check_stl(path)
    elif suffix in (".obj", ".off", ".ply"):
        _check_faces(path)
