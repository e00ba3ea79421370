"""SVG icons as pictures: drawn by resvg, read like a PNG, checked before drawing.

The icons are written here the way icon libraries ship them (a 24 x 24
viewBox, ``currentColor`` or black paths and strokes on a transparent
background, groups with transforms, ``fill-rule="evenodd"`` rings). The
height fields are checked against the shapes' exact areas and widths, in
units of one raster pixel.
"""
from __future__ import annotations

import base64
import io
import math
import time
import warnings

import numpy as np
import pytest

pytest.importorskip("resvg_py")

from shapedisplay.author import vector                                        # noqa: E402
from shapedisplay.author.imageio import picture_info, read_picture             # noqa: E402
from shapedisplay.author.sources import load_image, source_kind                # noqa: E402
from shapedisplay.errors import FileFormatError, InputError, MissingDependencyError   # noqa: E402

NS = 'xmlns="http://www.w3.org/2000/svg"'
XLINK = 'xmlns:xlink="http://www.w3.org/1999/xlink"'


def _icon(tmp_path, body, root=f'{NS} width="24" height="24" viewBox="0 0 24 24"', name="icon.svg"):
    p = tmp_path / name
    p.write_text(f"<svg {root}>{body}</svg>")
    return p


def _raised(hf, level=0.5e-3):
    """Fraction of samples above ``level`` (half the 0..1 mm range) and the mask of them, picture order."""
    up = np.asarray(hf.heights)[::-1] > level
    return up.mean(), up


# ------------------------------------------------------------------ shapes, exactly
def test_filled_circle_icon_has_the_circle_area_within_a_pixel(tmp_path):
    """A currentColor circle of r = 8 in a 24 viewBox: raised area = pi r^2 / 24^2 within one pixel's rim."""
    p = _icon(tmp_path, '<circle cx="12" cy="12" r="8"/>', root=f'{NS} width="24" height="24" viewBox="0 0 24 24" '
                                                                 'fill="currentColor"')
    hf = load_image(p, "20x20mm", "0:1mm")
    assert hf.heights.shape == (512, 512)                            # the default raster: 512 along the longer side
    assert hf.dx == pytest.approx(0.02 / 512) and hf.dy == pytest.approx(0.02 / 512)
    frac, up = _raised(hf)
    exact = math.pi * 8 ** 2 / 24 ** 2
    rim = 2 * math.pi * (8 / 24 * 512) / 512 ** 2                   # one pixel along the circumference
    assert abs(frac - exact) < rim, (frac, exact, rim)
    assert hf.heights[256, 256] == pytest.approx(1e-3) and hf.heights[5, 5] == 0.0
    assert any("alpha" in n for n in hf.meta["notes"])               # one colour: the shape is its alpha


def test_stroke_icon_has_the_stroke_width_and_a_group_transform_turns_it(tmp_path):
    """Feather-style stroke icons: stroke-width 2 of 24 is 2/24 x 512 = 42.7 pixels across."""
    root = (f'{NS} width="24" height="24" viewBox="0 0 24 24" fill="none" stroke="currentColor" stroke-width="2" '
            f'stroke-linecap="round"')
    flat = load_image(_icon(tmp_path, '<line x1="4" y1="12" x2="20" y2="12"/>', root), "24x24mm", "0:1mm")
    _, up = _raised(flat)
    assert abs(up[:, 256].sum() - 2 / 24 * 512) <= 1.0               # across the line, at its middle
    assert abs(up[256, :].sum() - 18 / 24 * 512) <= 1.0              # along it: 16 + two round caps of 1
    turned = load_image(_icon(tmp_path, '<g transform="rotate(90 12 12)"><line x1="4" y1="12" x2="20" y2="12"/></g>',
                              root, "turned.svg"), "24x24mm", "0:1mm")
    _, up_t = _raised(turned)
    assert np.array_equal(up_t, up.T)                                # the same line, upright


