"""What the 3D preview draws, in numpy only (no VTK): the preview model.

:class:`PreviewModel` holds the relief, every colourable channel in SI units,
what the compiler left out and widget outlines, on one regular grid;
:class:`Trace` is a played stroke. The channels are not computed here: a
table's come from the table, a scene's from the scene compiler
(:func:`shapedisplay.author.scene.compiler.scene_force_channels`), and the friction
limits mu_s N and mu_k N from the renderer's own derivation
(:func:`shapedisplay.render.renderer.friction_limits`). This module adds only
what is drawn (slope, walls, ``|F_lat|``) and the choices of the drawing
(exaggeration, stroke segments, chart envelope).

Display coordinates are millimetres: x and y as on the surface, z the
relief times the vertical exaggeration (stated on screen).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shapedisplay.errors import FileFormatError, InputError, ShapeDisplayError, TableError, unknown_key

#: Slope ``|grad h|`` at and above which a sample counts as a wall (45 degrees).
WALL_SLOPE = 1.0
#: Relief height, as a fraction of the larger horizontal extent, chosen by "auto" exaggeration.
AUTO_RELIEF_FRACTION = 0.15
#: Largest automatic vertical exaggeration.
MAX_AUTO_EXAGGERATION = 1000.0
#: Width of the strip a 1-D profile is drawn as, as a fraction of its length.
STRIP_FRACTION = 0.12

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
    """A played stroke, as written by ``shapedisplay.render.sinks.write_trace``.

    Attributes
    ----------
    t, x, y, normal_force, friction_force : ndarray of shape (n,), float64
        Tick times (s), cursor position (m), normal and friction force (N).
    state : ndarray of shape (n,), int8
        0 stick, 1 slip, at each tick.
    event_time, event_amplitude : ndarray of shape (m,), float64
        Stick-to-slip transitions (s) and their burst amplitude (device units).
    table_checksum : str
        ``FrictionTable.checksum`` of the table the stroke was played on.
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
        from shapedisplay.render.sinks import check_trace_arrays
        for name in TRACE_ARRAYS:
            a = np.asarray(getattr(self, name)).ravel()
            setattr(self, name, a if name == "state" else a.astype(np.float64))
        check_trace_arrays({k: getattr(self, k) for k in TRACE_ARRAYS}, f"trace {self.source!r}", InputError)
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
    """Read a trace ``.npz`` written by ``shapedisplay.render.sinks.write_trace`` (through its bounded reader)."""
    from shapedisplay.render.sinks import read_trace

    d = read_trace(path, required=(*TRACE_ARRAYS,))
    if "table_checksum" not in d:
        raise FileFormatError(f"trace '{path}': lacks 'table_checksum'; not a shapedisplay trace")
    return Trace(**{k: d[k] for k in TRACE_ARRAYS}, table_checksum=d["table_checksum"], source=str(path))


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
        False on flat ground outside every stored block: the table keeps one
        value per channel there (its background), drawn faintly.
    widgets : list of dict
        ``{"id": str, "x0", "y0", "x1", "y1"}`` outlines in metres.
    checksum : str or None
        Checksum of the table shown (trace check).
    strip : bool
        True when a 1-D profile was widened into a strip for drawing.
    ground : str
        What the unstored flat ground plays, e.g. "flat ground, stored as one
        value: N = 1 N" (empty when everything is stored).
    walls : dict or None
        The compile report's walls (``meta["report"]["walls"]``): the preview
        states its count, as compile and inspect do.
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
    ground: str = ""
    walls: dict | None = None

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
    """``|grad h|`` of ``heights`` (rows, cols) metres, as the compiler's default gradient computes it."""
    from shapedisplay.author.gradients import central, slope_magnitude
    from shapedisplay.author.heightfield import HeightField
    return slope_magnitude(*central(HeightField(np.asarray(heights, dtype=np.float64), dx, dy)))


def _widen(model_rows: dict, y0: float, length: float) -> tuple[np.ndarray, dict]:
    """Turn single-row arrays into a 2-row strip centred on ``y0``."""
    half = 0.5 * STRIP_FRACTION * length
    y = np.array([y0 - half, y0 + half])
    return y, {k: (np.repeat(v, 2, axis=0) if v is not None else None) for k, v in model_rows.items()}


