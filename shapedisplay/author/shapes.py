"""Shapes shared by the analytic primitives and the scene widgets: one home for each.

* :func:`rounded_rect_distance` — signed distance to a rounded rectangle
  (negative inside), evaluated on whatever grid the caller's coordinates span;
* the edge rises — how an edge climbs from 0 at the outline to 1 at the top
  of its ramp, as a function of ``t`` = inward distance / ramp width
  (:func:`linear_rise`, :func:`cosine_rise`, :func:`step_rise`).

The two authoring front ends spell the edges differently, and both spellings
stay accepted: :data:`PRIMITIVE_EDGES` (``sources.rounded_button(edge=...)``:
"ramp", "cosine", "step") and :data:`WIDGET_EDGES` (a scene widget's
``edge``: "linear", "cosine", "tent"; a tent is the linear rise over half the
widget). Each maps an accepted name to one of the rises above, so a name in
either spelling is the same function.
"""
from __future__ import annotations

import numpy as np

from shapedisplay.errors import unknown_key


def rounded_rect_distance(x, y, half_width: float, half_height: float, radius: float):
    """Signed distance from ``(x, y)`` to a rounded rectangle centred on the origin; < 0 inside.

    ``x``, ``y`` are coordinates relative to the rectangle's centre (arrays
    that broadcast, e.g. a row of x and a column of y), metres;
    ``half_width``/``half_height`` half its sides; ``radius`` its corner
    radius, at most the smaller half side (a larger one is taken as that).
    """
    r = min(radius, half_width, half_height)
    qx = np.abs(x) - (half_width - r)
    qy = np.abs(y) - (half_height - r)
    return np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0)) + np.minimum(np.maximum(qx, qy), 0.0) - r


def linear_rise(t):
    """Straight ramp: ``t`` clipped to 0..1."""
    return np.clip(t, 0.0, 1.0)


def cosine_rise(t):
    """Raised-cosine ramp ``(1 - cos(pi t)) / 2`` on ``t`` clipped to 0..1 (zero slope at both ends)."""
    t = np.clip(t, 0.0, 1.0)
    return 0.5 * (1 - np.cos(np.pi * t))


def step_rise(t):
    """Vertical wall: 1 wherever ``t`` > 0 (inside the outline), else 0."""
    return (np.asarray(t) > 0).astype(np.float64)


#: Edge names ``sources.rounded_button`` accepts -> the rise each names.
PRIMITIVE_EDGES = {"ramp": linear_rise, "cosine": cosine_rise, "step": step_rise}
#: Edge names a scene widget's ``edge`` accepts -> the rise each names ("tent": linear, ramp = half the widget).
WIDGET_EDGES = {"linear": linear_rise, "cosine": cosine_rise, "tent": linear_rise}


def edge_rise(name: str, accepted: dict = WIDGET_EDGES, what: str = "edge profile"):
    """The rise function ``name`` stands for in the spelling ``accepted``.

    An unknown name is an :class:`~shapedisplay.errors.InputError` listing
    the names ``accepted`` holds and the nearest one.
    """
    try:
        return accepted[name]
    except (KeyError, TypeError):
        raise unknown_key(what, str(name), accepted) from None

