"""3D preview: what is drawn (exact), and real off-screen images checked for content."""
from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from shapedisplay import viewer
from shapedisplay.errors import FileFormatError, InputError, MissingDependencyError, ShapeDisplayError, TableError
from shapedisplay.author.heightfield import HeightField
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization

pytest.importorskip("pyvista")   # the viewer extra; installed by `make test`

W, H = 480, 320                   # small frames keep the suite fast


# --------------------------------------------------------------------------------- fixtures
def gaussian_field(height=1e-3, sigma=5e-3) -> HeightField:
    x = np.linspace(-20e-3, 20e-3, 81)
    y = np.linspace(-15e-3, 15e-3, 61)
    X, Y = np.meshgrid(x, y)
    return HeightField(height * np.exp(-(X ** 2 + Y ** 2) / (2 * sigma ** 2)), x[1] - x[0], y[1] - y[0],
                       x[0], y[0], source="gaussian bump")


N_BASE, N_GAIN = 0.5, 2000.0      # N, N/m


def two_widget_table(tmp_path) -> FrictionTable:
    """60x100 canvas (0.5 mm), two identical bump widgets stored once, the rest left out."""
    g = Grid(60, 100, 0.5e-3, 0.5e-3)
    r, c = np.mgrid[0:40, 0:35]
    bump = np.exp(-(((r - 20) / 8.0) ** 2 + ((c - 17) / 7.0) ** 2))       # 0..1
    h = 1e-3 * bump                                                        # 1 mm bump
    n = N_BASE + N_GAIN * h
    chans = {"normal_force": n, "breakaway_force": 0.3 + 0.01 * c,          # ramp along x, 0.3..0.64 N
             "lateral_x": 0.3 * np.ones_like(n), "lateral_y": 0.4 * np.ones_like(n)}
    q = {k: choose_quantization(v, "float64") for k, v in chans.items()}
    meta = {"mapping": {"n_base": N_BASE, "n_gain": N_GAIN},
            "widgets": [{"id": "ok", "x0": 5e-3, "y0": 5e-3, "x1": 22e-3, "y1": 24.5e-3},
                        {"id": "cancel", "x0": 27.5e-3, "y0": 5e-3, "x1": 44.5e-3, "y1": 24.5e-3}]}
    bg = {"normal_force": N_BASE, "breakaway_force": 0.3, "lateral_x": 0.0, "lateral_y": 0.0}
    t = FrictionTable.from_patches(g, [((10, 10), chans), ((10, 55), chans)], q, bg, meta)
    path = tmp_path / "table.npz"
    t.save(path)
    return FrictionTable.load(path)


def write_trace(path, table: FrictionTable, checksum: str | None = None, n: int = 1500):
    """A stroke across both widgets in the format of shapedisplay.render.sinks.write_trace."""
    t = np.linspace(0.0, 1.5, n)
    x = np.linspace(2e-3, 48e-3, n)
    y = np.full(n, 15e-3)
    nf = table.sample("normal_force", x, y)
    state = ((t * 20) % 1 > 0.7).astype(np.int8)
    ff = 0.5 * nf * (1 - 0.3 * state)
    ev = t[np.flatnonzero(np.diff(state) == 1) + 1]
    amp = np.interp(ev, t, nf)
    np.savez(path, t=t, x=x, y=y, normal_force=nf, friction_force=ff, state=state, event_time=ev,
             event_amplitude=amp, table_checksum=np.array(checksum or table.checksum))
    return path


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    return two_widget_table(tmp_path_factory.mktemp("tab"))


@pytest.fixture(scope="module")
def trace_path(tmp_path_factory, table):
    return write_trace(tmp_path_factory.mktemp("trace") / "stroke.npz", table)


# --------------------------------------------------------------------------------- helpers
def surface_pixels(img: np.ndarray) -> np.ndarray:
    """Mask of pixels that are not the white background."""
    return np.any(img < 245, axis=2)


def lut_values(preview, img: np.ndarray, mask: np.ndarray):
    """Invert the colour map: scalar value of each masked pixel and its colour distance to the LUT."""
    lut = preview.surface_actor.mapper.lookup_table
    colours = np.asarray(lut.values[:, :3], dtype=np.float64)            # (n, 3)
    lo, hi = preview.surface_actor.mapper.scalar_range
    px = img[mask].astype(np.float64)
    d = np.linalg.norm(px[:, None, :] - colours[None, :, :], axis=2)
    k = np.argmin(d, axis=1)
    values = lo + (hi - lo) * (k + 0.5) / len(colours)
    return values, d[np.arange(len(k)), k]


