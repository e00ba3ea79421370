"""Scenes: each widget compiles to its exact height / N profile; pruning keeps every value."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.author.compile import CompileOptions
from shapedisplay.author.gradients import detect_walls, gradient, limit_walls
from shapedisplay.author.forces import EXPONENTS, force_channels, perceived
from shapedisplay.author.scene import check_scene, compile_scene, load_scene, scene_heightfield, select_state
from shapedisplay.author.scene.compiler import composite
from shapedisplay.author.sources import ramp_force, tent_force
from shapedisplay.table.model import CHANNELS, FrictionTable

SCENES = Path(__file__).resolve().parent.parent / "assets" / "scenes"

# default device: N range 0..10 N, so nothing is clamped in the exact cases
HEAD = """
[canvas]
size = "{size}"
resolution = "0.5 mm"
[mapping]
n_base = "{n_base}"
n_gain = "1 N/mm"
"""


def write(tmp_path, widgets: str, size="80x40 mm", n_base="0.5 N", extra="", name="s.toml") -> Path:
    p = tmp_path / name
    p.write_text(HEAD.format(size=size, n_base=n_base) + extra + widgets)
    return p


def row_at(table, y_mm: float, name="normal_force"):
    g = table.grid
    r = int(round(y_mm * 1e-3 / g.dy))
    return g.x0 + g.dx * np.arange(g.cols), table.dense(name)[r]


def tol(table, name="normal_force"):
    return table.quant[name].max_error + 1e-12


# ----------------------------------------------------------------- exact profiles
def test_button_linear_edge_is_the_published_ramp_plateau(tmp_path):
    # section through the middle: N1 = 0.5 N, ramp 10 mm at k = 0.2 N/mm, plateau N2 = 2.5 N
    p = write(tmp_path, """
[[widget]]
id = "b"
type = "button"
position = "10,5 mm"
size = "40x30 mm"
height = "2 mm"
ramp = "10 mm"
edge = "linear"
corner_radius = "0 mm"
""")
    res = compile_scene(p)
    x, n = row_at(res.table, 20.0)
    left = x <= 30e-3
    expect = ramp_force(x[left], 10e-3, 20e-3, n1=0.5, n2=2.5)
    np.testing.assert_allclose(n[left], expect, atol=tol(res.table))
    # mirror image on the right side: N(x) = N(60 mm - x)
    right = x >= 30e-3
    np.testing.assert_allclose(n[right], ramp_force(60e-3 - x[right], 10e-3, 20e-3, n1=0.5, n2=2.5),
                               atol=tol(res.table))
    assert res.table.channels == ["normal_force"]  # default device, symmetric mapping


def test_tent_edge_is_the_published_tent(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "t"
type = "button"
position = "10,0 mm"
size = "20x40 mm"
force = "2.5 N"
edge = "tent"
corner_radius = "0 mm"
""")
    res = compile_scene(p)
    x, n = row_at(res.table, 20.0)
    np.testing.assert_allclose(n, tent_force(x, 10e-3, 20e-3, n1=0.5, n2=2.5), atol=tol(res.table))


def test_cosine_edge_and_rounded_corner(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "c"
type = "button"
position = "10,5 mm"
size = "40x30 mm"
force_step = "3 N"
ramp = "8 mm"
edge = "cosine"
corner_radius = "10 mm"
""")
    res = compile_scene(p)
    x, n = row_at(res.table, 20.0)
    d = np.clip(np.minimum(x - 10e-3, 50e-3 - x), 0, None)
    expect = 0.5 + 3.0 * (0.5 - 0.5 * np.cos(np.pi * np.clip(d / 8e-3, 0, 1)))
    np.testing.assert_allclose(n, expect, atol=tol(res.table))
    # inside the rounded corner the distance to the edge is R - |p - corner centre|
    t = res.table
    px, py = 14e-3, 10e-3          # near the lower-left corner, centre (20, 15) mm
    dist = 10e-3 - math.hypot(px - 20e-3, py - 15e-3)
    assert dist > 0
    val = t.dense("normal_force")[int(round(py / 5e-4)), int(round(px / 5e-4))]
    assert abs(val - (0.5 + 3.0 * (0.5 - 0.5 * math.cos(math.pi * dist / 8e-3)))) <= tol(t)


def test_dent_goes_below_flat_ground(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "well"
type = "dent"
position = "10,5 mm"
size = "40x30 mm"
depth = "1 mm"
ramp = "5 mm"
corner_radius = "0 mm"
""", n_base="2 N")
    res = compile_scene(p)
    x, n = row_at(res.table, 20.0)
    expect = 2.0 - 1.0 * np.clip(np.minimum(x - 10e-3, 50e-3 - x) / 5e-3, 0, 1)
    np.testing.assert_allclose(n, expect, atol=tol(res.table))
    assert abs(n.min() - 1.0) <= tol(res.table)


