"""Regenerate terrain.png, the height map of map.toml (deterministic).

    .venv/bin/python assets/scenes/make_terrain.py

terrain.png: 16-bit gray, 240x160 px; smooth hills with a river valley
running across, no pixel noise (a tactile map should feel its landforms,
not its sensor noise). map.toml stretches it over 120x80 mm, 0..1.5 mm.
"""
from pathlib import Path

import numpy as np

from shapedisplay.author.imageio import write_png

HERE = Path(__file__).resolve().parent


def terrain(cols: int = 240, rows: int = 160) -> np.ndarray:
    y, x = np.mgrid[0:rows, 0:cols].astype(np.float64)
    x, y = (x + 0.5) / cols * 120.0, (y + 0.5) / rows * 80.0      # mm
    hills = [(25, 60, 12, 1.0), (60, 62, 9, 0.7), (95, 55, 14, 0.9), (30, 18, 10, 0.6), (100, 15, 8, 0.5)]
    h = np.zeros_like(x)
    for cx, cy, s, a in hills:
        h += a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
    river = 30.0 + 6.0 * np.sin(x / 120.0 * 2 * np.pi)             # valley centre line, mm
    h *= 1.0 - 0.8 * np.exp(-((y - river) ** 2) / (2 * 4.0 ** 2))
    h = (h - h.min()) / (h.max() - h.min())
    return np.rint(h * 65535).astype(np.uint16)


if __name__ == "__main__":
    p = write_png(HERE / "terrain.png", terrain())
    print(p.name, p.stat().st_size, "bytes")