def test_evenodd_ring_has_a_low_hole_and_nonzero_fills_it(tmp_path):
    ring = ('<path fill-rule="{rule}" d="M12 2a10 10 0 1 0 0 20a10 10 0 1 0 0-20z '
            'M12 6a6 6 0 1 0 0 12a6 6 0 1 0 0-12z"/>')
    even = load_image(_icon(tmp_path, ring.format(rule="evenodd")), "20x20mm", "0:1mm")
    frac, up = _raised(even)
    assert not up[256, 256] and up[256, 256 + int(8 / 24 * 512)]     # the hole low, the ring (r = 8) raised
    exact = math.pi * (10 ** 2 - 6 ** 2) / 24 ** 2
    assert abs(frac - exact) < 2 * math.pi * (10 + 6) / 24 / 512
    full = load_image(_icon(tmp_path, ring.format(rule="nonzero"), name="nonzero.svg"), "20x20mm", "0:1mm")
    assert _raised(full)[1][256, 256]                                # both circles drawn the same way round


def test_translate_and_scale_in_a_group_move_the_shape(tmp_path):
    """A 4 x 4 square translated to (16, 2) and scaled 1.5: 6 x 6 units at the top right, y down the picture."""
    p = _icon(tmp_path, '<g transform="translate(16 2) scale(1.5)"><rect width="4" height="4"/></g>')
    _, up = _raised(load_image(p, "24x24mm", "0:1mm"))
    rows, cols = np.nonzero(up)
    k = 512 / 24
    assert rows.min() == pytest.approx(2 * k, abs=1) and rows.max() + 1 == pytest.approx(8 * k, abs=1)
    assert cols.min() == pytest.approx(16 * k, abs=1) and cols.max() + 1 == pytest.approx(22 * k, abs=1)


def test_black_on_transparent_icon_reads_its_alpha_as_heights(tmp_path):
    """The end-to-end case: one colour on a transparent background -> alpha as heights, no mask, smooth rim."""
    one = _icon(tmp_path, '<rect x="4" y="4" width="16" height="16" rx="3"/>', name="one.svg")
    pic = read_picture(one)
    assert "alpha" in pic.description and pic.mask is None
    hf = load_image(one, "24x24mm", "0:1mm")
    h = np.unique(np.round(hf.heights * 1e6))
    assert h[0] == 0 and h[-1] == 1000 and len(h) > 3                 # antialiased rim: heights between


def test_coloured_icon_gives_its_shape_through_the_alpha_channel(tmp_path):
    p = _icon(tmp_path, '<circle cx="12" cy="12" r="8" fill="#1976d2"/>')
    for channel in (None, "a"):                        # one colour, any colour: alpha is read by default
        hf = load_image(p, "20x20mm", "0:1mm", channel=channel)
        frac, _ = _raised(hf)
        assert abs(frac - math.pi * 8 ** 2 / 24 ** 2) < 2 * math.pi * (8 / 24 * 512) / 512 ** 2
    assert any("alpha channel" in n for n in load_image(p, "20x20mm", "0:1mm").meta["notes"])


def test_raw_raster_is_rgba_with_the_shape_in_alpha(tmp_path):
    im = vector.rasterise_svg(_icon(tmp_path, '<circle cx="12" cy="12" r="8"/>'), pixels=(64, 64))
    a = np.asarray(im)
    assert im.mode == "RGBA" and a.shape == (64, 64, 4)
    assert a[32, 32, 3] == 255 and a[0, 0, 3] == 0 and (a[..., :3][a[..., 3] > 0] == 0).all()


# ------------------------------------------------------------------ size and resolution
@pytest.mark.parametrize("width, height, view_box, expect_mm", [
    ("20mm", "10mm", "0 0 24 12", (20, 10)),
    ("2cm", "1cm", None, (20, 10)),
    ("1in", "0.5in", None, (25.4, 12.7)),
    ("72pt", "36pt", None, (25.4, 12.7)),
    ("20mm", None, "0 0 24 12", (20, 10)),           # the other side follows the viewBox
    ("24", "24", "0 0 24 24", None),                  # screen pixels are not a length
    ("24px", "24px", None, None),
    ("100%", "100%", "0 0 24 24", None),
    ("20mm", "24", None, None),                       # half a length is none
    (None, None, "0 0 24 24", None),
])
def test_stated_physical_size(tmp_path, width, height, view_box, expect_mm):
    attrs = " ".join(f'{k}="{v}"' for k, v in (("width", width), ("height", height), ("viewBox", view_box)) if v)
    p = _icon(tmp_path, '<circle cx="12" cy="6" r="5"/>', root=f"{NS} {attrs}")
    got = vector.svg_size(p)
    if expect_mm is None:
        assert got is None
    else:
        assert got == pytest.approx((expect_mm[0] * 1e-3, expect_mm[1] * 1e-3))


