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

The work is one pass over the triangles in C (``sd_zbuffer`` in
``sd_kernels.c``, :func:`._kernels.zbuffer`): per triangle its bounding box
clipped to the grid, the three edge functions at each sample of it, the max
into the buffer. Linear in triangles plus covered samples: about 0.1 s for
the bundled keycap (5120 triangles) at 0.02 mm (901 x 901 samples) or for a
1,000,000-triangle relief at 1024 x 1024 (figures and method in
``docs/meshes.md``, ``benchmarks/bench_mesh.py``).
"""
from __future__ import annotations

import numpy as np

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


def rasterize_mesh(vertices, faces, rows: int, cols: int, fill: float = -np.inf) -> np.ndarray:
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

    Returns
    -------
    ndarray of shape (rows, cols), float64
        Highest surface at each sample; ``fill`` where no triangle covers it.
    """
    from shapedisplay.author import kernels as _kernels

    v, f = _check(vertices, faces)
    zbuf = np.full((int(rows), int(cols)), -np.inf)
    _kernels.zbuffer(v, f, zbuf, EDGE_TOLERANCE)
    if fill != -np.inf:
        zbuf[np.isneginf(zbuf)] = fill
    return zbuf


def rasterize(triangles, rows: int, cols: int, fill: float = -np.inf) -> np.ndarray:
    """Max z-buffer of a triangle soup (m, 3, 3) in grid units; see :func:`rasterize_mesh`."""
    tri = np.asarray(triangles, dtype=np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise ValueError(f"`triangles` must have shape (m, 3, 3) (got {tri.shape})")
    faces = np.arange(3 * len(tri), dtype=np.int64).reshape(-1, 3)
    return rasterize_mesh(tri.reshape(-1, 3), faces, rows, cols, fill)
