"""Generate ``keycap.stl``: a closed keycap mesh in millimetres (about 5,000 triangles).

A rounded-square frustum (base 18 x 18 mm, top 13 x 13 mm, corner radii
2 mm and 1.5 mm, height 8 mm) whose top is dished by a spherical cup
(radius 40 mm, 0.8 mm deep at the centre). The mesh is watertight, with
outward normals, placed with the base on z = 0 and centred on x = y = 0.

The exact surface, used by the tests: on the top, at (x, y) inside the top
outline, ``z = 8 - 0.8 + (40 - sqrt(40**2 - x**2 - y**2))`` clipped to 8 mm,
i.e. ``z = H - depth + (R - sqrt(R^2 - r^2))`` with ``r^2 = x^2 + y^2``.

Run ``python assets/meshes/make_keycap.py`` to rewrite ``keycap.stl`` beside
this script; the output is deterministic (byte-identical on every run).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

BASE = 18.0        # mm, base outline side
TOP = 13.0         # mm, top outline side
BASE_RADIUS = 2.0  # mm, corner radius of the base outline
TOP_RADIUS = 1.5   # mm, corner radius of the top outline
HEIGHT = 8.0       # mm, height at the top rim
DISH_R = 40.0      # mm, radius of the spherical dish
DISH_DEPTH = 0.8   # mm, depth of the dish at the centre
N_OUTLINE = 128    # points around an outline
N_WALL = 8         # wall bands
N_TOP = 12         # rings on the top surface


def outline(side: float, radius: float, n: int) -> np.ndarray:
    """Points (n, 2) around a rounded square, counter-clockwise, by angle from the centre."""
    theta = np.linspace(0.0, 2 * np.pi, n, endpoint=False) + np.pi / n
    d = np.column_stack([np.cos(theta), np.sin(theta)])
    h = side / 2 - radius
    pts = np.empty((n, 2))
    for i, (cx, sy) in enumerate(d):
        # ray from the centre to the rounded square boundary (bisection on the signed distance)
        lo, hi = 0.0, side
        for _ in range(60):
            t = (lo + hi) / 2
            q = np.abs(t * np.array([cx, sy])) - h
            dist = np.linalg.norm(np.maximum(q, 0.0)) + min(max(q[0], q[1]), 0.0) - radius
            lo, hi = (t, hi) if dist < 0 else (lo, t)
        pts[i] = lo * np.array([cx, sy])
    return pts


def dish(x, y):
    """Height of the top surface (mm) at (x, y) inside the top outline."""
    z = HEIGHT - DISH_DEPTH + (DISH_R - np.sqrt(DISH_R**2 - x**2 - y**2))
    return np.minimum(z, HEIGHT)


def keycap() -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) mm and faces (m, 3) of the keycap."""
    n = N_OUTLINE
    base = outline(BASE, BASE_RADIUS, n)
    top = outline(TOP, TOP_RADIUS, n)
    verts, faces = [], []

    def ring(points):
        verts.append(points)
        return sum(len(v) for v in verts) - len(points)

    def band(i0, i1):  # quads between two rings of n points, i0 below/outside i1
        j = np.arange(n)
        k = (j + 1) % n
        faces.append(np.column_stack([i0 + j, i0 + k, i1 + k]))
        faces.append(np.column_stack([i0 + j, i1 + k, i1 + j]))

    # walls: from the base outline up to the top outline at the dish rim height
    prev = None
    for b in range(N_WALL + 1):
        t = b / N_WALL
        xy = (1 - t) * base + t * top
        z = t * dish(top[:, 0], top[:, 1])
        cur = ring(np.column_stack([xy, z]))
        if prev is not None:
            band(prev, cur)
        prev = cur
    # top: rings shrinking towards the centre, on the dish
    for m in range(1, N_TOP):
        s = 1 - m / N_TOP
        xy = s * top
        cur = ring(np.column_stack([xy, dish(xy[:, 0], xy[:, 1])]))
        band(prev, cur)
        prev = cur
    centre = ring(np.array([[0.0, 0.0, dish(0.0, 0.0)]]))
    j = np.arange(n)
    faces.append(np.column_stack([prev + j, prev + (j + 1) % n, np.full(n, centre)]))
    # bottom: fan on z = 0, facing down
    b0 = 0
    bc = ring(np.array([[0.0, 0.0, 0.0]]))
    faces.append(np.column_stack([b0 + (j + 1) % n, b0 + j, np.full(n, bc)]))
    return np.vstack(verts), np.vstack(faces)


def main(argv=None) -> int:
    from shapedisplay.author.mesh import save_mesh

    out = Path(argv[0]) if argv else Path(__file__).with_name("keycap.stl")
    v, f = keycap()
    save_mesh(v * 1e-3, f, out, units="mm")
    print(f"{out}: {len(f)} triangles, {len(v)} vertices")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