def test_icon_with_a_size_in_mm_needs_no_size_and_resolution_sets_its_raster(tmp_path):
    p = _icon(tmp_path, '<rect x="2" y="2" width="20" height="8" rx="2"/>',
              root=f'{NS} width="20mm" height="10mm" viewBox="0 0 24 12"')
    hf = load_image(p, None, "0:1mm")
    assert hf.heights.shape == (256, 512) and hf.dx * 512 == pytest.approx(0.02)
    fine = load_image(p, None, "0:1mm", resolution="0.1mm")
    assert fine.heights.shape == (100, 200) and fine.dx == pytest.approx(1e-4) and fine.dy == pytest.approx(1e-4)
    stretched = load_image(p, "40x10mm", "0:1mm", resolution="0.5mm")   # a given size wins; the drawing is stretched
    assert stretched.heights.shape == (40, 80) and stretched.dx * 80 == pytest.approx(0.04)
    px = load_image(_icon(tmp_path, '<circle cx="12" cy="12" r="8"/>', name="px.svg"), None, None)
    assert px.dx * px.heights.shape[1] == pytest.approx(24 * 0.0254 / 96)       # 24 CSS px: 6.35 mm
    assert np.ptp(px.heights) == pytest.approx(2e-3)                            # the icon default, 0:2 mm
    assert any("at CSS 96 px/in" in n for n in px.meta["notes"])
    assert any("default of an SVG icon" in n for n in px.meta["notes"])


def test_raster_keeps_the_proportions_and_covers_the_grid():
    assert vector.raster_size((48, 24)) == (512, 256)
    assert vector.raster_size((24, 48)) == (256, 512)
    assert vector.raster_size((48, 24), (100, 100)) == (200, 100)     # at least 100 each way, proportions kept
    assert vector.raster_size((1e6, 1)) == (512, 1)


def test_picture_info_reports_the_default_raster(tmp_path):
    info = picture_info(_icon(tmp_path, '<circle cx="12" cy="12" r="8"/>', root=f'{NS} viewBox="0 0 48 24"'))
    assert (info["cols"], info["rows"], info["mode"]) == (512, 256, "RGBA")


def test_text_is_not_drawn_and_filters_are_not_applied_with_a_warning(tmp_path):
    p = _icon(tmp_path, '<defs><filter id="f"><feGaussianBlur stdDeviation="3"/></filter></defs>'
                        '<text x="1" y="20" font-size="20">A</text><rect x="6" y="6" width="12" height="12" '
                        'filter="url(#f)"/>')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        a = np.asarray(vector.rasterise_svg(p, pixels=(48, 48)))
    msgs = [str(w.message) for w in caught if issubclass(w.category, vector.VectorWarning)]
    assert any("1 <text> element(s) not drawn" in m for m in msgs)
    assert any("filters not applied (1 <filter> element(s), 1 element(s) with a filter)" in m for m in msgs)
    assert (a[..., 3] > 0).sum() == 24 * 24                           # the square, unblurred; no letter


def test_embedded_png_data_uri_is_drawn(tmp_path):
    from PIL import Image
    buf = io.BytesIO()
    Image.new("RGBA", (8, 8), (0, 0, 0, 255)).save(buf, "PNG")
    uri = "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()
    p = _icon(tmp_path, f'<image x="0" y="0" width="12" height="24" href="{uri}"/>')
    a = np.asarray(vector.rasterise_svg(p, pixels=(48, 48)))
    assert a[24, 6, 3] == 255 and a[24, 40, 3] == 0