def flat_top(model, channel, **kw):
    """Top view, unlit, no bar or text: pixel colours are exactly colour-map entries."""
    return viewer.render(model, channel, size=(W, H), view="top", lighting=False, scalar_bar=False,
                         annotations=False, **kw)


# --------------------------------------------------------------------------------- the model (exact)
def test_auto_exaggeration_draws_relief_at_fifteen_percent_of_extent():
    m = viewer.model_from_heightfield(gaussian_field(height=1e-3))
    # extent 40 mm, relief 1 mm: 0.15 * 40 / 1 = 6 -> 1-2-5 series floor = 5
    assert viewer.auto_exaggeration(m) == 5.0
    m = viewer.model_from_heightfield(gaussian_field(height=0.02e-3))
    assert viewer.auto_exaggeration(m) == 200.0                       # 0.15 * 40 / 0.02 = 300 -> 200
    m = viewer.model_from_heightfield(gaussian_field(height=30e-3))
    assert viewer.auto_exaggeration(m) == 1.0                         # never flattens
    flat = viewer.model_from_heightfield(HeightField(np.zeros((3, 4)), 1e-3, 1e-3))
    assert viewer.auto_exaggeration(flat) == 1.0


@pytest.mark.parametrize("value, expected", [(6.0, 5.0), (1.0, 1.0), (0.0299, 0.02), (199.9, 100.0), (2.0, 2.0)])
def test_nice_number_floor(value, expected):
    assert viewer.nice_number(value) == pytest.approx(expected)


def test_table_model_recovers_height_from_mapping_and_marks_left_out(table):
    m = viewer.model_from_table(table)
    assert m.relief_unit == "m"
    n = table.dense("normal_force")
    np.testing.assert_allclose(m.fields["height"], (n - N_BASE) / N_GAIN, rtol=0, atol=1e-15)
    assert m.fields["height"].max() == pytest.approx(1e-3)
    expected = np.zeros((60, 100), bool)
    expected[10:50, 10:45] = expected[10:50, 55:90] = True
    np.testing.assert_array_equal(m.stored, expected)
    # |(0.3, 0.4)| = 0.5 N where stored, background 0 elsewhere
    np.testing.assert_allclose(m.fields["lateral"], np.where(expected, 0.5, 0.0), atol=1e-12)
    assert [w["id"] for w in m.widgets] == ["ok", "cancel"]
    assert m.checksum == table.checksum


def test_table_without_mapping_draws_normal_force_as_relief(tmp_path):
    g = Grid(1, 50, 1e-3, 1e-3)
    n = np.linspace(0.5, 2.5, 50)[None, :]
    t = FrictionTable.from_dense(g, {"normal_force": n}, {"normal_force": choose_quantization(n, "float64")})
    m = viewer.model_from_table(t)
    assert m.relief_unit == "N" and "height" not in m.fields
    assert m.strip and m.relief.shape == (2, 50)                       # 1-D drawn as a strip
    assert np.ptp(m.y) == pytest.approx(viewer.STRIP_FRACTION * 49e-3)
    # "auto": relief of 2 N drawn at 15 % of 49 mm -> 3.675 mm/N -> 2 mm/N
    assert viewer.auto_exaggeration(m) == 2.0


def test_readout_is_bilinear_in_every_channel():
    x = np.linspace(0, 10e-3, 11)
    y = np.linspace(0, 5e-3, 6)
    X, Y = np.meshgrid(x, y)
    hf = HeightField(0.1 * X + 0.05 * Y, 1e-3, 1e-3)                  # a plane: bilinear is exact
    m = viewer.model_from_heightfield(hf)
    r = m.readout(3.3e-3, 2.7e-3)
    assert r["height"] == pytest.approx(0.1 * 3.3e-3 + 0.05 * 2.7e-3, rel=1e-12)
    assert r["slope"] == pytest.approx(np.hypot(0.1, 0.05), rel=1e-12)
    assert r["walls"] == 0.0
    text = m.format_readout(r)
    assert "x = 3.30 mm" in text and "slope" in text


def test_walls_follow_slope_threshold():
    h = np.zeros((5, 20))
    h[:, 10:] = 2e-3                                                   # 2 mm step over 1 mm spacing
    m = viewer.model_from_heightfield(HeightField(h, 1e-3, 1e-3))
    assert set(np.flatnonzero(m.fields["walls"][2])) == {9, 10}        # slope 1 >= WALL_SLOPE at the step


def test_unknown_channel_lists_valid_ones(table):
    m = viewer.model_from_table(table)
    assert m.resolve_channel("N") == "normal_force"
    assert m.resolve_channel("lateral_magnitude") == "lateral"
    with pytest.raises(InputError) as e:
        m.resolve_channel("normal_forc")
    msg = str(e.value)
    assert "did you mean 'normal_force'" in msg and "breakaway_force" in msg and "slope" in msg