def model_from_heightfield(hf, title: str | None = None) -> PreviewModel:
    """A preview of a :class:`~shapedisplay.author.heightfield.HeightField`: height, slope, walls."""
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


def _height_mapping(meta: dict):
    """The linear height mapping recorded in table meta (``meta["mapping"]`` with ``n_gain``), if any."""
    raw = meta.get("mapping") if isinstance(meta, dict) else None
    if not isinstance(raw, dict) or raw.get("n_gain") is None:
        return None
    from shapedisplay.author.forces import MappingOptions
    try:
        mapping = MappingOptions.from_json(raw)
    except (ShapeDisplayError, TypeError, ValueError):
        return None
    if not mapping.height or mapping.perceptual_exponent is not None or mapping.n_gain <= 0:
        return None     # N is not linear in h: draw the force itself
    return mapping


def model_from_table(table, title: str | None = None, widgets: list | None = None) -> PreviewModel:
    """A preview of a compiled :class:`~shapedisplay.table.model.FrictionTable`.

    The relief is the height the normal force encodes when the table's
    ``meta["mapping"]`` gives the gain (h = (N - n_base) / n_gain); otherwise
    the normal force itself is drawn as relief (``relief_unit == "N"``).
    Samples no block covers (left out by the compiler) are marked in
    ``stored``. Widget outlines come from ``widgets`` or, when absent, from
    ``meta["widgets"]`` (``[{"id", "x0", "y0", "x1", "y1"}]`` metres).
    """
    from shapedisplay.table.model import CHANNELS

    g = table.grid
    x = g.x0 + g.dx * np.arange(g.cols)
    y = g.y0 + g.dy * np.arange(g.rows)
    fields = {name: np.asarray(table.dense(name), dtype=np.float64) for name in table.channels}
    units = {name: CHANNELS[name][0] for name in fields}
    labels = {name: name.replace("_", " ") for name in fields}

    relief, relief_unit, notes = None, "N", []
    mapping = _height_mapping(table.meta)
    if "normal_force" in fields and mapping is not None:
        relief, relief_unit = mapping.height_of_force(fields["normal_force"]), "m"
        notes.append(f"height from N: n_gain {mapping.n_gain / 1e3:g} N/mm")
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
    ground = ""
    if stored is not None:
        values = [f"N = {table.background['normal_force']:.3g} N"] if "normal_force" in table.channels else []
        ground = "flat ground, stored as one value" + (": " + ", ".join(values) if values else "")

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
                        checksum=table.checksum, strip=strip, ground=ground,
                        title=title if title is not None else (default_title or "friction table"), notes=notes)
    model.widgets = _strip_widgets(_clean_widgets(widgets), model)
    report = table.meta.get("report") if isinstance(table.meta, dict) else None
    walls = report.get("walls") if isinstance(report, dict) else None
    model.walls = walls if isinstance(walls, dict) and isinstance(walls.get("count"), int) else None
    return model


def _derive_forces(fields: dict, units: dict, labels: dict, notes: list, friction) -> None:
    """Add what the runtime derives: mu_s*N, mu_k*N (when not stored) and |F_lat|; in place.

    ``friction`` is ``{"mu_s", "mu_k"}`` of the device (or empty: no friction
    limits); the limits come from the renderer's own per-tick derivation.
    """
    mu = {k: friction.get(k) for k in ("mu_s", "mu_k")} if isinstance(friction, dict) else {}
    have_mu = all(isinstance(v, (int, float)) and math.isfinite(v) for v in mu.values()) and len(mu) == 2
    if have_mu and "normal_force" in fields and not {"breakaway_force", "kinetic_force"} <= set(fields):
        from shapedisplay.render.renderer import friction_limits
        limits = dict(zip(("breakaway_force", "kinetic_force"),
                          friction_limits(fields, float(mu["mu_s"]), float(mu["mu_k"]))))
        for name, mu_key in (("breakaway_force", "mu_s"), ("kinetic_force", "mu_k")):
            if name not in fields:
                fields[name] = limits[name]
                notes.append(f"{name} = {mu_key} * N as the renderer derives it (device {mu_key} = {mu[mu_key]:g})")
    if "lateral_x" in fields or "lateral_y" in fields:
        fields["lateral"] = np.hypot(fields.get("lateral_x", 0.0), fields.get("lateral_y", 0.0))
    for name in fields:
        if name in DERIVED:
            units[name], labels[name] = DERIVED[name]
        elif name not in units:
            from shapedisplay.table.model import CHANNELS
            units[name], labels[name] = CHANNELS[name][0], name.replace("_", " ")


