"""Height-field sources: published profiles, primitives, PNG/npy images, arrays, dispatch."""
import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

from shapedisplay import sources
from shapedisplay.errors import FileFormatError, InputError, UnitError
from shapedisplay.imageio import PNG_SIGNATURE, _chunk, encode_png, png_info, read_png, write_png


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


# ----------------------------------------------------------------- PNG
@settings(max_examples=30, deadline=None)
@given(gray=hnp.arrays(st.sampled_from([np.uint8, np.uint16]), st.tuples(st.integers(1, 9), st.integers(1, 11))),
       data=st.data())
def test_png_round_trip_every_filter(tmp_path_factory, gray, data):
    ftypes = data.draw(hnp.arrays(np.uint8, (gray.shape[0],), elements=st.integers(0, 4)))
    p = tmp_path_factory.mktemp("png") / "g.png"
    write_png(p, gray, ftypes)
    back = read_png(p)
    assert back.dtype == gray.dtype and np.array_equal(back, gray)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("ftype", ["none", "sub", "up", "average", "paeth"])
def test_png_filters_agree_with_an_independent_decoder(tmp_path, dtype, ftype):
    pil = pytest.importorskip("PIL.Image")
    rng = np.random.default_rng(3)
    g = rng.integers(0, np.iinfo(dtype).max, size=(23, 31), endpoint=True).astype(dtype)
    write_png(tmp_path / "g.png", g, ftype)
    assert np.array_equal(np.asarray(pil.open(tmp_path / "g.png")).astype(np.int64), g.astype(np.int64))


def test_png_written_by_another_encoder(tmp_path):
    pil = pytest.importorskip("PIL.Image")
    y, x = np.mgrid[0:64, 0:80]
    g = ((x * 3 + y * 5 + (x * y) % 7) % 256).astype(np.uint8)
    pil.fromarray(g).save(tmp_path / "p.png", optimize=True)   # adaptive filters per row
    assert np.array_equal(read_png(tmp_path / "p.png"), g)


def _png(ihdr_fields, idat=b"", extra=b""):
    ihdr = struct.pack(">IIBBBBB", *ihdr_fields)
    return PNG_SIGNATURE + _chunk(b"IHDR", ihdr) + extra + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


@pytest.mark.parametrize("fields, match", [
    ((4, 4, 8, 2, 0, 0, 0), r"colour type 2 \(RGB\) is not supported; supported: 8- or 16-bit grayscale"),
    ((4, 4, 1, 0, 0, 0, 0), r"bit depth 1 is not supported; supported: 8- or 16-bit grayscale"),
    ((4, 4, 8, 6, 0, 0, 0), r"colour type 6 \(RGBA\)"),
    ((4, 4, 8, 3, 0, 0, 0), r"colour type 3 \(palette\)"),
    ((4, 4, 8, 0, 0, 0, 1), r"interlaced"),
])
def test_png_unsupported_formats(tmp_path, fields, match):
    p = tmp_path / "bad.png"
    p.write_bytes(_png(fields, zlib.compress(b"\0" * 40)))
    with pytest.raises(FileFormatError, match=match):
        read_png(p)


def test_png_huge_header_refused_before_decompressing(tmp_path, monkeypatch):
    p = tmp_path / "huge.png"
    p.write_bytes(_png((100_000, 100_000, 16, 0, 0, 0, 0), zlib.compress(b"\0" * 10)))

    def no_inflate(*a, **k):
        raise AssertionError("pixel data must not be decompressed")
    monkeypatch.setattr("shapedisplay.imageio._inflate", no_inflate)
    with pytest.raises(InputError, match=r"100000x100000 .* exceeds the limit"):
        read_png(p)
    with pytest.raises(InputError, match="exceeds the limit"):
        png_info(p)