def test_trace_round_trip_and_checksum_refusal(tmp_path, table, trace_path):
    tr = viewer.load_trace(trace_path)
    assert tr.table_checksum == table.checksum and tr.state.dtype == np.int8
    viewer.check_trace(tr, viewer.model_from_table(table))
    other = write_trace(tmp_path / "other.npz", table, checksum="sha256:" + "0" * 64)
    with pytest.raises(TableError, match="different table"):
        viewer.render(viewer.model_from_table(table), trace=viewer.load_trace(other))
    with pytest.raises(InputError, match="compiled table"):
        viewer.check_trace(tr, viewer.model_from_heightfield(gaussian_field()))


def test_bad_traces_are_refused(tmp_path):
    p = tmp_path / "t.npz"
    np.savez(p, t=np.arange(3.0), x=np.zeros(3))
    with pytest.raises(ShapeDisplayError, match="lacks array"):
        viewer.load_trace(p)
    arrays = dict(t=np.arange(3.0), x=np.zeros(3), y=np.zeros(3), normal_force=np.array([1, np.nan, 1]),
                  friction_force=np.zeros(3), state=np.zeros(3), event_time=np.zeros(0),
                  event_amplitude=np.zeros(0), table_checksum=np.array("sha256:x"))
    np.savez(p, **arrays)
    with pytest.raises(FileFormatError, match="normal_force.*NaN"):
        viewer.load_trace(p)
    arrays["normal_force"] = np.ones(3)
    arrays["state"] = np.array([0, 2, 1])
    np.savez(p, **arrays)
    with pytest.raises(FileFormatError, match="state"):
        viewer.load_trace(p)


@pytest.mark.parametrize("text, ok", [("auto", "auto"), ("12.5", 12.5), ("x3", 3.0), ("0", None), ("-1", None),
                                      ("nan", None), ("big", None)])
def test_parse_exaggeration(text, ok):
    if ok is None:
        with pytest.raises(InputError, match="exaggeration"):
            viewer.parse_exaggeration(text)
    else:
        assert viewer.parse_exaggeration(text) == ok


def test_window_size_parsing():
    assert viewer.parse_window_size("1600x1000") == (1600, 1000)
    for bad in ("1600", "10x10", "axb", "9000x100"):
        with pytest.raises(InputError, match="size"):
            viewer.parse_window_size(bad)


# --------------------------------------------------------------------------------- environment errors
def test_missing_pyvista_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyvista", None)                 # import pyvista -> ImportError
    with pytest.raises(MissingDependencyError) as e:
        viewer.render(viewer.model_from_heightfield(gaussian_field()), size=(W, H))
    assert "pip install 'shapedisplay[viewer]'" in str(e.value) and "\n" not in str(e.value)


def test_interactive_without_display_suggests_offscreen(monkeypatch):
    if not sys.platform.startswith("linux"):
        pytest.skip("display detection by environment is Linux-only")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(ShapeDisplayError, match="-o shot.png"):
        viewer.render(viewer.model_from_heightfield(gaussian_field()), off_screen=False)


