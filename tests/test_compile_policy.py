"""One compile policy: the CLI, the studio's session and the API give the same table for the same source."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import shapedisplay as sd
from shapedisplay.errors import InputError, ShapeDisplayError
from shapedisplay.studio.session import Session

ROOT = Path(__file__).resolve().parent.parent
ASSETS = ROOT / "assets"


def cli(*argv) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "shapedisplay", *map(str, argv)], capture_output=True, text=True)


def cli_checksum(source, out, *options) -> str:
    res = cli("compile", source, "-o", out, "-q", *options)
    assert res.returncode == 0, res.stderr
    res = cli("inspect", out, "--json")
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout)["checksum"]


def _flags(options: dict) -> list[str]:
    return [a for k, v in options.items() for a in ("--" + k.replace("_", "-"), v)]


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    d = tmp_path_factory.mktemp("sources")
    shutil.copy(ASSETS / "meshes" / "keycap.stl", d / "keycap.stl")
    shutil.copy(ASSETS / "maps" / "tent_profile.png", d / "tent.png")
    shutil.copy(ASSETS / "scenes" / "keypad.toml", d / "keypad.toml")
    # a haptic glb: a table exported with its textures
    res = cli("compile", d / "tent.png", "-o", d / "tent.npz", "-q", "--size", "60x4mm", "--height", "0:2mm")
    assert res.returncode == 0, res.stderr
    res = cli("export", d / "tent.npz", "--format", "glb", "-o", d / "tent.glb")
    assert res.returncode == 0, res.stderr
    return d


CASES = {
    "mesh": ("keycap.stl", {"resolution": "0.2mm", "up": "z"}),       # fitted to the force range
    "image": ("tent.png", {"size": "60x4mm", "height": "0:2mm", "n_base": "0.5N", "n_gain": "2N/mm"}),
    "scene": ("keypad.toml", {}),                                       # its own [device] and [mapping]
    "haptic glb": ("tent.glb", {}),                                     # rebuilt from its textures
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_cli_studio_and_api_give_the_same_table(sources, tmp_path, case):
    name, options = CASES[case]
    src = sources / name
    from_cli = cli_checksum(src, tmp_path / "cli.npz", *_flags(options))
    session = Session(src, options=options, out_dir=tmp_path / "studio-out")
    assert session.compile(), session.error
    from_api = sd.compile(src, **options)
    assert session.state()["checksum"] == from_cli == from_api.checksum


def test_studio_fits_a_mesh_to_the_force_range_as_compile_does(tmp_path):
    """A mesh taller than the device renders is fitted to its force range in the studio too (as compile does)."""
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(20.0, 20.0, 15.0))      # mm: 15 mm of relief is far above 10 N
    box.apply_translation((15.0, 15.0, 7.5))
    box.export(tmp_path / "block.stl")
    session = Session(tmp_path / "block.stl", options={"resolution": "0.5mm"}, out_dir=tmp_path / "o")
    assert session.compile(), session.error
    table = session.current.table
    n = table.dense("normal_force")
    lo, hi = sd.load_device(None).normal_force_range
    assert n.max() <= hi and n.max() == pytest.approx(hi, rel=1e-9)      # the top at the ceiling, not above
    assert table.checksum == sd.compile(tmp_path / "block.stl", resolution="0.5mm").checksum


def test_policy_refuses_what_does_not_apply_naming_the_option_as_written(sources):
    with pytest.raises(InputError, match=r"`n_base` applies to"):
        sd.compile(sources / "keypad.toml", n_base="1N")
    with pytest.raises(InputError, match=r"`size` does not apply to .*haptic textures"):
        sd.compile(sources / "tent.glb", size="10x10mm")
    with pytest.raises(InputError, match=r"did you mean 'n_gain'"):
        sd.compile(sources / "tent.png", size="60x4mm", n_gian="2N/mm")
    res = cli("compile", sources / "keypad.toml", "-o", sources / "x.npz", "--n-base", "1N")
    assert res.returncode == 2 and "`--n-base` applies to" in res.stderr and "Traceback" not in res.stderr
    assert not (sources / "x.npz").exists()


def test_play_events_carry_position_force_and_widget(sources):
    t = sd.compile(sources / "keypad.toml")
    widgets = {w["id"]: w["bbox_m"] for w in t.meta["scene"]["widgets"]}
    r = t.play("5,30 -> 115,30 @ 40mm/s", model="exact")
    ev = r.events
    assert len(ev) == r.event_time.size > 0
    for e in ev:
        assert np.isclose(e.x, np.interp(e.t, r.t, r.x)) and np.isclose(e.y, np.interp(e.t, r.t, r.y))
        k = int(np.searchsorted(r.t, e.t))
        assert e.normal_force == r.normal_force[k]
        inside = [w for w, (x0, y0, x1, y1) in widgets.items() if x0 <= e.x <= x1 and y0 <= e.y <= y1]
        assert (e.widget is None) == (not inside) and (e.widget is None or e.widget in inside)
    assert {e.widget for e in ev} - {None}, "a stroke across the keypad crosses keys"


def test_play_takes_strings_arrays_and_the_tables_tick_rate(sources):
    t = sd.load(sources / "tent.npz")
    assert isinstance(t, sd.Table)
    a = t.play("0,2 -> 60,2 @ 20mm/s")
    assert a.tick_rate == t.meta["device"]["tick_rate_hz"]
    rows = np.column_stack([a.t, a.x, a.y])
    b = t.play(rows)
    assert np.array_equal(a.event_time, b.event_time) and np.array_equal(a.audio, b.audio)
    c = t.play("0,2 -> 60,2 @ 20mm/s", tick_rate="5kHz")
    assert c.tick_rate == 5000.0
    with pytest.raises(ShapeDisplayError, match="shape"):
        t.play(np.zeros((4, 2)))