def test_levels_are_equal_perceived_steps(tmp_path):
    widgets = "".join(f"""
[[widget]]
id = "b{k}"
type = "button"
position = "{2 + 15 * (k - 1)},5 mm"
size = "12x30 mm"
level = {k}
ramp = "3 mm"
""" for k in range(1, 6))
    p = write(tmp_path, widgets, extra='[defaults]\nlevels = 5\nlevel_force = "4 N"\n')
    res = compile_scene(p)
    scene = load_scene(p)
    beta = EXPONENTS["bumpiness"]
    steps = []
    for k, w in enumerate(scene.widgets, start=1):
        expect = 4.0 * (k / 5) ** (1 / beta)
        assert w.params["height"] * 1e3 == pytest.approx(expect, rel=1e-12)
        r0, c0, r1, c1 = w.box
        plateau = res.table.dense("normal_force")[(r0 + r1) // 2, (c0 + c1) // 2]
        assert abs(plateau - (0.5 + expect)) <= tol(res.table)
        steps.append(float(perceived(expect, 1.0, beta)))
    # perceived magnitudes of the levels are equally spaced
    np.testing.assert_allclose(np.diff([0.0] + steps), steps[0], rtol=1e-12)


def test_slider_track_thumb_and_detents(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "s"
type = "slider"
position = "10,10 mm"
size = "60x10 mm"
track = "groove"
track_width = "6 mm"
track_depth = "0.5 mm"
track_ramp = "1 mm"
value = 0.75
thumb_size = "10 mm"
height = "1.5 mm"
detents = "10 mm"
detent_height = "0.3 mm"
detent_width = "2 mm"
""", n_base="2 N")
    res = compile_scene(p)
    t = res.table
    x, n = row_at(t, 15.0)                       # the track centre line
    thumb_x = 10e-3 + 5e-3 + 0.75 * (60e-3 - 10e-3)   # R + value (L - 2R)
    u = x - 10e-3
    expect = np.full_like(x, 2.0)
    on = (u >= 0) & (u <= 60e-3)
    expect[on] = 2.0 - 0.5 * (0.5 - 0.5 * np.cos(np.pi * np.clip(np.minimum(u[on], 60e-3 - u[on]) / 1e-3, 0, 1)))
    r = np.abs(x - thumb_x)
    expect += 1.5 * np.where(r < 5e-3, 0.5 + 0.5 * np.cos(np.pi * np.minimum(r / 5e-3, 1)), 0)
    det = np.zeros_like(x)
    for k in range(1, 6):                        # 5 detents inside 60 mm at 10 mm spacing
        rd = np.abs(u - k * 10e-3)
        det = np.maximum(det, np.where(rd < 1e-3, 0.5 + 0.5 * np.cos(np.pi * np.minimum(rd / 1e-3, 1)), 0))
    expect += 0.3 * det * on                     # detents lie where the track is full depth
    np.testing.assert_allclose(n, expect, atol=tol(t))
    assert load_scene(p).widgets[0].params["detents"] == 5
    # off the track (2.5 mm from its edge) the slider is flat except for the thumb
    x2, n2 = row_at(t, 10.5)
    far = np.abs(x2 - thumb_x) > 5e-3
    np.testing.assert_allclose(n2[far], 2.0, atol=tol(t))


def test_ridge_cross_section_and_groove(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "r"
type = "ridge"
from = "10,20 mm"
to = "70,20 mm"
width = "4 mm"
height = "1 mm"
[[widget]]
id = "g"
type = "groove"
from = "10,32 mm"
to = "70,32 mm"
width = "4 mm"
depth = "1 mm"
profile = "linear"
""", n_base="2 N")
    t = compile_scene(p).table
    g = t.grid
    col = t.dense("normal_force")[:, int(round(40e-3 / g.dx))]
    y = g.y0 + g.dy * np.arange(g.rows)
    r = np.abs(y - 20e-3)
    ridge = 1.0 * np.where(r < 2e-3, 0.5 + 0.5 * np.cos(np.pi * np.minimum(r / 2e-3, 1)), 0)
    rg = np.abs(y - 32e-3)
    groove = -1.0 * np.clip(1 - rg / 2e-3, 0, 1)
    np.testing.assert_allclose(col, 2.0 + ridge + groove, atol=tol(t))


def test_toggle_both_states_compiled_and_selectable(tmp_path):
    body = """
[[widget]]
id = "sw"
type = "toggle"
position = "20,10 mm"
size = "24x12 mm"
state = "{state}"
height = "1 mm"
track_depth = "0.3 mm"
[[widget]]
id = "b"
type = "button"
position = "55,10 mm"
size = "20x20 mm"
"""
    off = compile_scene(write(tmp_path, body.format(state="off"), n_base="1 N", name="off.toml"))
    on = compile_scene(write(tmp_path, body.format(state="on"), n_base="1 N", name="on.toml"))
    t = off.table
    info = t.meta["scene"]["toggles"]["sw"]
    assert info["state"] == "off" and set(info["states"]) == {"off", "on"}
    assert len(t.patch_shapes) == 3  # toggle off, toggle on, button
    # the knob sits at a quarter of the length for off, three quarters for on
    x, n = row_at(t, 16.0)
    knob_off = np.argmax(np.where((x > 20e-3) & (x < 44e-3), n, 0))
    assert x[knob_off] == pytest.approx(26e-3)
    switched = select_state(t, "sw", "on")
    for name in t.channels:
        np.testing.assert_array_equal(switched.dense(name), on.table.dense(name))
    np.testing.assert_array_equal(select_state(switched, "sw", "off").dense("normal_force"),
                                  t.dense("normal_force"))
    assert t.meta["scene"]["toggles"]["sw"]["state"] == "off"  # the original is not modified
    # the choice survives saving
    path = tmp_path / "t.npz"
    t.save(path)
    loaded = FrictionTable.load(path)
    np.testing.assert_array_equal(select_state(loaded, "sw", "on").dense("normal_force"),
                                  on.table.dense("normal_force"))
    with pytest.raises(Exception, match="did you mean 'sw'"):
        select_state(t, "sx", "on")
    with pytest.raises(Exception, match="unknown state of toggle 'sw' 'of'"):
        select_state(t, "sw", "of")


def test_toggle_profile_of_both_states_is_exact(tmp_path):
    """Centre line of a 24x12 mm toggle: a 0.3 mm stadium well (cosine edge over the default 2 mm ramp)
    plus a raised-cosine knob 9.6 mm across (0.8 x half the length) at 1/4 (off) or 3/4 (on) of the length."""
    p = write(tmp_path, """
[[widget]]
id = "sw"
type = "toggle"
position = "20,10 mm"
size = "24x12 mm"
state = "off"
height = "1 mm"
track_depth = "0.3 mm"
""", n_base="1 N")
    t = compile_scene(p, options=CompileOptions(quantize="float64")).table
    u = np.arange(t.grid.cols) * t.grid.dx - 20e-3
    inside = (u >= 0) & (u <= 24e-3)
    d = np.where(inside, np.minimum(u, 24e-3 - u), 0.0)
    well = np.where(inside & (d > 0), -0.3 * (0.5 - 0.5 * np.cos(np.pi * np.clip(d / 2e-3, 0, 1))), 0.0)
    for state, uc in (("off", 6e-3), ("on", 18e-3)):
        r = np.abs(u - uc)
        knob = np.where(r < 4.8e-3, 0.5 + 0.5 * np.cos(np.pi * np.minimum(r / 4.8e-3, 1)), 0.0)
        n = select_state(t, "sw", state).dense("normal_force")[int(round(16e-3 / t.grid.dy))]
        np.testing.assert_allclose(n, 1.0 + well + 1.0 * knob, atol=1e-12, err_msg=state)


def test_image_widget_places_the_height_map(tmp_path):
    from shapedisplay.author.imageio import write_png
    gray = np.array([[0, 1000, 2000, 3000], [4000, 5000, 6000, 65535]], dtype=np.uint16)
    write_png(tmp_path / "m.png", gray)
    p = write(tmp_path, """
[[widget]]
id = "img"
type = "image"
file = "m.png"
position = "10,10 mm"
size = "8x4 mm"
height = "0:2 mm"
""")
    t = compile_scene(p).table
    # pixel (r, c) of a 8x4 mm image of 4x2 px covers 2 mm; the picture is the top view (row 0 on top),
    # so its centre is at (11 + 2c, 13 - 2r) mm
    for r in range(2):
        for c in range(4):
            val = t.dense("normal_force")[int(round((13 - 2 * r) / 0.5)), int(round((11 + 2 * c) / 0.5))]
            assert abs(val - (0.5 + 2.0 * gray[r, c] / 65535)) <= tol(t)


def mesh_table(tmp_path, file, position: str, size: str, canvas: str = "80x40 mm", quantize: str = "auto"):
    """One mesh widget compiled for the desktop rig (N up to 8 N)."""
    pytest.importorskip("trimesh")
    p = write(tmp_path, f"""
[[widget]]
id = "m"
type = "mesh"
file = "{file}"
position = "{position}"
size = "{size}"
""", size=canvas, extra='[device]\nprofile = "desktop-rig"\n')
    return compile_scene(p, options=CompileOptions(quantize=quantize)).table


def test_mesh_widget(tmp_path):
    src = Path(__file__).resolve().parent.parent / "assets" / "meshes" / "keycap.stl"
    pytest.importorskip("trimesh")
    from shapedisplay.author.mesh import mesh_to_heightfield
    hf = mesh_to_heightfield(src, resolution=0.25e-3)
    t = mesh_table(tmp_path, src, "20,10 mm", f"{hf.size_m[0] * 1e3:g}x{hf.size_m[1] * 1e3:g} mm")
    n = t.dense("normal_force")
    hmax = float(hf.heights.max())
    assert n.max() == pytest.approx(min(0.5 + 1000 * hmax, 8.0), abs=2 * tol(t))
    assert np.all(n[:, : int(20e-3 / 5e-4) - 2] == t.background["normal_force"])


PYRAMID_OBJ = """\
v 0 0 0
v 20 0 0
v 20 20 0
v 0 20 0
v 10 10 2
f 1 2 5
f 2 3 5
f 3 4 5
f 4 1 5
f 1 3 2
f 1 4 3
"""


def pyramid_table(tmp_path, position: str, size: str, canvas: str):
    """The pyramid as a mesh widget, compiled unquantized (float64)."""
    (tmp_path / "pyr.obj").write_text(PYRAMID_OBJ)
    return mesh_table(tmp_path, "pyr.obj", position, size, canvas, quantize="float64")


@pytest.mark.parametrize("size, position", [("20x20 mm", "20,10 mm"), ("30x10 mm", "15.5,12 mm")])
def test_mesh_widget_is_the_analytic_pyramid_at_every_sample(tmp_path, size, position):
    """A 20x20x2 mm pyramid (mm units) stretched to the box: N = n_base + n_gain h at every canvas sample."""
    t = pyramid_table(tmp_path, position, size, "80x40 mm")
    g = t.grid
    X, Y = np.meshgrid(np.arange(g.cols) * g.dx, np.arange(g.rows) * g.dy)
    (x0, y0), (bw, bh) = [float(v) * 1e-3 for v in position[:-3].split(",")], \
        [float(v) * 1e-3 for v in size[:-3].split("x")]
    u, v = (X - x0) / bw, (Y - y0) / bh                  # 0..1 over the box
    h = np.where((u >= 0) & (u <= 1) & (v >= 0) & (v <= 1),
                 2e-3 * (1 - 2 * np.maximum(np.abs(u - 0.5), np.abs(v - 0.5))), 0.0)
    # half a sample off would leave errors of slope * 0.25 mm = 0.05 N and more
    np.testing.assert_allclose(t.dense("normal_force"), 0.5 + 1000.0 * h, atol=1e-9)


def test_mesh_widget_on_a_1d_canvas_follows_the_centre_line(tmp_path):
    t = pyramid_table(tmp_path, "10 mm", "20 mm", "40 mm")
    x = np.arange(t.grid.cols) * t.grid.dx
    h = np.clip(2e-3 * (1 - np.abs(x - 20e-3) / 10e-3), 0, None)   # the tent through the apex
    np.testing.assert_allclose(t.dense("normal_force")[0], 0.5 + 1000.0 * h, atol=1e-9)


def test_data_layer_perceptual_scaling(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "rain"
type = "data"
channel = "friction_scale"
values = [0, 50, 100]
position = "10,10 mm"
size = "20x10 mm"
range = "1:2"
data_range = "0:100"
[[widget]]
id = "b"
type = "button"
position = "50,10 mm"
size = "20x20 mm"
""")
    res = compile_scene(p, options=CompileOptions(quantize="float64"))
    t = res.table
    assert "friction_scale" in t.channels and "burst_gain" not in t.channels
    assert res.report["left_out"]["burst_gain"] == "no data layer of the scene drives it"
    beta = EXPONENTS["friction"]
    x, f = row_at(t, 15.0, "friction_scale")
    at = lambda xm: f[int(round(xm / 0.5))]  # noqa: E731
    mid = (1.0 + 0.5 * (2.0 ** beta - 1.0)) ** (1 / beta)
    assert at(10) == pytest.approx(1.0) and at(30) == pytest.approx(2.0) and at(20) == pytest.approx(mid)
    # equal data steps feel equal: perceived(phi) is linear in the data
    psi = perceived(np.array([at(10), at(20), at(30)]), 1.0, beta)
    assert psi[1] - psi[0] == pytest.approx(psi[2] - psi[1], rel=1e-9)
    assert at(5) == 1.0 and at(40) == 1.0      # background multiplier outside the layer


def test_overlap_rules(tmp_path):
    def plateau(rule):
        p = write(tmp_path, f"""
[defaults]
overlap = "{rule}"
ramp = "2 mm"
[[widget]]
id = "a"
type = "button"
position = "10,10 mm"
size = "30x20 mm"
height = "2 mm"
[[widget]]
id = "b"
type = "button"
position = "30,10 mm"
size = "30x20 mm"
height = "1 mm"
""", name=f"{rule}.toml")
        res = compile_scene(p)
        assert len(res.table.blocks) == 1 and res.report["widgets"][1]["notes"]
        return res.table.dense("normal_force")[40, int(35e-3 / 5e-4)]
    assert plateau("max") == pytest.approx(2.5, abs=0.01)
    assert plateau("min") == pytest.approx(1.5, abs=0.01)
    assert plateau("add") == pytest.approx(3.5, abs=0.01)
    assert plateau("over") == pytest.approx(1.5, abs=0.01)


# ----------------------------------------------------------------- compile only what is needed
def _dense_reference(scene, options=CompileOptions()):
    """Channels of the whole canvas compiled as one dense height field."""
    hf = scene_heightfield(scene)
    gx, gy = gradient(hf, options.gradient_method, **options.gradient_kw)
    if detect_walls(hf, gx, gy, options.max_slope).count and options.limit_walls:
        limit_walls(gx, gy, options.max_slope, out=(gx, gy))
    chans = dict(force_channels(hf, scene.device, scene.mapping, grad=(gx, gy)))
    c = scene.canvas
    for ch in ("friction_scale", "burst_gain"):
        _, data = composite(scene, (0, 0, c.rows - 1, c.cols - 1))
        if ch in data:
            chans[ch] = data[ch]
    return chans


@pytest.mark.parametrize("name", ["phone", "keypad", "media-player", "map"])
def test_blocks_hold_the_dense_values_everywhere(name):
    res = compile_scene(SCENES / f"{name}.toml")
    scene = load_scene(SCENES / f"{name}.toml")
    ref = _dense_reference(scene)
    t = res.table
    for ch in t.channels:
        np.testing.assert_allclose(t.dense(ch), ref[ch], atol=t.quant[ch].max_error + 1e-12, err_msg=ch)
    # flat ground reads the same code inside and outside the blocks
    assert t.background["normal_force"] in set(np.unique(t.dense("normal_force")))


def test_gaussian_gradient_reach_keeps_dense_values(tmp_path):
    opts = CompileOptions(gradient_method="gaussian", gradient_kw={"sigma": 1e-3})
    res = compile_scene(SCENES / "phone.toml", options=opts)
    ref = _dense_reference(load_scene(SCENES / "phone.toml"), opts)
    for ch in res.table.channels:
        np.testing.assert_allclose(res.table.dense(ch), ref[ch], atol=res.table.quant[ch].max_error + 1e-12)


def test_phone_is_small_and_identical_widgets_are_stored_once():
    res = compile_scene(SCENES / "phone.toml")
    t, rep = res.table, res.report
    assert t.stored_bytes <= 0.10 * t.dense_bytes
    assert rep["stored_bytes"] == t.stored_bytes and rep["dense_bytes"] == t.dense_bytes
    apps = [w for w in rep["widgets"] if w["id"].startswith("app-")]
    assert len({w["patch"] for w in apps}) == 1
    assert sum(w["bytes"] for w in apps) == t.patch_shapes[apps[0]["patch"]][0] * \
        t.patch_shapes[apps[0]["patch"]][1] * sum(np.dtype(t.quant[c].dtype).itemsize for c in t.channels)
    assert all("stored once" in " ".join(w["notes"]) for w in apps[1:])
    # per-widget bytes add up to what is stored
    assert sum(w["bytes"] for w in rep["widgets"]) == t.stored_bytes
    # channels as the device + mapping need: one-sided slope friction keeps the slopes, nothing else
    assert t.channels == ["grad_x", "grad_y", "normal_force"]
    assert set(rep["left_out"]) >= {"lateral_x", "skin_stretch", "friction_scale", "empty_regions"}
    assert t.meta["velocity_range_m_s"] == list(load_scene(SCENES / "phone.toml").device.velocity_range)
    assert all(q["meets_bound"] for q in rep["quantization"].values())
    assert json.loads(json.dumps(rep)) == rep


def test_one_dimensional_scene_compiles_to_1d_table():
    res = compile_scene(SCENES / "media-player.toml")
    t = res.table
    assert t.is_1d and t.grid.rows == 1 and t.grid.cols == 321
    assert "grad_y" not in t.channels and "lateral_y" not in t.channels
    # five blocks; prev and next are identical (one patch), the toggle's "on" state adds one
    assert len(t.blocks) == 5 and len(t.patch_shapes) == 5


def test_check_scene_returns_warnings_without_compiling():
    for name in ("phone", "keypad", "media-player", "map"):
        assert check_scene(SCENES / f"{name}.toml") == []
    scene = load_scene(SCENES / "phone.toml")
    ids = [w.id for w in scene.widgets]
    assert ids[:2] == ["frame", "app-1"] and len(ids) == 11
    x0, y0, x1, y1 = scene.widget("volume").bbox
    assert (x0, y0, x1, y1) == pytest.approx((5e-3, 60e-3, 75e-3, 72e-3))


def test_pixels_canvas_and_px_lengths(tmp_path):
    p = tmp_path / "px.toml"
    p.write_text("""
[canvas]
pixels = "508x254"
dpi = 254
resolution = "0.5 mm"
[[widget]]
type = "button"
position = "100,50 px"
size = "200x100 px"
""")
    s = load_scene(p)
    assert s.canvas.width == pytest.approx(50.8e-3) and s.canvas.height == pytest.approx(25.4e-3)
    assert s.widgets[0].bbox == pytest.approx((10e-3, 5e-3, 30e-3, 15e-3))


def test_new_scene_template_is_valid(tmp_path):
    from shapedisplay.cli.main import main
    out = tmp_path / "mine.toml"
    assert main(["new", "scene", "mine", "-o", str(out)]) == 0
    assert check_scene(out) == []
    res = compile_scene(out)
    assert {w["type"] for w in res.report["widgets"]} == {"button", "dent", "slider", "toggle"}
    assert main(["new", "scene", "mine", "-o", str(out)]) == 2  # exists


def test_template_commented_examples_compile_when_uncommented(tmp_path):
    """The template's commented ridge, image and data widgets are valid as written (given the image)."""
    import shutil
    from shapedisplay.author.scene.template import render_template
    lines, block = [], False
    for line in render_template("t", "t.toml").splitlines():
        block = line.startswith("# [[widget]]") or (block and line.startswith("# "))
        lines.append(line[2:] if block else line)
    (tmp_path / "t.toml").write_text("\n".join(lines) + "\n")
    shutil.copy(SCENES / "terrain.png", tmp_path / "terrain.png")
    res = compile_scene(tmp_path / "t.toml")
    assert {w["type"] for w in res.report["widgets"]} == {"button", "dent", "slider", "toggle", "ridge",
                                                          "image", "data"}


def test_cli_compile_inspect_and_check(tmp_path, capsys):
    from shapedisplay.cli.main import main
    out = tmp_path / "phone.npz"
    assert main(["compile", str(SCENES / "phone.toml"), "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["inspect", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["stored_bytes"] <= 0.1 * info["dense_bytes"]
    assert main(["check", str(SCENES / "keypad.toml")]) == 0
    assert "valid: 16 widget(s), 0 warning(s)" in capsys.readouterr().out


def test_vertical_slider_and_toggle_run_along_y(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "vs"
type = "slider"
position = "10,5 mm"
size = "10x60 mm"
value = 1.0
thumb_size = "10 mm"
height = "1 mm"
[[widget]]
id = "vt"
type = "toggle"
position = "40,5 mm"
size = "10x20 mm"
state = "on"
height = "1.2 mm"
""", size="60x80 mm", n_base="1 N")
    t = compile_scene(p).table
    n = t.dense("normal_force")
    y = t.grid.dy * np.arange(t.grid.rows)
    assert y[np.argmax(n[:, 30])] == pytest.approx(60e-3)   # thumb centre at L - R = 55 mm above y = 5 mm
    assert y[np.argmax(n[:, 90])] == pytest.approx(20e-3)   # "on" knob at 3/4 of 20 mm above y = 5 mm
    # thumb 1 mm above the groove floor (0.5 mm deep): 1 N + 1 N/mm * (1 - 0.5) mm
    assert n[:, 30].max() == pytest.approx(1.5, abs=tol(t))


# ----------------------------------------------------------------- property: blocks == dense canvas
from hypothesis import given, settings, strategies as st  # noqa: E402

_TYPES = ("button", "dent", "ridge", "toggle", "slider")


@st.composite
def layouts(draw):
    n = draw(st.integers(1, 6))
    out = []
    for i in range(n):
        t = draw(st.sampled_from(_TYPES))
        x, y = draw(st.integers(-4, 56)), draw(st.integers(-4, 36))
        w, h = draw(st.integers(4, 30)), draw(st.integers(4, 16))
        frac = draw(st.sampled_from(["", ".25", ".5"]))
        if t == "ridge":
            out.append(f'[[widget]]\nid = "w{i}"\ntype = "ridge"\nfrom = "{max(x, 1)}{frac},{max(y, 1)} mm"\n'
                       f'to = "{min(x + w, 59)},{min(y + h, 39)} mm"\nwidth = "2 mm"\n')
        else:
            out.append(f'[[widget]]\nid = "w{i}"\ntype = "{t}"\nposition = "{x}{frac},{y} mm"\n'
                       f'size = "{w}x{h} mm"\n')
    return "".join(out)


@settings(max_examples=25, deadline=None)
@given(layouts(), st.sampled_from(["symmetric", "one-sided"]))
def test_random_layouts_store_exactly_the_dense_values(tmp_path_factory, text, direction):
    from shapedisplay.errors import InputError
    d = tmp_path_factory.mktemp("lay")
    p = write(d, text, size="60x40 mm", n_base="2 N", extra=f'direction = "{direction}"\n')
    try:
        res = compile_scene(p)
    except InputError as exc:   # toggles sharing a block, or a widget entirely off the canvas, are refused
        assert "toggle" in str(exc) or "entirely outside" in str(exc)
        return
    t = res.table
    ref = _dense_reference(load_scene(p))
    for ch in t.channels:
        np.testing.assert_allclose(t.dense(ch), ref[ch], atol=t.quant[ch].max_error + 1e-12, err_msg=ch)
        assert np.isfinite(t.dense(ch)).all()
    assert sum(w["bytes"] for w in res.report["widgets"]) == t.stored_bytes


def test_lateral_cue_clamped_to_the_device_is_reported(tmp_path):
    p = write(tmp_path, """
[[widget]]
id = "b"
type = "button"
position = "10,10 mm"
size = "20x20 mm"
height = "2 mm"
ramp = "4 mm"
""", extra='lateral = "gradient"\nlateral_gain = "5 N"\n[device]\nprofile = "desktop-rig"\n')
    res = compile_scene(p)
    t = res.table
    assert t.channels == ["lateral_x", "lateral_y", "normal_force"]
    note = res.report["clamped"]["lateral"]
    # slope 0.5 on the straight flanks of the linear ramp: |F| = 5 N * 0.5 = 2.5 N, above the rig's 1.5 N
    # by 1 N (more at the rounded corners, where central differences see both sides)
    assert note["above"] > 0 and note["max_excess"] >= 1.0 - 1e-9
    mag = np.hypot(t.dense("lateral_x"), t.dense("lateral_y"))
    assert mag.max() <= 1.5 + 2 * t.quant["lateral_x"].max_error


def test_image_widget_reads_a_colour_channel(tmp_path):
    from PIL import Image
    rgb = np.zeros((2, 4, 3), np.uint8)
    rgb[..., 1] = [[0, 85, 170, 255], [255, 170, 85, 0]]          # the green channel carries the heights
    rgb[..., 0] = 200                                               # red would flatten them
    Image.fromarray(rgb).save(tmp_path / "c.png")
    body = """
[[widget]]
id = "img"
type = "image"
file = "c.png"
position = "10,10 mm"
size = "8x4 mm"
height = "0:2 mm"
channel = "g"
"""
    t = compile_scene(write(tmp_path, body)).table
    # picture row 0 (top) is at y = 13 mm, row 1 at y = 11 mm; column c at x = 11 + 2c mm
    for r, y in ((0, 13), (1, 11)):
        for c in range(4):
            val = t.dense("normal_force")[int(round(y / 0.5)), int(round((11 + 2 * c) / 0.5))]
            assert abs(val - (0.5 + 2.0 * rgb[r, c, 1] / 255)) <= tol(t)
    from shapedisplay.errors import InputError
    with pytest.raises(InputError, match=r"`widget\[0\].channel` must be one of luminance"):
        compile_scene(write(tmp_path, body.replace('channel = "g"', 'channel = "green"')))