def test_png_corruption(tmp_path):
    good = encode_png(np.arange(12, dtype=np.uint8).reshape(3, 4))
    cases = {
        "crc": good[:40] + bytes([good[40] ^ 0xFF]) + good[41:],
        "trunc": good[: len(good) - 20],
        "sig": b"GIF89a" + good[6:],
    }
    for name, data in cases.items():
        (tmp_path / f"{name}.png").write_bytes(data)
    with pytest.raises(FileFormatError, match="CRC mismatch"):
        read_png(tmp_path / "crc.png")
    with pytest.raises(FileFormatError, match="truncated"):
        read_png(tmp_path / "trunc.png")
    with pytest.raises(FileFormatError, match="not a PNG file"):
        read_png(tmp_path / "sig.png")
    short = tmp_path / "short.png"
    short.write_bytes(_png((4, 4, 8, 0, 0, 0, 0), zlib.compress(b"\0" * 7)))
    with pytest.raises(FileFormatError, match="holds 7 bytes, the header needs 20"):
        read_png(short)
    long_ = tmp_path / "long.png"
    long_.write_bytes(_png((4, 4, 8, 0, 0, 0, 0), zlib.compress(b"\0" * 200)))
    with pytest.raises(FileFormatError, match="more pixel data than the header"):
        read_png(long_)
    badz = tmp_path / "badz.png"
    badz.write_bytes(_png((4, 4, 8, 0, 0, 0, 0), b"not zlib at all"))
    with pytest.raises(FileFormatError, match="corrupt compressed pixel data"):
        read_png(badz)
    badf = tmp_path / "badf.png"
    badf.write_bytes(_png((2, 2, 8, 0, 0, 0, 0), zlib.compress(bytes([7, 0, 0, 0, 0, 0]))))
    with pytest.raises(FileFormatError, match="unknown PNG filter type 7"):
        read_png(badf)
    with pytest.raises(FileFormatError, match="no such file"):
        read_png(tmp_path / "missing.png")
    with pytest.raises(FileFormatError, match="is a directory"):
        read_png(tmp_path)