# ------------------------------------------------------------------ icons and mock-ups, by content
def test_icon_is_a_picture_and_a_mockup_a_scene(tmp_path):
    assert source_kind(_icon(tmp_path, '<circle cx="12" cy="12" r="8"/>')) == "image"
    fa = _icon(tmp_path, '<path d="M0 0h5v5z"/>', name="fa.svg",
               root=f'{NS} viewBox="0 0 512 512" data-prefix="fas" data-icon="house" class="svg-inline--fa"')
    assert source_kind(fa) == "image"                                 # data-* that are not shapedisplay's
    assert source_kind(_icon(tmp_path, '<rect id="button-a" width="5" height="5"/>', name="ids.svg")) == "svg"
    assert source_kind(_icon(tmp_path, '<rect class="sd-slider" width="5" height="5"/>', name="cls.svg")) == "svg"
    assert source_kind(_icon(tmp_path, '<rect width="5" height="5"/>', name="res.svg",
                             root=f'{NS} width="20mm" height="20mm" data-resolution="0.5 mm"')) == "svg"
    assert source_kind(tmp_path / "missing.svg") == "svg"             # the loader says it is missing


def test_widget_type_names_are_the_registry():
    from shapedisplay.author.scene.fields import WIDGET_TYPE_NAMES
    from shapedisplay.author.scene.widgets import WIDGET_TYPES
    assert WIDGET_TYPE_NAMES == tuple(WIDGET_TYPES)


def test_cli_compiles_an_icon_and_still_compiles_a_mockup(tmp_path, capsys):
    from pathlib import Path

    from shapedisplay.cli.main import main
    from shapedisplay.table.model import FrictionTable
    p = _icon(tmp_path, '<circle cx="12" cy="12" r="8"/>', root=f'{NS} width="24" height="24" viewBox="0 0 24 24" '
                                                                 'fill="currentColor"')
    out = tmp_path / "T.npz"
    assert main(["compile", str(p), "--size", "20x20mm", "--height", "0:1mm", "-o", str(out), "-q"]) == 0
    t = FrictionTable.load(out)
    n = t.sample("normal_force", np.array([0.010, 0.001]), np.array([0.010, 0.001]))
    assert n[0] > n[1]                                                # the disc is felt
    capsys.readouterr()
    assert main(["compile", str(p), "-o", str(tmp_path / "U.npz")]) == 0       # no option: 24 px, 0:2 mm
    out = capsys.readouterr().out
    assert "the SVG's 24 x 24 px at CSS 96 px/in (give `--size`" in out and "give `--height` to choose" in out
    u = FrictionTable.load(tmp_path / "U.npz")
    assert u.grid.dx * u.grid.cols == pytest.approx(6.35e-3)
    mock = Path(__file__).resolve().parent.parent / "assets" / "scenes" / "settings-mockup.svg"
    assert source_kind(mock) == "svg"
    assert main(["compile", str(mock), "-o", str(tmp_path / "M.npz"), "-q"]) == 0
    assert "scene" in FrictionTable.load(tmp_path / "M.npz").meta


def test_scene_image_widget_takes_an_svg_drawn_on_the_canvas_grid(tmp_path):
    from shapedisplay.author.scene import compile_scene, load_scene
    _icon(tmp_path, '<circle cx="12" cy="12" r="8"/>')
    scene = tmp_path / "s.toml"
    scene.write_text('[canvas]\nsize = "40x20 mm"\nresolution = "0.5 mm"\n\n'
                     '[[widget]]\nid = "home"\ntype = "image"\nfile = "icon.svg"\nposition = "5,5 mm"\n'
                     'size = "10x10 mm"\nheight = "0:1 mm"\n')
    s = load_scene(scene)
    assert s.widgets[0].params["values"].shape == (21, 21)           # one pixel a canvas sample of the box
    t = compile_scene(scene).table
    xs = np.array([0.010, 0.0055, 0.030])                            # the disc's centre, the box's corner, outside
    n = t.sample("normal_force", xs, np.full(3, 0.010))
    assert n[0] > n[1] + 0.3 and n[1] == pytest.approx(n[2])         # felt in the middle, flat ground around


def test_studio_opens_an_icon_as_a_picture(tmp_path):
    pytest.importorskip("starlette")
    from shapedisplay.studio.session import Session
    p = _icon(tmp_path, '<circle cx="12" cy="12" r="8"/>')
    s = Session(p, options={"size": "20x20mm", "height": "0:1mm"}, out_dir=tmp_path / "o")
    assert s.kind == "image" and s.compile(), s.error


