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


# ------------------------------------------------------------------ the default quantity carries the shape
PHONE = __import__("pathlib").Path(__file__).resolve().parent.parent / "assets" / "scenes" / "phone.toml"


@pytest.fixture(scope="module")
def phone(tmp_path_factory):
    out = tmp_path_factory.mktemp("phone") / "phone.npz"
    assert main(["compile", str(PHONE), "-o", str(out), "-q"]) == 0
    return out


def test_phone_bitmap_shows_its_buttons_with_no_option(phone, tmp_path, capsys):
    out = tmp_path / "phone.png"
    assert main(["export", str(phone), "--format", "friction-png", "-o", str(out)]) == 0
    assert "warning" not in capsys.readouterr().err
    grey = np.array(Image.open(out))
    info = json.loads((tmp_path / "phone.png.json").read_text())
    assert info["quantity"] == "breakaway_force" and info["quantity_rule"].startswith("mu is uniform")
    levels = np.unique(grey)
    assert len(levels) > 3 and grey.min() == 0 and grey.max() == 65535
    # the grey levels are mu_s N: the buttons stand out where N does
    t = FrictionTable.load(phone)
    v, _ = read_friction_png(out)
    from shapedisplay.exchange.export import device_of
    mu_s = device_of(t.meta).friction.mu_s
    assert np.max(np.abs(v - mu_s * np.maximum(t.dense("normal_force"), 0))) <= info["max_error"] * (1 + 1e-9)


def test_flat_bitmap_is_written_with_a_warning_naming_what_shows(phone, tmp_path, capsys):
    out = tmp_path / "mu.png"
    assert main(["export", str(phone), "--format", "friction-png", "-o", str(out), "--quantity", "mu"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("shapedisplay export: warning: friction bitmap of mu is flat (0.5 everywhere)")
    assert "normal_force or breakaway_force shows the table's shape (--quantity)" in err[0]
    assert len(np.unique(np.array(Image.open(out)))) == 1


def test_auto_picks_mu_where_mu_varies(tmp_path):
    from shapedisplay.exchange.friction_png import bitmap_choices, choose_quantity
    t, bump = corner_table()
    assert choose_quantity(t)[0] == "mu"
    _, info = read_friction_png(export_friction_png(t, tmp_path / "f.png"))
    assert info["quantity"] == "mu" and info["quantity_rule"] == "mu varies over the table"
    plain, _ = corner_table(with_scale=False)
    assert bitmap_choices(plain) == {"auto": "breakaway_force", "flat": ["mu"],
                                     "rule": "mu is uniform: the shape is in N, shown as the friction level mu_s N"}
