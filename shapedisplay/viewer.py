"""3D preview of height fields, compiled tables, scenes and played strokes.

The preview has two halves:

* a pure-numpy half (:class:`PreviewModel`, :class:`Trace`,
  :func:`model_from_heightfield`, :func:`model_from_table`,
  :func:`load_trace`, :func:`auto_exaggeration`) that decides what is drawn:
  the relief, every colourable channel in SI units, what the compiler left
  out, widget outlines and the played stroke;
* a rendering half (:func:`render`, :class:`Preview`) on top of pyvista,
  which is an optional extra imported only here, through
  :func:`shapedisplay.errors.require`.

Off-screen rendering works on a headless machine without a GPU through EGL
and Mesa's software rasterizer (or OSMesa); :func:`check_offscreen` probes it
once, in a child process, so a machine without any off-screen OpenGL gets a
clear error instead of a crash inside VTK. ``scripts/install-system-deps.sh``
installs the Debian packages it needs.

Display coordinates are millimetres: x and y as on the surface, z the
relief times the vertical exaggeration (stated on screen).
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import FileFormatError, InputError, ShapeDisplayError, TableError, require, unknown_key

#: Slope |grad h| at and above which a sample counts as a wall (45 degrees).
WALL_SLOPE = 1.0
#: Relief height, as a fraction of the larger horizontal extent, chosen by "auto" exaggeration.
AUTO_RELIEF_FRACTION = 0.15
#: Largest automatic vertical exaggeration.
MAX_AUTO_EXAGGERATION = 1000.0
#: Width of the strip a 1-D profile is drawn as, as a fraction of its length.
STRIP_FRACTION = 0.12
#: Most surface samples drawn (larger grids are drawn at a stride; read-outs use every sample).
MAX_DRAWN_SAMPLES = 1_000_000
#: Most stroke points drawn (longer traces are subsampled for drawing only).
MAX_STROKE_POINTS = 6000
#: Height of the stroke chart strip below the 3D view, as a fraction of the window.
CHART_HEIGHT = 0.28
#: Bins of the chart's min/max envelope (at most 4 points per bin are drawn).
CHART_BINS = 1500
#: Height of the spike of the largest burst, as a fraction of the larger extent.
SPIKE_FRACTION = 0.06
#: Most burst markers drawn (the largest are kept).
MAX_BURST_MARKERS = 3000

STICK_COLOR = "#1f6fd1"
SLIP_COLOR = "#e8590c"
BURST_COLOR = "#c2185b"
LEFT_OUT_COLOR = "#b8b8b8"
WIDGET_COLOR = "#202020"

#: Channel aliases accepted by ``--color``.
ALIASES = {
    "N": "normal_force", "h": "height", "z": "height", "breakaway": "breakaway_force",
    "kinetic": "kinetic_force", "lateral_magnitude": "lateral", "lateral_force": "lateral",
    "stretch": "skin_stretch", "wall": "walls",
}

#: Display unit of each SI unit: (label, factor from SI).
_DISPLAY_UNITS = {"m": ("mm", 1e3), "N": ("N", 1.0), "1": ("", 1.0)}

#: Meaning of derived (non-table) channels: name -> (SI unit, label). Labels avoid "|",
#: which VTK's text renderer drops.
DERIVED = {
    "height": ("m", "height"),
    "slope": ("1", "slope magnitude"),
    "walls": ("1", f"walls (slope >= {WALL_SLOPE:g})"),
    "lateral": ("N", "lateral force magnitude"),
}

#: Trace arrays and their dimension: "t" per tick, "e" per event.
TRACE_ARRAYS = {
    "t": "t", "x": "t", "y": "t", "normal_force": "t", "friction_force": "t", "state": "t",
    "event_time": "e", "event_amplitude": "e",
}


# ---------------------------------------------------------------------------------------------
# What is drawn (numpy only)
# ---------------------------------------------------------------------------------------------
@dataclass
class Trace:
    """A played stroke, as written by ``shapedisplay.sinks.write_trace``.

    Attributes
    ----------
    t, x, y, normal_force, friction_force : ndarray of shape (n,), float64
        Tick times (s), cursor position (m), normal and friction force (N).
    state : ndarray of shape (n,), int8
        0 stick, 1 slip, at each tick.
    event_time, event_amplitude : ndarray of shape (m,), float64
        Stick-to-slip transitions (s) and their burst amplitude (device units).
    table_checksum : str
        ``FrictionTable.checksum()`` of the table the stroke was played on.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    normal_force: np.ndarray
    friction_force: np.ndarray
    state: np.ndarray
    event_time: np.ndarray
    event_amplitude: np.ndarray
    table_checksum: str
    source: str = ""

    def __post_init__(self):
        n = None
        for name, kind in TRACE_ARRAYS.items():
            a = np.asarray(getattr(self, name), dtype=np.float64).ravel()
            if not np.all(np.isfinite(a)):
                raise InputError(f"trace {self.source!r}: array '{name}' holds NaN or infinite values")
            if kind == "t":
                if n is None:
                    n = a.size
                elif a.size != n:
                    raise InputError(f"trace {self.source!r}: array '{name}' has {a.size} values; 't' has {n}")
            setattr(self, name, a)
        if n is None or n < 1:
            raise InputError(f"trace {self.source!r}: holds no ticks")
        if self.event_time.size != self.event_amplitude.size:
            raise InputError(f"trace {self.source!r}: {self.event_time.size} event times but "
                             f"{self.event_amplitude.size} event amplitudes")
        if np.any(np.diff(self.t) < 0):
            raise InputError(f"trace {self.source!r}: times 't' must not decrease")
        if not np.all((self.state == 0) | (self.state == 1)):
            raise InputError(f"trace {self.source!r}: 'state' must be 0 (stick) or 1 (slip)")
        self.state = self.state.astype(np.int8)
        self.table_checksum = str(self.table_checksum)

    @property
    def arc_length(self) -> np.ndarray:
        """Distance travelled along the stroke at each tick, shape (n,), metres."""
        step = np.hypot(np.diff(self.x), np.diff(self.y))
        return np.concatenate([[0.0], np.cumsum(step)])

    def event_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Cursor (x, y) at each event time (linear in time between ticks), metres."""
        if self.t.size == 1:
            return np.full(self.event_time.shape, self.x[0]), np.full(self.event_time.shape, self.y[0])
        return np.interp(self.event_time, self.t, self.x), np.interp(self.event_time, self.t, self.y)


def load_trace(path: str | os.PathLike) -> Trace:
    """Read a trace ``.npz`` written by ``shapedisplay.sinks.write_trace``."""
    path = Path(path)
    if not path.is_file():
        raise FileFormatError(f"trace '{path}': no such file")
    try:
        with np.load(path, allow_pickle=False) as z:
            files = set(z.files)
            missing = [k for k in (*TRACE_ARRAYS, "table_checksum") if k not in files]
            if missing:
                if "header" in files:
                    raise FileFormatError(f"trace '{path}': this is a table, not a trace (use it as the input)")
                raise FileFormatError(f"trace '{path}': lacks array(s) {missing}; not a shapedisplay trace")
            arrays = {k: np.asarray(z[k]) for k in TRACE_ARRAYS}
            checksum = z["table_checksum"]
    except FileFormatError:
        raise
    except (OSError, ValueError, EOFError, KeyError) as exc:
        raise FileFormatError(f"trace '{path}': unreadable or not an .npz ({exc})") from None
    checksum = checksum.item() if checksum.ndim == 0 else checksum.ravel()[0]
    if isinstance(checksum, bytes):
        checksum = checksum.decode("utf-8", "replace")
    return Trace(**arrays, table_checksum=str(checksum), source=str(path))


@dataclass
class PreviewModel:
    """Everything the preview draws, on one regular grid, SI units.

    Attributes
    ----------
    x : ndarray of shape (cols,), metres
    y : ndarray of shape (rows,), metres
    relief : ndarray of shape (rows, cols), float64
        What is drawn as height: metres when ``relief_unit == "m"``; a
        normal force (N) when the table does not say how height maps to force.
    relief_unit : str
        "m" or "N".
    fields : dict name -> ndarray of shape (rows, cols), float64, SI
        Every channel the surface can be coloured by.
    units : dict name -> str
        SI unit of each field ("m", "N", "1").
    labels : dict name -> str
        Human-readable name of each field.
    stored : ndarray of shape (rows, cols), bool, or None
        False where the compiler left the samples out (drawn faintly).
    widgets : list of dict
        ``{"id": str, "x0", "y0", "x1", "y1"}`` outlines in metres.
    checksum : str or None
        Checksum of the table shown (trace check).
    strip : bool
        True when a 1-D profile was widened into a strip for drawing.
    """

    x: np.ndarray
    y: np.ndarray
    relief: np.ndarray
    relief_unit: str
    fields: dict
    units: dict
    labels: dict
    stored: np.ndarray | None = None
    widgets: list = field(default_factory=list)
    checksum: str | None = None
    strip: bool = False
    title: str = ""
    notes: list = field(default_factory=list)

    @property
    def channels(self) -> list[str]:
        return sorted(self.fields)

    def resolve_channel(self, name: str) -> str:
        """Canonical name of ``name`` (aliases allowed), or an error listing the valid ones."""
        key = ALIASES.get(name, name)
        if key not in self.fields:
            valid = sorted(set(self.fields) | {a for a, k in ALIASES.items() if k in self.fields})
            raise unknown_key("colour channel", name, valid)
        return key

    def display(self, name: str) -> tuple[str, float]:
        """(unit label, factor from SI) for showing ``name``."""
        return _DISPLAY_UNITS.get(self.units[name], (self.units[name], 1.0))

    def readout(self, x: float, y: float) -> dict:
        """Value of every field at (x, y) metres (bilinear; walls nearest), SI.

        Returns a dict with ``x``, ``y``, ``relief`` and one entry per field.
        Points outside the grid take the value at the nearest edge.
        """
        out = {"x": float(x), "y": float(y)}
        fr, fc = self._frac_index(x, y)
        out["relief"] = float(_bilinear(self.relief, fr, fc))
        for name, arr in sorted(self.fields.items()):
            if name == "walls":
                out[name] = float(arr[int(round(fr)), int(round(fc))])
            else:
                out[name] = float(_bilinear(arr, fr, fc))
        return out

    def relief_at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Bilinear relief at positions (x, y), metres (or N), shape of ``x``."""
        fr, fc = self._frac_index(np.asarray(x, float), np.asarray(y, float))
        return _bilinear(self.relief, fr, fc)

    def _frac_index(self, x, y):
        dx = self.x[1] - self.x[0] if self.x.size > 1 else 1.0
        dy = self.y[1] - self.y[0] if self.y.size > 1 else 1.0
        fc = np.clip((np.asarray(x, float) - self.x[0]) / dx, 0.0, self.x.size - 1)
        fr = np.clip((np.asarray(y, float) - self.y[0]) / dy, 0.0, self.y.size - 1)
        return fr, fc

    def format_readout(self, values: dict) -> str:
        """Multi-line text of a :meth:`readout` for the screen."""
        lines = [f"x = {values['x'] * 1e3:.2f} mm   y = {values['y'] * 1e3:.2f} mm"]
        if self.relief_unit == "m":
            lines.append(f"height = {values['relief'] * 1e3:.4g} mm")
        for name in self.channels:
            if name == "height":
                continue
            unit, f = self.display(name)
            lines.append(f"{name} = {values[name] * f:.4g} {unit}".rstrip())
        return "\n".join(lines)


