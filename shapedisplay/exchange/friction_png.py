"""Friction bitmaps: a grey PNG of mu (or of N) for screens that take friction maps.

Surface-haptic screens (electroadhesion, ultrasonic friction reduction)
render a grey image as friction: each pixel sets how much the finger is
held at that point. :func:`export_friction_png` writes one, 8- or 16-bit,
scaled to the full grey range, and a sidecar JSON (``FILE.json``) with the
scale back to SI:

``value = offset + scale * grey``  (``scale = (max - min) / (2^bits - 1)``)

Quantities (:data:`QUANTITIES`), chosen with ``quantity``; by default
(``"auto"``) the one that carries the table's shape: ``mu`` where the
friction coefficient varies over the canvas, else ``breakaway_force`` (a
height-mapped table keeps mu uniform and puts its shape in N; mu_s N is the
friction level a friction screen renders, and it has N's shape). A bitmap
that would come out flat (one grey level) is written with a
:class:`FlatBitmapWarning` naming the quantities that would show something.

* ``mu`` — the static friction coefficient each sample gives, as the
  renderer derives it with the cursor at rest (the device's ``mu_s``, times
  ``friction_scale`` or from ``breakaway_force / N`` where stored);
* ``normal_force`` — the virtual normal force N, N (the shape of a
  height-mapped table lives here);
* ``breakaway_force`` — ``mu_s N``, N: the friction force at breakaway.

The image is the top view of the surface: image row 0 is the top of the
screen (largest y), column 0 the left edge (smallest x), one pixel per
table sample. What a bitmap cannot carry — the direction-dependent slope
friction (``K_mu``), lateral and skin-stretch channels, the stick-slip
dynamics and the bursts — is listed in the sidecar's ``lost``.
"""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

import numpy as np

from shapedisplay.atomic import atomic_path
from shapedisplay.errors import InputError, unknown_key
from shapedisplay.author.heightfield import grid_from_picture, picture_from_grid

QUANTITIES = {"mu": "1", "normal_force": "N", "breakaway_force": "N"}
#: The default quantity: the one that carries the table's shape (:func:`choose_quantity`).
AUTO = "auto"
BITS = (8, 16)
#: Relative spread below which a quantity counts as uniform (float round-off of a constant).
UNIFORM_RTOL = 1e-9


class FlatBitmapWarning(UserWarning):
    """A friction bitmap is one grey level: the quantity asked for does not vary over the table."""


def _spread(v: np.ndarray) -> float:
    lo, hi = float(v.min()), float(v.max())
    return 0.0 if hi - lo <= UNIFORM_RTOL * max(abs(lo), abs(hi)) else hi - lo


def choose_quantity(table) -> tuple[str, str]:
    """The quantity that carries the table's shape, and why: ``mu`` where it varies, else
    ``breakaway_force`` (mu_s N, N's shape)."""
    if _spread(quantity_map(table, "mu")) > 0:
        return "mu", "mu varies over the table"
    return "breakaway_force", "mu is uniform: the shape is in N, shown as the friction level mu_s N"


def _device(table):
    from shapedisplay.exchange.export import device_of
    return device_of(table.meta)


def quantity_map(table, quantity: str = "mu") -> np.ndarray:
    """``quantity`` on every canvas sample, shape (rows, cols), SI, row r at y0 + r*dy."""
    if quantity not in QUANTITIES:
        raise unknown_key("friction bitmap quantity", quantity, QUANTITIES)
    table.require("normal_force")
    from shapedisplay.render.renderer import friction_limits
    dev = _device(table)
    ch = {n: table.dense(n) for n in table.channels}
    N = np.maximum(ch["normal_force"], 0.0)
    if quantity == "normal_force":
        return N
    bk, _ = friction_limits(ch, dev.friction.mu_s, dev.friction.mu_k)
    if quantity == "breakaway_force":
        return bk
    # mu where N > 0 from the renderer's own derivation; where N = 0 the coefficient at unit load
    unit = dict(ch, normal_force=np.ones_like(N))
    if "breakaway_force" in unit:
        unit["breakaway_force"] = np.where(N > 0, ch["breakaway_force"] / np.where(N > 0, N, 1.0), dev.friction.mu_s)
    if "kinetic_force" in unit:
        unit["kinetic_force"] = np.where(N > 0, ch["kinetic_force"] / np.where(N > 0, N, 1.0), dev.friction.mu_k)
    mu1, _ = friction_limits(unit, dev.friction.mu_s, dev.friction.mu_k)
    return mu1


