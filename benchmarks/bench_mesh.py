"""Mesh to height field: speed of the z-buffer rasteriser, with ratios and scaling.

Prints, for a 1,000,000-triangle mesh rasterised to 1024 x 1024 samples:
the mesh path (the C z-buffer, ``sd_zbuffer``), against a baseline measured
in the same run: the least memory work any rasteriser of it does (fill the
grid, gather every triangle's corners); the end-to-end time from a binary
STL file (trimesh load + rasterise), and the scaling exponents with triangle
count and grid size (fitted on log-log axes). Run:
``python benchmarks/bench_mesh.py``.
"""
from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

from shapedisplay.author import mesh

MM = 1e-3


def terrain(n_tri: int, size_mm: float = 100.0):
    """Closed-free wavy sheet of about ``n_tri`` triangles (mm): a relief map."""
    n = int(round(math.sqrt(n_tri / 2))) + 1
    t = np.linspace(0, size_mm, n)
    X, Y = np.meshgrid(t, t)
    Z = 2 + np.sin(X / 7) * np.cos(Y / 5) + 0.3 * np.sin(X * Y / 300)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]), faces


def best(fn, repeat=3):
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def slope(xs, ys):
    return float(np.polyfit(np.log(xs), np.log(ys), 1)[0])


def main() -> int:
    v, f = terrain(1_000_000)
    print(f"mesh: relief sheet, {len(f)} triangles, {len(v)} vertices; grid 1024 x 1024")

    mesh.mesh_to_heightfield(terrain(2000), grid=(8, 8))  # loads the C kernels
    t_fast, _ = best(lambda: mesh.mesh_to_heightfield((v, f), grid=(1024, 1024)))
    t_floor, _ = best(lambda: (np.full((1024, 1024), -np.inf), v[f]))
    print(f"mesh path   : {t_fast:7.3f} s   (target <= 3 s: {'met' if t_fast <= 3 else 'MISSED'})")
    print(f"baseline    : {t_floor:7.3f} s   (fill the grid, gather the corners): "
          f"the mesh path costs {t_fast / t_floor:.1f}x that")

    try:
        import trimesh
        sphere = trimesh.creation.icosphere(subdivisions=8, radius=50.0)
        t_sph, _ = best(lambda: mesh.mesh_to_heightfield((sphere.vertices, sphere.faces), grid=(1024, 1024)))
        print(f"closed sphere, {len(sphere.faces)} triangles (top and bottom overlap): {t_sph:.3f} s")
    except ImportError:
        print("closed sphere: skipped (trimesh not installed)")

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "relief.stl"
        mesh.save_mesh(v * MM, f, path)
        t_file, _ = best(lambda: mesh.mesh_to_heightfield(path, grid=(1024, 1024)), repeat=2)
        t_load, _ = best(lambda: mesh.load_mesh(path), repeat=2)
        mib = path.stat().st_size / 2**20
    print(f"from binary STL ({mib:.0f} MiB): {t_file:.3f} s end to end, "
          f"of which trimesh load {t_load:.3f} s")

    # scaling with triangles at a fixed grid
    counts = [125_000, 250_000, 500_000, 1_000_000, 2_000_000]
    tt = []
    for n in counts:
        vv, ff = terrain(n)
        tt.append(best(lambda: mesh.mesh_to_heightfield((vv, ff), grid=(1024, 1024)))[0])
    print("triangles -> time at 1024^2: " + ", ".join(f"{n / 1e6:g}M {t:.3f}s" for n, t in zip(counts, tt)))
    print(f"  scaling exponent with triangles: {slope(counts, tt):.2f} (1 = linear)")

    # scaling with grid size at a fixed mesh
    sides = [256, 512, 1024, 2048, 4096]
    tg = [best(lambda: mesh.mesh_to_heightfield((v, f), grid=(s, s)))[0] for s in sides]
    print("grid -> time with 1M triangles: " + ", ".join(f"{s}^2 {t:.3f}s" for s, t in zip(sides, tg)))
    print(f"  scaling exponent with samples: {slope(np.square(sides), tg):.2f} "
          f"(cost = per-triangle work + per-sample work; 1 = linear in samples)")

    # supersampling multiplies the samples by k^2
    for k in (2, 4):
        tk = best(lambda: mesh.mesh_to_heightfield((v, f), grid=(1024, 1024), supersample=k), repeat=2)[0]
        print(f"supersample {k}: {tk:.3f} s ({tk / t_fast:.1f}x the k=1 time)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