def _bilinear(arr: np.ndarray, fr, fc):
    rows, cols = arr.shape
    r0 = np.minimum(np.floor(fr).astype(np.int64), max(rows - 2, 0))
    c0 = np.minimum(np.floor(fc).astype(np.int64), max(cols - 2, 0))
    r1 = np.minimum(r0 + 1, rows - 1)
    c1 = np.minimum(c0 + 1, cols - 1)
    tr, tc = fr - r0, fc - c0
    return ((arr[r0, c0] * (1 - tc) + arr[r0, c1] * tc) * (1 - tr)
            + (arr[r1, c0] * (1 - tc) + arr[r1, c1] * tc) * tr)


def slope_of(heights: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """|grad h| by central differences (one-sided at edges), shape of ``heights``."""
    h = np.asarray(heights, dtype=np.float64)
    gx = np.gradient(h, dx, axis=1) if h.shape[1] > 1 else np.zeros_like(h)
    gy = np.gradient(h, dy, axis=0) if h.shape[0] > 1 else np.zeros_like(h)
    return np.hypot(gx, gy)


def _widen(model_rows: dict, y0: float, length: float) -> tuple[np.ndarray, dict]:
    """Turn single-row arrays into a 2-row strip centred on ``y0``."""
    half = 0.5 * STRIP_FRACTION * length
    y = np.array([y0 - half, y0 + half])
    return y, {k: (np.repeat(v, 2, axis=0) if v is not None else None) for k, v in model_rows.items()}


def model_from_heightfield(hf, title: str | None = None) -> PreviewModel:
    """A preview of a :class:`~shapedisplay.heightfield.HeightField`: height, slope, walls."""
    h = hf.heights
    slope = slope_of(h, hf.dx, hf.dy)
    fields = {"height": h, "slope": slope, "walls": (slope >= WALL_SLOPE).astype(np.float64)}
    x, y, strip = hf.x, hf.y, False
    if hf.is_1d:
        y, widened = _widen(fields, hf.y0, float(x[-1] - x[0]))
        fields, strip = widened, True
    units = {k: DERIVED[k][0] for k in fields}
    labels = {k: DERIVED[k][1] for k in fields}
    return PreviewModel(x=x, y=y, relief=fields["height"], relief_unit="m", fields=fields, units=units,
                        labels=labels, title=title if title is not None else (hf.source or "height field"),
                        strip=strip)


def _mapping_gain(meta: dict) -> tuple[float, float] | None:
    """(n_base N, n_gain N/m) of a height mapping recorded in table meta, if any."""
    mapping = meta.get("mapping") if isinstance(meta, dict) else None
    if not isinstance(mapping, dict):
        return None
    from .units import parse_quantity

    def q(keys, unit):
        for k in keys:
            if k in mapping and mapping[k] is not None:
                v = mapping[k]
                try:
                    return parse_quantity(v, unit, k, bare_ok=True) if isinstance(v, str) else float(v)
                except (ShapeDisplayError, TypeError, ValueError):
                    return None
        return None

    if not mapping.get("height", True) or mapping.get("perceptual_exponent") is not None:
        return None     # N is not linear in h: draw the force itself
    gain = q(("n_gain_n_per_m", "n_gain"), "N/m")
    base = q(("n_base_n", "n_base"), "N")
    if gain is None or not math.isfinite(gain) or gain <= 0:
        return None
    return (base if base is not None and math.isfinite(base) else 0.0), gain


def model_from_table(table, title: str | None = None, widgets: list | None = None) -> PreviewModel:
    """A preview of a compiled :class:`~shapedisplay.table.FrictionTable`.

    The relief is the height the normal force encodes when the table's
    ``meta["mapping"]`` gives the gain (h = (N - n_base) / n_gain); otherwise
    the normal force itself is drawn as relief (``relief_unit == "N"``).
    Samples no block covers (left out by the compiler) are marked in
    ``stored``. Widget outlines come from ``widgets`` or, when absent, from
    ``meta["widgets"]`` (``[{"id", "x0", "y0", "x1", "y1"}]`` metres).
    """
    from .table import CHANNELS

    g = table.grid
    x = g.x0 + g.dx * np.arange(g.cols)
    y = g.y0 + g.dy * np.arange(g.rows)
    fields = {name: np.asarray(table.dense(name), dtype=np.float64) for name in table.channels}
    units = {name: CHANNELS[name][0] for name in fields}
    labels = {name: name.replace("_", " ") for name in fields}

    relief, relief_unit, notes = None, "N", []
    gain = _mapping_gain(table.meta)
    if "normal_force" in fields and gain is not None:
        base, k = gain
        relief, relief_unit = (fields["normal_force"] - base) / k, "m"
        notes.append(f"height from N: n_gain {k / 1e3:g} N/mm")
    elif "normal_force" in fields:
        relief = fields["normal_force"]
        notes.append("relief drawn from normal force")
    else:
        relief = np.zeros((g.rows, g.cols))
        notes.append("flat: table holds no normal force")
    if relief_unit == "m":
        fields["height"] = relief
    if "grad_x" in fields or "grad_y" in fields:
        gx = fields.get("grad_x", np.zeros((g.rows, g.cols)))
        gy = fields.get("grad_y", np.zeros((g.rows, g.cols)))
        fields["slope"] = np.hypot(gx, gy)
    elif relief_unit == "m":
        fields["slope"] = slope_of(relief, g.dx, g.dy)
    if "slope" in fields:
        fields["walls"] = (fields["slope"] >= WALL_SLOPE).astype(np.float64)
    friction = table.meta.get("device", {}).get("friction", {}) if isinstance(table.meta.get("device"), dict) else {}
    _derive_forces(fields, units, labels, notes, friction)

    stored = np.zeros((g.rows, g.cols), dtype=bool)
    for r0, c0, p in table.blocks:
        nr, nc = table.patch_shapes[p]
        stored[r0:r0 + nr, c0:c0 + nc] = True
    if stored.all():
        stored = None

    strip = False
    if g.rows == 1:
        y, widened = _widen({"relief": relief, "stored": stored, **fields}, g.y0, float(x[-1] - x[0]) or g.dx)
        relief, stored = widened.pop("relief"), widened.pop("stored")
        fields, strip = widened, True
    if widgets is None:
        widgets = _widgets_of_meta(table.meta)
    src = table.meta.get("source", {})
    default_title = src.get("description", "") if isinstance(src, dict) else ""
    model = PreviewModel(x=x, y=y, relief=relief, relief_unit=relief_unit, fields=fields, units=units,
                        labels=labels, stored=stored, widgets=[],
                        checksum=table.checksum(), strip=strip,
                        title=title if title is not None else (default_title or "friction table"), notes=notes)
    model.widgets = _strip_widgets(_clean_widgets(widgets), model)
    return model


def _derive_forces(fields: dict, units: dict, labels: dict, notes: list, friction) -> None:
    """Add what the runtime derives: mu_s*N, mu_k*N (when not stored) and |F_lat|; in place."""
    scale = fields.get("friction_scale", 1.0)
    for name, mu_key in (("breakaway_force", "mu_s"), ("kinetic_force", "mu_k")):
        mu = friction.get(mu_key) if isinstance(friction, dict) else None
        if name not in fields and "normal_force" in fields and isinstance(mu, (int, float)) and math.isfinite(mu):
            fields[name] = float(mu) * scale * fields["normal_force"]     # what the runtime computes
            notes.append(f"{name} = {mu_key} * N (device {mu_key} = {mu:g})")
    if "lateral_x" in fields or "lateral_y" in fields:
        fields["lateral"] = np.hypot(fields.get("lateral_x", 0.0), fields.get("lateral_y", 0.0))
    for name in fields:
        if name in DERIVED:
            units[name], labels[name] = DERIVED[name]
        elif name not in units:
            from .table import CHANNELS
            units[name], labels[name] = CHANNELS[name][0], name.replace("_", " ")


def scene_forces(scene, hf) -> tuple[dict, list]:
    """Force channels of a scene's height field as its device and mapping make them (SI).

    Returns ``({name: ndarray (rows, cols)}, notes)``: the channels the
    compiler would keep, computed densely, including the data layers the
    device renders (``friction_scale``, ``burst_gain``), plus
    ``breakaway_force`` and ``kinetic_force`` from the device's friction
    (scaled by ``friction_scale``, as the runtime does).
    """
    import dataclasses

    from .forces import MappingOptions, force_channels
    from .scene.compiler import composite, scene_channels
    known = {f.name for f in dataclasses.fields(MappingOptions)}
    mapping = MappingOptions(**{k: v for k, v in scene.mapping.items() if k in known and k != "height"})
    chans = force_channels(hf, scene.device, mapping)
    fields = {name: np.asarray(a, dtype=np.float64) for name, a in chans.items()}
    kept, _ = scene_channels(scene, scene.device, mapping)
    layers = [ch for ch in ("friction_scale", "burst_gain") if ch in kept]
    if layers:
        c = scene.canvas
        _, data = composite(scene, (0, 0, c.rows - 1, c.cols - 1))
        fields.update({ch: data[ch] for ch in layers})
    friction = {"mu_s": scene.device.friction.mu_s, "mu_k": scene.device.friction.mu_k}
    notes: list = []
    _derive_forces(fields, {}, {}, notes, friction)
    return fields, notes


def _widgets_of_meta(meta: dict) -> list:
    """Widget outlines recorded by the scene compiler (``meta["scene"]["widgets"]``, ``bbox_m``)
    or given directly as ``meta["widgets"]`` (``x0``, ``y0``, ``x1``, ``y1``)."""
    scene = meta.get("scene")
    if isinstance(scene, dict) and isinstance(scene.get("widgets"), list):
        out = []
        for i, w in enumerate(scene["widgets"]):
            box = w.get("bbox_m") if isinstance(w, dict) else None
            if isinstance(box, (list, tuple)) and len(box) == 4:
                out.append({"id": w.get("id", str(i)), "x0": box[0], "y0": box[1], "x1": box[2], "y1": box[3]})
        return out
    widgets = meta.get("widgets")
    return [w for w in widgets if isinstance(w, dict)] if isinstance(widgets, list) else []


def _clean_widgets(widgets) -> list:
    out = []
    for i, w in enumerate(widgets or []):
        try:
            box = {k: float(w[k]) for k in ("x0", "y0", "x1", "y1")}
        except (KeyError, TypeError, ValueError):
            raise InputError(f"widget #{i}: needs numeric x0, y0, x1, y1 in metres (got {w!r})") from None
        if not all(math.isfinite(v) for v in box.values()):
            raise InputError(f"widget #{i}: outline must be finite (got {box})")
        out.append({"id": str(w.get("id", i)), **box})
    return out


def widgets_of_scene(scene) -> list:
    """Outlines ``[{"id", "x0", "y0", "x1", "y1"}]`` (metres) of a loaded scene's widgets."""
    out = []
    for w in scene.widgets:
        x0, y0, x1, y1 = w.bbox
        out.append({"id": w.id, "x0": x0, "y0": y0, "x1": x1, "y1": y1})
    return out


def load_model(path: str | os.PathLike, scene: str | os.PathLike | None = None, **source_opts) -> PreviewModel:
    """Preview model of a file: table (.npz), scene (.toml) or source (image, mesh).

    ``scene`` adds the widget outlines and ids of a scene file to a table.
    ``source_opts`` (``size``, ``height_range``, ``resolution``, ... ; None
    dropped) go to :func:`shapedisplay.sources.load_source`.
    """
    path = Path(os.fspath(path))
    suffix = path.suffix.lower()
    opts = {k: v for k, v in source_opts.items() if v is not None}
    if suffix == ".npz":
        if opts:
            raise InputError(f"table '{path}': source options {sorted(opts)} apply to images and meshes only")
        if path.is_file():
            try:
                with np.load(path, allow_pickle=False) as z:
                    is_trace = "header" not in z.files and "table_checksum" in z.files
            except (OSError, ValueError, EOFError):
                is_trace = False
            if is_trace:
                raise InputError(f"input '{path}' is a trace; give the table as input and the trace with --trace")
        from .table import FrictionTable
        table = FrictionTable.load(path)
        widgets = None
        if scene:
            sc = _load_scene(scene)
            _check_scene_fits(sc, table, path)
            widgets = widgets_of_scene(sc)
        return model_from_table(table, title=path.name, widgets=widgets)
    if suffix == ".toml":
        if opts:
            raise InputError(f"scene '{path}': source options {sorted(opts)} apply to images and meshes only")
        sc = _load_scene(path)
        from .scene import scene_heightfield
        hf = scene_heightfield(sc)
        model = model_from_heightfield(hf, title=getattr(sc, "name", "") or path.name)
        forces, notes = scene_forces(sc, hf)
        for name, arr in forces.items():
            model.fields[name] = np.repeat(arr, 2, axis=0) if model.strip else arr
        _derive_forces(model.fields, model.units, model.labels, [], {})
        model.notes += notes
        model.widgets = _strip_widgets(_clean_widgets(widgets_of_scene(sc)), model)
        return model
    if scene:
        raise InputError(f"`--scene` draws widget outlines on a table; '{path}' is a source")
    from .sources import load_source
    return model_from_heightfield(load_source(path, **opts))


def _load_scene(path):
    path = Path(os.fspath(path))
    if not path.is_file():
        raise FileFormatError(f"scene '{path}': no such file")
    from .scene import load_scene
    return load_scene(path)


def _check_scene_fits(scene, table, path) -> None:
    """Refuse to draw the outlines of a scene whose canvas is not the table's grid."""
    g, c = table.grid, scene.canvas
    same = (g.rows, g.cols) == (c.rows, c.cols) and math.isclose(g.dx, c.spacing, rel_tol=1e-9) \
        and math.isclose(g.dy, c.spacing, rel_tol=1e-9) and g.x0 == 0.0 and g.y0 == 0.0
    if not same:
        raise InputError(
            f"`--scene` '{scene.path}' does not fit table '{path}': the scene's canvas is "
            f"{c.rows}x{c.cols} samples of {c.spacing * 1e3:g} mm from (0, 0), the table's grid "
            f"{g.rows}x{g.cols} samples of {g.dx * 1e3:g} x {g.dy * 1e3:g} mm from "
            f"({g.x0 * 1e3:g}, {g.y0 * 1e3:g}) mm; give the scene the table was compiled from")


def _strip_widgets(widgets: list, model: PreviewModel) -> list:
    """On a 1-D strip, widget boxes (zero depth) span the strip's width."""
    if not model.strip:
        return widgets
    return [{**w, "y0": float(model.y[0]), "y1": float(model.y[-1])} for w in widgets]


def check_trace(trace: Trace, model: PreviewModel) -> None:
    """Refuse a trace that was not played on the table shown."""
    if model.checksum is None:
        raise InputError(f"trace {trace.source!r}: a stroke can only be drawn on the compiled table it was "
                         f"played on (give the table file, not a source)")
    if trace.table_checksum != model.checksum:
        raise TableError(f"trace {trace.source!r} was played on a different table "
                         f"(trace table_checksum {trace.table_checksum}, table {model.checksum})")


def nice_number(value: float) -> float:
    """The largest 1-2-5 series number (..., 0.5, 1, 2, 5, 10, ...) <= ``value``; 1 for a bad value."""
    if not value > 0 or not math.isfinite(value):
        return 1.0
    e = math.floor(math.log10(value))
    cands = [m * 10.0 ** k for k in (e - 1, e, e + 1) for m in (1, 2, 5)]
    return max(c for c in cands if c <= value * (1 + 1e-12))


def auto_exaggeration(model: PreviewModel) -> float:
    """Vertical exaggeration drawing the relief at about 15 % of the larger extent.

    A 1-2-5 series number >= 1 (never flattens a metric relief) and
    <= :data:`MAX_AUTO_EXAGGERATION`; 1 for a flat surface. For a force
    relief the result is millimetres per newton.
    """
    extent = max(float(np.ptp(model.x)), float(np.ptp(model.y))) * 1e3   # mm
    span = float(np.ptp(model.relief)) * (1e3 if model.relief_unit == "m" else 1.0)
    if span <= 0 or extent <= 0:
        return 1.0
    ex = nice_number(AUTO_RELIEF_FRACTION * extent / span)
    if model.relief_unit == "m":
        ex = max(1.0, ex)
    return min(ex, MAX_AUTO_EXAGGERATION)


def parse_exaggeration(value) -> str | float:
    """"auto" or a finite number > 0."""
    if value is None or str(value).strip().lower() == "auto":
        return "auto"
    try:
        v = float(str(value).strip().lstrip("x"))
    except ValueError:
        raise InputError(f"`exaggeration` must be 'auto' or a number > 0 (got {value!r})") from None
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"`exaggeration` must be 'auto' or a number > 0 (got {value!r})")
    return v


