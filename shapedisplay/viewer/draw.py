"""Drawing the preview with pyvista: the surface, outlines, stroke, chart and camera.

pyvista is an optional extra, imported only when drawing (through
:func:`.offscreen.load_pyvista`). What is drawn is decided by the numpy
model (:mod:`~shapedisplay.viewer.model`); this module only turns it into VTK actors.
"""
from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Callable

import numpy as np

from shapedisplay.errors import InputError, require, unknown_key
from shapedisplay.viewer.model import (WALL_SLOPE, PreviewModel, Trace, auto_exaggeration, check_trace, envelope_indices, nice_number,
                    parse_exaggeration, parse_window_size, stroke_segments)
from shapedisplay.viewer.offscreen import load_pyvista

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
WALL_COLOR = "#d62728"
LEGEND_GROUND_COLOR = "#8a8a8a"
#: Alternating colours of the widget bands on the stroke chart.
SPAN_COLORS = ("#5b8fd1", "#d1955b")
#: Opacity of the wall overlay (the surface colour stays readable through it).
WALL_OPACITY = 0.55
#: Colours of the orientation triad's x, y and z arrows.
TRIAD_COLORS = ("#c62828", "#2e7d32", "#1565c0")
#: Part of the frame (normalized device coordinates) the content is fitted into: left, right, bottom, top;
#: the right and top parts are kept for the colour bar, the legend and the text.
FREE_FRAME = {"left": -0.94, "right": 0.96, "bottom": -0.92, "top": 0.95}

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
        self.legend: list = []                          # [label, colour] entries of the legend
        self.wall_actor = None                          # the wall overlay, when the surface has walls
        self.wall_cells = 0                             # cells drawn in the wall overlay
        self.triad: dict = {}                           # axis -> (origin, tip) display mm, and "labels"
        self.frame: dict = {}                           # content box and free region of the 3D view (NDC)
        self.chart_spans: list = []                     # widget spans marked on the stroke chart
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
        from shapedisplay.atomic import atomic_path
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
        Shading, colour bar, N/friction chart along the stroke (widgets crossed marked), texts, legend
        and the orientation triad (x, y, z arrows labelled with their length in mm).
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
    pv = load_pyvista(off_screen)
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
    bar_args = dict(title=bar_title, vertical=True, position_x=0.85, position_y=0.42, width=0.05, height=0.45,
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
            _draw_chart(pv, pl, preview, trace, model.widgets)
            pl.subplot(0, 0)

    # ---- walls ----------------------------------------------------------------------------
    walls = model.fields.get("walls")
    if walls is not None and channel != "walls" and walls.any():
        wall_cells = np.flatnonzero(_cell_mask(walls[np.ix_(rs, cs)] > 0, any_corner=True))
        if wall_cells.size:
            overlay = grid.extract_cells(wall_cells)
            preview.wall_actor = pl.add_mesh(overlay, color=WALL_COLOR, opacity=WALL_OPACITY, lighting=lighting,
                                             pickable=False)
            mapper = preview.wall_actor.GetMapper()       # drawn over the surface it lies on
            mapper.SetResolveCoincidentTopologyToPolygonOffset()
            mapper.SetRelativeCoincidentTopologyPolygonOffsetParameters(-2.0, -4.0)
            preview.wall_cells = int(wall_cells.size)

    # ---- legend -----------------------------------------------------------------------------
    legend = []
    if trace is not None:
        legend += [["stroke, stuck", STICK_COLOR], ["stroke, slipping", SLIP_COLOR],
                   ["burst (spike ~ amplitude)", BURST_COLOR]]
    if model.widgets:
        legend.append(["widget outline", WIDGET_COLOR])
    if model.stored is not None:
        legend.append(["flat ground (one value)", LEFT_OUT_COLOR])
    if preview.wall_actor is not None:
        legend.append([f"wall (slope >= {WALL_SLOPE:g})", WALL_COLOR])
    preview.legend = legend
    if legend and annotations:     # entry text takes the entry's colour: the light grey is darkened for reading
        shown = [[label, LEGEND_GROUND_COLOR if colour == LEFT_OUT_COLOR else colour] for label, colour in legend]
        box_w, box_h = 0.3, min(0.032 * len(legend), 0.4)
        actor = pl.add_legend(shown, bcolor="white", border=True, size=(box_w, box_h), face="rectangle",
                              font_family="arial")
        actor.SetPosition(0.985 - box_w, 0.015)         # lower right corner, inside the frame
        actor.SetPosition2(box_w, box_h)

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
            lines.append(f"drawn with 1 in {stride} samples per axis of the {model.relief.shape[1]} x "
                         f"{model.relief.shape[0]}-sample grid; read-out uses all")
        if model.stored is not None:
            lines.append("grey: " + (model.ground or "flat ground, stored as one value"))
        if model.walls is not None and model.walls["count"]:     # the compile report's count, as inspect says
            from shapedisplay.author.gradients import wall_lines
            lines += ["red: " + ln.strip() for ln in wall_lines(model.walls, boxes=3)]
        elif preview.wall_actor is not None:
            lines.append(f"red: walls, slope >= {WALL_SLOPE:g} (45 deg), {100 * float(walls.mean()):.3g} % of the canvas")
        if trace is not None:
            lines.append(f"stroke: {trace.t.size} ticks, {trace.event_time.size} bursts (spike height ~ amplitude)")
        preview.info = "\n".join(lines)
        pl.add_text(preview.info, position="upper_left", font_size=10, color="black", name="info")

    # ---- orientation triad (x, y, z with lengths in mm): at the near left corner --------------
    triad_pts = _draw_triad(pv, pl, preview, xs, ys, extent) if annotations else np.zeros((0, 3))

    # ---- camera ---------------------------------------------------------------------------
    centre = (float(xs.mean()), float(ys.mean()), 0.5 * top)
    direction = {"top": (0.0, 0.0, 1.0), "side": (0.0, -1.0, 0.12), "iso": (0.3, -1.0, 0.8)}[view]
    up = (0.0, 1.0, 0.0) if view == "top" else (0.0, 0.0, 1.0)
    pl.camera_position = [tuple(c + extent * d for c, d in zip(centre, direction)), centre, up]
    if view == "top":
        pl.enable_parallel_projection()
    pl.reset_camera()
    # fill the free part of the frame with the surface and the triad (zoom in or out, centred)
    edge_pts = [np.column_stack([xs[i], ys[i], zs[i]]) for i in (0, -1)]
    edge_pts += [np.column_stack([xs[:, j], ys[:, j], zs[:, j]]) for j in (0, -1)]
    k = max(1, zs.size // 20000)
    edge_pts.append(np.column_stack([xs.ravel()[::k], ys.ravel()[::k], zs.ravel()[::k]]))
    edge_pts.append(triad_pts)
    if preview.stroke_points is not None:
        edge_pts.append(preview.stroke_points)
    region = dict(FREE_FRAME)
    if scalar_bar:
        region["right"] = 0.66
    if annotations:     # below the text block (about 18 px a line, whatever the window size)
        view_px = height * ((1.0 - CHART_HEIGHT) if with_chart else 1.0)
        region["top"] = max(0.97 - 2.0 * (18 * len(preview.info.splitlines()) + 12) / max(view_px, 1.0), 0.2)
    if legend and annotations and not scalar_bar:
        region["right"] = 0.45
    preview.frame = fit_in_frame(pl, np.concatenate(edge_pts), **region)

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


def fit_in_frame(pl, points: np.ndarray, left=-0.97, right=0.97, bottom=-0.95, top=0.97) -> dict:
    """Move and zoom the camera so ``points`` fill the given part of the frame, centred in it.

    The box of the points in normalized device coordinates (-1..1) is
    brought to the centre of ``left..right`` x ``bottom..top`` and scaled
    until it touches that region's sides in one direction (zoom in or out).

    Returns
    -------
    dict
        ``{"content": (x0, y0, x1, y1), "region": (left, bottom, right, top)}`` after the fit, NDC.
    """
    cam = pl.camera
    for _ in range(8):      # perspective: a zoom scales the view angle, a pan shifts the depth; a few passes
        ndc = frame_coordinates(pl, points)
        (x0, y0), (x1, y1) = ndc.min(axis=0), ndc.max(axis=0)
        w, h = max(x1 - x0, 1e-9), max(y1 - y0, 1e-9)
        f = min((right - left) / w, (top - bottom) / h)
        dx = 0.5 * (left + right) - 0.5 * (x0 + x1)
        dy = 0.5 * (bottom + top) - 0.5 * (y0 + y1)
        if abs(f - 1.0) < 0.005 and abs(dx) < 0.003 and abs(dy) < 0.003:
            break
        # pan: shift position and focal point along the view's right and up vectors
        pos, foc = np.array(cam.position), np.array(cam.focal_point)
        fwd = foc - pos
        dist = float(np.linalg.norm(fwd))
        upv = np.array(cam.up, float)
        right_v = np.cross(fwd, upv)
        right_v /= max(np.linalg.norm(right_v), 1e-12)
        up_v = np.cross(right_v, fwd)
        up_v /= max(np.linalg.norm(up_v), 1e-12)
        aspect = pl.renderer.GetTiledAspectRatio()
        if cam.parallel_projection:
            half_h = cam.parallel_scale
        else:
            half_h = dist * math.tan(math.radians(cam.view_angle) / 2.0)
        shift = -(dx * half_h * aspect) * right_v - (dy * half_h) * up_v
        cam.position = tuple(pos + shift)
        cam.focal_point = tuple(foc + shift)
        cam.zoom(float(np.clip(f * 0.995, 0.2, 5.0)))
    for _ in range(4):      # never crop: zoom out while anything is outside the region
        ndc = frame_coordinates(pl, points)
        (x0, y0), (x1, y1) = ndc.min(axis=0), ndc.max(axis=0)
        f = min(1.0, left / x0 if x0 < left else 1.0, right / x1 if x1 > right else 1.0,
                bottom / y0 if y0 < bottom else 1.0, top / y1 if y1 > top else 1.0)
        if f >= 0.999:
            break
        cam.zoom(f * 0.99)
    ndc = frame_coordinates(pl, points)
    (x0, y0), (x1, y1) = ndc.min(axis=0), ndc.max(axis=0)
    return {"content": (float(x0), float(y0), float(x1), float(y1)),
            "region": (float(left), float(bottom), float(right), float(top))}


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


def _cell_mask(point_mask: np.ndarray, any_corner: bool = False) -> np.ndarray:
    """Cells (quads between 4 samples) whose samples are all True (or any, with ``any_corner``),
    StructuredGrid cell order."""
    m = point_mask
    if any_corner:
        cells = m[:-1, :-1] | m[1:, :-1] | m[:-1, 1:] | m[1:, 1:]
    else:
        cells = m[:-1, :-1] & m[1:, :-1] & m[:-1, 1:] & m[1:, 1:]
    return cells.ravel(order="F")   # StructuredGrid(xs, ys, zs) of (rows, cols) arrays: rows fastest


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


def _draw_chart(pv, pl, preview: Preview, trace: Trace, widgets: list) -> None:
    """N and friction force along the stroke; the stretches inside widgets shaded (ids in the legend)."""
    s = trace.arc_length * 1e3
    if trace.t.size < 2 or float(np.ptp(s)) <= 0:
        s = trace.t - trace.t[0]
        xlabel = "time [s]"
    else:
        xlabel = "distance along stroke [mm]"
    chart = pv.Chart2D(size=(0.9, 0.92), loc=(0.02, 0.04), x_label=xlabel, y_label="force [N]")
    if xlabel.startswith("distance") and widgets:   # the widgets crossed: a band below the curves
        from shapedisplay.render.strokes import widget_spans
        spans = widget_spans(trace.x, trace.y, widgets)
        top = float(max(np.max(trace.normal_force), np.max(trace.friction_force), 0.0)) or 1.0
        level = min(float(np.min(trace.friction_force)), 0.0) - 0.1 * top
        ids = ", ".join(dict.fromkeys(d["id"] for d in spans))
        for i, sp in enumerate(spans):
            chart.line(np.array([sp["s0"], sp["s1"]]) * 1e3, np.array([level, level]), width=10.0,
                       color=SPAN_COLORS[i % 2], label=f"widgets crossed: {ids}" if i == 0 else "")
        preview.chart_spans = spans
    for values, colour, label in ((trace.normal_force, "black", "normal force N"),
                                  (trace.friction_force, SLIP_COLOR, "friction force")):
        idx = envelope_indices(values, CHART_BINS)
        chart.line(s[idx], values[idx], color=colour, width=2.0, label=label)
    chart.background_color = (1.0, 1.0, 1.0, 1.0)
    chart.legend_visible = True
    pl.add_chart(chart)



def _draw_triad(pv, pl, preview: Preview, xs: np.ndarray, ys: np.ndarray, extent: float) -> np.ndarray:
    """Arrows along x, y and z at the near left corner, each one ``length`` long, labelled with what that
    length is (mm of the surface; z: mm of height, or N of force, at the drawn exaggeration).

    Returns the display points (n, 3) the triad and its labels take, for framing.
    """
    model = preview.model
    length = nice_number(max(float(np.ptp(xs)), float(np.ptp(ys))) / 6.0) if extent > 0 else 1.0
    gap = 0.05 * extent
    origin = np.array([float(xs.min()) - gap, float(ys.min()) - gap, 0.0])
    z_len = length / preview.exaggeration
    z_unit = "mm" if model.relief_unit == "m" else "N"
    texts = {"x": f"x {length:g} mm", "y": f"y {length:g} mm",
             "z": f"z {z_len:.3g} {z_unit}" + (" of N" if z_unit == "N" else "")}
    tips = {}
    for axis, direction, colour in zip("xyz", np.eye(3), TRIAD_COLORS):
        tip = origin + length * direction
        arrow = pv.Arrow(start=origin, direction=direction, scale=length, tip_length=0.22, tip_radius=0.07,
                         shaft_radius=0.025)
        pl.add_mesh(arrow, color=colour, pickable=False, lighting=False)
        tips[axis] = tip
    # x label past its tip, y label to the right of its tip, z label to the left: never on each other
    offsets = {"x": (0.35, 0.0, 0.0), "y": (0.45, 0.1, 0.0), "z": (-0.35, 0.0, 0.12)}
    pts = np.array([tips[a] + length * np.array(offsets[a]) for a in "xyz"])
    pl.add_point_labels(pts, [texts[a] for a in "xyz"], font_size=12, text_color="black", shape=None,
                        show_points=False, always_visible=True, bold=True)
    preview.triad = {"origin": origin, "tips": tips, "length": length, "labels": texts}
    pad = 0.25 * length
    return np.array([origin, origin + [length + 3 * pad, 0, 0], origin + [0, length + pad, 0],
                     origin + [0, 0, length + pad]])
