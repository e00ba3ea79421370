"""The compile / inspect / export commands, and every bad input: exit 2, one line, no partial output."""
import json
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.author.imageio import write_png
from shapedisplay.cli.main import main

ROOT = Path(__file__).resolve().parent.parent
TENT = ROOT / "assets" / "maps" / "tent_profile.png"
DEMO = ["--size", "60x4mm", "--height", "0:2mm", "--mapping", "height", "--n-base", "0.5N", "--n-gain", "2N/mm"]


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_demo_compile_inspect_export(tmp_path, capsys):
    t = tmp_path / "t.npz"
    code, out, err = run(["compile", TENT, "-o", t, *DEMO], capsys)
    assert code == 0 and t.is_file(), err
    assert "normal_force" in out and "left out" in out
    code, out, _ = run(["inspect", t, "--json"], capsys)
    s = json.loads(out)
    # 40 identical rows: one 600-sample uint8 row is stored and placed on every row
    assert code == 0 and s["stored_bytes"] == 600 and s["dense_bytes"] == 40 * 600 * 10 * 4
    assert list(s["channels"]) == ["normal_force"]
    code, out, _ = run(["inspect", t], capsys)
    assert code == 0 and "left out:" in out and "lateral_x" in out and "stored 600 bytes" in out
    code, _, _ = run(["export", t, "--format", "json", "-o", tmp_path / "t.json"], capsys)
    doc = json.loads((tmp_path / "t.json").read_text())
    assert code == 0 and doc["grid"]["cols"] == 600 and doc["grid"]["dx_m"] == pytest.approx(1e-4)
    n = np.array(doc["channels"]["normal_force"]["values"])
    assert doc["channels"]["normal_force"]["unit"] == "N" and n.shape == (40, 600)
    assert n.min() == pytest.approx(0.5) and n.max() == pytest.approx(4.5, abs=0.02)
    code, _, _ = run(["export", t, "--format", "c", "-o", tmp_path / "t.h"], capsys)
    assert code == 0 and "static const uint8_t t_normal_force_codes" in (tmp_path / "t.h").read_text()


def test_mapping_gains_and_device_options(tmp_path, capsys):
    t = tmp_path / "b.npz"
    code, out, err = run(["compile", ROOT / "assets/maps/buttons.png", "-o", t, "--size", "60x24mm",
                          "--height", "0:1mm", "--device", "desktop-rig", "--mapping", "height+lateral+slope",
                          "--lateral-gain", "0.8N", "--slope-gain", "0.3", "--gradient", "gaussian",
                          "--sigma", "0.3mm", "--max-slope", "2", "--json"], capsys)
    assert code == 0, err
    rep = json.loads(out)
    assert rep["kept"] == ["normal_force", "grad_x", "grad_y", "lateral_x", "lateral_y"]
    from shapedisplay.table.model import FrictionTable
    meta = FrictionTable.load(t).meta
    assert meta["mapping"]["lateral_gain"] == 0.8 and meta["mapping"]["slope_friction_gain"] == 0.3
    assert meta["compile"]["gradient_method"] == "gaussian"
    assert meta["compile"]["gradient_kw"]["sigma"] == pytest.approx(3e-4)


def _bad_png(tmp_path, name, fields, payload=b"\0" * 40):
    import struct

    def chunk(ctype, body):
        return struct.pack(">I", len(body)) + ctype + body + struct.pack(">I", zlib.crc32(ctype + body) & 0xFFFFFFFF)
    p = tmp_path / name
    p.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", *fields))
                  + chunk(b"IDAT", zlib.compress(payload)) + chunk(b"IEND", b""))
    return p