def parse_window_size(value) -> tuple[int, int]:
    """"1600x1000" -> (1600, 1000) pixels; each side 64..8192."""
    if isinstance(value, (tuple, list)):
        parts = list(value)
    else:
        parts = str(value).lower().replace(" ", "").split("x")
    try:
        w, h = (int(p) for p in parts)
    except (TypeError, ValueError):
        raise InputError(f"`size` must be WIDTHxHEIGHT in pixels, e.g. 1600x1000 (got {value!r})") from None
    if not (64 <= w <= 8192 and 64 <= h <= 8192):
        raise InputError(f"`size` sides must be 64..8192 pixels (got {w}x{h})")
    return w, h


# ---------------------------------------------------------------------------------------------
# Off-screen support and display
# ---------------------------------------------------------------------------------------------
#: Window classes tried for off-screen rendering without a display, in order.
OFFSCREEN_WINDOWS = ("vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow")

_PROBE = """
import vtkmodules.vtkRenderingOpenGL2, vtkmodules.vtkRenderingCore as rc
from vtkmodules.vtkCommonCore import vtkUnsignedCharArray, vtkLogger
vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
w = rc.vtkRenderWindow(); w.SetOffScreenRendering(1); w.SetSize(8, 8)
r = rc.vtkRenderer(); r.SetBackground(1.0, 0.0, 0.0); w.AddRenderer(r); w.Render()
a = vtkUnsignedCharArray(); w.GetPixelData(0, 0, 7, 7, 1, a, 0)
print(w.GetClassName(), *a.GetTuple3(0))
"""

