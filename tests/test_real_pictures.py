"""Pictures as tools write them: normal maps baked the way map generators do, at several JPEG qualities,
resampled and painted by hand; icons exported on a transparent background. Each reads as what it is, or
the user is told what to pass -- never a silent wrong relief or a flat widget."""
from __future__ import annotations

import io
import warnings

import numpy as np
import pytest
from PIL import Image, ImageFilter
from scipy import ndimage

from shapedisplay.author import sources
from shapedisplay.author.imageio import PictureWarning, normal_map_stats, normal_map_verdict
from shapedisplay.cli.main import main
from shapedisplay.errors import InputError

RNG_SEED = 7


def _relief(rows=192, cols=256, seed=RNG_SEED):
    """Bumps and dents with fine noise, in picture order (height units: pixels)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:rows, 0:cols].astype(float)
    h = np.zeros((rows, cols))
    for _ in range(12):
        cx, cy, r, a = rng.uniform(0, cols), rng.uniform(0, rows), rng.uniform(8, 30), rng.uniform(-6, 6)
        h += a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * r * r))
    return h + 0.5 * rng.standard_normal(h.shape)


def _baked(h, strength=1.0):
    """An 8-bit tangent-space map as generators bake it: Sobel slopes, normalised, (n + 1) / 2 * 255,
    green = +y up the picture."""
    gx, gy = ndimage.sobel(h, 1) / 8, ndimage.sobel(h, 0) / 8
    n = np.stack([-strength * gx, strength * gy, np.ones_like(h)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return np.round((n + 1) / 2 * 255).astype(np.uint8)


def _jpeg(rgb, quality):
    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, "JPEG", quality=quality)
    return np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))


def _painted(rgb, seed=RNG_SEED):
    """Soft brush strokes of hand-picked colours blended over the map, then blurred (a painted detail)."""
    rng = np.random.default_rng(seed)
    out = rgb.astype(float)
    rows, cols = rgb.shape[:2]
    y, x = np.mgrid[0:rows, 0:cols]
    for _ in range(40):
        cx, cy, r = rng.uniform(0, cols), rng.uniform(0, rows), rng.uniform(10, 40)
        col = np.array([rng.uniform(40, 216), rng.uniform(40, 216), rng.uniform(150, 255)])
        a = 0.7 * np.clip(1 - np.hypot(x - cx, y - cy) / r, 0, 1)[..., None]
        out = out * (1 - a) + col * a
    return np.asarray(Image.fromarray(out.round().astype(np.uint8)).filter(ImageFilter.GaussianBlur(3)))


def _short_vectors(rgb, seed=RNG_SEED):
    """A map whose vectors are as short as a real one's: |n| with median 0.81, 5-95 % about 0.59-1.07."""
    rng = np.random.default_rng(seed)
    n = rgb.astype(float) * (2 / 255) - 1
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    s = ndimage.gaussian_filter(rng.standard_normal(rgb.shape[:2]), 6)
    s = 0.81 + 0.145 * s / s.std()
    return np.clip(np.round((n * s[..., None] + 1) / 2 * 255), 0, 255).astype(np.uint8)


MAPS = {
    "baked png": lambda h: _baked(h),
    **{f"baked jpeg q{q}": (lambda q: lambda h: _jpeg(_baked(h), q))(q) for q in (95, 75, 50, 25)},
    "resampled": lambda h: np.asarray(Image.fromarray(_baked(h)).resize((96, 72), Image.LANCZOS)),
    "painted": lambda h: _painted(_baked(h)),
    "painted jpeg q60": lambda h: _jpeg(_painted(_baked(h)), 60),
    "short vectors": lambda h: _short_vectors(_baked(h)),
    "short vectors jpeg q80": lambda h: _jpeg(_short_vectors(_baked(h)), 80),
}