def _cases(tmp_path):
    write_png(tmp_path / "ok.png", np.arange(12, dtype=np.uint8).reshape(3, 4))
    write_png(tmp_path / "one.png", np.zeros((1, 1), np.uint8))
    (tmp_path / "corrupt.png").write_bytes((tmp_path / "ok.png").read_bytes()[:30])
    good_bytes = bytearray((tmp_path / "ok.png").read_bytes())
    i = good_bytes.index(b"IDAT") + 6
    good_bytes[i] ^= 0xFF
    (tmp_path / "crc.png").write_bytes(bytes(good_bytes))
    from PIL import Image
    flat = np.zeros((8, 8, 3), np.uint8) + np.array([128, 128, 255], np.uint8)
    Image.fromarray(flat).save(tmp_path / "normals.png")
    np.save(tmp_path / "nan.npy", np.array([[0.0, np.inf], [0.0, 0.0]]))
    np.save(tmp_path / "empty.npy", np.zeros((0, 3)))
    ok = tmp_path / "ok.png"
    good = ["--size", "4x3mm", "--height", "0:1mm"]
    dev = tmp_path / "dev.toml"
    dev.write_text('[device]\nname = "x"\n[friction]\nmu_s = 0.4\nmu_k = 0.6\n')
    dev2 = tmp_path / "dev2.toml"
    dev2.write_text('[device]\nname = "x"\ntick_rte = "1 kHz"\n')
    return {
        "missing image": ([tmp_path / "missing.png", *good], "no such file"),
        "corrupt image": ([tmp_path / "corrupt.png", *good], "not a picture Pillow can read"),
        "short pixel data": ([_bad_png(tmp_path, "short.png", (40, 30, 8, 2, 0, 0, 0)), *good],
                             "corrupt or truncated pixel data"),
        "bad CRC": ([tmp_path / "crc.png", *good], "corrupt or truncated pixel data"),
        "huge image": ([_bad_png(tmp_path, "huge.png", (90000, 90000, 16, 0, 0, 0, 0)), *good],
                       "refused before decoding"),
        "normal map without channel": ([tmp_path / "normals.png", *good], "`--channel normal`"),
        "unknown channel option": ([ok, *good, "--channel", "green"], "unknown image channel 'green'"),
        "z units of gray codes": ([ok, *good, "--z-units", "nm"], "`--z-units` applies to float data"),
        "NaN heights": ([tmp_path / "nan.npy", "--size", "2x2mm"], "must be finite"),
        "empty map": ([tmp_path / "empty.npy", "--size", "2x2mm"], "at least 2 samples"),
        "one pixel": ([tmp_path / "one.png", *good], "at least 2 samples"),
        "negative size": ([ok, "--size=-4x3mm", "--height", "0:1mm"], "`--size` must be positive"),
        "zero size": ([ok, "--size", "0x3mm", "--height", "0:1mm"], "`--size` must be positive"),
        "zero resolution": ([ok, "--resolution", "0mm", "--height", "0:1mm"], "`--resolution` must be a length > 0"),
        "bare number": ([ok, *good, "--n-gain", "2"], "`--n-gain` needs a unit"),
        "unknown unit": ([ok, *good, "--n-gain", "2 N/furlong"], "unknown unit 'furlong'"),
        "wrong dimension": ([ok, *good, "--n-base", "2 mm"], "`--n-base` must be a force"),
        "mu_k > mu_s": ([ok, *good, "--device", dev], "`mu_k` must be <= `mu_s` (got mu_k=0.6, mu_s=0.4)"),
        "unknown device key": ([ok, *good, "--device", dev2], "unknown [device] key 'tick_rte' (did you mean 'tick_rate'?)"),
        "unknown device": ([ok, *good, "--device", "desktop-rug"], "(did you mean 'desktop-rig'?)"),
        "unknown channel": ([ok, *good, "--keep", "lateral_xx"], "unknown channel 'lateral_xx'"),
        "unknown mapping": ([ok, *good, "--mapping", "hieght"], "(did you mean 'height'?)"),
        "unknown gradient": ([ok, *good, "--gradient", "centrl"], "(did you mean 'central'?)"),
        "option of another gradient method": ([ok, *good, "--sigma", "1mm"], "unknown option of gradient method 'central' 'sigma'"),
        "missing size": ([ok, "--height", "0:1mm"], "needs `--size`"),
        "mesh option on image": ([ok, *good, "--up", "y"], "`--up` applies to meshes"),
        "unknown source": ([tmp_path / "x.pgn", *good], f"source '{tmp_path / 'x.pgn'}': unknown source type '.pgn'"),
        "size and resolution": ([ok, *good, "--resolution", "1mm"], "give `--size` or `--resolution`, not both"),
        "huge gaussian sigma": ([ok, *good, "--gradient", "gaussian", "--sigma", "1km"], "must not exceed the map extent"),
        "mapping gain on a scene": ([ROOT / "assets/scenes/phone.toml", "--n-gain", "2N/mm"], "`--n-gain` applies to images and meshes"),
        "picture option on a scene": ([ROOT / "assets/scenes/phone.toml", "--z-units", "nm"],
                                      "`--z-units` applies to image sources, not to"),
    }


