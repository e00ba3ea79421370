"""Scene bad input: each error names the widget, the field path, the rule and the value."""
from __future__ import annotations

import re

import pytest

from shapedisplay.errors import FileFormatError, InputError, ShapeDisplayError, UnitError
from shapedisplay.author.scene import check_scene, compile_scene, load_scene

HEAD = """
[canvas]
size = "80x40 mm"
resolution = "0.5 mm"
[device]
profile = "handheld-stick"
[mapping]
n_base = "1 N"
"""

BUTTON = """
[[widget]]
id = "ok"
type = "button"
position = "10,10 mm"
size = "20x10 mm"
"""


def scene(tmp_path, text: str, head: str = HEAD):
    p = tmp_path / "bad.toml"
    p.write_text(head + text)
    return p


def err(tmp_path, text, head=HEAD, exc=InputError):
    with pytest.raises(exc) as info:
        check_scene(scene(tmp_path, text, head))
    msg = str(info.value)
    assert "\n" not in msg and "bad.toml" in msg
    return msg


def test_unknown_widget_type_suggests_nearest(tmp_path):
    msg = err(tmp_path, BUTTON.replace('"button"', '"buton"'))
    assert "widget[0] 'ok'" in msg and "`widget[0].type`" in msg and "'buton'" in msg
    assert "did you mean 'button'" in msg


def test_typo_in_key_suggests_nearest(tmp_path):
    msg = err(tmp_path, BUTTON + 'heigth = "2 mm"\n')
    assert "`widget[0].heigth`" in msg and "did you mean 'height'" in msg and "widget[0] 'ok'" in msg


def test_typo_in_section_and_defaults(tmp_path):
    assert "did you mean 'canvas'" in err(tmp_path, '[canvass]\nsize = "1 mm"\n' + BUTTON, head="")
    msg = err(tmp_path, '[defaults]\nrmap = "3 mm"\n' + BUTTON)
    assert "`defaults.rmap`" in msg and "did you mean 'ramp'" in msg


def test_missing_size(tmp_path):
    msg = err(tmp_path, '[[widget]]\nid = "x"\ntype = "button"\nposition = "1,1 mm"\n')
    assert "widget[0] 'x'" in msg and "`widget[0].size` is required" in msg


def test_bare_number_needs_a_unit(tmp_path):
    with pytest.raises(UnitError) as info:
        load_scene(scene(tmp_path, BUTTON + "height = 2\n"))
    msg = str(info.value)
    assert "widget[0] 'ok'" in msg and "`widget[0].height` needs a unit" in msg and "2" in msg


def test_widget_entirely_outside_is_an_error(tmp_path):
    msg = err(tmp_path, BUTTON.replace('"10,10 mm"', '"100,10 mm"'))
    assert "`widget[0].position`" in msg and "entirely outside" in msg and "80 x 40 mm" in msg


def test_widget_partly_outside_is_clipped_with_warning(tmp_path):
    p = scene(tmp_path, BUTTON.replace('"10,10 mm"', '"70,35 mm"'))
    warnings = check_scene(p)
    assert any("widget[0] 'ok'" in w and "clipped" in w and "right by 10 mm" in w and "top by 5 mm" in w
               for w in warnings)
    t = compile_scene(p).table
    assert load_scene(p).widgets[0].bbox == pytest.approx((70e-3, 35e-3, 80e-3, 40e-3))
    assert t.dense("normal_force")[-1, -1] > 1.0


def test_overlapping_widgets_with_conflicting_rules(tmp_path):
    text = BUTTON + 'overlap = "add"\n' + BUTTON.replace('"ok"', '"two"').replace('"10,10 mm"', '"20,12 mm"')
    msg = err(tmp_path, text)
    assert "widget[0] 'ok'" in msg and "widget[1] 'two'" in msg and "conflicting rules" in msg
    assert "'add'" in msg and "'max'" in msg