def test_no_offscreen_opengl_gives_clear_error():
    """With no display and EGL/OSMesa unusable, the probe fails cleanly (VTK itself would crash)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("EGL/OSMesa selection is Linux-only")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY",
                                                             "VTK_DEFAULT_OPENGL_WINDOW")}
    env["__EGL_VENDOR_LIBRARY_FILENAMES"] = os.devnull                # no EGL vendor library
    env["LD_LIBRARY_PATH"] = ""
    try:
        import ctypes.util
        has_osmesa = ctypes.util.find_library("OSMesa") is not None
    except Exception:  # noqa: BLE001
        has_osmesa = False
    if has_osmesa:
        pytest.skip("OSMesa is installed: off-screen still works without EGL")
    with pytest.raises(ShapeDisplayError) as e:
        viewer.check_offscreen(env=env)
    assert "libegl-mesa0" in str(e.value) and "install-system-deps" in str(e.value)


def test_offscreen_probe_succeeds_here():
    assert viewer.check_offscreen().startswith("vtk")


# --------------------------------------------------------------------------------- real images
def test_height_colours_span_the_channel_range():
    hf = gaussian_field()
    m = viewer.model_from_heightfield(hf)
    p = flat_top(m, "height")
    img = p.screenshot()
    p.close()
    assert img.shape == (H, W, 3)
    mask = surface_pixels(img)
    assert 0.3 < mask.mean() < 0.95                                     # the surface fills most of the frame
    lo, hi = p.surface_actor.mapper.scalar_range
    assert (lo, hi) == pytest.approx((hf.heights.min() * 1e3, hf.heights.max() * 1e3))   # mm
    values, dist = lut_values(p, img, mask)
    assert np.median(dist) < 3.0                                        # unlit pixels are colour-map colours
    span = hi - lo
    assert values.min() < lo + 0.02 * span and values.max() > hi - 0.02 * span
    # where the colours are: the bump's top in the middle of the frame, low at the edge
    rows, cols = np.nonzero(mask)
    cy, cx = int(rows.mean()), int(cols.mean())
    centre, _ = lut_values(p, img, np.pad(np.ones((3, 3), bool), ((cy - 1, H - cy - 2), (cx - 1, W - cx - 2))))
    assert centre.min() > hi - 0.05 * span
    edge = np.zeros_like(mask)
    edge[rows.min() + 2, cols.min() + 2:cols.max() - 2] = True
    v_edge, _ = lut_values(p, img, edge & mask)
    assert v_edge.max() < lo + 0.1 * span


@pytest.mark.parametrize("view", ["side", "iso", "top"])
@pytest.mark.parametrize("size_mm", [(60, 40), (120, 20), (20, 120)])
def test_every_view_keeps_the_whole_surface_in_the_frame(view, size_mm):
    """Wide, long or square: the surface never touches the frame's edges (nothing cropped)."""
    w, d = size_mm
    x = np.linspace(0, w * 1e-3, 2 * w + 1)
    y = np.linspace(0, d * 1e-3, 2 * d + 1)
    X, Y = np.meshgrid(x, y)
    h = 2e-3 * np.exp(-((X - w * 5e-4) ** 2 + (Y - d * 5e-4) ** 2) / (2 * (5e-3) ** 2))
    m = viewer.model_from_heightfield(HeightField(h, x[1] - x[0], y[1] - y[0]))
    p = viewer.render(m, "height", size=(W, H), view=view, annotations=False)
    img = p.screenshot()
    p.close()
    mask = surface_pixels(img)
    mask[:, int(0.8 * W):] = False                                     # the colour bar and its title
    assert mask.mean() > 0.02
    assert not mask[:, :2].any() and not mask[:2, :].any() and not mask[-2:, :].any()


def test_walls_colours_are_fixed_no_wall_is_one_colour():
    """A surface without walls is drawn all in the 'no wall' colour; a step shows its wall."""
    m = viewer.model_from_heightfield(gaussian_field())                # slope < 1 everywhere
    assert m.fields["walls"].max() == 0.0
    p = flat_top(m, "walls")
    img = p.screenshot()
    p.close()
    assert p.surface_actor.mapper.scalar_range == (0.0, 1.0)
    values, dist = lut_values(p, img, surface_pixels(img))
    values = values[dist < 3.0]                                        # not the anti-aliased rim
    assert values.size > 1000 and values.max() < 0.5
    h = np.zeros((40, 60))
    h[:, 30:] = 2e-3                                                   # a 2 mm step: slope 1 at the step
    q = flat_top(viewer.model_from_heightfield(HeightField(h, 1e-3, 1e-3)), "walls")
    img = q.screenshot()
    q.close()
    values, dist = lut_values(q, img, surface_pixels(img))
    values = values[dist < 3.0]
    assert 0 < np.mean(values > 0.5) < 0.2


def test_colour_range_end_next_to_zero_reads_zero():
    hf = gaussian_field()
    hf = hf.with_heights(hf.heights - hf.heights.min() + 1e-35)        # lowest sample 1e-35 m
    p = flat_top(viewer.model_from_heightfield(hf), "height")
    p.close()
    assert p.surface_actor.mapper.scalar_range == (0.0, pytest.approx(1.0, rel=1e-5))   # not 1e-32 on the bar


def test_channel_choice_changes_colours_and_units(table):
    m = viewer.model_from_table(table)
    p = flat_top(m, "breakaway_force")
    img = p.screenshot()
    p.close()
    lo, hi = p.surface_actor.mapper.scalar_range
    ba = table.dense("breakaway_force")
    assert (lo, hi) == pytest.approx((ba.min(), ba.max()))
    mask = surface_pixels(img)
    # stored blocks are coloured; the left-out canvas is faint grey: mostly unsaturated light pixels
    sat = img.max(axis=2).astype(int) - img.min(axis=2)
    coloured = mask & (sat > 40)
    faint = mask & (sat < 15) & (img.min(axis=2) > 200)
    assert coloured.mean() > 0.15 and faint.mean() > 0.1
    values, dist = lut_values(p, img, coloured)
    assert np.median(dist) < 3.0
    # breakaway force ramps along x inside each widget: colours left of a widget's middle are lower
    rows, cols = np.nonzero(coloured)
    left = coloured & (np.arange(W)[None, :] < np.percentile(cols, 15))
    right_of_left_widget = coloured & (np.arange(W)[None, :] > np.percentile(cols, 35)) \
        & (np.arange(W)[None, :] < np.percentile(cols, 48))
    v_left, _ = lut_values(p, img, left)
    v_right, _ = lut_values(p, img, right_of_left_widget)
    assert np.median(v_left) < np.median(v_right)