@pytest.mark.parametrize("name", MAPS)
def test_real_normal_maps_are_recognised(tmp_path, name, capsys):
    rgb = MAPS[name](_relief())
    assert normal_map_verdict(rgb, 255.0)[0] == "normal", normal_map_stats(rgb, 255.0)
    path = tmp_path / ("n.jpg" if "jpeg" in name else "n.png")
    Image.fromarray(rgb).save(path, quality=100) if path.suffix == ".jpg" else Image.fromarray(rgb).save(path)
    with pytest.raises(InputError, match=r"normal map.*`--channel normal`"):
        sources.load_image(path, "25.6x19.2mm", "0:1mm")
    rc = main(["compile", str(path), "-o", str(tmp_path / "t.npz"), "--size", "25.6x19.2mm", "--height", "0:1mm"])
    err = capsys.readouterr().err
    assert rc == 2 and "--channel normal" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "t.npz").exists()


def test_short_vector_map_has_the_statistics_of_a_real_one():
    n = _short_vectors(_baked(_relief())).astype(float) * (2 / 255) - 1
    length = np.linalg.norm(n, axis=-1)
    assert np.median(length) == pytest.approx(0.81, abs=0.02)
    assert np.percentile(length, 5) == pytest.approx(0.59, abs=0.05)
    assert np.percentile(length, 95) == pytest.approx(1.05, abs=0.05)


def test_real_normal_map_integrates_to_the_relief_it_was_baked_from(tmp_path):
    h = _relief()
    path = tmp_path / "n.png"          # lossless: JPEG's block errors integrate into a drift of the relief
    Image.fromarray(_short_vectors(_baked(h))).save(path)
    hf = sources.load_image(path, "25.6x19.2mm", None, channel="normal")
    ref = ndimage.gaussian_filter(h, 1.0)[::-1]              # height-field order; Sobel slopes are smoothed
    inner = (slice(10, -10), slice(10, -10))                 # Frankot-Chellappa wraps at the edges
    assert np.corrcoef(hf.heights[inner].ravel(), ref[inner].ravel())[0, 1] > 0.99