# ----------------------------------------------------------------- load_image
@pytest.mark.parametrize("dtype, full", [(np.uint8, 255), (np.uint16, 65535)])
def test_gray_maps_linearly_onto_height_range(tmp_path, dtype, full):
    g = np.array([[0, full // 2, full], [full, 0, 1]], dtype=dtype)
    write_png(tmp_path / "m.png", g)
    hf = sources.load_image(tmp_path / "m.png", "60x4mm", "-1:2mm")
    assert np.allclose(hf.heights, -1e-3 + 3e-3 * g / full, rtol=0, atol=1e-15)
    assert hf.heights[0, 0] == -1e-3 and hf.heights[0, 2] == pytest.approx(2e-3, abs=1e-18)
    # pixel centres are the sample centres: dx = width / cols
    assert hf.dx == pytest.approx(0.02) and hf.dy == pytest.approx(0.002)
    assert hf.x0 == pytest.approx(0.01) and hf.y0 == pytest.approx(0.001)
    assert hf.x[-1] == pytest.approx(0.05)


def test_image_errors(tmp_path):
    write_png(tmp_path / "one.png", np.zeros((1, 1), np.uint8))
    with pytest.raises(InputError, match="at least 2 samples"):
        sources.load_image(tmp_path / "one.png", "1x1mm", "0:1mm")
    write_png(tmp_path / "m.png", np.zeros((2, 2), np.uint8))
    with pytest.raises(InputError, match="`size` must be positive"):
        sources.load_image(tmp_path / "m.png", "-1x1mm", "0:1mm")
    with pytest.raises(InputError, match="low <= high"):
        sources.load_image(tmp_path / "m.png", "1x1mm", (2e-3, 1e-3))
    with pytest.raises(InputError, match="`height_range` is required"):
        sources.load_image(tmp_path / "m.png", "1x1mm", None)
    with pytest.raises(InputError, match=r"unknown image type '.jpg'"):
        sources.load_image(tmp_path / "m.jpg", "1x1mm", "0:1mm")


def test_npy_sources(tmp_path):
    h = np.linspace(0, 1e-3, 12).reshape(3, 4)
    np.save(tmp_path / "h.npy", h)
    hf = sources.load_image(tmp_path / "h.npy", "4x3mm", None)
    assert np.array_equal(hf.heights, h)
    hf = sources.load_image(tmp_path / "h.npy", None, None, resolution="0.5mm")
    assert hf.dx == 0.5e-3 and hf.size_m == pytest.approx((2e-3, 1.5e-3))
    np.save(tmp_path / "g.npy", np.array([[0, 65535]], dtype=np.uint16))
    assert np.allclose(sources.load_image(tmp_path / "g.npy", "2x1mm", "0:2mm").heights, [[0, 2e-3]])
    np.save(tmp_path / "nan.npy", np.array([[0.0, np.nan]]))
    with pytest.raises(InputError, match="must be finite"):
        sources.load_image(tmp_path / "nan.npy", "2x1mm", None)
    np.save(tmp_path / "empty.npy", np.zeros((0, 5)))
    with pytest.raises(InputError, match="at least 2 samples"):
        sources.load_image(tmp_path / "empty.npy", "2x1mm", None)
    np.save(tmp_path / "cube.npy", np.zeros((2, 2, 2)))
    with pytest.raises(FileFormatError, match=r"shape \(rows, cols\)"):
        sources.load_image(tmp_path / "cube.npy", "2x1mm", None)
    np.save(tmp_path / "b.npy", np.zeros((2, 2), dtype=bool))
    with pytest.raises(FileFormatError, match="dtype bool is not supported"):
        sources.load_image(tmp_path / "b.npy", "2x1mm", None)
    (tmp_path / "junk.npy").write_bytes(b"garbage")
    with pytest.raises(FileFormatError, match="not a .npy file"):
        sources.load_image(tmp_path / "junk.npy", "2x1mm", None)
    # with a height range, values must lie on the gray scale (they used to extrapolate silently)
    np.save(tmp_path / "f5.npy", np.array([[0.0, 5.0]]))
    with pytest.raises(InputError, match=r"normalised float values must lie within 0..1 \(got 0..5\)"):
        sources.load_image(tmp_path / "f5.npy", "2x1mm", "0:1mm")
    np.save(tmp_path / "i8.npy", np.array([[-5, 100]], dtype=np.int8))
    with pytest.raises(InputError, match=r"int8 gray values must lie within 0..127 \(got -5..100\)"):
        sources.load_image(tmp_path / "i8.npy", "2x1mm", "0:1mm")
    half = np.array([[0.0, 0.5, 1.0]])
    assert np.allclose(sources.gray_to_heights(half, 1.0, (0.0, 2e-3)), [[0.0, 1e-3, 2e-3]])
    assert np.array_equal(half, [[0.0, 0.5, 1.0]])          # the input is not scaled in place


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


def test_image_options_parse_command_line_strings():
    from shapedisplay.sources import image_options, resolution_option
    assert image_options("m.png", "60x4mm", "0:2mm") == {"size": pytest.approx((0.06, 0.004)),
                                                         "height_range": pytest.approx((0.0, 0.002))}
    assert image_options("m.npy", None, None, "0.1mm") == {"resolution": pytest.approx(1e-4)}
    with pytest.raises(InputError, match=r"image 'm.png' needs `--height`"):
        image_options("m.png", "60x4mm", None)
    with pytest.raises(InputError, match=r"needs `--extent`"):
        image_options("m.png", None, "0:1mm", size_flag="--extent")
    with pytest.raises(InputError, match=r"`--size` must be positive"):
        image_options("m.png", "0x4mm", "0:1mm")
    with pytest.raises(InputError, match=r"`--resolution` must be a length > 0"):
        resolution_option("-1mm")


def test_source_kind_and_option_applicability_live_in_the_library(tmp_path):
    """One table says which command-line option applies to which source; every command asks it."""
    from shapedisplay.sources import check_applicable, source_kind, source_options
    assert [source_kind(p) for p in ("t.npz", "s.TOML", "a.png", "b.npy", "c.stl", "d.glb")] == \
        ["table", "scene", "image", "image", "mesh", "mesh"]
    with pytest.raises(InputError, match=r"unknown source type '\.bmp'"):
        source_kind("x.bmp")
    with pytest.raises(InputError, match=r"`--up` applies to meshes, not to 'a\.png' \(an image\)"):
        check_applicable("a.png", {"up": "y"})
    with pytest.raises(InputError, match=r"`--extent` applies to image sources, not to 'k\.stl' \(a mesh\)"):
        source_options("k.stl", size="1x1mm", flags={"size": "--extent"})
    with pytest.raises(InputError, match=r"`--n-gain` applies to images and meshes, not to 'p\.toml' \(a scene"):
        check_applicable("p.toml", {"n_gain": "2N/mm"}, kinds={"n_gain": ("image", "mesh")})
    assert check_applicable("p.toml", {"up": None, "size": None}) == "scene"
    assert source_options("k.stl", resolution="0.1mm", up="y") == {"resolution": pytest.approx(1e-4), "up": "y"}
    assert source_options("a.png", size="60x4mm", height="0:2mm") == {
        "size": pytest.approx((0.06, 0.004)), "height_range": pytest.approx((0.0, 0.002))}
    assert source_options("t.npz") == {}