def test_stroke_overlay_changes_the_image(table, trace_path):
    m = viewer.model_from_table(table)
    m.widgets = []                     # outlines lie on the surface; keep only the overlay as a change
    tr = viewer.load_trace(trace_path)
    base = viewer.render(m, "N", size=(W, H), view="top", lighting=False, annotations=False, chart=False)
    img0 = base.screenshot()
    base.close()
    over = viewer.render(m, "N", trace=tr, size=(W, H), view="top", lighting=False, annotations=False,
                         chart=False)
    img1 = over.screenshot()
    changed = np.any(np.abs(img1.astype(int) - img0.astype(int)) > 30, axis=2)
    assert changed.mean() > 0.005

    def near(colour, tol=60):
        rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])
        return np.linalg.norm(img1.astype(float) - rgb, axis=2) < tol

    assert (near(viewer.draw.STICK_COLOR) & changed).sum() > 20
    assert (near(viewer.draw.SLIP_COLOR) & changed).sum() > 20
    assert (near(viewer.draw.BURST_COLOR) & changed).sum() > 20
    # the overlay lies along y = 15 mm: changed pixels form a horizontal band, not all over the frame
    rows = np.nonzero(changed[:, :int(0.8 * W)])[0]                   # right of that: colour bar, legend
    assert np.mean(np.abs(rows - np.median(rows)) < 0.1 * H) > 0.7
    # replay moves the cursor marker from the first to the last stroke point
    seen = []
    assert over.replay(frames=4, realtime=False, on_frame=lambda i, pos: seen.append(tuple(pos))) == 4
    assert seen[0] == pytest.approx(tuple(over.stroke_points[0]))
    assert tuple(over.cursor_actor.position) == pytest.approx(tuple(over.stroke_points[-1]))
    # read-out at a picked point on the path equals the model's read-out there
    r = over.read_at_display(over.stroke_points[700])
    assert r["normal_force"] == pytest.approx(m.readout(tr.x[700], tr.y[700])["normal_force"])
    over.close()


def test_annotations_state_exaggeration_and_chart_adds_pixels(table, trace_path):
    m = viewer.model_from_table(table)
    tr = viewer.load_trace(trace_path)
    p = viewer.render(m, "N", trace=tr, size=(W, H), exaggeration="7.5", chart=False)
    assert "vertical exaggeration x7.5" in p.info and "normal force [N]" in p.info
    img0 = p.screenshot()
    p.close()
    q = viewer.render(m, "N", trace=tr, size=(W, H), exaggeration=7.5, chart=True)
    img1 = q.screenshot()
    q.close()
    # the chart sits in the lower-left corner and draws there
    corner = (slice(int(0.7 * H), H), slice(0, int(0.44 * W)))
    assert np.any(img1[corner] != img0[corner], axis=2).mean() > 0.05


# --------------------------------------------------------------------------------- command line
MAPS = os.path.join(os.path.dirname(__file__), os.pardir, "assets", "maps")


def run_cli(argv):
    from shapedisplay.cli import main as cli_main
    return cli_main.main(argv)


def test_cli_writes_png_of_requested_size(tmp_path, table, trace_path, capsys):
    tpath = tmp_path / "t.npz"
    table.save(tpath)
    out = tmp_path / "shot.png"
    assert run_cli(["preview", str(tpath), "--trace", str(trace_path), "--color", "N", "-o", str(out),
                    "--pixels", "400x260"]) == 0
    assert "wrote" in capsys.readouterr().out
    from PIL import Image
    img = np.asarray(Image.open(out).convert("RGB"))
    assert img.shape == (260, 400, 3)
    assert 0.2 < surface_pixels(img).mean() < 0.98
    assert not list(tmp_path.glob(".shot*"))                            # written atomically