# ------------------------------------------------------------------ hostile and foreign files: one line each
HOSTILE = {
    "absolute href": ('<image href="/etc/passwd" width="24" height="24"/>', FileFormatError,
                      r"<image> number 2 refers to '/etc/passwd'; an SVG picture is read alone"),
    "relative xlink:href": (f'<g {XLINK}><image id="pic" xlink:href="../x.png" width="24" height="24"/></g>',
                            FileFormatError, r"<image> 'pic' refers to '\.\./x\.png'"),
    "file URL on use": ('<use href="file:///etc/passwd#x"/>', FileFormatError, r"<use> number 2 refers to 'file:"),
    "feImage": ('<filter id="f"><feImage href="/etc/hosts"/></filter>', FileFormatError, r"<feImage> number 3 refers"),
    "script": ("<script>alert(1)</script>", FileFormatError, r"<script> number 2 is refused: .* no script"),
    "foreignObject": ('<foreignObject width="5" height="5"><div xmlns="http://www.w3.org/1999/xhtml">x</div>'
                      '</foreignObject>', FileFormatError, r"<foreignObject> number 2 is refused"),
    "SVG in a data URI": ('<image href="data:image/svg+xml;utf8,&lt;svg/&gt;" width="24" height="24"/>',
                          FileFormatError, r"data: URI holds no PNG, JPEG, GIF or WebP picture"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_icon_is_refused_in_one_line_naming_file_and_element(tmp_path, case):
    body, exc, pattern = HOSTILE[case]
    p = _icon(tmp_path, body)
    for read in (lambda: vector.rasterise_svg(p), lambda: load_image(p, "20x20mm", "0:1mm")):
        with pytest.raises(exc, match=pattern) as info:
            read()
        assert "\n" not in str(info.value) and "icon.svg" in str(info.value)


def test_entity_tricks_are_refused(tmp_path):
    decl = '<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY p "/etc/passwd">]>'
    p = tmp_path / "ent.svg"
    p.write_text(decl + f'<svg {NS} viewBox="0 0 24 24"><image href="&p;" width="24" height="24"/></svg>')
    with pytest.raises(FileFormatError, match=r"refers to '/etc/passwd'"):      # expanded before it is checked
        vector.rasterise_svg(p)
    laughs = "".join(f'<!ENTITY l{i + 1} "{f"&l{i};" * 10}">' for i in range(9))
    p.write_text(f'<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY l0 "ha">{laughs}]><svg {NS}><text>&l9;</text></svg>')
    for read in (lambda: vector.rasterise_svg(p), lambda: source_kind(p)):
        with pytest.raises(FileFormatError, match=r"cannot read the SVG \(limit on input amplification") as info:
            read()
        assert "\n" not in str(info.value)
    p.write_text(f'<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY x SYSTEM "file:///etc/passwd">]><svg {NS}>'
                 f'<text>&x;</text></svg>')
    with pytest.raises(FileFormatError, match=r"undefined entity"):
        vector.rasterise_svg(p)


def test_hundred_thousand_elements_are_refused_before_drawing(tmp_path):
    from shapedisplay.author.scene.svg import MAX_SVG_ELEMENTS
    p = _icon(tmp_path, '<rect width="1" height="1"/>' * 100_000)
    t = time.perf_counter()
    with pytest.raises(FileFormatError, match=rf"more than {MAX_SVG_ELEMENTS} elements, the limit"):
        load_image(p, "20x20mm", "0:1mm")
    assert time.perf_counter() - t < 5.0


def test_huge_rasters_are_refused_before_drawing(tmp_path):
    p = _icon(tmp_path, '<circle cx="12" cy="12" r="8"/>', root=f'{NS} width="100000mm" height="100000mm" '
                                                                 f'viewBox="0 0 24 24"')
    t = time.perf_counter()
    with pytest.raises(InputError, match=r"drawn as pixels: grid of 1000000 x 1000000 .* exceeds the limit .*MAX_SAMPLES"):
        load_image(p, None, "0:1mm", resolution="0.1mm")
    with pytest.raises(InputError, match=r"more than Pillow reads"):
        vector.rasterise_svg(p, pixels=(15000, 15000))
    many = _icon(tmp_path, '<rect width="1" height="1"/>' * 10_000, name="many.svg")
    with pytest.raises(InputError, match=r"element-pixels, more than the limit .*MAX_RASTER_WORK"):
        vector.rasterise_svg(many, pixels=(1000, 1000))
    assert time.perf_counter() - t < 5.0
    with pytest.raises(InputError, match=r"`pixels` must be \(cols, rows\)"):
        vector.rasterise_svg(p, pixels=(0, 10))


def test_embedded_picture_past_the_limits_is_refused_from_its_header(tmp_path):
    import struct
    import zlib
    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    ihdr = struct.pack(">IIBBBBB", 100_000, 100_000, 8, 0, 0, 0, 0)        # 10^10 grey pixels announced
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 1000)) + chunk(b"IEND", b"")
    uri = "data:image/png;base64," + base64.b64encode(png).decode()
    p = _icon(tmp_path, f'<image width="24" height="24" href="{uri}"/>')
    with pytest.raises(InputError, match=r"<image> number 2's data: URI: refused before decoding|exceeds the limit"):
        vector.rasterise_svg(p)


