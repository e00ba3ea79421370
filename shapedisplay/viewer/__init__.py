"""3D preview of height fields, compiled tables, scenes and played strokes.

Three modules, one job each (pyvista's split between data and plotting):

* :mod:`.model` -- what is drawn, numpy only and testable without VTK:
  :class:`PreviewModel`, :class:`Trace`, :func:`load_model`,
  :func:`model_from_heightfield`, :func:`model_from_table`,
  :func:`load_trace`, :func:`auto_exaggeration`;
* :mod:`.offscreen` -- whether a display exists and whether VTK can render
  off-screen here (:func:`check_offscreen`, probed in a child process);
* :mod:`.draw` -- drawing with pyvista (:func:`render`, :class:`Preview`),
  an optional extra imported only when something is drawn.

The names below are the public interface; ``import shapedisplay.viewer``
loads neither pyvista nor VTK.
"""
from __future__ import annotations

from shapedisplay.viewer.draw import VIEWS, Preview, draw_stride, fit_in_frame, frame_coordinates, render
from shapedisplay.viewer.model import (
    ALIASES, AUTO_RELIEF_FRACTION, DERIVED, MAX_AUTO_EXAGGERATION, STRIP_FRACTION, TRACE_ARRAYS, WALL_SLOPE,
    PreviewModel, Trace, auto_exaggeration, check_trace, envelope_indices, load_model, load_trace,
    model_from_heightfield, model_from_table, nice_number, parse_exaggeration, parse_window_size,
    scene_forces, slope_of, stroke_segments, widgets_of_scene,
)
from shapedisplay.viewer.offscreen import OFFSCREEN_WINDOWS, check_offscreen, has_display

__all__ = [
    "VIEWS", "Preview", "draw_stride", "fit_in_frame", "frame_coordinates", "render",
    "ALIASES", "AUTO_RELIEF_FRACTION", "DERIVED", "MAX_AUTO_EXAGGERATION", "STRIP_FRACTION", "TRACE_ARRAYS",
    "WALL_SLOPE", "PreviewModel", "Trace", "auto_exaggeration", "check_trace", "envelope_indices", "load_model",
    "load_trace", "model_from_heightfield", "model_from_table", "nice_number", "parse_exaggeration",
    "parse_window_size", "scene_forces", "slope_of", "stroke_segments", "widgets_of_scene",
    "OFFSCREEN_WINDOWS", "check_offscreen", "has_display",
]