def test_every_bad_input_exits_2_with_one_line_and_no_output(tmp_path, capsys):
    for name, (argv, message) in _cases(tmp_path).items():
        out_file = tmp_path / f"out_{name.replace(' ', '_')}.npz"
        code, out, err = run(["compile", *argv, "-o", out_file], capsys)
        assert code == 2, (name, out, err)
        lines = err.strip().split("\n")
        assert len(lines) == 1 and lines[0].startswith("shapedisplay compile: error: "), (name, err)
        assert message in lines[0], (name, lines[0])
        assert "Traceback" not in err
        assert not out_file.exists(), name
    leftovers = [p.name for p in tmp_path.iterdir() if ".part" in p.name]
    assert leftovers == []


def _table_file(tmp_path, capsys):
    t = tmp_path / "t.npz"
    assert run(["compile", TENT, "-o", t, *DEMO, "-q"], capsys)[0] == 0
    return t


def test_bad_tables(tmp_path, capsys):
    t = _table_file(tmp_path, capsys)
    with np.load(t) as z:
        header = json.loads(bytes(z["header"]).decode())
        codes = z["normal_force"].copy()
    from shapedisplay.table.model import _checksum
    h2 = dict(header, format_version=2)
    h2["checksum"] = _checksum(h2, {"normal_force": codes})
    np.savez(tmp_path / "v2.npz", header=np.frombuffer(json.dumps(h2).encode(), np.uint8), normal_force=codes)
    codes[5] += 1
    np.savez(tmp_path / "bad.npz", header=np.frombuffer(json.dumps(header).encode(), np.uint8), normal_force=codes)
    for cmd in (["inspect"], ["export", "--format", "json", "-o", tmp_path / "x.json"]):
        code, _, err = run([cmd[0], tmp_path / "v2.npz", *cmd[1:]], capsys)
        assert code == 2 and "format_version must be 1 (got 2)" in err and len(err.strip().split("\n")) == 1
        code, _, err = run([cmd[0], tmp_path / "bad.npz", *cmd[1:]], capsys)
        assert code == 2 and "checksum mismatch" in err
    assert not (tmp_path / "x.json").exists()
    code, _, err = run(["export", t, "--format", "yaml", "-o", tmp_path / "x.yaml"], capsys)
    assert code == 2 and "unknown export format 'yaml'" in err and not (tmp_path / "x.yaml").exists()


