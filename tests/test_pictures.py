"""Pictures as height maps: every kind a designer has, read through Pillow.

Fixtures are generated here with Pillow (and, for interlaced PNG, which
Pillow cannot write, with a small Adam7 encoder below).
"""
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from shapedisplay.author import sources
from shapedisplay.errors import FileFormatError, InputError
from shapedisplay.author.imageio import (BT709, PictureWarning, frankot_chellappa, looks_like_normal_map, picture_info,
                                  png_text, read_picture, write_png)


def _asym(rows=12, cols=16, top=255, dtype=np.uint8):
    """An asymmetric picture: a ramp along x plus a bright block in the top-left corner."""
    x = np.arange(cols)[None, :]
    g = (x * (top // 2) // (cols - 1)) + np.zeros((rows, 1), dtype=np.int64)
    g[:3, :4] = top
    return g.astype(dtype)


def _chunk(ctype: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + ctype + body + struct.pack(">I", zlib.crc32(ctype + body) & 0xFFFFFFFF)


def _png_bytes(width, height, depth, colour, raw: bytes, interlace=0) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, interlace)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(raw))
            + _chunk(b"IEND", b""))


def _adam7_gray8(g: np.ndarray) -> bytes:
    """An interlaced (Adam7) 8-bit grey PNG, every row filter None."""
    raw = b""
    for x0, y0, dx, dy in ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2),
                           (0, 1, 1, 2)):
        sub = g[y0::dy, x0::dx]
        if sub.size:
            raw += b"".join(b"\0" + row.tobytes() for row in sub)
    return _png_bytes(g.shape[1], g.shape[0], 8, 0, raw, interlace=1)


# ----------------------------------------------------------------- grey
@pytest.mark.parametrize("dtype, full", [(np.uint8, 255), (np.uint16, 65535)])
def test_grey_png_maps_gray_onto_height_range_as_top_view(tmp_path, dtype, full):
    g = _asym(top=full, dtype=dtype)
    write_png(tmp_path / "m.png", g)
    hf = sources.load_image(tmp_path / "m.png", "16x12mm", "-1:2mm")
    # picture row 0 is the top edge: the largest y, the last height-field row
    assert np.allclose(hf.heights, (-1e-3 + 3e-3 * g / full)[::-1], rtol=0, atol=1e-15)
    assert hf.heights[-1, 0] == pytest.approx(2e-3) and hf.y[-1] > hf.y[0]
    assert hf.dx == pytest.approx(1e-3) and hf.x0 == pytest.approx(0.5e-3) and hf.y0 == pytest.approx(0.5e-3)
    assert hf.meta["scale"]["source_unit"] == "gray level"
    assert hf.meta["scale"]["m_per_unit"] == pytest.approx(3e-3 / full)


def test_low_bit_depth_and_interlaced_png(tmp_path):
    g = _asym()
    (tmp_path / "i.png").write_bytes(_adam7_gray8(g))
    assert np.array_equal(read_picture(tmp_path / "i.png").values, g)
    bits = (g > 100).astype(np.uint8)
    Image.fromarray(bits * 255).convert("1").save(tmp_path / "b.png")          # 1-bit grey
    pic = read_picture(tmp_path / "b.png")
    assert pic.full_scale == 255 and np.array_equal(pic.values, bits * 255)
    assert picture_info(tmp_path / "b.png")["bit_depth"] == 1


def test_tiff_16_bit_and_float_with_units(tmp_path):
    g = _asym(top=65535, dtype=np.uint16)
    Image.frombytes("I;16", (g.shape[1], g.shape[0]), g.astype("<u2").tobytes()).save(tmp_path / "g.tif")
    hf = sources.load_image(tmp_path / "g.tif", "16x12mm", "0:1mm")
    assert np.allclose(hf.heights, (1e-3 * g / 65535.0)[::-1], atol=1e-15)
    f = (np.random.default_rng(1).random((6, 5)) * 500).astype(np.float32)      # nanometres
    Image.fromarray(f).save(tmp_path / "f.tif")
    hf = sources.load_image(tmp_path / "f.tif", "5x6um", None, z_units="nm")
    assert np.allclose(hf.heights, f.astype(np.float64)[::-1] * 1e-9, rtol=1e-15, atol=0)
    assert hf.meta["scale"]["source_unit"] == "nm"
    with pytest.raises(InputError, match="`z_units` applies to float data"):
        sources.load_image(tmp_path / "g.tif", "16x12mm", "0:1mm", z_units="nm")
    with pytest.raises(InputError, match=r"unknown z unit 'pm'"):
        sources.load_image(tmp_path / "f.tif", "5x6um", None, z_units="pm")


