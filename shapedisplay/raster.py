"""Z-buffer rasterisation of triangle soups onto a regular grid.

Functions for dealing with triangle meshes -- vertices (n, 3) and faces
(m, 3), or soups in (m, 3, 3) float form -- already expressed in *grid
units*: a vertex ``(u, v, z)`` has ``u`` in columns,
``v`` in rows (sample ``(r, c)`` sits at ``u = c, v = r``) and ``z`` in any
height unit. Every sample takes the **highest** surface above it (max
reduction), so overhangs keep their top and the triangle winding (normal
direction) does not matter.

A sample belongs to a triangle when it lies inside it or within
:data:`EDGE_TOLERANCE` samples of one of its edges. The test is inclusive so
that a sample exactly on an edge shared by two triangles is never lost (max
reduction makes a double hit harmless). Heights are interpolated
barycentrically relative to the first vertex (so a flat triangle gives
its height exactly) and clamped to the triangle's own height range (a sample
just outside a steep sliver would otherwise extrapolate far beyond it). Triangles with zero projected area (vertical faces) cover no
sample: a vertical wall appears as a step between neighbouring samples.

Backends, by name in :data:`METHODS`:

``"numba"``
    Compiled loop over triangles; per-triangle bounding box, edge functions,
    max into the buffer. Linear in triangles plus covered samples. Default.
``"numpy"``
    Pure numpy reference: candidate (triangle, sample) pairs from each
    bounding box in chunks, the same edge test, ``np.maximum.at``. Same answer,
    slower; used to check the compiled kernel and as a benchmark baseline.
"""
from __future__ import annotations

import numpy as np

from .errors import unknown_key

#: A sample within this distance (in samples) of a triangle edge counts as inside
#: (absorbs float32 rounding of coordinates read from STL/PLY files).
EDGE_TOLERANCE = 1e-5


def _check(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"`vertices` must have shape (n, 3) (got {v.shape})")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"`faces` must have shape (m, 3) (got {f.shape})")
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError(f"`faces` index outside 0..{len(v) - 1} (got {f.min()}..{f.max()})")
    return v, f


def _numba_kernel():
    import numba

    @numba.njit(cache=True, nogil=True)
    def kernel(vert, faces, zbuf, tol):  # pragma: no cover - compiled
        rows, cols = zbuf.shape
        for t in range(faces.shape[0]):
            i, j, k = faces[t, 0], faces[t, 1], faces[t, 2]
            ax, ay, az = vert[i, 0], vert[i, 1], vert[i, 2]
            bx, by, bz = vert[j, 0], vert[j, 1], vert[j, 2]
            cx, cy, cz = vert[k, 0], vert[k, 1], vert[k, 2]
            area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
            if area == 0.0:
                continue
            s = 1.0 if area > 0.0 else -1.0
            area = area * s
            # edge lengths scale the tolerance into edge-function units
            la = np.sqrt((cx - bx) ** 2 + (cy - by) ** 2) * tol
            lb = np.sqrt((ax - cx) ** 2 + (ay - cy) ** 2) * tol
            lc = np.sqrt((bx - ax) ** 2 + (by - ay) ** 2) * tol
            c0 = max(int(np.ceil(min(ax, bx, cx) - tol)), 0)
            c1 = min(int(np.floor(max(ax, bx, cx) + tol)), cols - 1)
            r0 = max(int(np.ceil(min(ay, by, cy) - tol)), 0)
            r1 = min(int(np.floor(max(ay, by, cy) + tol)), rows - 1)
            if c0 > c1 or r0 > r1:
                continue
            zlo, zhi = min(az, bz, cz), max(az, bz, cz)
            for r in range(r0, r1 + 1):
                py = float(r)
                for c in range(c0, c1 + 1):
                    px = float(c)
                    wa = s * ((cx - bx) * (py - by) - (cy - by) * (px - bx))
                    if wa < -la:
                        continue
                    wb = s * ((ax - cx) * (py - cy) - (ay - cy) * (px - cx))
                    if wb < -lb:
                        continue
                    wc = s * ((bx - ax) * (py - ay) - (by - ay) * (px - ax))
                    if wc < -lc:
                        continue
                    z = az + (wb * (bz - az) + wc * (cz - az)) / area
                    z = min(max(z, zlo), zhi)  # no overshoot just outside a steep sliver
                    if z > zbuf[r, c]:
                        zbuf[r, c] = z
        return zbuf

    return kernel


_KERNEL = None


def zbuffer_numba(vertices, faces, rows: int, cols: int) -> np.ndarray:
    """Max z-buffer with the compiled kernel.

    Parameters
    ----------
    vertices : ndarray of shape (n, 3), float64
        ``(u, v, z)`` in grid units (u = column, v = row).
    faces : ndarray of shape (m, 3), int64
        Vertex indices of each triangle.
    rows, cols : int
        Output grid shape.

    Returns
    -------
    ndarray of shape (rows, cols), float64
        Highest surface at each sample; ``-inf`` where no triangle covers it.
    """
    global _KERNEL
    if _KERNEL is None:
        _KERNEL = _numba_kernel()
    v, f = _check(vertices, faces)
    zbuf = np.full((int(rows), int(cols)), -np.inf)
    return _KERNEL(v, f, zbuf, EDGE_TOLERANCE)


