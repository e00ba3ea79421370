"""Scenes: screens of GUI widgets described in TOML and compiled to one table.

A scene file lays out widgets (buttons, dents, sliders, toggles, ridges,
height-map images, meshes and free data layers) on a canvas, with the target
device and the tactile parameters written in the designer's language
(perceived height in equal-feeling steps, or N ranges and ramp spans).

* :func:`load_scene` parses and validates a file into a :class:`Scene`
  (widgets with ``id``, ``type`` and bounding box in metres);
* :func:`check_scene` validates without compiling and returns the warnings;
* :func:`compile_scene` compiles only what the scene needs: one block per
  widget (or per group of overlapping widgets), identical widgets stored
  once, a 1-D table for a 1-D canvas, channels as the device and mapping
  need, both states of every toggle;
* :func:`select_state` switches a toggle of a compiled table.

Modules: :mod:`.fields` (value parsers, scene errors, the canvas and widget
records), :mod:`.spec` (file format, validation), :mod:`.widgets` (the
geometry of each widget type, a registry), :mod:`.compiler` (boxes, merging,
force mapping, table), :mod:`.template` (the commented template written by
``shapedisplay new scene``).
"""
from __future__ import annotations

from shapedisplay.author.scene.fields import Canvas, SceneError, Widget
from shapedisplay.author.scene.spec import Scene, import_svg, load_scene, parse_scene
from shapedisplay.author.scene.widgets import WIDGET_TYPES
from shapedisplay.author.scene.compiler import check_scene, compile_scene, format_widget_report, scene_heightfield, select_state
from shapedisplay.author.scene.template import TEMPLATE

__all__ = ["Canvas", "Scene", "SceneError", "Widget", "import_svg", "load_scene", "parse_scene", "WIDGET_TYPES",
           "check_scene", "compile_scene", "format_widget_report", "scene_heightfield", "select_state",
           "TEMPLATE"]
