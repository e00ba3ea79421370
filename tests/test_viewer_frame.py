"""3D preview: framing, orientation triad, legend, flat ground, wall overlay and the widgets on the stroke
chart, checked by the data each is drawn from."""
from __future__ import annotations

import numpy as np
import pytest

from shapedisplay import viewer
from shapedisplay.author.heightfield import HeightField

pytest.importorskip("pyvista")

from test_viewer import H, W, two_widget_table, write_trace  # noqa: E402

#: Largest empty margin allowed between the content and the free part of the frame, in its tightest direction.
MAX_MARGIN = 0.10


def _step_field(step=2e-3):
    """A 40 x 30 mm plate with a 2 mm step: a wall one sample wide across it (slope 2 mm / 0.5 mm = 4)."""
    x = np.arange(81) * 0.5e-3
    y = np.arange(61) * 0.5e-3
    h = np.where(x[None, :] >= 20e-3, step, 0.0) + 0 * y[:, None]
    return HeightField(h, 0.5e-3, 0.5e-3, source="step")


def _smooth_field():
    x = np.arange(81) * 0.5e-3
    y = np.arange(61) * 0.5e-3
    X, Y = np.meshgrid(x, y)
    return HeightField(0.3e-3 * np.exp(-((X - 20e-3) ** 2 + (Y - 15e-3) ** 2) / (2 * 6e-3 ** 2)), 0.5e-3, 0.5e-3)


@pytest.mark.parametrize("view", ["iso", "top", "side"])
@pytest.mark.parametrize("size", [(W, H), (H, W)])
def test_content_fills_the_free_frame_within_the_margin(view, size):
    m = viewer.model_from_heightfield(_smooth_field())
    p = viewer.render(m, "height", size=size, view=view)
    (x0, y0, x1, y1), (left, bottom, right, top) = p.frame["content"], p.frame["region"]
    p.close()
    tol = 0.01
    assert left - tol <= x0 and x1 <= right + tol and bottom - tol <= y0 and y1 <= top + tol   # nothing cropped
    fill = max((x1 - x0) / (right - left), (y1 - y0) / (top - bottom))
    assert fill >= 1.0 - MAX_MARGIN                                                  # not lost in white space
    # and the surface's own corners are inside the content box (the box is what the camera was fitted to)
    assert x1 - x0 > 0.3 and y1 - y0 > 0.2


def test_triad_points_along_x_y_z_with_lengths_in_mm():
    m = viewer.model_from_heightfield(_smooth_field())
    p = viewer.render(m, "height", size=(W, H), exaggeration=5)
    tri = p.triad
    p.close()
    o, L = tri["origin"], tri["length"]
    for i, axis in enumerate("xyz"):
        assert np.allclose(tri["tips"][axis] - o, L * np.eye(3)[i])
    assert L == 5.0                                            # 40 mm wide: a 40/6 mm arrow rounds to 5 mm
    assert tri["labels"] == {"x": "x 5 mm", "y": "y 5 mm", "z": "z 1 mm"}   # z: 5 mm drawn = 1 mm at x5
    # the triad lies outside the surface, at its near left corner
    assert o[0] < m.x[0] * 1e3 and o[1] < m.y[0] * 1e3


def test_wall_overlay_exists_exactly_where_walls_do():
    m = viewer.model_from_heightfield(_step_field())
    walls = m.fields["walls"] > 0
    assert walls.any()
    p = viewer.render(m, "height", size=(W, H))
    expected = int((walls[:-1, :-1] | walls[1:, :-1] | walls[:-1, 1:] | walls[1:, 1:]).sum())
    assert p.wall_actor is not None and p.wall_cells == expected
    assert p.wall_actor.GetMapper().GetInput().GetNumberOfCells() == expected
    assert any(label.startswith("wall") for label, _ in p.legend)
    assert "red: walls" in p.info and f"{100 * walls.mean():.3g} % of the canvas" in p.info
    p.close()
    smooth = viewer.render(viewer.model_from_heightfield(_smooth_field()), "height", size=(W, H))
    assert smooth.wall_actor is None and smooth.wall_cells == 0
    assert not any(label.startswith("wall") for label, _ in smooth.legend)
    smooth.close()
    # coloured by the walls channel itself, no overlay is drawn on top of it
    by_walls = viewer.render(m, "walls", size=(W, H))
    assert by_walls.wall_actor is None
    by_walls.close()


def test_flat_ground_says_what_it_is_and_the_legend_lists_what_is_drawn(tmp_path):
    table = two_widget_table(tmp_path)
    m = viewer.model_from_table(table)
    assert m.ground == f"flat ground, stored as one value: N = {table.background['normal_force']:.3g} N"
    tr = viewer.load_trace(write_trace(tmp_path / "s.npz", table))
    p = viewer.render(m, "N", trace=tr, size=(W, 2 * H))
    labels = [label for label, _ in p.legend]
    assert labels == ["stroke, stuck", "stroke, slipping", "burst (spike ~ amplitude)", "widget outline",
                      "flat ground (one value)"]
    assert "grey: flat ground, stored as one value: N = 0.5 N" in p.info
    assert "left out" not in p.info
    # the stroke chart marks the widgets crossed: spans equal the widget extents along the stroke
    spans = p.chart_spans
    p.close()
    x0 = tr.x[0]
    expected = sorted(((w["id"], w["x0"] - x0, w["x1"] - x0) for w in m.widgets), key=lambda e: e[1])
    assert [(s["id"], s["s0"], s["s1"]) for s in spans] == [(i, pytest.approx(a), pytest.approx(b))
                                                            for i, a, b in expected]
