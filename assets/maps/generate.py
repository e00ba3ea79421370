"""Regenerate the bundled sample height maps (deterministic).

    .venv/bin/python assets/maps/generate.py

tent_profile.png   16-bit, 600x40 px. Compile with --size 60x4mm --height 0:2mm
                   --n-base 0.5N --n-gain 2N/mm to get the published tent N(x)
                   : N1 = 0.5 N, N2 = 4.5 N, L1 = 10 mm, L2 = 30 mm,
                   L3 = 50 mm, L4 = 60 mm (k = 0.2 N/mm), at the pixel centres.
terrain_noisy.png  16-bit, 256x256 px: smooth hills plus fine noise; try
                   --size 40x40mm --height 0:1mm --gradient gaussian --sigma 0.5mm.
buttons.png        8-bit, 300x120 px: three rounded buttons (ramp, cosine and
                   step rims); try --size 60x24mm --height 0:1mm (the step rim
                   is reported as a wall).
"""
from pathlib import Path

import numpy as np

from shapedisplay.author import sources
from shapedisplay.author.imageio import write_png

HERE = Path(__file__).resolve().parent


def tent() -> np.ndarray:
    cols, rows = 600, 40
    x = (np.arange(cols) + 0.5) * 0.1e-3
    n = sources.tent_force(x, 0.010, 0.030, n1=0.5, n2=4.5)
    h = (n - 0.5) / 2000.0                      # m, with G = 2 N/mm
    gray = np.rint(h / 2e-3 * 65535).astype(np.uint16)
    return np.repeat(gray[None, :], rows, axis=0)


def terrain() -> np.ndarray:
    rng = np.random.default_rng(7)
    n = 256
    y, x = np.mgrid[0:n, 0:n] / n
    h = np.zeros((n, n))
    for _ in range(12):
        cx, cy, s, a = rng.random(), rng.random(), 0.05 + 0.15 * rng.random(), rng.uniform(-1, 1)
        h += a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
    h += 0.03 * rng.standard_normal((n, n))
    h = (h - h.min()) / (h.max() - h.min())
    return np.rint(h * 65535).astype(np.uint16)


def buttons() -> np.ndarray:
    h = np.zeros((120, 300))
    for cx, edge in ((10e-3, "ramp"), (30e-3, "cosine"), (50e-3, "step")):
        b = sources.rounded_button("14mm", "10mm", "1mm", ("60mm", "24mm"), "0.2mm", center=(cx, 12e-3),
                                   corner_radius="3mm", edge=edge, edge_width="2mm")
        h = np.maximum(h, b.heights)
    return np.rint(h / 1e-3 * 255).astype(np.uint8)


if __name__ == "__main__":
    write_png(HERE / "tent_profile.png", tent())
    write_png(HERE / "terrain_noisy.png", terrain())
    write_png(HERE / "buttons.png", buttons())
    for p in sorted(HERE.glob("*.png")):
        print(p.name, p.stat().st_size, "bytes")