def test_toggles_sharing_a_block(tmp_path):
    t = '[[widget]]\nid = "{i}"\ntype = "toggle"\nposition = "{x},10 mm"\nsize = "16x8 mm"\n'
    msg = err(tmp_path, t.format(i="t1", x=10) + t.format(i="t2", x=26.5))
    assert "widget[0] 't1'" in msg and "widget[1] 't2'" in msg and "toggle" in msg


def test_missing_image(tmp_path):
    msg = err(tmp_path, '[[widget]]\nid = "map"\ntype = "image"\nfile = "nowhere.png"\n'
                        'position = "0,0 mm"\nsize = "10x10 mm"\n')
    assert "widget[0] 'map'" in msg and "`widget[0].file`" in msg and "missing image" in msg and "nowhere.png" in msg


def test_heights_beyond_device_range_are_clamped_with_warning(tmp_path):
    p = scene(tmp_path, BUTTON + 'height = "7 mm"\nramp = "3 mm"\n')
    warnings = check_scene(p)
    assert len(warnings) == 1
    w = warnings[0]
    # 1 N + 7 N = 8 N asked, the handheld stick stops at 6 N: 2 N (2 mm) too much
    assert "widget[0] 'ok'" in w and "8 N" in w and "6 N" in w and "by 2 N" in w and "clamped" in w
    res = compile_scene(p)
    assert res.table.dense("normal_force").max() == pytest.approx(6.0, abs=res.table.quant["normal_force"].max_error)
    assert res.report["warnings"] == warnings


def test_dent_below_device_minimum_is_clamped_with_warning(tmp_path):
    p = scene(tmp_path, BUTTON.replace('"button"', '"dent"') + 'depth = "1 mm"\nramp = "3 mm"\n')
    (w,) = check_scene(p)
    assert "below" in w and "0.5 N" in w and "by 0.5 N" in w and "n_base" in w


def test_too_many_detents_warn(tmp_path):
    p = scene(tmp_path, '[[widget]]\nid = "vol"\ntype = "slider"\nposition = "5,5 mm"\nsize = "60x8 mm"\n'
                        'detents = "0.3 mm"\ndetent_width = "0.2 mm"\n')
    warnings = check_scene(p)
    felt = [w for w in warnings if "felt apart" in w]
    assert felt and "widget[0] 'vol'" in felt[0] and "0.5 mm resolution" in felt[0] and "199 detents" in felt[0]


def test_empty_scene(tmp_path):
    msg = err(tmp_path, "")
    assert "empty" in msg and "[[widget]]" in msg


def test_conflicting_strength_keys(tmp_path):
    msg = err(tmp_path, BUTTON + 'height = "1 mm"\nlevel = 2\n')
    assert "`widget[0].level`" in msg and "conflicts" in msg and "height" in msg


def test_button_force_below_flat_ground(tmp_path):
    msg = err(tmp_path, BUTTON + 'force = "0.7 N"\n')
    assert "`widget[0].force`" in msg and "above the base force 1 N" in msg and "0.7 N" in msg


def test_duplicate_ids_and_bad_choices(tmp_path):
    msg = err(tmp_path, BUTTON + BUTTON)
    assert "must be unique" in msg and "widget[1]" in msg
    msg = err(tmp_path, BUTTON + 'edge = "cosin"\n')
    assert "`widget[0].edge`" in msg and "did you mean 'cosine'" in msg


def test_unknown_device(tmp_path):
    msg = err(tmp_path, BUTTON, head=HEAD.replace("handheld-stick", "handheld-stik"))
    assert "device.profile" in msg and "did you mean 'handheld-stick'" in msg


def test_invalid_toml_and_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="invalid TOML"):
        check_scene(scene(tmp_path, "[[widget]\n"))
    with pytest.raises(FileFormatError, match="no such file"):
        check_scene(tmp_path / "none.toml")


def test_canvas_errors(tmp_path):
    assert "`canvas.size`" in err(tmp_path, BUTTON, head=HEAD.replace('"80x40 mm"', '"80x0 mm"'))
    assert "needs `canvas.dpi`" in err(tmp_path, BUTTON, head=HEAD.replace('size = "80x40 mm"', 'pixels = "800x400"'))
    msg = err(tmp_path, BUTTON, head=HEAD.replace('"0.5 mm"', '"0.001 mm"'))
    assert "`canvas.resolution`" in msg and "limit" in msg


