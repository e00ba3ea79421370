"""SVG mockups as scenes: the same table as the equivalent TOML, import-svg, the attribute scheme."""
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.errors import FileFormatError, InputError
from shapedisplay.author.scene import compile_scene, import_svg, load_scene
from shapedisplay.cli.main import main

pytest.importorskip("svgelements")
ROOT = Path(__file__).resolve().parent.parent
MOCKUP = ROOT / "assets" / "scenes" / "settings-mockup.svg"

#: The scene the mockup shows, written by hand (y measured up from the bottom edge: 50 mm - SVG y).
EQUIVALENT = """
[scene]
name = "settings"
[canvas]
size = "90x50 mm"
resolution = "0.5 mm"
[device]
profile = "handheld-stick"
[mapping]
n_base = "1 N"
n_gain = "1 N/mm"

[[widget]]
id = "ok"
type = "button"
position = "4,4 mm"
size = "24x12 mm"
corner_radius = "3 mm"
height = "1.5 mm"
ramp = "3 mm"

[[widget]]
id = "button-cancel"
type = "button"
position = "32,4 mm"
size = "24x12 mm"
corner_radius = "3 mm"
level = 2
ramp = "3 mm"

[[widget]]
id = "volume"
type = "slider"
position = "4,28 mm"
size = "60x10 mm"
detents = 5
value = 0.25
thumb_size = "8 mm"

[[widget]]
id = "wifi"
type = "toggle"
position = "70,14 mm"
size = "12x28 mm"
state = "on"

[[widget]]
id = "divider"
type = "ridge"
from = "4,41 mm"
to = "64,41 mm"
width = "2 mm"
height = "0.4 mm"
"""


def _same_table(a, b):
    assert a.channels == b.channels and a.quant == b.quant
    assert a.patch_shapes == b.patch_shapes and a.blocks == b.blocks and a.background == b.background
    for name in a.channels:
        assert np.array_equal(a.codes[name], b.codes[name]), name


def test_mockup_with_two_buttons_a_five_detent_slider_and_a_toggle_compiles_to_the_toml_table(tmp_path):
    toml = tmp_path / "settings.toml"
    toml.write_text(EQUIVALENT.replace('id = "divider"', 'id = "ridge-divider"'))
    a, b = compile_scene(MOCKUP), compile_scene(toml)
    _same_table(a.table, b.table)
    scene = load_scene(MOCKUP)
    types = {w.id: w.type for w in scene.widgets}
    assert types == {"ok": "button", "button-cancel": "button", "volume": "slider", "wifi": "toggle",
                     "ridge-divider": "ridge"}
    assert scene.widget("volume").params["detents"] == 5
    assert scene.widget("wifi").params["state"] == "on"
    assert scene.warnings == ()