def test_cli_bad_inputs_one_line_exit_2(tmp_path, table, capsys):
    tpath = tmp_path / "t.npz"
    table.save(tpath)
    bad = write_trace(tmp_path / "bad.npz", table, checksum="sha256:" + "1" * 64, n=10)
    cases = [
        (["preview", str(tpath), "--color", "heigth", "-o", str(tmp_path / "a.png")], "valid:"),
        (["preview", str(tpath), "--trace", str(bad), "-o", str(tmp_path / "a.png")], "different table"),
        (["preview", str(bad), "-o", str(tmp_path / "a.png")], "is a trace"),
        (["preview", str(tpath), "-o", str(tmp_path / "a.jpg")], "PNG"),
        (["preview", str(tpath), "--exaggeration", "-2", "-o", str(tmp_path / "a.png")], "exaggeration"),
        (["preview", str(tpath), "--resolution", "1mm", "-o", str(tmp_path / "a.png")], "--resolution"),
        (["preview", os.path.join(MAPS, "buttons.png"), "-o", str(tmp_path / "a.png")], "--size"),
        (["preview", os.path.join(MAPS, "buttons.png"), "--size", "80x50mm", "-o", str(tmp_path / "a.png")],
         "--height"),
        (["preview", str(tpath), "--pixels", "10x10", "-o", str(tmp_path / "a.png")], "64..8192"),
        (["preview", str(tpath), "--view", "below", "-o", str(tmp_path / "a.png")], "valid: iso, side, top"),
        (["preview", str(tpath), "--scene", os.path.join(SCENES, "phone.toml"), "-o", str(tmp_path / "a.png")],
         "does not fit table"),
    ]
    for argv, words in cases:
        assert run_cli(argv) == 2
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1, err
    assert not (tmp_path / "a.png").exists()


# --------------------------------------------------------------------------------- interaction
def test_readout_text_follows_the_picked_point(table):
    m = viewer.model_from_table(table)
    p = viewer.render(m, "N", size=(W, H), annotations=False)
    x, y = 16e-3, 15e-3                                                # near the top of the 'ok' bump
    z = float(p.z_display(m.relief_at(x, y)))
    p._show_readout((x * 1e3, y * 1e3, z))
    expected = m.readout(x, y)
    assert p.last_readout == pytest.approx(expected)
    text = p.plotter.actors["readout"].GetText(0)
    assert "x = 16.00 mm" in text and f"normal_force = {expected['normal_force']:.4g} N" in text
    assert f"height = {expected['height'] * 1e3:.4g} mm" in text
    p.close()


INTERACTIVE = r'''
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from test_viewer import two_widget_table, write_trace
from shapedisplay import viewer
import pathlib
tab = two_widget_table(pathlib.Path(sys.argv[2]))
tr = viewer.load_trace(write_trace(pathlib.Path(sys.argv[2]) / "s.npz", tab))
m = viewer.model_from_table(tab)
p = viewer.render(m, "N", trace=tr, size=(640, 400), off_screen=False)
pl = p.plotter
pl.show(auto_close=False, interactive_update=True)
iren = pl.iren.interactor
iren.SetEventPosition(5, 395)                        # top-left corner: background, no read-out
iren.InvokeEvent("MouseMoveEvent")
assert p.last_readout is None
iren.SetEventPosition(320, 200)                      # middle of the frame: on the surface
iren.InvokeEvent("MouseMoveEvent")
r = p.last_readout
assert r is not None and set(m.fields) <= set(r)
assert 0 <= r["x"] <= 50e-3 and 0 <= r["y"] <= 30e-3
iren.SetKeySym("space"); iren.SetKeyCode(" ")
iren.InvokeEvent("KeyPressEvent")                    # replays the stroke to its end
assert tuple(p.cursor_actor.position) == tuple(p.stroke_points[-1])
pl.close()
print("interactive ok")
'''


def test_interactive_window_hover_and_replay_key(tmp_path):
    """Under a virtual X server: hover reads out the surface, space replays the stroke."""
    import shutil
    import subprocess
    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run not installed (interactive mode needs a display)")
    script = tmp_path / "interactive.py"
    script.write_text(INTERACTIVE)
    env = {k: v for k, v in os.environ.items() if k != "VTK_DEFAULT_OPENGL_WINDOW"}
    res = subprocess.run(["xvfb-run", "-a", sys.executable, str(script), os.path.dirname(__file__), str(tmp_path)],
                         capture_output=True, text=True, timeout=120, env=env)
    assert res.returncode == 0 and "interactive ok" in res.stdout, res.stderr[-2000:]


# --------------------------------------------------------------------------------- scenes
SCENES = os.path.join(os.path.dirname(__file__), os.pardir, "assets", "scenes")