def test_data_layer_errors(tmp_path):
    base = '[[widget]]\nid = "d"\ntype = "data"\nposition = "0,0 mm"\nsize = "10x10 mm"\n'
    assert "did you mean 'burst_gain'" in err(tmp_path, base + 'channel = "burst_gan"\nvalues = [1, 2]\n')
    assert "exactly one of `values`" in err(tmp_path, base + 'channel = "burst_gain"\n')
    assert "must be finite" in err(tmp_path, base + 'channel = "burst_gain"\nvalues = [1, nan]\n')
    msg = err(tmp_path, base + 'channel = "burst_gain"\nvalues = [1, 2]\nexponent = "abc"\n')
    assert "widget[0] 'd'" in msg and "`widget[0].exponent` must be a number (got 'abc')" in msg


def test_cli_errors_are_one_line_exit_2(tmp_path, capsys):
    from shapedisplay.cli.main import main
    p = scene(tmp_path, BUTTON.replace('"button"', '"buton"'))
    assert main(["check", str(p)]) == 2
    e = capsys.readouterr().err
    assert e.count("\n") == 1 and "Traceback" not in e and "did you mean 'button'" in e
    assert main(["compile", str(p), "-o", str(tmp_path / "t.npz")]) == 2
    assert not (tmp_path / "t.npz").exists()


def test_every_error_is_a_shapedisplay_error(tmp_path):
    for text in ("", BUTTON.replace("size", "sise"), BUTTON + 'ramp = "-1 mm"\n'):
        with pytest.raises(ShapeDisplayError) as info:
            check_scene(scene(tmp_path, text))
        assert re.search(r"`[a-z_\[\]0-9.]+`|empty", str(info.value))


def test_added_heights_beyond_device_range_warn(tmp_path):
    text = (BUTTON + 'overlap = "add"\nheight = "3 mm"\nramp = "2 mm"\n'
            + BUTTON.replace('"ok"', '"two"').replace('"10,10 mm"', '"20,12 mm"')
            + 'overlap = "add"\nheight = "3 mm"\nramp = "2 mm"\n')
    p = scene(tmp_path, text)
    res = compile_scene(p)
    (w,) = res.report["warnings"]       # each button alone fits the 6 N device, together they do not
    assert check_scene(p) == [w]        # check finds it without compiling
    # 1 N + 6 mm * 1 N/mm = 7 N, 1 N above the handheld stick's 6 N
    assert "'ok'" in w and "'two'" in w and "6 mm" in w and "by 1 mm (1 N)" in w and "clamped to 5 mm" in w
    assert res.table.dense("normal_force").max() == pytest.approx(6.0, abs=res.table.quant["normal_force"].max_error)


@pytest.mark.parametrize("wtype", ["slider", "toggle"])
def test_vertical_widget_on_a_1d_canvas(tmp_path, wtype):
    head = HEAD.replace('"80x40 mm"', '"80 mm"')
    msg = err(tmp_path, f'[[widget]]\nid = "v"\ntype = "{wtype}"\nposition = "10 mm"\nsize = "30 mm"\n'
                        'orientation = "vertical"\n', head=head)
    assert "widget[0] 'v'" in msg and "`widget[0].orientation` must be horizontal on a 1-D canvas" in msg


def test_type_defaults_must_be_a_table(tmp_path):
    msg = err(tmp_path, '[defaults]\nbutton = "2 mm"\n' + BUTTON)
    assert "`defaults.button` must be a table [defaults.button]" in msg and "'2 mm'" in msg


# --------------------------------------------------------------- detents, overlaps, unit hints
SLIDER = '[[widget]]\nid = "vol"\ntype = "slider"\nposition = "5,5 mm"\nsize = "60x8 mm"\n'