def test_big_file_and_broken_files_are_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr(vector, "MAX_SVG_BYTES", 1000)
    p = _icon(tmp_path, '<rect width="1" height="1"/>' * 100)
    with pytest.raises(FileFormatError, match=r"more than the limit of .* MiB for an SVG picture"):
        vector.rasterise_svg(p)
    monkeypatch.undo()
    (tmp_path / "broken.svg").write_text(f"<svg {NS}><rect")
    with pytest.raises(FileFormatError, match=r"cannot read the SVG"):
        load_image(tmp_path / "broken.svg", "20x20mm", "0:1mm")
    (tmp_path / "page.svg").write_text("<html><body/></html>")
    with pytest.raises(FileFormatError, match=r"not an SVG \(its root element is <html>\)"):
        vector.rasterise_svg(tmp_path / "page.svg")
    with pytest.raises(FileFormatError, match=r"no such file"):
        load_image(tmp_path / "missing.svg", "20x20mm", "0:1mm")


@pytest.mark.parametrize("suffix", [".pdf", ".eps", ".ai", ".ps", ".emf", ".wmf"])
def test_other_vector_formats_get_the_export_advice(tmp_path, suffix, capsys):
    from shapedisplay.cli.main import main
    p = tmp_path / f"icon{suffix}"
    p.write_bytes(b"%!PS")
    advice = rf"{suffix} \(.*\) is a vector format shapedisplay does not read; export it as SVG or PNG"
    for read in (lambda: load_image(p, "20x20mm", "0:1mm"), lambda: source_kind(p)):
        with pytest.raises(InputError, match=advice):
            read()
    assert main(["compile", str(p), "--size", "20x20mm", "-o", str(tmp_path / "t.npz")]) == 2
    err = capsys.readouterr().err
    assert "export it as SVG or PNG" in err and "did you mean" not in err


def test_svgz_and_the_scene_widget_get_the_advice(tmp_path):
    from shapedisplay.author.scene import load_scene
    from shapedisplay.author.scene.fields import SceneError
    (tmp_path / "icon.svgz").write_bytes(b"\x1f\x8b")
    with pytest.raises(InputError, match=r"gzip-compressed SVG .*gunzip -c 'icon.svgz' > 'icon.svg'"):
        source_kind(tmp_path / "icon.svgz")
    (tmp_path / "logo.pdf").write_bytes(b"%PDF-1.4")
    scene = tmp_path / "s.toml"
    scene.write_text('[canvas]\nsize = "40x20 mm"\nresolution = "0.5 mm"\n\n[[widget]]\ntype = "image"\n'
                     'file = "logo.pdf"\nposition = "5,5 mm"\nsize = "10x10 mm"\n')
    with pytest.raises(SceneError, match=r"`widget\[0\]\.file`: .*\.pdf \(PDF\) is a vector format .*export it as SVG"):
        load_scene(scene)


def test_missing_resvg_names_the_extra(tmp_path, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "resvg_py", None)
    with pytest.raises(MissingDependencyError, match=r"pip install 'shapedisplay\[svg\]'"):
        vector.rasterise_svg(_icon(tmp_path, '<circle cx="12" cy="12" r="8"/>'))