def test_import_svg_writes_the_equivalent_scene(tmp_path, capsys):
    out = tmp_path / "settings.toml"
    assert main(["import-svg", str(MOCKUP), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "wrote" in text and "(5 widgets)" in text and "2 element(s) without a widget type left out" in text
    _same_table(compile_scene(out).table, compile_scene(MOCKUP).table)
    assert 'detents = 5' in out.read_text()
    before = out.read_bytes()
    assert main(["import-svg", str(MOCKUP), "-o", str(out)]) == 2              # never overwritten silently
    assert "exists" in capsys.readouterr().err and out.read_bytes() == before
    assert main(["import-svg", str(MOCKUP), "-o", str(out), "--overwrite"]) == 0
    assert main(["compile", str(MOCKUP), "-o", str(tmp_path / "t.npz"), "-q"]) == 0


def _svg(tmp_path, body, root='width="80mm" height="40mm" viewBox="0 0 80 40"'):
    p = tmp_path / "m.svg"
    p.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" {root}>{body}</svg>')
    return p


def test_shapes_groups_and_transforms(tmp_path):
    p = _svg(tmp_path, """
      <g transform="rotate(90 40 20)"><rect id="dent-a" x="30" y="15" width="20" height="10"/></g>
      <circle id="round" cx="10" cy="10" r="5" class="big sd-button"/>
      <ellipse id="oval" cx="30" cy="8" rx="6" ry="4" data-widget="dent" data-depth="0.5 mm"/>
      <path id="groove-l" d="M 5 35 L 25 35 L 25 25" stroke-width="2"/>
      <polyline id="edge-z" points="60,35 75,35" data-width="3 mm"/>""")
    s = load_scene(p)
    w = {x.id: x for x in s.widgets}
    # a 20 x 10 rect turned 90 degrees about (40, 20): 10 x 20 mm, centred on (40, 40 - 20)
    assert w["dent-a"].type == "dent" and w["dent-a"].size == pytest.approx((0.010, 0.020))
    assert w["dent-a"].bbox == pytest.approx((0.035, 0.010, 0.045, 0.030))
    assert w["round"].type == "button" and w["round"].params["corner_radius"] == pytest.approx(0.005)
    # y flipped: the circle's centre at SVG y = 10 is 30 mm up the 40 mm canvas
    assert w["round"].bbox == pytest.approx((0.005, 0.025, 0.015, 0.035))
    assert w["oval"].params["corner_radius"] == pytest.approx(0.004) and w["oval"].params["height"] < 0
    # a path: one groove per straight segment, the width from the stroke
    assert [x for x in w if x.startswith("groove-l")] == ["groove-l-1", "groove-l-2"]
    assert w["groove-l-1"].params["width"] == pytest.approx(0.002)
    assert w["edge-z"].type == "edge" and w["edge-z"].params["width"] == pytest.approx(0.003)


def test_pixel_sized_svg_uses_css_pixels(tmp_path):
    p = _svg(tmp_path, '<rect id="button-a" x="0" y="0" width="96" height="48"/>',
             root='width="192" height="96" data-resolution="0.1 mm"')
    s = load_scene(p)
    assert s.canvas.width == pytest.approx(0.0508) and s.widgets[0].size == pytest.approx((0.0254, 0.0127))


@pytest.mark.parametrize("body, root, exc, pattern", [
    ('<rect x="0" y="0" width="5" height="5"/>', None, InputError, "no element names a widget type"),
    ('<rect id="button-a" x="0" y="0" width="5" height="5" data-hieght="1 mm"/>', None, InputError,
     r"unknown key `widget\[0\].hieght` \(did you mean 'height'\?\)"),
    ('<rect id="b" x="0" y="0" width="5" height="5" data-widget="buton"/>', None, InputError,
     r"unknown widget type 'buton' \(did you mean 'button'\?\)"),
    ('<rect id="button-a" x="0" y="0" width="5" height="5"/>', 'width="80em" height="40em"', FileFormatError,
     "needs an absolute unit"),
    ('<rect id="button-a" x="0" y="0" width="5" height="5"/>', 'data-n-gane="1 N/mm" width="80mm" height="40mm"',
     InputError, r"unknown key `mapping.n_gane`"),
])
def test_bad_mockups_are_one_line_errors(tmp_path, body, root, exc, pattern):
    import re
    p = _svg(tmp_path, body) if root is None else _svg(tmp_path, body, root)
    with pytest.raises(exc) as info:
        load_scene(p)
    assert re.search(pattern, str(info.value)) and "\n" not in str(info.value)
    with pytest.raises(FileFormatError, match="no such file"):
        load_scene(tmp_path / "missing.svg")
    (tmp_path / "broken.svg").write_text("<svg width='10mm' height='10mm'><rect")
    with pytest.raises((FileFormatError, InputError)):
        load_scene(tmp_path / "broken.svg")


# ------------------------------------------------------------------ limits checked before svgelements parses
def _zigzag(n):
    """A path of ``n`` line segments across the 80 x 40 canvas (13 bytes a segment)."""
    return "M 5 20 " + " ".join(f"L {5 + 70 * i / n:.4f} {20 + (5 if i % 2 else -5)}" for i in range(1, n + 1))


@pytest.mark.parametrize("d", ["M 0 0 L 1 1 L 2 2", "M0,0 1,1 2,2z", "m0 0h5v5h-5z", "M0 0C1 1 2 2 3 3 4 4 5 5 6 6",
                               "M0 0 Q 1 1 2 0 T 4 0 6 0", "M0 0 S 1 1 2 0 3 3 4 0", "M0 0A5 5 0 0 1 10 10 5 5 0 1 0 0 0",
                               "M 1 1 L 2 2 M 5 5 L 6 6 Z M 8 8", "M 5 5", ""])
def test_path_segments_are_counted_as_svgelements_draws_them(d):
    import svgelements as se
    from shapedisplay.author.scene.svg import _path_segment_count
    drawn = [s for s in se.Path(d).segments() if not isinstance(s, se.Move)]
    assert _path_segment_count(d) == len(drawn)


def test_path_polyline_and_polygon_past_the_segment_limit_are_refused_in_one_line(tmp_path, monkeypatch):
    from shapedisplay.author.scene import svg
    monkeypatch.setattr(svg, "MAX_PATH_SEGMENTS", 40)
    pts = " ".join(f"{5 + i},{10 + i % 2}" for i in range(41))       # 41 points: 40 segments, 41 closed
    ok = _svg(tmp_path, f'<path id="ridge-a" d="{_zigzag(40)}"/><polyline id="ridge-b" points="{pts}"/>')
    assert len(svg.svg_scene_data(ok)["widget"]) == 80
    for body, what in [(f'<path id="ridge-a" d="{_zigzag(41)}"/>', "<path> 'ridge-a' has 41 segments"),
                       (f'<g><polygon points="{pts}"/></g>', "<polygon> number 3 has 41 segments")]:
        with pytest.raises(FileFormatError) as info:
            svg.svg_scene_data(_svg(tmp_path, body))
        msg = str(info.value)
        assert what in msg and "more than the limit of 40 (svg.MAX_PATH_SEGMENTS, docs/limits.md)" in msg
        assert "raise shapedisplay.author.scene.svg.MAX_PATH_SEGMENTS" in msg and "\n" not in msg


def test_long_ridge_path_and_many_elements_are_refused_before_parsing(tmp_path):
    """200,000 segments (2.6 MB) or 100,000 rects (5 MB): refused by the first pass over the XML."""
    import time
    from shapedisplay.author.scene.svg import MAX_PATH_SEGMENTS, MAX_SVG_ELEMENTS
    long_path = _svg(tmp_path, f'<path id="ridge-long" d="{_zigzag(200_000)}" stroke-width="0.5"/>')
    t = time.perf_counter()
    with pytest.raises(FileFormatError, match=rf"has 200000 segments, more than the limit of {MAX_PATH_SEGMENTS} "):
        load_scene(long_path)
    rects = "".join(f'<rect x="{i % 300 * 0.25:.2f}" y="{i // 300 * 0.1:.2f}" width="0.2" height="0.05"/>'
                    for i in range(100_000))
    many = _svg(tmp_path, rects + '<rect id="button-a" x="1" y="1" width="5" height="5"/>')
    with pytest.raises(FileFormatError, match=rf"more than {MAX_SVG_ELEMENTS} elements, the limit "
                                              r"\(svg.MAX_SVG_ELEMENTS, docs/limits.md\)"):
        load_scene(many)
    assert time.perf_counter() - t < 5.0            # svgelements alone takes 5 s for the rects, 6 s for the path


def test_use_copies_count_toward_the_element_limit_before_parsing(tmp_path):
    """200 <use> of a 1,000-rect group: svgelements built 200,000 copies (25.7 s, 375 MB); refused in one pass now."""
    import time
    from shapedisplay.author.scene.svg import MAX_SVG_ELEMENTS
    rects = "".join(f'<rect x="{i % 50}" y="{i // 50}" width="0.5" height="0.5"/>' for i in range(1000))
    uses = "".join(f'<use href="#g" x="{i % 20}"/>' for i in range(200))
    path = _svg(tmp_path, f'<defs><g id="g">{rects}</g></defs>{uses}<rect id="button-a" x="1" y="1" width="5" height="5"/>')
    t = time.perf_counter()
    with pytest.raises(FileFormatError, match=rf"(\d+) elements with the copies its <use> elements make, more than "
                                              rf"the limit of {MAX_SVG_ELEMENTS}"):
        load_scene(path)
    assert time.perf_counter() - t < 3.0


def test_use_copies_of_copies_are_counted_and_a_use_of_itself_is_refused(tmp_path):
    """Copies nest: 40 uses of a group holding 40 uses of a 40-rect group are 64,000 elements."""
    rects = "".join(f'<rect x="{i}" y="0" width="0.5" height="0.5"/>' for i in range(40))
    inner = "".join('<use href="#a"/>' for _ in range(40))
    outer = "".join('<use xmlns:xlink="http://www.w3.org/1999/xlink" xlink:href="#b"/>' for _ in range(40))
    path = _svg(tmp_path, f'<defs><g id="a">{rects}</g><g id="b">{inner}</g></defs>{outer}')
    with pytest.raises(FileFormatError, match=r"elements with the copies its <use> elements make"):
        load_scene(path)
    path = _svg(tmp_path, '<g id="a"><use href="#b"/></g><g id="b"><use href="#a"/></g>'
                          '<rect id="button-a" x="1" y="1" width="5" height="5"/>')
    with pytest.raises(FileFormatError, match=r"<use> of '#\w' copies itself"):
        load_scene(path)


def test_a_few_use_copies_still_compile(tmp_path):
    rects = "".join(f'<rect x="{i}" y="0" width="0.5" height="0.5"/>' for i in range(10))
    path = _svg(tmp_path, f'<defs><g id="deco">{rects}</g></defs><use href="#deco"/><use href="#deco" x="20"/>'
                          '<rect id="button-a" x="10" y="10" width="5" height="5"/>')
    assert [w.id for w in load_scene(path).widgets] == ["button-a"]