def test_scene_file_preview_has_scene_heights_and_widget_ids():
    from shapedisplay.author.scene import load_scene, scene_heightfield
    path = os.path.join(SCENES, "phone.toml")
    m = viewer.load_model(path)
    sc = load_scene(path)
    np.testing.assert_array_equal(m.fields["height"], scene_heightfield(sc).heights)
    assert [w["id"] for w in m.widgets] == [w.id for w in sc.widgets]
    app = next(w for w in m.widgets if w["id"] == "app-1")
    assert (app["x0"], app["y0"], app["x1"], app["y1"]) == pytest.approx(sc.widget("app-1").bbox)
    # forces as the scene's device and mapping make them: N = n_base + n_gain h, breakaway = mu_s N
    lo, hi = sc.device.normal_force_range
    n = np.clip(sc.mapping.n_base + sc.mapping.n_gain * m.fields["height"], lo, hi)
    np.testing.assert_allclose(m.fields["normal_force"], n, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(m.fields["breakaway_force"], sc.device.friction.mu_s * n, rtol=1e-12)
    assert m.resolve_channel("N") == "normal_force"


def test_scene_file_preview_has_its_data_layers():
    """The map's rainfall layer (friction_scale) is colourable and scales breakaway force, as in its table."""
    from shapedisplay.author.scene import compile_scene, load_scene
    path = os.path.join(SCENES, "map.toml")
    m = viewer.load_model(path)
    t = compile_scene(path).table
    assert m.resolve_channel("friction_scale") == "friction_scale" and m.units["friction_scale"] == "1"
    np.testing.assert_allclose(m.fields["friction_scale"], t.dense("friction_scale"),
                               atol=t.quant["friction_scale"].max_error + 1e-12)
    assert np.ptp(m.fields["friction_scale"]) > 0.3
    mu_s = load_scene(path).device.friction.mu_s
    np.testing.assert_allclose(m.fields["breakaway_force"],
                               mu_s * m.fields["friction_scale"] * m.fields["normal_force"], rtol=1e-12)


def test_compiled_scene_table_shows_outlines_and_left_out(tmp_path):
    from shapedisplay.author.scene import compile_scene
    res = compile_scene(os.path.join(SCENES, "phone.toml"))
    path = tmp_path / "phone.npz"
    res.table.save(path)
    m = viewer.load_model(path)
    assert {w["id"] for w in m.widgets} >= {"app-1", "call", "home", "volume"}
    assert m.stored is not None and 0.1 < m.stored.mean() < 0.9      # empty screen between widgets left out
    # the relief recovered from N = n_base + n_gain h matches the scene's heights where stored
    from shapedisplay.author.scene import scene_heightfield
    h = scene_heightfield(os.path.join(SCENES, "phone.toml")).heights
    q = res.table.quant["normal_force"].max_error / res.table.meta["mapping"]["n_gain"]
    assert np.max(np.abs(m.fields["height"] - h)[m.stored]) <= q + 1e-12
    with_outlines = viewer.render(m, "N", size=(W, H), view="top", lighting=False, scalar_bar=False,
                                  annotations=False)
    img1 = with_outlines.screenshot()
    with_outlines.close()
    m.widgets = []
    bare = viewer.render(m, "N", size=(W, H), view="top", lighting=False, scalar_bar=False, annotations=False)
    img0 = bare.screenshot()
    bare.close()
    dark = lambda img: np.all(img < 70, axis=2)                        # noqa: E731  outline colour #202020
    assert dark(img1).sum() > dark(img0).sum() + 200


def test_every_widget_id_is_drawn_even_where_labels_overlap():
    """Two widgets with label anchors 1 mm apart: the second id is drawn too (VTK's label placement
    would drop it): changing only its text changes the picture."""
    m = viewer.model_from_heightfield(gaussian_field())

    def shot(second_id):
        m.widgets = [{"id": "first", "x0": -10e-3, "y0": -5e-3, "x1": 0.0, "y1": 5e-3},
                     {"id": second_id, "x0": -9e-3, "y0": -5e-3, "x1": 0.0, "y1": 5e-3}]
        p = viewer.render(m, "height", size=(W, H), view="top", lighting=False, scalar_bar=False)
        img = p.screenshot()
        p.close()
        return img

    a, b = shot("second"), shot("XXXXXXXXXX")
    assert np.any(np.abs(a.astype(int) - b.astype(int)) > 60, axis=2).sum() > 30


def test_one_dimensional_scene_is_a_strip_with_full_width_outlines():
    from shapedisplay.author.scene import compile_scene
    res = compile_scene(os.path.join(SCENES, "media-player.toml"))
    m = viewer.model_from_table(res.table)
    assert res.table.is_1d and m.strip and m.relief.shape == (2, res.table.grid.cols)
    assert all(w["y0"] == m.y[0] and w["y1"] == m.y[-1] for w in m.widgets)
    p = viewer.render(m, "N", size=(W, H))
    assert "1-D profile drawn as a strip" in p.info
    assert 0.05 < surface_pixels(p.screenshot()).mean() < 0.9
    p.close()


# --------------------------------------------------------------------------------- drawing helpers (exact)
def test_stroke_segments_exact_for_short_strokes_majority_for_long():
    state = np.array([0, 0, 1, 1, 0, 1, 0], np.int8)
    edges, slip = viewer.stroke_segments(state, 100)
    np.testing.assert_array_equal(edges, np.arange(7))
    np.testing.assert_array_equal(slip, state[:-1] == 1)
    # 100 000 ticks: single-tick slips every 50 ticks (stick-slip), then 20 000 ticks of sliding
    state = np.zeros(100_000, np.int8)
    state[::50] = 1
    state[60_000:80_000] = 1
    edges, slip = viewer.stroke_segments(state, 1000)
    assert len(slip) == 1000 and edges[0] == 0 and edges[-1] == state.size - 1
    mid = (edges[:-1] + edges[1:]) // 2
    np.testing.assert_array_equal(slip, (mid >= 60_000) & (mid < 80_000))


def test_envelope_indices_keep_extremes_of_every_bin():
    rng = np.random.default_rng(1)
    v = np.cumsum(rng.normal(size=50_000)) + 5 * np.sin(np.arange(50_000))   # fast oscillation
    idx = viewer.envelope_indices(v, 500)
    assert idx.size <= 4 * 500 and np.all(np.diff(idx) > 0)
    assert idx[0] == 0 and idx[-1] == v.size - 1
    for a, b in ((0, 100), (25_000, 25_100), (49_900, 50_000)):
        inside = idx[(idx >= a) & (idx < b)]
        assert v[inside].max() == v[a:b].max() and v[inside].min() == v[a:b].min()
    np.testing.assert_array_equal(viewer.envelope_indices(v[:1000], 500), np.arange(1000))


def test_trace_written_by_the_runtime_is_drawn_and_checked(tmp_path, table, capsys):
    """End to end: compile a scene, play a stroke with the runtime, preview it; another table refuses it."""
    from shapedisplay.author.scene import compile_scene
    tab = tmp_path / "mp.npz"
    compile_scene(os.path.join(SCENES, "media-player.toml")).table.save(tab)
    trace = tmp_path / "mp-trace.npz"
    assert run_cli(["play", str(tab), "--stroke", "0:100mm @ 100mm/s", "-o", str(tmp_path / "mp.wav"),
                    "--trace-out", str(trace)]) == 0
    out = tmp_path / "mp.png"
    assert run_cli(["preview", str(tab), "--trace", str(trace), "-o", str(out), "--pixels", "400x300"]) == 0
    tr = viewer.load_trace(trace)
    assert tr.table_checksum == viewer.load_model(tab).checksum and tr.event_time.size > 0
    other = tmp_path / "other.npz"
    table.save(other)
    capsys.readouterr()
    assert run_cli(["preview", str(other), "--trace", str(trace), "-o", str(tmp_path / "x.png")]) == 2
    assert "different table" in capsys.readouterr().err


# --------------------------------------------------------------------------------- properties
from hypothesis import given, settings, strategies as st  # noqa: E402
from hypothesis.extra.numpy import arrays  # noqa: E402


@settings(max_examples=40, deadline=None)
@given(h=arrays(np.float64, st.tuples(st.integers(1, 6), st.integers(2, 7)),
                elements=st.floats(-1e-2, 1e-2, allow_nan=False)),
       px=st.floats(-0.05, 0.05), py=st.floats(-0.05, 0.05))
def test_readout_and_exaggeration_finite_and_bounded(h, px, py):
    """Finite heights give a finite read-out inside each field's range, anywhere; exaggeration in [1, 1000]."""
    m = viewer.model_from_heightfield(HeightField(h, 1e-3, 2e-3))
    r = m.readout(px, py)
    for name, arr in m.fields.items():
        assert np.isfinite(r[name])
        assert arr.min() - 1e-12 <= r[name] <= arr.max() + 1e-12
    ex = viewer.auto_exaggeration(m)
    assert 1.0 <= ex <= viewer.MAX_AUTO_EXAGGERATION


def test_large_grid_drawn_at_a_stride_with_full_colour_range(monkeypatch):
    monkeypatch.setattr(viewer.draw, "MAX_DRAWN_SAMPLES", 1000)
    hf = gaussian_field()                                   # 61 x 81 = 4941 samples -> stride 3
    m = viewer.model_from_heightfield(hf)
    assert viewer.draw_stride(61, 81) == 3
    p = viewer.render(m, "height", size=(W, H))
    assert "drawn with 1 in 3 samples per axis of the 81 x 61-sample grid" in p.info
    assert p.surface_actor.mapper.dataset.n_points == 21 * 28   # 0,3,..,60 and 0,3,..,78,80
    assert p.surface_actor.mapper.scalar_range == pytest.approx((hf.heights.min() * 1e3, hf.heights.max() * 1e3))
    p.close()