def test_jpeg_is_read_as_pillow_decodes_it(tmp_path):
    g = np.kron(_asym(), np.ones((4, 4), dtype=np.uint8))
    Image.fromarray(g).save(tmp_path / "g.jpg", quality=95)
    hf = sources.load_image(tmp_path / "g.jpg", "64x48mm", "0:1mm")
    decoded = np.asarray(Image.open(tmp_path / "g.jpg")).astype(np.float64)
    assert np.allclose(hf.heights, (decoded / 255 * 1e-3)[::-1], atol=1e-15)
    assert np.abs(decoded - g).max() < 40                   # lossy, but the same picture


# ----------------------------------------------------------------- colour, channels, alpha
def test_rgb_luminance_is_bt709_and_channels_pick_one(tmp_path):
    rng = np.random.default_rng(5)
    rgb = rng.integers(0, 256, (7, 9, 3)).astype(np.uint8)
    Image.fromarray(rgb).save(tmp_path / "c.png")
    lum = read_picture(tmp_path / "c.png")
    expect = rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722
    assert BT709 == (0.2126, 0.7152, 0.0722)
    assert np.allclose(lum.values, expect, rtol=0, atol=1e-12) and "BT.709" in lum.description
    for i, ch in enumerate("rgb"):
        assert np.array_equal(read_picture(tmp_path / "c.png", ch).values, rgb[..., i])
    with pytest.raises(FileFormatError, match="has no alpha channel"):
        read_picture(tmp_path / "c.png", "a")
    write_png(tmp_path / "grey.png", rgb[..., 0])
    with pytest.raises(FileFormatError, match="is a grey picture .* `channel` 'g' needs colour"):
        read_picture(tmp_path / "grey.png", "g")
    with pytest.raises(InputError, match=r"unknown image channel 'red'"):
        read_picture(tmp_path / "c.png", "red")


