"""Offline play through the C runtime (runtime.native, play --engine) is the numba renderer's play, bit for bit."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.errors import InputError
from shapedisplay.runtime import native
from shapedisplay.runtime.cursor import CursorPath, parse_stroke
from shapedisplay.runtime.play import PathRenderer
from shapedisplay.runtime.renderer import Renderer
from shapedisplay.runtime.result import RenderResult
from shapedisplay.scene import compile_scene
from shapedisplay.sinks import read_trace, read_wav
from shapedisplay_cli.main import main

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "assets" / "scenes"

#: The shipped samples with a stroke across their widgets (mm on the table grid).
SAMPLES = {
    "phone": ("phone.toml", "62,2 -> 62,70 -> 20,40 @ 30mm/s"),        # handheld stick, several widgets
    "keypad": ("keypad.toml", "5,5 -> 65,90 @ 40mm/s"),                # desktop rig: lateral channels
    "media-player": ("media-player.toml", "0:160mm @ 80mm/s"),         # 1-D slider at 5 kHz
}
FIELDS = [f for f in RenderResult.__dataclass_fields__ if f != "mu_s"]


@pytest.fixture(scope="module")
def tables():
    return {name: compile_scene(SCENES / scene).table for name, (scene, _) in SAMPLES.items()}


def assert_same_result(a: RenderResult, b: RenderResult) -> None:
    for name in FIELDS:
        va, vb = getattr(a, name), getattr(b, name)
        if isinstance(va, np.ndarray):
            assert va.dtype == vb.dtype and va.shape == vb.shape, name
            np.testing.assert_array_equal(va, vb, err_msg=name)
        else:
            assert va == vb, name


@pytest.mark.parametrize("sample", sorted(SAMPLES))
@pytest.mark.parametrize("model, policy", [("exact", "retrigger"), ("jump", "retrigger"), ("exact", "add"),
                                           ("jump", "max")])
def test_c_runtime_plays_the_shipped_samples_as_the_numba_renderer(tables, sample, model, policy):
    table = tables[sample]
    py = Renderer(table, model=model, burst_policy=policy)
    cp = parse_stroke(SAMPLES[sample][1], py.tick_rate)
    ref = py.render(cp)
    c = PathRenderer(table, engine="c", model=model, burst_policy=policy)
    got = c.render(cp)
    assert c.engine == "c" and got.mu_s is None
    assert ref.event_time.size > 20 and np.count_nonzero(ref.audio) > 0
    assert_same_result(got, ref)


def test_same_bits_with_options_and_a_resampled_trace(tables):
    """Stick-period limit, burst gain, other rates, and a recorded path off the tick grid (resampled)."""
    table = tables["phone"]
    opts = dict(model="jump", tick_rate=4000.0, audio_rate=44100.0, max_stick_period=0.01, burst_policy="add")
    t = np.linspace(0.0, 2.0, 777)
    cp = CursorPath(t, 0.03 + 0.02 * np.cos(3 * t), 0.06 + 0.04 * np.sin(2 * t), 1000.0, "recorded")
    ref = Renderer(table, **opts).render(cp)
    got = PathRenderer(table, engine="c", **opts).render(cp)
    assert ref.event_time.size > 20
    assert_same_result(got, ref)


def test_same_bits_on_a_constant_normal_force_table(tmp_path):
    """A slope-only mapping stores no normal_force: both engines play the header's constant N."""
    from shapedisplay.table import FrictionTable
    src = tmp_path / "ramp.npy"
    np.save(src, np.tile(np.r_[np.zeros(40), np.linspace(0.0, 1e-3, 40)], (3, 1)))
    out = tmp_path / "t.npz"
    assert main(["compile", str(src), "--size", "80x3mm", "--mapping", "slope", "--n-base", "1.5N",
                 "--device", "linear-slider", "-o", str(out), "-q"]) == 0
    table = FrictionTable.load(out)
    assert "normal_force" not in table.channels
    for model in ("exact", "jump"):
        py = Renderer(table, model=model)
        cp = parse_stroke("0,1 <-> 80,1 @ 20mm/s", py.tick_rate)
        ref = py.render(cp)
        got = PathRenderer(table, engine="c", model=model).render(cp)
        assert ref.event_time.size > 20 and np.all(ref.normal_force == 1.5)
        assert_same_result(got, ref)


def test_auto_plays_other_models_and_off_grid_paths_with_the_python_kernels(tables):
    table = tables["phone"]
    r = PathRenderer(table, model="karnopp")
    assert r.engine == "python" and "karnopp" in r.note
    cp = parse_stroke("62,2 -> 62,40 @ 30mm/s", r.tick_rate)
    assert_same_result(r.render(cp), Renderer(table, model="karnopp").render(cp))
    # sample times that are not t0 + k / rate (as a force recording integrates them): the runtime would
    # shift events by an ulp, so auto plays this path with the Python kernels
    n = 5000
    off = CursorPath(np.arange(n) * (1.0 / r.tick_rate), np.linspace(0.03, 0.06, n), np.full(n, 0.05),
                     r.tick_rate, "force")
    assert not np.array_equal(off.t, np.arange(n) / r.tick_rate)
    a = PathRenderer(table, model="exact")
    assert a.engine == "c"
    res = a.render(off)
    assert a.engine == "python" and "tick_rate" in a.note
    assert_same_result(res, Renderer(table, model="exact").render(off))
    with pytest.raises(InputError, match="t0 \\+ k / tick_rate"):
        PathRenderer(table, engine="c").render(off)
    with pytest.raises(InputError, match="engine.*karnopp"):
        PathRenderer(table, engine="c", model="karnopp")