_offscreen_cache: dict = {}


def has_display() -> bool:
    """True when an interactive window can be opened (X11/Wayland on Linux; always elsewhere)."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_offscreen(env: dict | None = None) -> str:
    """Make sure VTK can render off-screen here; return the window class used.

    Without a display, each class of :data:`OFFSCREEN_WINDOWS` is tried in a
    child process (a missing OpenGL library crashes VTK rather than raising),
    and the first that renders correctly is selected through
    ``VTK_DEFAULT_OPENGL_WINDOW``. With a display the default window is used.
    The answer is cached per process (``env`` given: not cached, not selected).

    Raises
    ------
    ShapeDisplayError
        No off-screen OpenGL is available; names the packages to install.
    """
    probe_env = dict(os.environ if env is None else env)
    if env is None and "window" in _offscreen_cache:
        return _offscreen_cache["window"]
    display = bool(probe_env.get("DISPLAY") or probe_env.get("WAYLAND_DISPLAY")) \
        or not sys.platform.startswith("linux")
    wanted = probe_env.get("VTK_DEFAULT_OPENGL_WINDOW")
    candidates = [wanted] if wanted else ([None] if display else list(OFFSCREEN_WINDOWS))
    tried = []
    for cls in candidates:
        e = dict(probe_env)
        if cls:
            e["VTK_DEFAULT_OPENGL_WINDOW"] = cls
        try:
            res = subprocess.run([sys.executable, "-c", _PROBE], env=e, capture_output=True, text=True,
                                 timeout=60)
        except subprocess.TimeoutExpired:
            tried.append(f"{cls or 'default'}: timed out")
            continue
        words = res.stdout.split()
        if res.returncode == 0 and len(words) == 4 and words[1:] == ["255.0", "0.0", "0.0"]:
            if env is None:
                if cls:
                    os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = cls
                _offscreen_cache["window"] = words[0]
            return words[0]
        tried.append(f"{cls or 'default'}: " + ("crashed" if res.returncode < 0 else f"exit {res.returncode}"))
    where = "the display's OpenGL" if display and not wanted else "EGL/OSMesa OpenGL"
    raise ShapeDisplayError(
        f"off-screen rendering is not available: {where} does not work here ({'; '.join(tried)}); "
        "install libegl1 libegl-mesa0 libgl1-mesa-dri (scripts/install-system-deps.sh), "
        "or unset DISPLAY to render through EGL")


def _pyvista(off_screen: bool):
    if not off_screen and not has_display():
        raise ShapeDisplayError("interactive preview needs a display (DISPLAY is not set); "
                                "render off-screen instead: -o shot.png")
    pv = require("pyvista", "viewer", "3D preview")
    if off_screen:
        check_offscreen()     # VTK reads VTK_DEFAULT_OPENGL_WINDOW when a window is made, not at import
    try:
        from vtkmodules.vtkCommonCore import vtkLogger
        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except ImportError:  # pragma: no cover - vtk always ships vtkLogger with pyvista >= 0.43
        pass
    return pv


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------
VIEWS = ("iso", "top", "side")


class Preview:
    """A rendered preview: the pyvista plotter plus what it shows.

    Build with :func:`render`. ``screenshot()`` returns the image,
    ``save(path)`` writes a PNG atomically, ``show()`` opens the window
    (orbit/zoom; click or hover reads out every channel; space replays the
    stroke).
    """

    def __init__(self, plotter, model: PreviewModel, channel: str, exaggeration: float, trace: Trace | None):
        self.plotter = plotter
        self.model = model
        self.channel = channel
        self.exaggeration = exaggeration
        self.trace = trace
        self.surface_actor = None
        self.cursor_actor = None
        self.stroke_points: np.ndarray | None = None    # (n, 3) display coordinates of the path
        self.stroke_times: np.ndarray | None = None
        self.last_readout: dict | None = None
        self.info = ""                                  # text shown in the upper left corner
        self._picker = None

    # -- coordinates ------------------------------------------------------------------------
    def z_display(self, relief) -> np.ndarray:
        """Display z (mm) of a relief value (m or N)."""
        base = float(self.model.relief.min())
        scale = 1e3 if self.model.relief_unit == "m" else 1.0
        return (np.asarray(relief, float) - base) * scale * self.exaggeration

    def to_surface(self, xd: float, yd: float) -> tuple[float, float]:
        """Display (mm) -> surface (m) coordinates."""
        return xd * 1e-3, yd * 1e-3

    # -- interaction ------------------------------------------------------------------------
    def read_at_display(self, point) -> dict:
        """Read-out of every channel at a picked display point (x, y, z) mm."""
        x, y = self.to_surface(float(point[0]), float(point[1]))
        values = self.model.readout(x, y)
        self.last_readout = values
        return values

    def _show_readout(self, point) -> None:
        if point is None:
            return
        values = self.read_at_display(point)
        self.plotter.add_text(self.model.format_readout(values), position="lower_left", font_size=9,
                              color="black", name="readout")

    def replay(self, frames: int = 240, realtime: bool = True, on_frame: Callable | None = None) -> int:
        """Move the cursor marker along the stroke; returns the number of frames drawn.

        ``realtime`` plays the stroke over its own duration (at most 10 s),
        dropping frames when rendering is slow; otherwise exactly ``frames``
        evenly spaced frames are drawn. The last frame is always the stroke's
        end. ``on_frame(i, position)`` is called after each frame.
        """
        if self.stroke_points is None or self.cursor_actor is None:
            return 0
        pts, times = self.stroke_points, self.stroke_times
        n = len(pts)
        duration = min(10.0, float(times[-1] - times[0])) if realtime else 0.0

        def draw(i, k):
            self.cursor_actor.position = tuple(pts[k])
            self.plotter.render()
            if on_frame is not None:
                on_frame(i, pts[k])

        if duration <= 0:
            idx = np.unique(np.linspace(0, n - 1, max(2, min(int(frames), n))).round().astype(int))
            for i, k in enumerate(idx):
                draw(i, int(k))
            return len(idx)
        t_start, i, k = time.perf_counter(), 0, 0
        speed = float(times[-1] - times[0]) / duration
        period = duration / max(int(frames), 1)
        while k < n - 1:
            elapsed = time.perf_counter() - t_start
            k = min(int(np.searchsorted(times, times[0] + elapsed * speed)), n - 1)
            draw(i, k)
            i += 1
            wait = t_start + i * period - time.perf_counter()
            if wait > 0 and k < n - 1:
                time.sleep(wait)
        return i

    # -- output -----------------------------------------------------------------------------
    def screenshot(self) -> np.ndarray:
        """The rendered frame, shape (height, width, 3), uint8 RGB."""
        return np.asarray(self.plotter.screenshot(return_img=True))

    def save(self, path: str | os.PathLike) -> Path:
        """Write the frame to ``path`` as PNG, atomically."""
        from .atomic import atomic_path
        path = Path(path)
        if path.suffix.lower() != ".png":
            raise InputError(f"output '{path}': preview pictures are PNG files (name must end in .png)")
        img = self.screenshot()
        pil = require("PIL.Image", "viewer", "3D preview")
        with atomic_path(path) as tmp:
            pil.fromarray(img).save(tmp, format="PNG", optimize=True)
        return path

    def show(self) -> None:
        """Open the interactive window (blocks until closed)."""
        self.plotter.show(title=f"shapedisplay preview - {self.model.title}")

    def close(self) -> None:
        self.plotter.close()


def render(model: PreviewModel, channel: str = "height", trace: Trace | None = None,
           exaggeration="auto", size=(1600, 1000), off_screen: bool = True, view: str = "iso",
           lighting: bool = True, scalar_bar: bool = True, chart: bool = True, annotations: bool = True,
           cmap: str = "viridis") -> Preview:
    """Draw ``model`` coloured by ``channel``, with an optional played stroke.

    Parameters
    ----------
    model : PreviewModel
    channel : str
        A field of the model or an alias ("N", "lateral_magnitude", ...).
        When the model has no height, "height" falls back to normal force.
    trace : Trace, optional
        Played stroke; must come from the table shown (checksum).
    exaggeration : "auto" or float
        Vertical exaggeration (mm per N for a force relief).
    size : (width, height) pixels
    off_screen : bool
        Render without a window (PNG output); else interactive.
    view : "iso" | "top" | "side"
    lighting, scalar_bar, chart, annotations : bool
        Shading, colour bar, N/friction chart along the stroke, texts and scale bar.
    cmap : str
        Colour map of the surface.
    """
    if channel == "height" and "height" not in model.fields and "normal_force" in model.fields:
        channel = "normal_force"
    channel = model.resolve_channel(channel)
    if view not in VIEWS:
        raise unknown_key("view", view, VIEWS)
    ex = parse_exaggeration(exaggeration)
    ex = auto_exaggeration(model) if ex == "auto" else ex
    width, height = parse_window_size(size)
    if trace is not None:
        check_trace(trace, model)
    pv = _pyvista(off_screen)
    try:
        from pyvista.plotting.colors import get_cmap_safe
        get_cmap_safe(cmap)
    except (ValueError, KeyError, ImportError) as exc:
        raise InputError(f"`cmap` {cmap!r} is not a known colour map ({exc})") from None

    with_chart = trace is not None and chart
    if with_chart:   # 3D view above, chart of the stroke in a strip below
        pl = pv.Plotter(off_screen=off_screen, window_size=(width, height), shape=(2, 1),
                        row_weights=[1.0 - CHART_HEIGHT, CHART_HEIGHT], border=False)
        pl.subplot(0, 0)
    else:
        pl = pv.Plotter(off_screen=off_screen, window_size=(width, height))
    pl.set_background("white")
    preview = Preview(pl, model, channel, ex, trace)

    # ---- surface --------------------------------------------------------------------------
    stride = draw_stride(*model.relief.shape)
    rs, cs = _strided(model.relief.shape[0], stride), _strided(model.relief.shape[1], stride)
    xs, ys = np.meshgrid(model.x[cs] * 1e3, model.y[rs] * 1e3)
    zs = preview.z_display(model.relief[np.ix_(rs, cs)])
    grid = pv.StructuredGrid(xs, ys, zs)
    unit, factor = model.display(channel)
    values = model.fields[channel] * factor           # colour range from every sample, drawn or not
    grid.point_data[channel] = values[np.ix_(rs, cs)].ravel(order="F")   # (rows, cols) points: rows fastest
    title = f"{model.labels.get(channel, channel)}" + (f" [{unit}]" if unit else "")
    bar_title = f"{model.labels.get(channel, channel)}" + (f"\n[{unit}]" if unit else "")
    bar_args = dict(title=bar_title, vertical=True, position_x=0.85, position_y=0.25, width=0.05, height=0.55,
                    color="black", title_font_size=14, label_font_size=12, fmt="%.3g")
    if channel == "walls":
        bar_args["n_labels"] = 2
    lo, hi = float(values.min()), float(values.max())
    lo, hi = (0.0 if abs(v) <= 1e-9 * (hi - lo) else v for v in (lo, hi))   # no "1.5e-32" on the bar
    if channel == "walls":     # 0 or 1: fixed, so a surface without walls is not drawn half as walls
        clim = (0.0, 1.0)
    else:
        clim = (lo, hi) if hi > lo else (lo - 0.5, hi + 0.5)
    surf_kwargs = dict(scalars=channel, cmap=cmap, clim=clim, show_scalar_bar=scalar_bar,
                       scalar_bar_args=bar_args, lighting=lighting, smooth_shading=lighting,
                       n_colors=2 if channel == "walls" else 256, pickable=True)
    if model.stored is not None:
        stored_cells = _cell_mask(model.stored[np.ix_(rs, cs)])
        keep = np.flatnonzero(stored_cells)
        drop = np.flatnonzero(~stored_cells)
        if keep.size:
            preview.surface_actor = pl.add_mesh(grid.extract_cells(keep), **surf_kwargs)
        if drop.size:
            pl.add_mesh(grid.extract_cells(drop), color=LEFT_OUT_COLOR, opacity=0.3, lighting=lighting,
                        pickable=True)
    else:
        preview.surface_actor = pl.add_mesh(grid, **surf_kwargs)
    if scalar_bar:
        for bar in pl.scalar_bars.values():
            bar.SetVerticalTitleSeparation(10)    # keep the unit line clear of the top value

    extent = max(float(np.ptp(xs)), float(np.ptp(ys)), 1e-9)
    top = float(zs.max())
    lift = 0.004 * extent

    # ---- widgets --------------------------------------------------------------------------
    if model.widgets:   # outlines draped on the surface, all in one mesh
        s_ = np.linspace(0.0, 1.0, 60)[:-1]
        rings = []
        for w in model.widgets:
            x0, y0, x1, y1 = (w[k] * 1e3 for k in ("x0", "y0", "x1", "y1"))
            corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]])
            rings.append(np.concatenate([a + s_[:, None] * (b - a) for a, b in zip(corners[:-1], corners[1:])]
                                        + [corners[:1]]))
        ring = np.concatenate(rings)
        zr = preview.z_display(model.relief_at(ring[:, 0] * 1e-3, ring[:, 1] * 1e-3)) + lift
        starts = np.cumsum([0] + [len(r) for r in rings[:-1]])
        cells = np.concatenate([np.concatenate([[len(r)], np.arange(len(r)) + a]) for r, a in zip(rings, starts)])
        pl.add_mesh(pv.PolyData(np.column_stack([ring, zr]), lines=cells), color=WIDGET_COLOR, line_width=3,
                    pickable=False)
        if annotations:
            pts = np.array([[w["x0"] * 1e3, w["y1"] * 1e3,
                             float(preview.z_display(model.relief_at(w["x0"], w["y1"]))) + 2 * lift]
                            for w in model.widgets])
            for pt, w in zip(pts, model.widgets):   # one label each: VTK drops labels that overlap others
                pl.add_point_labels(pt[None, :], [w["id"]], font_size=12, text_color="black",
                                    shape_opacity=0.6, shape_color="white", show_points=False,
                                    always_visible=True)

    # ---- stroke ---------------------------------------------------------------------------
    if trace is not None:
        _draw_stroke(pv, pl, preview, trace, lift, extent)
        if with_chart:
            pl.subplot(1, 0)
            pl.set_background("white")
            _draw_chart(pv, pl, trace)
            pl.subplot(0, 0)

    # ---- annotations ----------------------------------------------------------------------
    if annotations:
        if model.relief_unit == "m":
            ex_text = f"vertical exaggeration x{ex:g}"
        else:
            ex_text = f"relief = normal force, 1 N drawn as {ex:g} mm"
        lines = [model.title, f"colour: {title}", ex_text]
        lines += [n for n in model.notes if n.startswith((channel, "height", "relief", "flat"))]
        if model.strip:
            lines.append("1-D profile drawn as a strip")
        if stride > 1:
            lines.append(f"drawn with 1 in {stride} samples per axis of the {model.relief.shape[0]}x"
                         f"{model.relief.shape[1]} grid; read-out uses all")
        if model.stored is not None:
            lines.append("grey: left out by the compiler")
        if trace is not None:
            lines.append(f"stroke: {trace.t.size} ticks, {trace.event_time.size} bursts (spike height ~ amplitude)")
        preview.info = "\n".join(lines)
        pl.add_text(preview.info, position="upper_left", font_size=10, color="black", name="info")
        _draw_scale_bar(pv, pl, xs, ys)

    # ---- camera ---------------------------------------------------------------------------
    centre = (float(xs.mean()), float(ys.mean()), 0.5 * top)
    direction = {"top": (0.0, 0.0, 1.0), "side": (0.0, -1.0, 0.12), "iso": (0.3, -1.0, 0.8)}[view]
    up = (0.0, 1.0, 0.0) if view == "top" else (0.0, 0.0, 1.0)
    pl.camera_position = [tuple(c + extent * d for c, d in zip(centre, direction)), centre, up]
    if view == "top":
        pl.enable_parallel_projection()
    pl.reset_camera()
    pl.camera.zoom({"top": 1.35, "side": 1.6, "iso": 1.15}[view])
    if scalar_bar:   # move the surface a little left, clear of the colour bar
        cam = pl.camera
        fwd = np.subtract(cam.focal_point, cam.position)
        right = np.cross(fwd, cam.up)
        right *= 0.06 * np.linalg.norm(fwd) / max(np.linalg.norm(right), 1e-12)
        cam.focal_point = tuple(np.add(cam.focal_point, right))
        cam.position = tuple(np.add(cam.position, right))
    # never crop: zoom out until the surface and the scale bar fit the free part of the frame
    edge_pts = [np.column_stack([xs[i], ys[i], zs[i]]) for i in (0, -1)]
    edge_pts += [np.column_stack([xs[:, j], ys[:, j], zs[:, j]]) for j in (0, -1)]
    k = max(1, zs.size // 20000)
    edge_pts.append(np.column_stack([xs.ravel()[::k], ys.ravel()[::k], zs.ravel()[::k]]))
    y_bar = float(ys.min()) - 0.08 * extent          # the scale bar and its label
    edge_pts.append(np.array([[float(xs.min()), y_bar, 0.0], [float(xs.min()) + extent / 5, y_bar, 0.0]]))
    fit_in_frame(pl, np.concatenate(edge_pts), right=0.68 if scalar_bar else 0.97,
                 top=0.76 if annotations else 0.97)

    if not off_screen:
        pl.enable_surface_point_picking(callback=preview._show_readout, show_message=False,
                                        left_clicking=True, show_point=True, color="black")
        pl.iren.add_observer("MouseMoveEvent", lambda *a: _hover(preview))
        if trace is not None:
            pl.add_key_event("space", lambda: preview.replay())
        hint = "click/hover: read-out    space: replay stroke" if trace is not None else "click/hover: read-out"
        pl.add_text(hint, position="lower_right", font_size=9, color="black", name="hint")
    return preview


def frame_coordinates(pl, points: np.ndarray) -> np.ndarray:
    """Normalized device coordinates (n, 2) in -1..1 of display points (n, 3) in the active view."""
    ren = pl.renderer
    aspect = ren.GetTiledAspectRatio()
    m = ren.GetActiveCamera().GetCompositeProjectionTransformMatrix(aspect, -1.0, 1.0)
    mat = np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)])
    h = np.column_stack([points, np.ones(len(points))]) @ mat.T
    return h[:, :2] / h[:, 3:4]


def fit_in_frame(pl, points: np.ndarray, left=-0.97, right=0.97, bottom=-0.95, top=0.97) -> float:
    """Zoom the camera out (never in) until ``points`` lie inside the given part of the frame.

    Returns the total zoom factor applied (1 when everything already fits).
    """
    total = 1.0
    for _ in range(4):      # a perspective zoom scales the view angle, not its tangent: a few passes
        ndc = frame_coordinates(pl, points)
        (x0, y0), (x1, y1) = ndc.min(axis=0), ndc.max(axis=0)
        f = min(1.0, left / x0 if x0 < left else 1.0, right / x1 if x1 > right else 1.0,
                bottom / y0 if y0 < bottom else 1.0, top / y1 if y1 > top else 1.0)
        if f >= 0.999:
            break
        pl.camera.zoom(f * 0.99)
        total *= f * 0.99
    return total


def draw_stride(rows: int, cols: int) -> int:
    """Sample stride that keeps a drawn grid within :data:`MAX_DRAWN_SAMPLES` points."""
    return max(1, math.ceil(math.sqrt(rows * cols / MAX_DRAWN_SAMPLES)))


def _strided(n: int, stride: int) -> np.ndarray:
    """0, stride, 2*stride, ... and always the last index (the surface keeps its full extent)."""
    idx = np.arange(0, n, stride)
    return idx if idx[-1] == n - 1 else np.append(idx, n - 1)


def _hover(preview: Preview) -> None:
    """Read out the surface under the mouse; nothing when the mouse is off the surface."""
    from vtkmodules.vtkRenderingCore import vtkCellPicker

    pl = preview.plotter
    if preview._picker is None:
        preview._picker = vtkCellPicker()
        preview._picker.SetTolerance(0.0005)
    x, y = pl.iren.get_event_position()
    picker = preview._picker
    if picker.Pick(x, y, 0, pl.renderer) and picker.GetActor() is not None:
        preview._show_readout(picker.GetPickPosition())
        pl.render()


def _cell_mask(point_mask: np.ndarray) -> np.ndarray:
    """Cells (quads between 4 samples) whose samples are all True, StructuredGrid cell order."""
    m = point_mask
    cells = m[:-1, :-1] & m[1:, :-1] & m[:-1, 1:] & m[1:, 1:]
    return cells.ravel(order="F")   # StructuredGrid(xs, ys, zs) of (rows, cols) arrays: rows fastest


def stroke_segments(state: np.ndarray, limit: int) -> tuple[np.ndarray, np.ndarray]:
    """Split a stroke of ``n`` ticks into at most ``limit`` drawn segments.

    Returns
    -------
    edges : ndarray of shape (m + 1,), int64
        Tick index where each segment starts (and the last tick).
    slip : ndarray of shape (m,), bool
        True where the pad is slipping for at least half of the segment's
        ticks. With ``n - 1 <= limit`` every tick is its own segment and
        ``slip == state[:-1] == 1`` exactly; longer strokes show the state
        the pad is in most of the time (a slip of the stiff pad often lasts
        one tick, far shorter than a pixel).
    """
    n = state.size
    m = max(1, min(n - 1, int(limit)))
    edges = np.unique(np.linspace(0, n - 1, m + 1).round().astype(np.int64))
    slip_ticks = np.concatenate([[0], np.cumsum(state == 1)])
    counts = slip_ticks[edges[1:]] - slip_ticks[edges[:-1]]
    return edges, 2 * counts >= (edges[1:] - edges[:-1])


def _draw_stroke(pv, pl, preview: Preview, trace: Trace, lift: float, extent: float) -> None:
    """Path coloured stick/slip; each burst a spike of height ~ amplitude with a ball at its tip."""
    model = preview.model
    idx, seg_slip = stroke_segments(trace.state, MAX_STROKE_POINTS)
    x, y = trace.x[idx], trace.y[idx]
    if model.strip:
        y = np.clip(y, model.y[0], model.y[-1])
    z = preview.z_display(model.relief_at(x, y)) + lift
    pts = np.column_stack([x * 1e3, y * 1e3, z])
    preview.stroke_points, preview.stroke_times = pts, trace.t[idx]
    if len(pts) >= 2:
        for value, color in ((False, STICK_COLOR), (True, SLIP_COLOR)):
            segs = np.flatnonzero(seg_slip == value)
            if segs.size == 0:
                continue
            lines = np.column_stack([np.full(segs.size, 2), segs, segs + 1]).ravel()
            poly = pv.PolyData(pts, lines=lines)
            pl.add_mesh(poly, color=color, line_width=5, render_lines_as_tubes=True, pickable=False)
    if trace.event_time.size:
        ex_, ey_ = trace.event_positions()
        amp = np.abs(trace.event_amplitude)
        order = np.sort(np.argsort(amp)[::-1][:MAX_BURST_MARKERS])       # largest kept, in time order
        ex_, ey_, amp = ex_[order], ey_[order], amp[order]
        if model.strip:
            ey_ = np.clip(ey_, model.y[0], model.y[-1])
        base = preview.z_display(model.relief_at(ex_, ey_)) + lift
        top = float(amp.max()) if amp.size and amp.max() > 0 else 1.0
        tip = base + SPIKE_FRACTION * extent * amp / top
        foot = np.column_stack([ex_ * 1e3, ey_ * 1e3, base])
        head = np.column_stack([ex_ * 1e3, ey_ * 1e3, tip])
        k = len(foot)
        spikes = pv.PolyData(np.concatenate([foot, head]),
                             lines=np.column_stack([np.full(k, 2), np.arange(k), np.arange(k) + k]).ravel())
        pl.add_mesh(spikes, color=BURST_COLOR, line_width=1.5, pickable=False)
        # ball radius: about half the typical distance between bursts, within 0.2..1 % of the extent
        typical = float(np.median(np.hypot(np.diff(ex_), np.diff(ey_)))) * 1e3 if k > 1 else extent
        r_max = float(np.clip(0.5 * typical, 0.002 * extent, 0.01 * extent))
        cloud = pv.PolyData(head)
        cloud.point_data["radius"] = np.maximum(r_max * np.sqrt(amp / top), 0.25 * r_max)
        glyphs = cloud.glyph(geom=pv.Sphere(radius=1.0, theta_resolution=10, phi_resolution=10),
                             scale="radius", orient=False)
        pl.add_mesh(glyphs, color=BURST_COLOR, pickable=False)
    cursor = pv.Sphere(radius=0.015 * extent, center=(0.0, 0.0, 0.0))
    preview.cursor_actor = pl.add_mesh(cursor, color="black", pickable=False)
    preview.cursor_actor.position = tuple(pts[0])
    legend = [["stick", STICK_COLOR], ["slip", SLIP_COLOR], ["burst", BURST_COLOR]]
    pl.add_legend(legend, bcolor="white", size=(0.12, 0.1), loc="lower right", face="circle")


def _draw_chart(pv, pl, trace: Trace) -> None:
    s = trace.arc_length * 1e3
    if trace.t.size < 2 or float(np.ptp(s)) <= 0:
        s = trace.t - trace.t[0]
        xlabel = "time [s]"
    else:
        xlabel = "distance along stroke [mm]"
    chart = pv.Chart2D(size=(0.9, 0.92), loc=(0.02, 0.04), x_label=xlabel, y_label="force [N]")
    for values, colour, label in ((trace.normal_force, "black", "normal force N"),
                                  (trace.friction_force, SLIP_COLOR, "friction force")):
        idx = envelope_indices(values, CHART_BINS)
        chart.line(s[idx], values[idx], color=colour, width=2.0, label=label)
    chart.background_color = (1.0, 1.0, 1.0, 1.0)
    chart.legend_visible = True
    pl.add_chart(chart)


def envelope_indices(values: np.ndarray, bins: int) -> np.ndarray:
    """Indices keeping the first, last, min and max sample of each of ``bins`` bins, in order.

    Draws a long, fast-oscillating signal (friction under stick-slip) with
    at most ``4 * bins`` points without aliasing its envelope away.
    """
    n = values.size
    if n <= 4 * bins:
        return np.arange(n)
    edges = np.linspace(0, n, bins + 1).astype(np.int64)
    starts, ends = edges[:-1], edges[1:]
    lo = np.array([a + int(np.argmin(values[a:b])) for a, b in zip(starts, ends)])
    hi = np.array([a + int(np.argmax(values[a:b])) for a, b in zip(starts, ends)])
    return np.unique(np.concatenate([starts, ends - 1, lo, hi]))


def _draw_scale_bar(pv, pl, xs: np.ndarray, ys: np.ndarray) -> None:
    width = float(np.ptp(xs))
    depth = float(np.ptp(ys))
    length = nice_number(width / 5.0) if width > 0 else 1.0
    x0 = float(xs.min())
    extent = max(width, depth)
    y = float(ys.min()) - 0.04 * extent
    bar = pv.Line((x0, y, 0.0), (x0 + length, y, 0.0))
    pl.add_mesh(bar, color="black", line_width=6, pickable=False)
    y_label = y - 0.04 * extent
    pl.add_point_labels(np.array([[x0 + 0.5 * length, y_label, 0.0]]), [f"{length:g} mm"], font_size=12,
                        text_color="black", shape=None, show_points=False, always_visible=True)