def test_detents_as_a_count_are_evenly_spaced_with_no_detent_at_the_ends(tmp_path):
    w = load_scene(scene(tmp_path, SLIDER + "detents = 5\n")).widgets[0]
    assert w.params["detents"] == 5 and w.params["detent_spacing"] == pytest.approx(0.060 / 6)
    same = load_scene(scene(tmp_path, SLIDER + 'detents = "10 mm"\n')).widgets[0]
    assert same.params["detents"] == 5 and same.params["detent_spacing"] == pytest.approx(0.010)
    assert check_scene(scene(tmp_path, SLIDER + "detents = 5\n")) == []
    assert load_scene(scene(tmp_path, SLIDER + 'detents = "5"\n')).widgets[0].params["detents"] == 5


def test_a_spacing_that_does_not_divide_the_track_is_warned_about(tmp_path):
    (msg,) = check_scene(scene(tmp_path, SLIDER + 'detents = "14 mm"\n'))
    assert "widget[0] 'vol'" in msg and "do not divide the 60 mm track: 4 detents, the last gap is 4 mm" in msg
    assert "detents = 4 spaces them evenly (12 mm apart)" in msg


@pytest.mark.parametrize("value, pattern", [
    ('"5 m"', r"`widget\[0\].detents` spacing 5000 mm leaves no detent on the 60 mm track"),
    ("0.5", r"`widget\[0\].detents` must be a whole count \(e.g. 5\) or a spacing with its unit"),
    ("0", None),
    ("-3", r"`widget\[0\].detents` as a count must be 1..1000 \(got -3\)"),
    ('"12"', None),
])
def test_bad_detents(tmp_path, value, pattern):
    if pattern is None:
        load_scene(scene(tmp_path, SLIDER + f"detents = {value}\n"))
        return
    msg = err(tmp_path, SLIDER + f"detents = {value}\n")
    assert re.search(pattern, msg), msg


def test_overlapping_widgets_warn_unless_both_choose_a_rule(tmp_path):
    two = BUTTON + '[[widget]]\nid = "dot"\ntype = "button"\nposition = "25,12 mm"\nsize = "10x6 mm"\n'
    def overlaps(text):
        return [w for w in check_scene(scene(tmp_path, text)) if " overlap on " in w]
    (msg,) = overlaps(two)
    # where both rise above flat ground (the boxes' shared edge samples are at height 0)
    assert "widget[0] 'ok' and widget[1] 'dot' overlap on 97 samples (x 25.5..29.5 mm, y 12.5..17.5 mm)" in msg
    assert "`overlap` = 'max' (the higher wins)" in msg and "set `overlap` on both" in msg
    chosen = two.replace('size = "20x10 mm"\n', 'size = "20x10 mm"\noverlap = "add"\n') + 'overlap = "add"\n'
    assert overlaps(chosen) == []
    # boxes that touch without both shapes rising on the same sample do not warn
    apart = BUTTON + '[[widget]]\nid = "far"\ntype = "button"\nposition = "30,10 mm"\nsize = "10x10 mm"\n'
    assert overlaps(apart) == []


def test_unit_hints_propose_millimetres_and_newtons(tmp_path):
    msg = err(tmp_path, BUTTON + "height = 2\n", exc=UnitError)
    assert "e.g. '2 mm'" in msg
    msg = err(tmp_path, SLIDER + "detents = \"5 furlong\"\n", exc=UnitError)
    assert "unknown unit 'furlong'" in msg
    msg = err(tmp_path, BUTTON + "force = 2\n", exc=UnitError)
    assert "e.g. '2 N'" in msg
    from shapedisplay.units import parse_quantity
    with pytest.raises(UnitError, match=r"e.g. '2 N/mm'"):
        parse_quantity("2", "N/m", "n_gain")


# --------------------------------------------------------------- limits checked as the scene is read
def _cli_one_line(args, capsys) -> str:
    from shapedisplay.cli.main import main
    assert main(args) == 2
    e = capsys.readouterr().err
    assert e.count("\n") == 1 and "Traceback" not in e, e[:2000]
    return e