def test_foreign_tables_with_recomputed_checksum_never_trace_back(tmp_path, capsys):
    """inspect/export on headers that pass the checksum but not the format: one line, exit 2."""
    from shapedisplay.table.model import _checksum
    t = _table_file(tmp_path, capsys)
    with np.load(t) as z:
        header = json.loads(bytes(z["header"]).decode())
        codes = z["normal_force"].copy()

    def write(name, edit):
        h = json.loads(json.dumps(header))
        edit(h)
        h.pop("checksum")
        h["checksum"] = _checksum(h, {"normal_force": codes})
        np.savez(tmp_path / name, header=np.frombuffer(json.dumps(h).encode(), np.uint8), normal_force=codes)
        return tmp_path / name

    cases = {
        write("blocks.npz", lambda h: h.update(blocks=[[0, 0]])): "each block",
        write("chan.npz", lambda h: h["channels"].update(bogus=h["channels"].pop("normal_force"))): "unknown channel",
        write("dev.npz", lambda h: h.update(device="x")): "'device' must be an object",
        write("grid.npz", lambda h: h["grid"].update(rows=10 ** 6, cols=10 ** 6)): "exceeds the limit",
    }
    for path, message in cases.items():
        for cmd in (["inspect"], ["inspect", "--json"], ["export", "--format", "c", "-o", tmp_path / "x.h"]):
            code, _, err = run([cmd[0], path, *cmd[1:]], capsys)
            assert code == 2 and message in err and len(err.strip().split("\n")) == 1, (path, cmd, err)
    assert not (tmp_path / "x.h").exists()
    # a header without mapping gains or a numeric tick rate still prints
    sparse = write("sparse.npz", lambda h: (h.update(mapping={"spec": "height"}), h["device"].pop("tick_rate_hz")))
    code, out, err = run(["inspect", sparse], capsys)
    assert code == 0 and "mapping: height (n_base ? N" in out and "tick ? Hz" in out, err
    code, _, err = run(["export", sparse, "--format", "c", "-o", tmp_path / "s.h"], capsys)
    assert code == 0 and "n_base_n" not in (tmp_path / "s.h").read_text()


def test_console_script_and_light_imports(tmp_path):
    exe = Path(sys.executable).parent / "shapedisplay"
    r = subprocess.run([str(exe), "compile", str(TENT), "-o", str(tmp_path / "t.npz"), *DEMO],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-m", "shapedisplay", "inspect", str(tmp_path / "t.npz")],
                       capture_output=True, text=True)
    assert r.returncode == 0 and "normal_force" in r.stdout
    code = ("import sys, shapedisplay, shapedisplay.author.compile, shapedisplay.author.sources, shapedisplay.exchange.export; "
            "import shapedisplay.cli.main as m; m.build_parser(); "
            "print([k for k in ('trimesh', 'pyvista', 'serial', 'matplotlib') if k in sys.modules])")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]"


def test_mesh_source_passes_mesh_options(tmp_path, capsys):
    t = tmp_path / "k.npz"
    code, out, err = run(["compile", ROOT / "assets/meshes/keycap.stl", "-o", t, "--resolution", "0.5mm",
                          "--up", "z", "--units", "mm", "--device", "desktop-rig", "--mapping", "height+lateral",
                          "--json"], capsys)
    assert code == 0, err
    rep = json.loads(out)
    assert rep["grid"]["dx_m"] == pytest.approx(0.5e-3)
    assert rep["kept"] == ["normal_force", "lateral_x", "lateral_y"]
    code, _, err = run(["compile", ROOT / "assets/meshes/keycap.stl", "-o", tmp_path / "bad.npz",
                        "--resolution=-1mm"], capsys)
    assert code == 2 and "`--resolution` must be a length > 0" in err and not (tmp_path / "bad.npz").exists()


def test_stretch_perceptual_and_coding_options(tmp_path, capsys):
    from shapedisplay.table.model import FrictionTable
    t = tmp_path / "s.npz"
    code, out, err = run(["compile", TENT, "-o", t, "--size", "60x4mm", "--height", "0:0.4mm",
                          "--device", "skin-stretch-tactor", "--mapping", "height+stretch+perceptual",
                          "--n-base", "1N", "--n-gain", "1N/mm", "--skin-stretch", "0.4mm",
                          "--perceptual", "bumpiness", "--quantize", "uint16", "--json"], capsys)
    assert code == 0, err
    rep = json.loads(out)
    assert rep["kept"] == ["normal_force", "skin_stretch"]
    assert rep["quantization"]["normal_force"]["dtype"] == "uint16"
    table = FrictionTable.load(t)
    n, s = table.dense("normal_force"), table.dense("skin_stretch")
    assert n.min() == pytest.approx(1.0) and n.max() == pytest.approx(1.4, abs=2e-3)   # 1 N + 1 N/mm * 0.4 mm (apex between samples)
    assert np.allclose(s, 0.4e-3 * n / 1.0, atol=2 * rep["quantization"]["skin_stretch"]["max_error"] + 1e-9)
    assert table.meta["mapping"]["perceptual_exponent"] == 0.76