def test_palette_png_expands_through_its_palette(tmp_path):
    idx = (_asym() // 64).astype(np.uint8)                       # 4 colours
    im = Image.frombytes("P", idx.shape[::-1], idx.tobytes())
    pal = [0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255] + [0] * (256 * 3 - 12)
    im.putpalette(pal)
    im.save(tmp_path / "p.png")
    pic = read_picture(tmp_path / "p.png", "g")
    assert np.array_equal(pic.values, np.where(idx == 2, 255, 0)) and "palette expanded" in pic.notes
    im.info["transparency"] = 0
    im.save(tmp_path / "pt.png", transparency=0)
    pic = read_picture(tmp_path / "pt.png", "luminance")
    assert pic.mask is not None and np.array_equal(pic.mask, idx != 0)


def test_alpha_is_a_mask_and_outside_is_not_stored(tmp_path):
    from shapedisplay.author.compile import compile_heightfield
    rows, cols = 96, 128
    la = np.zeros((rows, cols, 2), np.uint8)
    la[..., 0] = np.arange(cols)[None, :] * 2
    la[20:40, 30:60, 1] = 255                                   # a small opaque island
    Image.fromarray(la, mode="LA").save(tmp_path / "la.png")
    hf = sources.load_image(tmp_path / "la.png", "128x96mm", "0:1mm")
    assert hf.mask is not None and hf.mask.sum() == 20 * 30
    assert np.array_equal(hf.mask, (la[..., 1] > 0)[::-1])
    assert np.all(hf.heights[~hf.mask] == 0.0)                  # flat ground (gray 0) outside
    res = compile_heightfield(hf)
    assert res.report["layout"].startswith("masked: ")
    dense = compile_heightfield(type(hf)(hf.heights, hf.dx, hf.dy, hf.x0, hf.y0))
    assert res.report["stored_bytes"] <= dense.report["stored_bytes"] / 3     # 4 of 12 tiles
    # leaving the outside out changes nothing the renderer reads
    assert np.array_equal(res.table.dense("normal_force"), dense.table.dense("normal_force"))
    # RGBA: same rule
    rgba = np.zeros((rows, cols, 4), np.uint8)
    rgba[..., :3] = la[..., :1]
    rgba[..., 3] = la[..., 1]
    Image.fromarray(rgba).save(tmp_path / "rgba.png")
    assert np.array_equal(sources.load_image(tmp_path / "rgba.png", "128x96mm", "0:1mm").mask, hf.mask)
    # alpha as the height channel instead: no mask
    hf_a = sources.load_image(tmp_path / "rgba.png", "128x96mm", "0:1mm", channel="a")
    assert hf_a.mask is None and hf_a.heights.max() == pytest.approx(1e-3)


def test_sixteen_bit_colour_is_read_at_eight_bits_with_a_warning(tmp_path):
    rgb16 = (np.arange(4 * 5 * 3).reshape(4, 5, 3) * 1000).astype(">u2")
    raw = b"".join(b"\0" + row.tobytes() for row in rgb16)
    (tmp_path / "c16.png").write_bytes(_png_bytes(5, 4, 16, 2, raw))
    with pytest.warns(PictureWarning, match="16-bit-per-channel colour is read at 8 bits"):
        pic = read_picture(tmp_path / "c16.png", "r")
    assert np.array_equal(pic.values, (rgb16[..., 0] >> 8).astype(np.uint8))


# ----------------------------------------------------------------- normal maps
def _normal_map(rows=64, cols=80, dx=1e-4):
    """A smooth periodic surface, its slopes and its 8-bit tangent-space normal map (picture order)."""
    y, x = np.mgrid[0:rows, 0:cols] * dx
    Lx, Ly = cols * dx, rows * dx
    a = 0.3e-3
    h = a * np.sin(2 * np.pi * x / Lx) * np.cos(2 * np.pi * y / Ly)        # height-field order (row = y)
    p = a * 2 * np.pi / Lx * np.cos(2 * np.pi * x / Lx) * np.cos(2 * np.pi * y / Ly)
    q = -a * 2 * np.pi / Ly * np.sin(2 * np.pi * x / Lx) * np.sin(2 * np.pi * y / Ly)
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rgb = np.round((n + 1) / 2 * 255).astype(np.uint8)[::-1]                 # to picture order
    return h, p, q, rgb


def test_frankot_chellappa_recovers_an_analytic_surface():
    h, p, q, _ = _normal_map()
    z = frankot_chellappa(p, q, 1e-4, 1e-4)
    ref = h - h.mean()
    assert np.abs(z - ref).max() < 0.02 * np.ptp(ref)


def test_normal_map_is_recognised_refused_and_integrated_on_request(tmp_path):
    h, _, _, rgb = _normal_map()
    Image.fromarray(rgb).save(tmp_path / "n.png")
    assert looks_like_normal_map(rgb, 255.0)
    with pytest.raises(InputError, match=r"looks like a tangent-space normal map.*`--channel normal`"):
        sources.load_image(tmp_path / "n.png", "8x6.4mm", "0:1mm")
    hf = sources.load_image(tmp_path / "n.png", "8x6.4mm", None, channel="normal")
    ref = h - h.min()
    assert np.abs(hf.heights - ref).max() < 0.03 * np.ptp(ref)        # 8-bit normals: a few % of the relief
    assert any("Frankot-Chellappa" in n for n in hf.meta["notes"])
    fitted = sources.load_image(tmp_path / "n.png", "8x6.4mm", "0:2mm", channel="normal")
    assert fitted.heights.min() == pytest.approx(0) and fitted.heights.max() == pytest.approx(2e-3)
    photo = np.random.default_rng(0).integers(0, 256, (32, 32, 3)).astype(np.uint8)
    assert not looks_like_normal_map(photo, 255.0)
    Image.fromarray(photo).save(tmp_path / "photo.png")
    with pytest.raises(InputError, match="is not a tangent-space normal map"):
        sources.load_image(tmp_path / "photo.png", "8x8mm", None, channel="normal")


# ----------------------------------------------------------------- limits and bad files
def test_decompression_bomb_refused_from_the_header(tmp_path, monkeypatch):
    p = tmp_path / "huge.png"
    p.write_bytes(_png_bytes(100_000, 100_000, 16, 0, b"\0" * 10))
    write_png(tmp_path / "small.png", np.zeros((40, 30), np.uint8))

    def no_decode(*a, **k):
        raise AssertionError("pixel data must not be decoded")
    monkeypatch.setattr(Image.Image, "load", no_decode)
    monkeypatch.setattr("PIL.ImageFile.ImageFile.load", no_decode)
    with pytest.raises(InputError, match=r"refused before decoding: Image size \(10000000000 pixels\) exceeds"):
        read_picture(p)
    with pytest.raises(InputError, match="refused before decoding"):
        picture_info(p)
    # below Pillow's own limit ours applies, also before decoding
    monkeypatch.setattr("shapedisplay.author.heightfield.MAX_SAMPLES", 1000)
    with pytest.raises(InputError, match=r"30 x 40 = 1200 samples .* exceeds the limit of 1000"):
        read_picture(tmp_path / "small.png")


def test_corrupt_truncated_and_missing_files(tmp_path):
    write_png(tmp_path / "good.png", _asym())
    good = (tmp_path / "good.png").read_bytes()
    (tmp_path / "trunc.png").write_bytes(good[: len(good) - 30])
    (tmp_path / "junk.png").write_bytes(b"GIF89a" + b"\0" * 40)
    (tmp_path / "text.jpg").write_text("not a picture")
    with pytest.raises(FileFormatError, match="corrupt or truncated|not a picture"):
        read_picture(tmp_path / "trunc.png")
    with pytest.raises(FileFormatError, match="not a picture Pillow can read"):
        read_picture(tmp_path / "junk.png")
    with pytest.raises(FileFormatError, match="not a picture Pillow can read"):
        sources.load_image(tmp_path / "text.jpg", "1x1mm", "0:1mm")
    with pytest.raises(FileFormatError, match="no such file"):
        read_picture(tmp_path / "missing.png")
    with pytest.raises(FileFormatError, match="is a directory"):
        read_picture(tmp_path)
    write_png(tmp_path / "one.png", np.zeros((1, 1), np.uint8))
    with pytest.raises(InputError, match="at least 2 samples"):
        sources.load_image(tmp_path / "one.png", "1x1mm", "0:1mm")
    with pytest.raises(InputError, match="needs `height_range`"):
        sources.load_image(tmp_path / "good.png", "1x1mm", None)
    with pytest.raises(InputError, match="needs `--height`"):
        sources.load_image(tmp_path / "good.png", "1x1mm", None, flags={"height": "--height"})


def test_written_png_records_its_scale(tmp_path):
    write_png(tmp_path / "t.png", _asym(), text={"height_max_m": "0.002"})
    assert png_text(tmp_path / "t.png")["height_max_m"] == "0.002"
    assert np.array_equal(np.asarray(Image.open(tmp_path / "t.png")), _asym())


# ----------------------------------------------------------------- arrays and units
def test_npy_float_data_carry_a_unit_and_fit_under_height(tmp_path):
    rng = np.random.default_rng(7)
    nm = (rng.random((20, 30)) * 572).astype(np.float32)              # an AFM scan, nanometres
    m = nm.astype(np.float64) * 1e-9                                  # the same data in metres
    np.save(tmp_path / "nm.npy", nm)
    np.save(tmp_path / "m.npy", m)
    a = sources.load_image(tmp_path / "m.npy", "3x2um", None)
    b = sources.load_image(tmp_path / "nm.npy", "3x2um", None, z_units="nm")
    assert np.allclose(a.heights, b.heights, rtol=1e-15, atol=0)
    assert np.allclose(a.heights, m[::-1], rtol=0, atol=0)           # picture order, no rescaling
    fa = sources.load_image(tmp_path / "m.npy", "3x2um", "0:2mm")
    fb = sources.load_image(tmp_path / "nm.npy", "3x2um", "0:2mm", z_units="nm")
    assert fa.heights.min() == 0 and fa.heights.max() == pytest.approx(2e-3, rel=1e-15)
    assert np.allclose(fa.heights, fb.heights, rtol=1e-12, atol=1e-18)
    assert fb.meta["scale"]["source_unit"] == "nm"
    assert fb.meta["scale"]["m_per_unit"] == pytest.approx(2e-3 / (float(nm.max()) - float(nm.min())))
    assert fa.meta["scale"]["m_per_unit"] == pytest.approx(fb.meta["scale"]["m_per_unit"] * 1e9)


def test_npy_sources(tmp_path):
    h = np.linspace(0, 1e-3, 12).reshape(3, 4)
    np.save(tmp_path / "h.npy", h)
    hf = sources.load_image(tmp_path / "h.npy", "4x3mm", None)
    assert np.array_equal(hf.heights, h[::-1])
    hf = sources.load_image(tmp_path / "h.npy", None, None, resolution="0.5mm")
    assert hf.dx == 0.5e-3 and hf.size_m == pytest.approx((2e-3, 1.5e-3))
    np.save(tmp_path / "g.npy", np.array([[0, 65535]], dtype=np.uint16))
    assert np.allclose(sources.load_image(tmp_path / "g.npy", "2x1mm", "0:2mm").heights, [[0, 2e-3]])
    np.save(tmp_path / "nan.npy", np.array([[0.0, np.nan]]))
    with pytest.raises(InputError, match="must be finite"):
        sources.load_image(tmp_path / "nan.npy", "2x1mm", None)
    np.save(tmp_path / "cube.npy", np.zeros((2, 2, 2)))
    with pytest.raises(FileFormatError, match=r"shape \(rows, cols\)"):
        sources.load_image(tmp_path / "cube.npy", "2x1mm", None)
    np.save(tmp_path / "b.npy", np.zeros((2, 2), dtype=bool))
    with pytest.raises(FileFormatError, match="dtype bool is not supported"):
        sources.load_image(tmp_path / "b.npy", "2x1mm", None)
    (tmp_path / "junk.npy").write_bytes(b"garbage")
    with pytest.raises(FileFormatError, match="not a .npy file"):
        sources.load_image(tmp_path / "junk.npy", "2x1mm", None)
    np.save(tmp_path / "i8.npy", np.array([[-5, 100]], dtype=np.int8))
    with pytest.raises(FileFormatError, match=r"must be uint8 or uint16 gray codes"):
        sources.load_image(tmp_path / "i8.npy", "2x1mm", "0:1mm")
    with pytest.raises(InputError, match=r"`channel` applies to colour pictures"):
        sources.load_image(tmp_path / "h.npy", "4x3mm", None, channel="r")


@pytest.mark.parametrize("kind", ["8-bit", "16-bit", "16-bit big endian tiff", "interlaced", "grey+alpha"])
def test_grey_pictures_read_as_pillow_decodes_them(tmp_path, kind):
    """8- and 16-bit grey pictures in every layout: the pixels of numpy.asarray of the Pillow image."""
    g16 = (np.random.default_rng(2).integers(0, 65536, (37, 53))).astype(np.uint16)
    p = tmp_path / "m.png"
    if kind == "8-bit":
        write_png(p, (g16 >> 8).astype(np.uint8))
    elif kind == "16-bit":
        write_png(p, g16)
    elif kind == "16-bit big endian tiff":
        p = tmp_path / "m.tif"
        Image.frombytes("I;16B", (53, 37), g16.astype(">u2").tobytes()).save(p)
    elif kind == "interlaced":
        p.write_bytes(_adam7_gray8((g16 >> 8).astype(np.uint8)))
    else:
        Image.fromarray(np.dstack([(g16 >> 8).astype(np.uint8), np.full((37, 53), 255, np.uint8)]), "LA").save(p)
    with Image.open(p) as im:
        expected = np.asarray(im.convert("I;16") if im.mode == "I;16B" else im)
        expected = expected[..., 0] if expected.ndim == 3 else expected
    pic = read_picture(p)
    assert pic.values.dtype == expected.dtype and np.array_equal(pic.values, expected)
    if kind == "16-bit":
        assert np.array_equal(pic.values, g16) and pic.full_scale == 65535.0


def test_truncated_grey_png_is_refused(tmp_path):
    write_png(tmp_path / "good.png", np.arange(64 * 80, dtype=np.uint16).reshape(64, 80) * 7)
    good = (tmp_path / "good.png").read_bytes()
    (tmp_path / "trunc.png").write_bytes(good[: len(good) // 2])
    with pytest.raises(FileFormatError, match="corrupt or truncated"):
        read_picture(tmp_path / "trunc.png")


# ----------------------------------------------------------------- 16-bit grey PNG, the usual height-map file
def _paeth(a, b, c):
    p = a + b - c
    pa, pb, pc = np.abs(p - a), np.abs(p - b), np.abs(p - c)
    return np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))


def _filtered_gray16(g: np.ndarray, filters) -> bytes:
    """PNG image data of 16-bit grey pixels ``g``, row r filtered with filters[r] (0..4), as an encoder does:
    every predictor comes from the unfiltered bytes, so each row is filtered at once."""
    raw = g.astype(">u2").view(np.uint8).reshape(g.shape[0], -1).astype(np.int64)
    out = []
    prev = np.zeros(raw.shape[1], np.int64)
    for row, kind in zip(raw, filters):
        left = np.concatenate([[0, 0], row[:-2]])
        upleft = np.concatenate([[0, 0], prev[:-2]])
        pred = [0, left, prev, (left + prev) // 2, _paeth(left, prev, upleft)][kind]
        out.append(bytes([kind]) + ((row - pred) % 256).astype(np.uint8).tobytes())
        prev = row
    return b"".join(out)


def _gray16_png(g: np.ndarray, filters, pieces=1, seed=0) -> bytes:
    """A 16-bit grey PNG whose zlib stream is cut into ``pieces`` IDAT chunks at random places."""
    z = zlib.compress(_filtered_gray16(g, filters))
    cuts = sorted(np.random.default_rng(seed).integers(0, len(z) + 1, pieces - 1).tolist())
    ihdr = struct.pack(">IIBBBBB", g.shape[1], g.shape[0], 16, 0, 0, 0, 0)
    idat = b"".join(_chunk(b"IDAT", z[a:b]) for a, b in zip([0] + cuts, cuts + [len(z)]))
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + idat + _chunk(b"IEND", b"")


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (9, 1), (5, 3), (40, 33), (300, 260)])
@pytest.mark.parametrize("kind", [0, 1, 2, 3, 4, "mixed"])
def test_sixteen_bit_grey_png_reads_exactly_under_every_filter(tmp_path, shape, kind):
    """Every PNG filter, on pixels that carry and borrow in both bytes, in IDAT chunks cut anywhere: the
    stored codes exactly, as uint16 on the 0..65535 scale."""
    rng = np.random.default_rng(shape[0] * 100 + shape[1])
    g = rng.integers(0, 65536, shape).astype(np.uint16)
    g[0, 0], g.flat[-1] = 65535, 0
    filters = rng.integers(0, 5, shape[0]) if kind == "mixed" else [kind] * shape[0]
    p = tmp_path / "g.png"
    p.write_bytes(_gray16_png(g, filters, pieces=1 + shape[0] % 4))
    pic = read_picture(p)
    assert pic.values.dtype == np.uint16 and np.array_equal(pic.values, g)
    assert pic.full_scale == 65535.0 and pic.description == "grey 16-bit" and pic.mask is None and not pic.notes


