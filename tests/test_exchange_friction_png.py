"""Friction bitmaps (export --format friction-png): values, scale sidecar, top-view orientation."""
import json

import numpy as np
import pytest
from PIL import Image

from shapedisplay.table.devices import load_device
from shapedisplay.exchange import export_table
from shapedisplay.exchange.friction_png import export_friction_png, quantity_map, read_friction_png
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
from shapedisplay.cli.main import main


def corner_table(with_scale=True):
    """N = 0.5 N with a 3 N bump near the upper-left corner (small x, large y); friction_scale 1.2 there."""
    rows, cols, d = 30, 40, 0.5e-3
    yy, xx = np.mgrid[0:rows, 0:cols] * d
    bump = np.exp(-(((xx - 4e-3) / 1.5e-3) ** 2 + ((yy - 11e-3) / 1.5e-3) ** 2))
    ch = {"normal_force": 0.5 + 2.5 * bump, "friction_scale": 1.0 + 0.2 * bump}
    if not with_scale:
        del ch["friction_scale"]
    q = {n: choose_quantization(v, "float64") for n, v in ch.items()}
    meta = {"device": load_device(None).to_json(), "mapping": {"slope_friction_gain": 0.3}}
    return FrictionTable.from_dense(Grid(rows, cols, d, d, 1e-3, 2e-3), ch, q, meta), bump


@pytest.mark.parametrize("bits", [8, 16])
@pytest.mark.parametrize("quantity", ["mu", "normal_force", "breakaway_force"])
def test_values_round_trip_within_half_a_grey_step(tmp_path, bits, quantity):
    t, bump = corner_table()
    p = export_friction_png(t, tmp_path / "f.png", quantity, bits)
    with Image.open(p) as im:
        assert im.size == (40, 30) and im.mode == ("L" if bits == 8 else "I;16")
        grey = np.array(im)
    assert grey.min() == 0 and grey.max() == (1 << bits) - 1      # full range
    v, info = read_friction_png(p)
    mu_s = load_device(None).friction.mu_s
    exact = {"mu": mu_s * (1 + 0.2 * bump), "normal_force": 0.5 + 2.5 * bump,
             "breakaway_force": mu_s * (1 + 0.2 * bump) * (0.5 + 2.5 * bump)}[quantity]
    assert np.max(np.abs(v - exact)) <= info["max_error"] * (1 + 1e-9) + 1e-12
    assert info["max_error"] == pytest.approx((exact.max() - exact.min()) / ((1 << bits) - 1) / 2)
    assert info["pixel_m"] == [0.5e-3, 0.5e-3] and info["origin_m"] == [1e-3, 2e-3]
    assert any("K_mu = 0.3" in s for s in info["lost"])


def test_image_is_the_top_view(tmp_path):
    """The bump at small x, large y appears at the image's top-left."""
    t, _ = corner_table()
    p = export_friction_png(t, tmp_path / "f.png", "normal_force", 8)
    grey = np.array(Image.open(p))
    r, c = np.unravel_index(np.argmax(grey), grey.shape)
    assert r < 15 and c < 20
    assert (r, c) == (30 - 1 - round(11e-3 / 0.5e-3), round(4e-3 / 0.5e-3))


def test_cli_export_friction_png_and_option_rules(tmp_path, capsys):
    t, _ = corner_table()
    src = t.save(tmp_path / "t.npz")
    out = tmp_path / "f.png"
    assert main(["export", str(src), "--format", "friction-png", "-o", str(out), "--quantity", "mu"]) == 0
    info = json.loads((tmp_path / "f.png.json").read_text())
    assert info["quantity"] == "mu" and info["bits"] == 16 and info["unit"] == "1"
    code = main(["export", str(src), "--format", "friction-png", "-o", str(tmp_path / "g.png"), "--quantity", "mus"])
    err = capsys.readouterr().err
    assert code == 2 and "mus" in err and not (tmp_path / "g.png").exists()
    code = main(["export", str(src), "--format", "json", "-o", str(tmp_path / "g.json"), "--bits", "8"])
    assert code == 2 and "--bits" in capsys.readouterr().err and not (tmp_path / "g.json").exists()
    with pytest.raises(Exception, match="8 or 16"):
        export_table(t, tmp_path / "h.png", "friction-png", bits=12)
    assert not (tmp_path / "h.png").exists()


def test_constant_mu_table_gives_a_flat_image_with_its_value(tmp_path):
    t, _ = corner_table(with_scale=False)
    v = quantity_map(t, "mu")
    assert np.all(v == load_device(None).friction.mu_s)