@pytest.mark.parametrize("value", [
    "[" * 6000 + "]" * 6000,                                   # 12 KB of nested arrays
    "{a = " * 3000 + "1" + "}" * 3000,                         # nested inline tables
    "[" * 33 + "1" + "]" * 33,                                 # one level past the limit
])
def test_deep_nesting_is_one_line_exit_2(tmp_path, capsys, value):
    from shapedisplay.author.scene.spec import MAX_NESTING
    p = scene(tmp_path, BUTTON + f"label = {value}\n")
    for cmd in (["check", str(p)], ["compile", str(p), "-o", str(tmp_path / "t.npz")]):
        e = _cli_one_line(cmd, capsys)
        assert f"more than {MAX_NESTING} levels" in e and "at line 15" in e
    assert not (tmp_path / "t.npz").exists()


def test_nesting_within_the_limit_and_brackets_in_strings_pass_the_depth_check(tmp_path):
    deep = "[" * 100
    for extra in (f'label = "{deep}"  # {deep}\n', f"label = '{deep}'\n", f'label = """\n{deep}"""\n',
                  f"label = \'\'\'{deep}\'\'\'\n", "label = " + "[" * 5 + "1" + "]" * 5 + "\n"):
        assert isinstance(check_scene(scene(tmp_path, BUTTON + extra)), list), extra


def test_deep_dotted_keys_are_refused(tmp_path, capsys):
    p = scene(tmp_path, BUTTON + "label." + ".".join(["a"] * 3000) + " = 1\n")
    assert "levels deep" in _cli_one_line(["check", str(p)], capsys)


@pytest.mark.parametrize("key, value", [
    ("size", '"1e308x5 mm"'), ("position", '"1e308,0 mm"'), ("position", '"0,-1e308 mm"'),
    ("size", '["1e308 mm", "5 mm"]'), ("ramp", '"1e308 mm"'), ("height", '"1e300 mm"'),
])
def test_huge_geometry_is_refused_naming_key_and_value(tmp_path, capsys, key, value):
    from shapedisplay.author.scene.fields import MAX_LENGTH_M
    text = BUTTON.replace(f"{key} = ", f"{key}_old = ") if key in BUTTON else BUTTON
    text = "\n".join(line for line in text.splitlines() if not line.startswith(f"{key}_old")) + f"\n{key} = {value}\n"
    p = scene(tmp_path, text)
    e = _cli_one_line(["compile", str(p), "-o", str(tmp_path / "t.npz")], capsys)
    assert f"`widget[0].{key}`" in e and f"within {MAX_LENGTH_M:g} m" in e and "1e30" in e
    assert _cli_one_line(["check", str(p)], capsys)


def test_a_widget_box_too_large_for_the_grid_is_refused(tmp_path):
    from shapedisplay.author.scene.widgets import MAX_WIDGET_SAMPLES
    text = BUTTON.replace('size = "20x10 mm"', 'size = "900x900 m"')
    with pytest.raises(InputError, match=f"more than the limit of {MAX_WIDGET_SAMPLES}"):
        check_scene(scene(tmp_path, text))


def test_huge_canvas_resolution_is_one_line(tmp_path, capsys):
    p = scene(tmp_path, BUTTON, head=HEAD.replace('"0.5 mm"', '"1e-300 mm"'))
    e = _cli_one_line(["check", str(p)], capsys)
    assert "`canvas.resolution`" in e and len(e) < 400


def test_widget_count_limit_is_checked_before_any_work(tmp_path, capsys, monkeypatch):
    import time

    from shapedisplay.author.scene import spec
    n = spec.MAX_WIDGETS + 1
    text = "".join(f'[[widget]]\nid = "b{i}"\ntype = "button"\nposition = "1,1 mm"\nsize = "2x2 mm"\n'
                   for i in range(n))
    p = scene(tmp_path, text)
    t0 = time.perf_counter()
    e = _cli_one_line(["check", str(p)], capsys)
    assert f"{n} [[widget]] entries, more than the limit of {spec.MAX_WIDGETS}" in e
    assert time.perf_counter() - t0 < 2.0
    called = []
    monkeypatch.setattr(spec, "place_widget", lambda *a, **k: called.append(1))
    with pytest.raises(InputError, match="MAX_WIDGETS"):
        load_scene(p)
    assert not called