def test_sixteen_bit_grey_png_written_with_text_reads_exactly(tmp_path):
    """A file Pillow's encoder wrote (its own choice of filters, text chunks before the data)."""
    g = (np.random.default_rng(5).normal(30000, 9000, (64, 70)).clip(0, 65535)).astype(np.uint16)
    write_png(tmp_path / "w.png", g, text={"height_max_m": "0.002"})
    pic = read_picture(tmp_path / "w.png")
    assert np.array_equal(pic.values, g) and pic.description == "grey 16-bit"
    assert png_text(tmp_path / "w.png") == {"height_max_m": "0.002"}


@pytest.mark.parametrize("damage", ["filter type 5", "truncated", "bad stream", "length past the end", "no data"])
def test_corrupt_sixteen_bit_grey_png_is_refused_or_read_as_pillow_reads_it(tmp_path, damage):
    """Damaged image data is refused with the reader's message (never pixels from memory nothing was decoded
    into); a chunk length past the end of the file is read as Pillow reads it: the whole stream."""
    g = np.arange(12 * 10, dtype=np.uint16).reshape(12, 10) * 500
    data = bytearray(_gray16_png(g, [4] * 12))
    if damage == "filter type 5":
        body = bytearray(_filtered_gray16(g, [4] * 12))
        body[21 * 5] = 5                                   # row 5's filter byte
        z = zlib.compress(bytes(body))
        ihdr = struct.pack(">IIBBBBB", 10, 12, 16, 0, 0, 0, 0)
        data = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", z) + _chunk(b"IEND", b"")
    elif damage == "truncated":
        data = data[:60]
    elif damage == "bad stream":
        data[50] ^= 0xFF
    elif damage == "length past the end":
        data[33:37] = struct.pack(">I", 1 << 30)            # the IDAT length
    else:
        data = data[:33] + _chunk(b"IEND", b"")
    p = tmp_path / "c.png"
    p.write_bytes(bytes(data))
    if damage == "length past the end":
        assert np.array_equal(read_picture(p).values, g)
        return
    with pytest.raises(FileFormatError, match=r"corrupt or truncated pixel data \(|not a picture Pillow can read"):
        read_picture(p)


