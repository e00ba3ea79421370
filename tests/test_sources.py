"""Height-field sources: published profiles, primitives, arrays, dispatch (pictures: test_pictures.py)."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

from shapedisplay.author import sources
from shapedisplay.errors import FileFormatError, InputError, UnitError
from shapedisplay.author.imageio import write_png


# ----------------------------------------------------------------- published profiles
def test_tent_profile_gives_published_force_exactly():
    # L1 = 10 mm, L2 = 20 mm (k = 0.1 N/mm), N1 = 0.5 N, N2 = 1.5 N, L4 = 40 mm
    hf = sources.tent_profile("10 mm", "20 mm", "40 mm", n1="0.5 N", n2="1.5 N", n_gain="2 N/mm", dx="0.1 mm")
    assert hf.is_1d and hf.cols == 400
    n = 0.5 + 2000.0 * hf.heights[0]
    x = hf.x
    expected = np.select([x < 0.010, x < 0.020, x < 0.030], [0.5, 0.5 + 100.0 * (x - 0.010),
                                                            1.5 - 100.0 * (x - 0.020)], 0.5)
    assert np.abs(n - expected).max() < 1e-12
    assert x[0] == pytest.approx(0.05e-3) and hf.dx == pytest.approx(0.1e-3)


def test_tent_rate_and_level_forms_agree():
    a = sources.tent_profile(0.01, 0.02, 0.04, n2=1.5, dx=1e-4)
    b = sources.tent_profile(0.01, 0.02, 0.04, k="0.1 N/mm", dx=1e-4)
    assert np.array_equal(a.heights, b.heights)
    with pytest.raises(InputError, match="l3 = 2\\*l2 - l1"):
        sources.tent_profile(0.01, 0.02, 0.04, n2=1.5, l3=0.035)
    with pytest.raises(InputError, match="exactly one of `n2`"):
        sources.tent_profile(0.01, 0.02, 0.04, n2=1.5, k=100.0)


def test_ramp_profile_published():
    hf = sources.ramp_profile("5mm", "25mm", "40mm", n2="2.5N", n_gain="1 N/mm", dx="0.5mm", rows=3)
    assert hf.shape == (3, 80)
    n = 0.5 + 1000.0 * hf.heights
    assert np.abs(n[1] - sources.ramp_force(hf.x, 0.005, 0.025, 0.5, 2.5)).max() < 1e-12
    assert n[0, -1] == pytest.approx(2.5) and n[0, 0] == pytest.approx(0.5)
    assert hf.meta["n_base"] == 0.5 and hf.meta["n_gain"] == 1000.0


# ----------------------------------------------------------------- primitives
def test_gaussian_bump_and_dent():
    hf = sources.gaussian_bump("1 mm", "2 mm", ("20mm", "10mm"), "0.1mm")
    assert hf.shape == (100, 200)
    r, c = np.unravel_index(np.argmax(hf.heights), hf.shape)
    assert hf.x[c] == pytest.approx(10e-3, abs=0.051e-3) and hf.y[r] == pytest.approx(5e-3, abs=0.051e-3)
    x, y = hf.x[None, :], hf.y[:, None]
    assert np.allclose(hf.heights, 1e-3 * np.exp(-((x - 0.01) ** 2 + (y - 0.005) ** 2) / (2 * 0.002 ** 2)))
    dent = sources.gaussian_bump("-1 mm", "2 mm", "20x10mm", "0.1mm")
    assert np.array_equal(dent.heights, -hf.heights)


def test_raised_cosine_has_compact_support():
    hf = sources.raised_cosine_bump(0.5e-3, 3e-3, (0.02, 0.02), 0.2e-3)
    r = np.hypot(hf.x[None, :] - 0.01, hf.y[:, None] - 0.01)
    assert np.all(hf.heights[r >= 3e-3] == 0)
    inside = r < 3e-3
    assert np.allclose(hf.heights[inside], 0.25e-3 * (1 + np.cos(np.pi * r[inside] / 3e-3)))


@pytest.mark.parametrize("edge", ["ramp", "cosine", "step"])
def test_rounded_button_top_and_outline(edge):
    hf = sources.rounded_button("10mm", "6mm", "1mm", "20x20mm", "0.1mm", corner_radius="2mm",
                                edge=edge, edge_width="1mm")
    x, y = hf.x[None, :] - 0.01, hf.y[:, None] - 0.01
    outside = (np.abs(x) > 5e-3) | (np.abs(y) > 3e-3)
    assert np.all(hf.heights[outside] == 0)
    top = (np.abs(x) < 3e-3) & (np.abs(y) < 1.5e-3)
    assert np.allclose(hf.heights[top], 1e-3)
    assert hf.heights.max() == pytest.approx(1e-3) and hf.heights.min() == 0.0
    # corners are rounded: the rectangle's corner point lies outside
    corner = (np.abs(np.abs(x) - 4.95e-3) < 0.06e-3) & (np.abs(np.abs(y) - 2.95e-3) < 0.06e-3)
    assert np.all(hf.heights[corner] == 0)


def test_rounded_button_bad_corner():
    with pytest.raises(InputError, match="corner_radius"):
        sources.rounded_button("10mm", "6mm", "1mm", "20x20mm", "0.1mm", corner_radius="4mm")
    with pytest.raises(InputError, match=r"did you mean 'cosine'"):
        sources.rounded_button("10mm", "6mm", "1mm", "20x20mm", "0.1mm", edge="cosin")


def test_groove_and_ridge_cross_sections():
    g = sources.groove("0.5mm", "2mm", "10x4mm", "0.05mm")          # axis along y through x = 5 mm
    u = g.x - 5e-3
    expect = np.where(np.abs(u) < 1e-3, -0.25e-3 * (1 + np.cos(np.pi * np.abs(u) / 1e-3)), 0.0)
    assert np.allclose(g.heights, expect[None, :], atol=1e-15)
    r = sources.ridge("0.5mm", "2mm", "10x4mm", "0.05mm", angle=0.0, profile="tent")  # along x
    v = r.y - 2e-3
    assert np.allclose(r.heights, np.clip(0.5e-3 * (1 - np.abs(v) / 1e-3), 0, None)[:, None])


def test_step_edge():
    s = sources.step_edge("1mm", "10x2mm", "0.1mm", position="5mm")
    assert np.all(s.heights[:, s.x < 5e-3] == 0) and np.all(s.heights[:, s.x >= 5e-3] == 1e-3)
    ramp = sources.step_edge("1mm", "10x2mm", "0.1mm", position="5mm", width="2mm")
    assert np.allclose(ramp.heights[0], np.clip((ramp.x - 5e-3) / 2e-3 + 0.5, 0, 1) * 1e-3)


def test_bad_sizes_and_spacings():
    with pytest.raises(InputError, match="`size` must be positive"):
        sources.gaussian_bump(1e-3, 1e-3, (-0.01, 0.01), 1e-4)
    with pytest.raises(InputError, match="`size` must be positive"):
        sources.gaussian_bump(1e-3, 1e-3, "0x10mm", 1e-4)
    with pytest.raises(InputError, match="`dx` must be a finite length > 0"):
        sources.gaussian_bump(1e-3, 1e-3, (0.01, 0.01), 0.0)
    with pytest.raises(InputError, match="`dx` must be a finite length > 0"):
        sources.from_array(np.zeros((3, 3)), -1e-4)
    with pytest.raises(UnitError, match="`sigma` needs a unit"):
        sources.gaussian_bump("1mm", "2", "10x10mm", "0.1mm")
    with pytest.raises(InputError, match="exceeds the limit"):
        sources.gaussian_bump(1e-3, 1e-3, (10.0, 10.0), 1e-5)


# ----------------------------------------------------------------- arrays
def test_from_array_cell_centres_and_checks():
    hf = sources.from_array(np.arange(6.0).reshape(2, 3) * 1e-4, "0.5mm")
    assert hf.x0 == pytest.approx(0.25e-3) and hf.dy == pytest.approx(0.5e-3)
    with pytest.raises(InputError, match="must be finite"):
        sources.from_array(np.array([[0.0, np.nan], [0, 0]]), 1e-4)
    with pytest.raises(InputError, match="must be finite"):
        sources.from_array(np.array([0.0, np.inf]), 1e-4)
    with pytest.raises(InputError, match="is empty"):
        sources.from_array(np.zeros((0, 4)), 1e-4)
    with pytest.raises(InputError, match="single sample"):
        sources.from_array(np.zeros((1, 1)), 1e-4)



# ----------------------------------------------------------------- load_source / options
def test_load_source_dispatch(tmp_path):
    write_png(tmp_path / "m.png", np.zeros((2, 3), np.uint16))
    hf = sources.load_source(tmp_path / "m.png", size=(3e-3, 2e-3), height_range=(0, 1e-3), up=None)
    assert hf.shape == (2, 3)
    with pytest.raises(InputError, match=r"unknown image option 'sise' \(did you mean 'size'\?\)"):
        sources.load_source(tmp_path / "m.png", sise=(1, 1))
    with pytest.raises(InputError, match=r"unknown source type '.pgn'.*did you mean '.png'"):
        sources.load_source(tmp_path / "m.pgn")
    with pytest.raises(FileFormatError, match="mesh .* no such file"):
        sources.load_source(tmp_path / "missing.stl", resolution=1e-4)


def test_source_options_parse_command_line_strings():
    from shapedisplay.author.sources import resolution_option, source_options
    assert source_options("m.png", size="60x4mm", height="0:2mm") == {
        "size": pytest.approx((0.06, 0.004)), "height_range": pytest.approx((0.0, 0.002))}
    assert source_options("m.npy", resolution="0.1mm", z_units="nm") == {
        "resolution": pytest.approx(1e-4), "z_units": "nm"}
    assert source_options("m.stl", size="60mm", height="0:3mm", up="-y") == {
        "size": pytest.approx(0.06), "height_range": pytest.approx((0.0, 0.003)), "up": "-y"}
    assert source_options("m.stl", size="60x40mm", up="0,1,0")["up"] == [0.0, 1.0, 0.0]
    with pytest.raises(InputError, match=r"needs `--extent`"):
        source_options("m.png", height="0:1mm", flags={"size": "--extent"})
    with pytest.raises(InputError, match=r"`size` must be positive"):
        source_options("m.png", size="0x4mm")
    with pytest.raises(InputError, match=r"`resolution` must be a length > 0"):
        resolution_option("-1mm")
    with pytest.raises(InputError, match=r"`--resolution` must be a length > 0"):
        resolution_option("-1mm", "--resolution")
    with pytest.raises(InputError, match=r"`channel` applies to image sources, not to 'm.stl' \(a mesh\)"):
        source_options("m.stl", channel="r")
    with pytest.raises(InputError, match=r"`height` must run low:high"):
        source_options("m.png", size="1x1mm", height="2:1mm")


def test_source_kind_and_option_applicability_live_in_the_library(tmp_path):
    """One table says which command-line option applies to which source; every command asks it."""
    from shapedisplay.author.sources import check_applicable, source_kind, source_options
    assert [source_kind(p) for p in ("t.npz", "s.TOML", "a.png", "b.npy", "c.stl", "d.glb", "m.svg")] == \
        ["table", "scene", "image", "image", "mesh", "mesh", "svg"]
    with pytest.raises(InputError, match=r"unknown source type '\.pgn'"):
        source_kind("x.pgn")
    with pytest.raises(InputError, match=r"`up` applies to meshes, not to 'a\.png' \(an image\)"):
        check_applicable("a.png", {"up": "y"})
    with pytest.raises(InputError, match=r"`--extent` applies to images and meshes, not to 's\.toml' \(a scene"):
        source_options("s.toml", size="1x1mm", flags={"size": "--extent"})
    with pytest.raises(InputError, match=r"`--n-gain` applies to images and meshes, not to 'p\.toml' \(a scene"):
        check_applicable("p.toml", {"n_gain": "2N/mm"}, flags={"n_gain": "--n-gain"}, kinds={"n_gain": ("image", "mesh")})
    assert check_applicable("p.toml", {"up": None, "size": None}) == "scene"
    assert source_options("k.stl", resolution="0.1mm", up="y") == {"resolution": pytest.approx(1e-4), "up": "y"}
    assert source_options("t.npz") == {}


def test_a_picture_source_is_identified_by_its_codes_and_map(tmp_path):
    """The source digest of a picture hashes its gray codes, the map onto heights and the grid: equal for
    the same file read twice, different for one changed pixel, another height range or size; a height
    field made from it with new heights hashes those heights."""
    g = (np.arange(40 * 30, dtype=np.uint16).reshape(30, 40) * 37) % 65535
    write_png(tmp_path / "a.png", g)
    g2 = g.copy()
    g2[29, 0] += 1                                       # bottom-left pixel: the grid's first row
    write_png(tmp_path / "b.png", g2)
    load = lambda name, size="4x3mm", height="0:2mm": sources.load_image(tmp_path / name, size, height)  # noqa: E731
    a = load("a.png")
    assert a.sha256() == load("a.png").sha256() and len(a.sha256()) == 64
    others = {load("b.png").sha256(), load("a.png", height="0:3mm").sha256(), load("a.png", size="4x4mm").sha256()}
    assert a.sha256() not in others and len(others) == 3
    remade = a.with_heights(a.heights.copy())
    plain = sources.from_array(a.heights, a.dx, a.dy)
    assert remade.sha256() != a.sha256() and remade.sha256() == plain.sha256()
    with pytest.raises(InputError, match="unsigned integers of the heights' shape"):
        plain.made_from_codes(g.astype(np.int32), 65535.0, (0.0, 2e-3))
    with pytest.raises(InputError, match="unsigned integers of the heights' shape"):
        plain.made_from_codes(g[:5], 65535.0, (0.0, 2e-3))