def test_overlapping_pairs_equal_every_pair_checked():
    import random

    from shapedisplay.author.scene.compiler import _overlap, overlapping_pairs
    rng = random.Random(7)
    for n in (0, 1, 2, 50, 300):
        boxes = []
        for _ in range(n):
            r0, c0 = rng.randrange(0, 200), rng.randrange(0, 300)
            boxes.append((r0, c0, r0 + rng.randrange(0, 30), c0 + rng.randrange(0, 30)))
        brute = [(i, j) for i in range(n) for j in range(i + 1, n) if _overlap(boxes[i], boxes[j])]
        assert overlapping_pairs(boxes) == brute
    strip = [(0, c, 0, c + 3) for c in range(0, 400, 2)]             # a 1-D canvas: one row, swept by columns
    assert overlapping_pairs(strip) == [(i, j) for i in range(200) for j in range(i + 1, 200) if j - i <= 1]


def _grid_of_buttons(n: int) -> str:
    side = int(n ** 0.5) + 1
    head = f'[canvas]\nsize = "{side * 6}x{side * 6} mm"\nresolution = "1 mm"\n'
    return head + "".join(f'[[widget]]\nid = "b{i}"\ntype = "button"\nposition = "{i % side * 6 + 1},{i // side * 6 + 1} mm"\n'
                          f'size = "4x4 mm"\nheight = "1 mm"\nramp = "1 mm"\n' for i in range(n))


def test_many_widgets_cost_about_n_pair_checks_and_the_table_reads_back(tmp_path, monkeypatch):
    """2,000 touching buttons (one block): ~n box comparisons, not n^2/2; the report lists a bounded
    number of ids per widget, so the table's header stays within what the reader takes."""
    from shapedisplay.author.scene import compiler
    from shapedisplay.table.model import FrictionTable
    n = 2000
    p = tmp_path / "many.toml"
    p.write_text(_grid_of_buttons(n))
    calls = []
    real = compiler._overlap
    monkeypatch.setattr(compiler, "_overlap", lambda a, b: calls.append(1) or real(a, b))
    result = compile_scene(p)
    side = int(n ** 0.5) + 1
    # four passes (groups, their rectangles, rules, warnings), each ~ n x (buttons in two rows);
    # every pair in every pass would be 4 x n^2 / 2 = 8,000,000
    assert len(calls) < 4 * n * 2 * side, len(calls)
    monkeypatch.undo()
    assert len(result.report["widgets"]) == n
    out = tmp_path / "many.npz"
    out.write_bytes(result.table.to_bytes())
    assert FrictionTable.load(out).checksum == result.table.checksum


def test_widgets_stacked_on_one_another_are_refused_past_the_pair_limit(tmp_path, capsys):
    from shapedisplay.author.scene.compiler import MAX_OVERLAP_PAIRS
    n = int((2 * MAX_OVERLAP_PAIRS) ** 0.5) + 2
    text = "".join(f'[[widget]]\nid = "b{i}"\ntype = "button"\nposition = "10,10 mm"\nsize = "20x10 mm"\n'
                   for i in range(n))
    e = _cli_one_line(["check", str(scene(tmp_path, text))], capsys)
    assert f"more than {MAX_OVERLAP_PAIRS} pairs of widgets" in e


def test_deeply_nested_svg_groups_are_one_line(tmp_path, capsys):
    pytest.importorskip("svgelements")
    from shapedisplay.author.scene.svg import MAX_SVG_DEPTH
    n = 3000
    p = tmp_path / "deep.svg"
    p.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="20mm" height="20mm" viewBox="0 0 20 20">'
                 + "<g>" * n + '<rect data-widget="button" x="0" y="0" width="5" height="5"/>' + "</g>" * n + "</svg>")
    e = _cli_one_line(["check", str(p)], capsys)
    assert f"more than {MAX_SVG_DEPTH} levels deep" in e