def _with_chunk_before_data(png: bytes, kind: bytes, body: bytes, crc_ok=True) -> bytes:
    chunk = _chunk(kind, body)
    if not crc_ok:
        chunk = chunk[:-1] + bytes([chunk[-1] ^ 1])
    return png[:33] + chunk + png[33:]


@pytest.mark.parametrize("case", ["transparency", "animation", "critical chunk", "bad text CRC", "interlaced", "text"])
def test_other_sixteen_bit_grey_pngs(tmp_path, case):
    """Chunks around the image data: a grey transparency colour and unknown chunks change nothing, an
    animation reads its first frame (with a note), a chunk with a bad CRC before the data is refused."""
    g = (np.arange(9 * 11, dtype=np.uint16).reshape(9, 11) * 601)
    png = _gray16_png(g, [0, 1, 2, 3, 4, 4, 3, 2, 1])
    notes = []
    if case == "transparency":
        png = _with_chunk_before_data(png, b"tRNS", struct.pack(">H", 601))
    elif case == "animation":
        png = _with_chunk_before_data(png, b"acTL", struct.pack(">II", 1, 0))
        notes = ["first of 2 frames used"]
    elif case == "critical chunk":
        png = _with_chunk_before_data(png, b"ABCD", b"x")
    elif case == "bad text CRC":
        png = _with_chunk_before_data(png, b"tEXt", b"k\0v", crc_ok=False)
    elif case == "interlaced":
        # Adam7 passes 1 and 6 hold the two pixels: a filter byte and one big-endian sample each
        png, g = _png_bytes(2, 1, 16, 0, b"\0\0\1" + b"\0\0\2", interlace=1), np.array([[1, 2]], np.uint16)
    else:
        png = _with_chunk_before_data(png, b"tEXt", b"height_max_m\x000.002")
    p = tmp_path / "o.png"
    p.write_bytes(png)
    if case == "bad text CRC":
        with pytest.raises(FileFormatError, match="not a picture Pillow can read"):
            read_picture(p)
        return
    pic = read_picture(p)
    assert pic.values.dtype == np.uint16 and np.array_equal(pic.values, g) and pic.full_scale == 65535.0
    assert pic.mask is None and pic.description == "grey 16-bit" and pic.notes == notes


def test_sixteen_bit_grey_png_over_the_sample_limit_is_refused_from_its_header(tmp_path, monkeypatch):
    """The size limit is checked from the header, before anything is decoded: a file whose image data is
    damaged is refused for its size, not for its data."""
    data = bytearray(_gray16_png(np.zeros((30, 40), np.uint16), [0] * 30))
    data[50] ^= 0xFF
    p = tmp_path / "big.png"
    p.write_bytes(bytes(data))
    with pytest.raises(FileFormatError, match="corrupt or truncated"):
        read_picture(p)
    monkeypatch.setattr("shapedisplay.author.heightfield.MAX_SAMPLES", 1000)
    with pytest.raises(InputError, match=r"40 x 30 = 1200 samples .* exceeds the limit of 1000"):
        read_picture(p)


def test_pictures_are_read_through_pillow_public_api_only():
    """No private attribute of a Pillow image, and no second PNG decoder beside Pillow's."""
    import inspect

    import shapedisplay.author.imageio as imageio
    source = inspect.getsource(imageio)
    assert "im.im" not in source and "._im" not in source and "import deflate" not in source
