"""Wall reports say where: each region's box in mm and the widgets it touches, and compile, inspect and
the 3D preview state the same count and share of the canvas."""
from __future__ import annotations

import json

import numpy as np
import pytest

from shapedisplay.author.gradients import wall_lines
from shapedisplay.cli.main import main
from shapedisplay.table.model import FrictionTable

SCENE = """
[canvas]
size = "80x40 mm"
resolution = "0.5 mm"

[[widget]]
id = "steep"
type = "button"
position = "10,10 mm"
size = "12x10 mm"
height = "3 mm"
ramp = "0.5 mm"

[[widget]]
id = "gentle"
type = "button"
position = "50,10 mm"
size = "20x20 mm"
height = "0.5 mm"
"""


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    d = tmp_path_factory.mktemp("walls")
    (d / "s.toml").write_text(SCENE)
    out = d / "t.npz"
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["compile", str(d / "s.toml"), "-o", str(out), "--json"]) == 0
    return out, json.loads(buf.getvalue())


def test_scene_walls_name_their_widget_and_box(compiled):
    out, report = compiled
    w = report["walls"]
    assert w["count"] > 0 and w["regions"] >= 1
    assert w["boxes_mm"] and len(w["boxes_mm"]) == len(w["region_widgets"])
    assert all(ids == ["steep"] for ids in w["region_widgets"])          # the gentle button has no wall
    for x0, x1, y0, y1 in w["boxes_mm"]:                                 # inside the steep button's box
        assert 10 - 0.5 <= x0 <= x1 <= 22 + 0.5 and 10 - 0.5 <= y0 <= y1 <= 20 + 0.5
    t = FrictionTable.load(out)
    assert w["fraction"] == pytest.approx(w["count"] / (t.grid.rows * t.grid.cols))    # share of the canvas


def test_compile_inspect_and_preview_state_the_same_count(compiled, capsys, tmp_path):
    out, report = compiled
    first = wall_lines(report["walls"])[0]
    assert first.startswith(f"walls: {report['walls']['count']} samples (") and "% of the canvas" in first
    (tmp_path / "s.toml").write_text(SCENE)
    assert main(["compile", str(tmp_path / "s.toml"), "-o", str(tmp_path / "t.npz")]) == 0
    compile_out = capsys.readouterr().out
    assert first in compile_out and "widget steep" in compile_out
    assert main(["inspect", str(out)]) == 0
    inspect_out = capsys.readouterr().out
    assert first in inspect_out and "widget steep" in inspect_out
    viewer = pytest.importorskip("shapedisplay.viewer")
    pytest.importorskip("pyvista")
    model = viewer.model_from_table(FrictionTable.load(out))
    assert model.walls["count"] == report["walls"]["count"]
    p = viewer.render(model, "N", size=(320, 200))
    try:
        assert "red: " + first in p.info and "widget steep" in p.info
    finally:
        p.close()


def test_wall_lines_of_an_image_compile_have_boxes_and_no_widgets():
    w = {"count": 12, "fraction": 0.012, "regions": 7, "max_slope": 1.0, "steepest": 2.5,
         "limited": "slope magnitude clipped to 1, direction kept",
         "boxes_mm": [[1, 2, 3, 4]] * 7}
    lines = wall_lines(w, boxes=5)
    assert lines[0] == ("walls: 12 samples (1.2 % of the canvas) in 7 region(s) steeper than 1.0, steepest 2.5; "
                        "slope magnitude clipped to 1, direction kept")
    assert lines[1] == "  x 1..2 mm, y 3..4 mm" and lines[-1] == "  ... and 2 smaller region(s)"
    assert wall_lines({"count": 0, "steepest": 0.5}) == ["walls: none (steepest slope 0.5)"]
    w2 = dict(w, regions=1, boxes_mm=[[1, 2, 3, 4]], region_widgets=[[]])
    assert wall_lines(w2)[1].endswith(": between widgets")
    assert np.isfinite(w["fraction"])