def scene_forces(scene) -> tuple[dict, list]:
    """Force channels of a scene as its compiled table stores them, densely (SI).

    Returns ``({name: ndarray (rows, cols)}, notes)``: the channels of
    :func:`shapedisplay.author.scene.compiler.scene_force_channels`, plus
    ``breakaway_force`` and ``kinetic_force`` from the device's friction as
    the renderer derives them (:func:`shapedisplay.render.renderer.friction_limits`).
    """
    from shapedisplay.author.scene.compiler import scene_force_channels
    fields = scene_force_channels(scene)
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


def _is_trace(path) -> bool:
    """True if ``path`` holds a trace's entries and no table header (read through the bounded reader)."""
    from shapedisplay.table.container import NpzReader
    try:
        with NpzReader(path, f"input '{path}'", None, max_entries=64, error=FileFormatError) as z:
            return "header" not in z and "table_checksum" in z
    except ShapeDisplayError:
        return False


def load_model(path: str | os.PathLike, scene: str | os.PathLike | None = None, flags: dict | None = None,
               **source_opts) -> PreviewModel:
    """Preview model of a file: table (.npz), scene (.toml) or source (image, mesh).

    ``scene`` adds the widget outlines and ids of a scene file to a table.
    ``source_opts`` (``size``, ``height_range``, ``resolution``, ... ; None
    dropped) and ``flags`` (how messages spell an option) go to
    :func:`shapedisplay.author.sources.load_source`.
    """
    path = Path(os.fspath(path))
    from shapedisplay.author.sources import load_source, source_kind
    kind = source_kind(path)
    opts = {k: v for k, v in source_opts.items() if v is not None}
    if kind in ("table", "scene", "svg") and opts:
        raise InputError(f"{kind} '{path}': source options {sorted(opts)} apply to images and meshes only")
    if kind == "table":
        from shapedisplay.table.model import FrictionTable
        try:
            table = FrictionTable.load(path)
        except TableError:
            if _is_trace(path):
                raise InputError(f"input '{path}' is a trace; give the table as input and the trace with --trace") \
                    from None
            raise
        widgets = None
        if scene:
            sc = _load_scene(scene)
            _check_scene_fits(sc, table, path)
            widgets = widgets_of_scene(sc)
        return model_from_table(table, title=path.name, widgets=widgets)
    if kind in ("scene", "svg"):      # a scene file or an SVG mockup of one
        sc = _load_scene(path)
        from shapedisplay.author.scene import scene_heightfield
        hf = scene_heightfield(sc)
        model = model_from_heightfield(hf, title=getattr(sc, "name", "") or path.name)
        forces, notes = scene_forces(sc)
        for name, arr in forces.items():
            model.fields[name] = np.repeat(arr, 2, axis=0) if model.strip else arr
        _derive_forces(model.fields, model.units, model.labels, [], {})
        model.notes += notes
        model.widgets = _strip_widgets(_clean_widgets(widgets_of_scene(sc)), model)
        return model
    if scene:
        raise InputError(f"`--scene` draws widget outlines on a table; '{path}' is a source")
    return model_from_heightfield(load_source(path, flags=flags, **opts))


def _load_scene(path):
    path = Path(os.fspath(path))
    if not path.is_file():
        raise FileFormatError(f"scene '{path}': no such file")
    from shapedisplay.author.scene import load_scene
    return load_scene(path)


def _check_scene_fits(scene, table, path) -> None:
    """Refuse to draw the outlines of a scene whose canvas is not the table's grid."""
    g, c = table.grid, scene.canvas
    same = (g.rows, g.cols) == (c.rows, c.cols) and math.isclose(g.dx, c.spacing, rel_tol=1e-9) \
        and math.isclose(g.dy, c.spacing, rel_tol=1e-9) and g.x0 == 0.0 and g.y0 == 0.0
    if not same:
        raise InputError(
            f"`--scene` '{scene.path}' does not fit table '{path}': the scene's canvas is "
            f"{c.cols} x {c.rows} samples of {c.spacing * 1e3:g} mm from (0, 0), the table's grid "
            f"{g.cols} x {g.rows} samples of {g.dx * 1e3:g} x {g.dy * 1e3:g} mm from "
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

