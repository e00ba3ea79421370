"""The compiled C engine as the package loads it: a missing or stale library is one line, play needs no numba."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.errors import InputError
from shapedisplay.render import native
from shapedisplay.render.cursor import parse_stroke
from shapedisplay.render.renderer import Renderer
from shapedisplay.author.scene import compile_scene
from shapedisplay.cli.main import main

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "assets" / "scenes"


@pytest.fixture(scope="module")
def phone():
    return compile_scene(SCENES / "phone.toml").table


def test_a_table_without_normal_force_plays_the_headers_constant(tmp_path):
    """A slope-only mapping stores no normal_force: every model plays the header's constant N (1.5 N here)."""
    from shapedisplay.table.model import FrictionTable
    src = tmp_path / "ramp.npy"
    np.save(src, np.tile(np.r_[np.zeros(40), np.linspace(0.0, 1e-3, 40)], (3, 1)))
    out = tmp_path / "t.npz"
    assert main(["compile", str(src), "--size", "80x3mm", "--mapping", "slope", "--n-base", "1.5N",
                 "--device", "linear-slider", "-o", str(out), "-q"]) == 0
    table = FrictionTable.load(out)
    assert "normal_force" not in table.channels
    for model in ("exact", "jump", "karnopp"):
        r = Renderer(table, model=model)
        assert r.normal_force_constant == 1.5
        res = r.render(parse_stroke("0,1 <-> 80,1 @ 20mm/s", r.tick_rate))
        assert res.event_time.size >= (20 if model != "karnopp" else 2) and np.all(res.normal_force == 1.5), model


def test_a_missing_compiled_engine_is_one_line_with_the_reinstall_hint(phone, tmp_path, monkeypatch, capsys):
    """The C engine is compiled at install (shapedisplay._engine): a broken install without it, or with a file
    that does not load, is refused in one line naming the module or the file; nothing falls back."""
    monkeypatch.setattr(native, "EXTENSION", "shapedisplay._no_such_engine")
    monkeypatch.setattr(native, "_LIB", None)
    with pytest.raises(InputError, match="_no_such_engine.*missing.*reinstall") as exc:
        Renderer(phone, model="jump")
    assert "\n" not in str(exc.value)
    table = phone.save(tmp_path / "phone.npz")
    capsys.readouterr()
    assert main(["play", str(table), "--stroke", "62,2 -> 62,30 @ 30mm/s", "-o", str(tmp_path / "o.wav")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "reinstall" in err and not (tmp_path / "o.wav").exists()
    # a library file that does not load (say, cut short by a full disk): one line naming it
    cut = tmp_path / "engine.so"
    cut.write_bytes(b"\x7fELF cut short")
    monkeypatch.setattr(native, "library_path", lambda: cut)
    with pytest.raises(InputError, match="reinstall") as exc:
        Renderer(phone, model="jump")
    assert str(cut) in str(exc.value) and "\n" not in str(exc.value)
    monkeypatch.setattr(native, "_LIB", None)


def test_play_imports_no_numba_and_no_scipy(tmp_path):
    """What keeps a warm play short: playing a table never loads numba (nor scipy, which numba pulls in)."""
    table = tmp_path / "phone.npz"
    assert main(["compile", str(SCENES / "phone.toml"), "-o", str(table)]) == 0
    code = ("import sys\nfrom shapedisplay.cli.main import main\n"
            f"rc = main(['play', {str(table)!r}, '--stroke', '62,2 -> 62,60 @ 30mm/s', '-o', "
            f"{str(tmp_path / 'o.wav')!r}])\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'scipy', 'llvmlite'})\n"
            "print(rc, heavy)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "stick-slip events" in out and out.strip().endswith("0 []"), out


def test_in_a_checkout_a_library_older_than_its_sources_is_refused(tmp_path, monkeypatch):
    """An editable install does not rebuild a changed C source by itself: the stale library is refused with
    the command that rebuilds it (an installed package is never checked)."""
    from shapedisplay import extensions
    pkg = tmp_path / "shapedisplay"
    pkg.mkdir()
    (tmp_path / ".git").mkdir()
    lib, src = pkg / "_engine.so", pkg / "sd_new.c"
    lib.write_bytes(b"")
    src.write_text("")
    import os
    os.utime(lib, (1_000_000, 1_000_000))
    monkeypatch.setattr(extensions, "PACKAGE", pkg)
    with pytest.raises(InputError, match="older than shapedisplay/sd_new.c; rebuild it: pip install -e ."):
        extensions.load_extension(lib, "the compiled C runtime", [src])
    (tmp_path / ".git").rmdir()                                # not a checkout: loaded (and this file fails)
    with pytest.raises(InputError, match="loading the compiled C runtime .* failed .*reinstall"):
        extensions.load_extension(lib, "the compiled C runtime", [src])