def zbuffer_numpy(vertices, faces, rows: int, cols: int, chunk_pairs: int = 4_000_000) -> np.ndarray:
    """Max z-buffer in pure numpy; same contract and answer as :func:`zbuffer_numba`.

    ``chunk_pairs`` bounds the number of (triangle, sample) candidate pairs
    held in memory at once.
    """
    vert, fc = _check(vertices, faces)
    rows, cols = int(rows), int(cols)
    zbuf = np.full(rows * cols, -np.inf)
    tol = EDGE_TOLERANCE
    a, b, c = vert[fc[:, 0]], vert[fc[:, 1]], vert[fc[:, 2]]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    u = np.column_stack([a[:, 0], b[:, 0], c[:, 0]])
    v = np.column_stack([a[:, 1], b[:, 1], c[:, 1]])
    c0 = np.maximum(np.ceil(u.min(1) - tol), 0).astype(np.int64)
    c1 = np.minimum(np.floor(u.max(1) + tol), cols - 1).astype(np.int64)
    r0 = np.maximum(np.ceil(v.min(1) - tol), 0).astype(np.int64)
    r1 = np.minimum(np.floor(v.max(1) + tol), rows - 1).astype(np.int64)
    nw = np.maximum(c1 - c0 + 1, 0)
    nh = np.maximum(r1 - r0 + 1, 0)
    keep = np.flatnonzero((area != 0.0) & (nw > 0) & (nh > 0))
    counts = nw[keep] * nh[keep]
    bounds = np.cumsum(counts)
    start = 0
    while start < keep.size:
        base = bounds[start - 1] if start else 0
        stop = int(np.searchsorted(bounds, base + chunk_pairs, side="right"))
        stop = max(stop, start + 1)
        idx = keep[start:stop]
        cnt = counts[start:stop]
        t = np.repeat(idx, cnt)
        local = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        w = nw[t]
        cc = c0[t] + local % w
        rr = r0[t] + local // w
        px, py = cc.astype(np.float64), rr.astype(np.float64)
        s = np.sign(area[t])
        A, B, C = a[t], b[t], c[t]
        wa = s * ((C[:, 0] - B[:, 0]) * (py - B[:, 1]) - (C[:, 1] - B[:, 1]) * (px - B[:, 0]))
        wb = s * ((A[:, 0] - C[:, 0]) * (py - C[:, 1]) - (A[:, 1] - C[:, 1]) * (px - C[:, 0]))
        wc = s * ((B[:, 0] - A[:, 0]) * (py - A[:, 1]) - (B[:, 1] - A[:, 1]) * (px - A[:, 0]))
        la = np.hypot(C[:, 0] - B[:, 0], C[:, 1] - B[:, 1]) * tol
        lb = np.hypot(A[:, 0] - C[:, 0], A[:, 1] - C[:, 1]) * tol
        lc = np.hypot(B[:, 0] - A[:, 0], B[:, 1] - A[:, 1]) * tol
        inside = (wa >= -la) & (wb >= -lb) & (wc >= -lc)
        z = A[:, 2] + (wb * (B[:, 2] - A[:, 2]) + wc * (C[:, 2] - A[:, 2])) / (s * area[t])
        zs = np.column_stack([A[:, 2], B[:, 2], C[:, 2]])
        z = np.clip(z, zs.min(1), zs.max(1))
        np.maximum.at(zbuf, (rr * cols + cc)[inside], z[inside])
        start = stop
    return zbuf.reshape(rows, cols)


#: Rasteriser backends by name.
METHODS = {"numba": zbuffer_numba, "numpy": zbuffer_numpy}


def rasterize_mesh(vertices, faces, rows: int, cols: int, fill: float = -np.inf,
                   method: str = "numba") -> np.ndarray:
    """Max z-buffer of an indexed triangle mesh in grid units; see the module docstring.

    Parameters
    ----------
    vertices : ndarray of shape (n, 3), float64
        ``(u, v, z)`` per vertex; u in columns, v in rows.
    faces : ndarray of shape (m, 3), int
        Vertex indices per triangle.
    rows, cols : int
        Grid shape.
    fill : float
        Value for samples no triangle covers (``-inf`` by default).
    method : {"numba", "numpy"}
        Backend (:data:`METHODS`); both give the same answer.

    Returns
    -------
    ndarray of shape (rows, cols), float64
    """
    if method not in METHODS:
        raise unknown_key("rasteriser method", method, METHODS)
    zbuf = METHODS[method](vertices, faces, rows, cols)
    if fill != -np.inf:
        zbuf[np.isneginf(zbuf)] = fill
    return zbuf


def rasterize(triangles, rows: int, cols: int, fill: float = -np.inf, method: str = "numba") -> np.ndarray:
    """Max z-buffer of a triangle soup (m, 3, 3) in grid units; see :func:`rasterize_mesh`."""
    tri = np.asarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise ValueError(f"`triangles` must have shape (m, 3, 3) (got {tri.shape})")
    faces = np.arange(3 * len(tri), dtype=np.int64).reshape(-1, 3)
    return rasterize_mesh(tri.reshape(-1, 3), faces, rows, cols, fill, method)