def bitmap_choices(table) -> dict:
    """What the default picks for ``table`` and which quantities would give a flat bitmap (the studio's note)."""
    quantity, rule = choose_quantity(table)
    return {"auto": quantity, "rule": rule, "flat": [q for q in QUANTITIES if _spread(quantity_map(table, q)) == 0]}


def friction_image(table, quantity: str = AUTO, bits: int = 16) -> tuple[np.ndarray, dict]:
    """Grey image (top view) and its scale; ``quantity`` "auto" picks it (:func:`choose_quantity`).

    Returns
    -------
    grey : ndarray (rows, cols), uint8 or uint16; row 0 = largest y
    scale : dict with ``quantity``, ``unit``, ``bits``, ``scale``, ``offset``, ``min``, ``max``,
        ``max_error`` (half a grey step, unit), ``pixel_m`` [dx, dy], ``origin_m`` (centre of the
        bottom-left pixel), ``orientation`` and ``lost``
    """
    if bits not in BITS:
        raise InputError(f"`bits` must be 8 or 16 (got {bits!r})")
    quantity = AUTO if quantity is None else quantity
    if quantity != AUTO and quantity not in QUANTITIES:
        raise unknown_key("friction bitmap quantity", quantity, (AUTO, *QUANTITIES))
    rule = "given"
    if quantity == AUTO:
        quantity, rule = choose_quantity(table)
    v = quantity_map(table, quantity)
    lo, hi = float(v.min()), float(v.max())
    if _spread(v) == 0:
        hi = lo
        shown = [q for q in QUANTITIES if q != quantity and _spread(quantity_map(table, q)) > 0]
        unit = "" if QUANTITIES[quantity] == "1" else " " + QUANTITIES[quantity]
        warnings.warn(f"friction bitmap of {quantity} is flat ({lo:.6g}{unit} everywhere)"
                      + (f"; {' or '.join(shown)} shows the table's shape (--quantity)" if shown
                         else ": the table is uniform"), FlatBitmapWarning, stacklevel=2)
    top = (1 << bits) - 1
    scale = (hi - lo) / top if hi > lo else 0.0
    grey = np.zeros(v.shape) if scale == 0 else np.rint((v - lo) / scale)
    grey = picture_from_grid(np.clip(grey, 0, top).astype(np.uint8 if bits == 8 else np.uint16))
    g = table.grid
    lost = ["stick-slip dynamics and bursts (a bitmap is static)"]
    mp = table.meta.get("mapping", {}) if isinstance(table.meta, dict) else {}
    if (mp or {}).get("slope_friction_gain"):
        lost.append(f"direction-dependent slope friction (K_mu = {mp['slope_friction_gain']:g}): a bitmap has no "
                    "direction of motion")
    lost += [f"channel {n}" for n in table.channels
             if n in ("lateral_x", "lateral_y", "skin_stretch", "burst_gain")]
    toggles = (table.meta.get("scene", {}) or {}).get("toggles") if isinstance(table.meta, dict) else None
    if toggles:
        lost.append("toggle states other than the current one: " + ", ".join(sorted(toggles)))
    info = {
        "format": "shapedisplay-friction-bitmap", "quantity": quantity, "quantity_rule": rule,
        "unit": QUANTITIES[quantity],
        "bits": bits, "scale": scale, "offset": lo, "min": lo, "max": hi, "max_error": scale / 2,
        "rule": "value = offset + scale * grey",
        "pixel_m": [g.dx, g.dy], "origin_m": [g.x0, g.y0], "size_px": [g.cols, g.rows],
        "orientation": "top view: image row 0 is the largest y (top of the screen), column 0 the smallest x",
        "table_checksum": table.checksum, "lost": lost,
    }
    return grey, info


def export_friction_png(table, path: str | os.PathLike, quantity: str = AUTO, bits: int = 16) -> Path:
    """Write the friction bitmap to ``path`` and its scale to ``path`` + ``.json``, both atomically."""
    from PIL import Image
    grey, info = friction_image(table, quantity, bits)
    path = Path(path)
    side = path.with_name(path.name + ".json")
    with atomic_path(path) as tmp, atomic_path(side) as tmp_side:
        Image.fromarray(grey).save(tmp, format="PNG")
        tmp_side.write_text(json.dumps(info, indent=1, allow_nan=False) + "\n")
    return path


def read_friction_png(path: str | os.PathLike) -> tuple[np.ndarray, dict]:
    """The SI values (rows, cols; row r at y0 + r*dy, as a table) and the sidecar of a friction bitmap."""
    from PIL import Image
    path = Path(path)
    info = json.loads(path.with_name(path.name + ".json").read_text())
    with Image.open(path) as im:
        grey = np.array(im)
    return info["offset"] + info["scale"] * grid_from_picture(grey).astype(np.float64), info