def test_a_missing_compiled_runtime_falls_back_with_a_reinstall_line(tables, tmp_path, monkeypatch):
    """The C runtime is compiled at install (shapedisplay._engine): a broken install without it, or with a
    file that does not load, plays with the Python kernels under auto and is one line under --engine c."""
    table = tables["phone"]
    cp = parse_stroke("62,2 -> 62,30 @ 30mm/s", 10_000.0)
    ref = Renderer(table, model="jump").render(cp)
    monkeypatch.setattr(native, "EXTENSION", "shapedisplay._no_such_engine")
    monkeypatch.setattr(native, "_LIB", None)
    assert native.unavailable("jump") is None                  # only a model without a C tick is a reason
    r = PathRenderer(table, model="jump")
    assert_same_result(r.render(cp), ref)
    assert r.engine == "python" and "reinstall shapedisplay" in r.note and "\n" not in r.note
    with pytest.raises(InputError, match="_no_such_engine.*missing.*reinstall"):
        PathRenderer(table, engine="c", model="jump").render(cp)
    # a library file that does not load (say, cut short by a full disk): one line naming it
    cut = tmp_path / "engine.so"
    cut.write_bytes(b"\x7fELF cut short")
    monkeypatch.setattr(native, "library_path", lambda: cut)
    r = PathRenderer(table, model="jump")
    assert_same_result(r.render(cp), ref)
    assert r.engine == "python" and str(cut) in r.note and "reinstall" in r.note
    monkeypatch.setattr(native, "_LIB", None)


def test_cli_play_engines_write_the_same_files(tmp_path, capsys):
    table = tmp_path / "phone.npz"
    assert main(["compile", str(SCENES / "phone.toml"), "-o", str(table)]) == 0
    out = {}
    for engine in ("c", "python"):
        args = ["play", str(table), "--stroke", "62,2 -> 62,60 @ 30mm/s", "--model", "jump", "--engine", engine,
                "-o", str(tmp_path / f"{engine}.wav"), "--trace-out", str(tmp_path / f"{engine}.npz"),
                "--ahap", str(tmp_path / f"{engine}.ahap"), "--sample-format", "int16", "--json"]
        capsys.readouterr()
        assert main(args) == 0
        out[engine] = json.loads(capsys.readouterr().out)
    assert out["c"].pop("engine") == "c" and out["python"].pop("engine") == "python"
    assert out["c"] == out["python"] and out["c"]["events"] > 10
    assert (tmp_path / "c.wav").read_bytes() == (tmp_path / "python.wav").read_bytes()
    assert (tmp_path / "c.ahap").read_bytes() == (tmp_path / "python.ahap").read_bytes()
    tc, tp = read_trace(tmp_path / "c.npz"), read_trace(tmp_path / "python.npz")
    assert tc.keys() == tp.keys()
    for k in tc:
        np.testing.assert_array_equal(tc[k], tp[k], err_msg=k)
    assert read_wav(tmp_path / "c.wav")[0].size == out["c"]["audio_samples"]
    # the text summary names the engine; a model without a C tick is refused by --engine c in one line
    assert main(["play", str(table), "--stroke", "0:20mm @ 20mm/s", "-o", str(tmp_path / "k.wav"),
                 "--model", "karnopp"]) == 0
    assert "(Python kernels)" in capsys.readouterr().out
    assert main(["play", str(table), "--stroke", "0:20mm @ 20mm/s", "-o", str(tmp_path / "k2.wav"),
                 "--model", "karnopp", "--engine", "c"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--engine" in err and "karnopp" in err and not (tmp_path / "k2.wav").exists()


def test_play_through_the_c_runtime_imports_no_numba_and_no_scipy(tmp_path):
    """What keeps a warm play short: the C path never loads numba (nor scipy, which numba pulls in)."""
    table = tmp_path / "phone.npz"
    assert main(["compile", str(SCENES / "phone.toml"), "-o", str(table)]) == 0
    code = ("import sys\nfrom shapedisplay_cli.main import main\n"
            f"rc = main(['play', {str(table)!r}, '--stroke', '62,2 -> 62,60 @ 30mm/s', '-o', "
            f"{str(tmp_path / 'o.wav')!r}])\n"
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'scipy', 'llvmlite'})\n"
            "print(rc, heavy)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "(C runtime)" in out and out.strip().endswith("0 []"), out


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