def test_steep_jpeg_map_warns_with_both_channels(tmp_path):
    rgb = _jpeg(_baked(_relief(), strength=4.0), 75)        # half the map steeper than 45 degrees
    assert normal_map_verdict(rgb, 255.0)[0] == "maybe", normal_map_stats(rgb, 255.0)
    path = tmp_path / "steep.png"
    Image.fromarray(rgb).save(path)
    with pytest.warns(PictureWarning, match=r"may be a tangent-space normal map.*--channel normal.*--channel luminance"):
        hf = sources.load_image(path, "25.6x19.2mm", "0:1mm")
    assert any("may be a normal map" in n for n in hf.meta["notes"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sources.load_image(path, "25.6x19.2mm", "0:1mm", channel="luminance")    # the user decided: no warning


def test_map_stored_in_another_range_warns(tmp_path):
    """A map darkened to two thirds (three.js's water normals: mean colour (85, 85, 167)) is no longer made
    of outward unit vectors, but every pixel is blue: a warning, not a silent luminance relief."""
    rgb = np.round(_baked(_relief()) * (2 / 3)).astype(np.uint8)
    verdict, st = normal_map_verdict(rgb, 255.0)
    assert verdict == "maybe" and st["facing"] < 0.6 and st["blue"] > 0.9, st
    Image.fromarray(rgb).save(tmp_path / "water.png")
    with pytest.warns(PictureWarning, match="may be a tangent-space normal map"):
        sources.load_image(tmp_path / "water.png", "20x20mm", "0:1mm")


def _not_maps():
    rng = np.random.default_rng(3)
    h = _relief()
    g = ((h - h.min()) / np.ptp(h) * 255).astype(np.uint8)
    ui = np.full((120, 200, 3), 245, np.uint8)
    ui[20:60, 20:90] = (0, 122, 255)
    ui[70:110, 100:180] = (52, 199, 89)
    photo = ndimage.gaussian_filter(rng.uniform(0, 255, (96, 128, 3)), (4, 4, 0))
    photo = np.clip((photo - photo.mean()) * 6 + np.array([120, 110, 90]), 0, 255).astype(np.uint8)
    return {"grey relief as RGB": np.repeat(g[..., None], 3, -1), "screenshot": ui,
            "noise": rng.integers(0, 256, (64, 64, 3)).astype(np.uint8), "smooth photo": photo,
            "photo jpeg": _jpeg(photo, 70)}


@pytest.mark.parametrize("name", list(_not_maps()))
def test_pictures_of_heights_are_not_taken_for_normal_maps(tmp_path, name):
    rgb = _not_maps()[name]
    assert normal_map_verdict(rgb, 255.0)[0] is None, normal_map_stats(rgb, 255.0)
    Image.fromarray(rgb).save(tmp_path / "p.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PictureWarning)
        sources.load_image(tmp_path / "p.png", "20x20mm", "0:1mm")


# ------------------------------------------------------------------ icons on a transparent background
def _icon(mode, colour, size=128, r=40):
    """A filled, anti-aliased disc of one colour on a transparent background (drawn at 4x, reduced)."""
    big = Image.new("L", (size * 4, size * 4), 0)
    from PIL import ImageDraw
    c = size * 2
    ImageDraw.Draw(big).ellipse([c - 4 * r, c - 4 * r, c + 4 * r, c + 4 * r], fill=255)
    alpha = big.resize((size, size), Image.LANCZOS)
    if mode == "LA":
        im = Image.merge("LA", [Image.new("L", (size, size), colour), alpha])
    else:
        im = Image.merge("RGBA", [Image.new("L", (size, size), c_) for c_ in colour] + [alpha])
    return im


@pytest.mark.parametrize("mode,colour", [("RGBA", (0, 0, 0)), ("RGBA", (255, 255, 255)), ("RGBA", (0, 122, 255)),
                                         ("LA", 0)])
def test_icon_on_transparent_background_reads_its_alpha(tmp_path, mode, colour):
    path = tmp_path / "icon.png"
    _icon(mode, colour).save(path)
    hf = sources.load_image(path, "20x20mm", "0:1mm")
    assert any("alpha channel" in n for n in hf.meta["notes"])
    raised = hf.heights > 0.5e-3
    assert raised.mean() == pytest.approx(np.pi * 40 ** 2 / 128 ** 2, abs=0.01)     # the disc, area to 1 %
    assert hf.heights.max() == pytest.approx(1e-3) and hf.heights.min() == pytest.approx(0.0)


def test_icon_in_a_scene_image_widget_is_felt(tmp_path):
    _icon("RGBA", (0, 0, 0)).save(tmp_path / "icon.png")
    scene = tmp_path / "s.toml"
    scene.write_text('[canvas]\nsize = "40x30 mm"\nresolution = "0.25 mm"\n\n'
                     '[[widget]]\ntype = "image"\nid = "icon"\nfile = "icon.png"\nposition = "10,5 mm"\n'
                     'size = "20x20 mm"\nheight = "0:1 mm"\n')
    out = tmp_path / "t.npz"
    assert main(["compile", str(scene), "-o", str(out), "-q"]) == 0
    from shapedisplay.table import FrictionTable
    n = FrictionTable.load(out).dense("normal_force")
    assert np.ptp(n) > 0.1                                     # a relief, not a flat widget


def test_uniform_alpha_or_varying_colour_keeps_the_mask_rule(tmp_path):
    im = _icon("RGBA", (0, 0, 0))
    arr = np.array(im)
    arr[..., 0] = np.linspace(0, 255, 128, dtype=np.uint8)[None, :]      # colour varies: heights from luminance
    Image.fromarray(arr).save(tmp_path / "c.png")
    hf = sources.load_image(tmp_path / "c.png", "20x20mm", "0:1mm")
    assert any("alpha used as mask" in n for n in hf.meta["notes"])


def test_normal_map_beyond_the_integration_limit_is_refused_before_integrating(tmp_path, monkeypatch):
    from shapedisplay.author import imageio
    monkeypatch.setattr(imageio, "MAX_NORMAL_MAP_SAMPLES", 64 * 64)
    Image.fromarray(_baked(_relief(rows=65, cols=64))).save(tmp_path / "n.png")
    with pytest.raises(InputError, match=r"a normal map of 64 x 65 pixels; .*at most 4096 pixels.*resample the map"):
        sources.load_image(tmp_path / "n.png", "20x20mm", None, channel="normal")
    Image.fromarray(_baked(_relief(rows=64, cols=64))).save(tmp_path / "m.png")
    assert sources.load_image(tmp_path / "m.png", "20x20mm", None, channel="normal").heights.shape == (64, 64)
