"""Cursor input parsing, WAV/trace sinks and the play/study commands."""
from __future__ import annotations

import json
import wave

import numpy as np
import pytest

from shapedisplay.errors import FileFormatError, InputError, UnitError
from shapedisplay.render.cursor import CursorPath, force_input, load_force_csv, load_trace_csv, parse_stroke
from shapedisplay.render.sinks import read_trace, read_wav, write_trace, write_wav
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
from shapedisplay.cli.main import main


# ------------------------------------------------------------------ cursor
def test_polyline_stroke_timing_and_geometry():
    cp = parse_stroke("0,10 -> 60,10 -> 60,30 @ 20 mm/s", 1000)
    assert cp.tick_rate == 1000
    assert np.isclose(cp.duration, 0.080 / 0.020)
    assert np.allclose(np.diff(cp.t), 1e-3)
    step = np.hypot(np.diff(cp.x), np.diff(cp.y))
    assert np.allclose(step[:-1], 20e-6)          # 20 mm/s at 1 kHz, including around the corner
    assert (cp.x[0], cp.y[0]) == (0.0, 0.010)
    assert np.isclose(cp.x[-1], 0.060) and np.isclose(cp.y[-1], 0.030)
    i = int(round(3.0 * 1000))                      # at 3 s: 60 mm along x then 0 along y... 60 mm done at 3 s
    assert np.isclose(cp.x[i], 0.060) and np.isclose(cp.y[i], 0.010)


def test_back_and_forth_and_repeat():
    cp = parse_stroke("0,2 <-> 60,2 @ 20mm/s x3", 1000)
    assert np.isclose(cp.duration, 3 * 0.120 / 0.020)
    assert np.allclose(cp.y, 0.002)
    assert np.isclose(cp.x.max(), 0.060) and np.isclose(cp.x[-1], 0.0)
    turns = np.sum(np.diff(np.sign(np.diff(cp.x))) != 0)
    assert turns == 5
    one_d = parse_stroke("0:60mm @ 50mm/s", 1000)
    assert np.allclose(one_d.y, 0) and np.isclose(one_d.x[-1], 0.06)


@pytest.mark.parametrize("text,match", [
    ("0,2 -> 60,2", "needs a speed"),
    ("0,2 -> 60,2 @ 0 mm/s", "speed must be > 0"),
    ("0,2 -> 60,2 @ 20", "needs a unit"),
    ("0,2 -> 0,2 @ 20 mm/s", "zero length"),
    ("0,2 @ 20 mm/s", "at least two points"),
    ("0,2 -> 60,2 @ 20 mm/s x3", "closed"),
    ("a,b -> 60,2 @ 20 mm/s", "cannot read point"),
    ("", "needs a speed"),
    ("-1e308,2 -> 1e308,2 @ 20 mm/s", r"lies beyond \+-1000 m"),
    ("0,2 -> 60,2 @ 1e-300 mm/s", "more than the 10,000,000 ticks"),
    ("0,2 -> 6e4,2 @ 1 mm/s", "more than the 10,000,000 ticks"),   # 6e8 ticks: refused before allocation
])
def test_bad_strokes(text, match):
    with pytest.raises(InputError, match=match):
        parse_stroke(text, 1000)


def test_trace_csv(tmp_path):
    p = tmp_path / "tr.csv"
    p.write_text("t,x,y\n0,0,0\n0.01,0.2,0\n0.02,0.4,0.1\n")
    cp = load_trace_csv(p)
    assert np.allclose(cp.x, [0, 0.2e-3, 0.4e-3]) and cp.tick_rate is None
    r = cp.resample(1000)
    assert r.t.size == 21 and np.isclose(r.x[10], 0.2e-3)
    p.write_text("t,x_m,y_m\n0,0,0\n0.01,0.2,0\n")
    assert np.isclose(load_trace_csv(p).x[1], 0.2)
    p.write_text("0,0,0\n0.01,0.2,0\n0.01,0.3,0\n")
    with pytest.raises(InputError, match="increase strictly"):
        load_trace_csv(p)
    p.write_text("0,0,0\n0.01,nan,0\n0.02,0.3,0\n")
    with pytest.raises(InputError, match="NaN"):
        load_trace_csv(p)
    with pytest.raises(FileFormatError, match="no such file"):
        load_trace_csv(tmp_path / "missing.csv")
    p.write_text("0,0\n0.01,0.2\n")
    with pytest.raises(FileFormatError, match="columns"):
        load_trace_csv(p)
    p.write_text("0,0,0\n1e9,0.2,0\n")                # 1e13 ticks at 10 kHz
    with pytest.raises(InputError, match="more than the 10,000,000 ticks"):
        load_trace_csv(p, tick_rate=10_000)


def test_force_input_integrates_alpha_f():
    f = np.full(5001, 0.5)                          # 0.5 N for 1 s at 5 kHz
    cp = force_input(f, alpha=0.080, force_rate=5000, tick_rate=1000)
    assert np.isclose(cp.x[-1], 0.080 * 0.5 * 1.0)   # v = alpha f = 40 mm/s for 1 s
    assert np.allclose(np.diff(cp.x), 40e-6)
    with pytest.raises(InputError, match="alpha"):
        force_input(f, alpha=0.0, force_rate=5000, tick_rate=1000)


def test_cursor_path_rejects_bad_arrays():
    with pytest.raises(InputError, match="increase"):
        CursorPath(np.array([0.0, 0.0]), np.zeros(2), np.zeros(2))
    with pytest.raises(InputError, match="NaN"):
        CursorPath(np.array([0.0, 1.0]), np.array([0.0, np.inf]), np.zeros(2))


# ------------------------------------------------------------------ sinks
def test_wav_int16_readable_by_wave_module(tmp_path):
    x = 0.5 * np.sin(2 * np.pi * 300 * np.arange(4801) / 48000)
    p = write_wav(tmp_path / "a.wav", x, 48000, "int16")
    with wave.open(str(p)) as w:
        assert w.getnchannels() == 1 and w.getsampwidth() == 2 and w.getframerate() == 48000
        assert w.getnframes() == 4801
        data = np.frombuffer(w.readframes(4801), "<i2")
    assert np.max(np.abs(data / 32767 - x)) <= 0.5 / 32767 + 1e-12


def test_wav_float32_round_trip_and_errors(tmp_path):
    x = np.linspace(-1, 1, 1001)
    p = write_wav(tmp_path / "f.wav", x, 44100)
    y, rate = read_wav(p)
    assert rate == 44100 and y.size == 1001 and np.allclose(y, x, atol=1e-7)
    from scipy.io import wavfile   # an independent reader
    r2, y2 = wavfile.read(p)
    assert r2 == 44100 and y2.dtype == np.float32 and np.allclose(y2, x, atol=1e-7)
    with pytest.raises(InputError, match="NaN"):
        write_wav(tmp_path / "n.wav", np.array([0.0, np.nan]), 48000)
    with pytest.raises(InputError, match="sample format"):
        write_wav(tmp_path / "n.wav", x, 48000, "int24")
    assert not (tmp_path / "n.wav").exists()


# ------------------------------------------------------------------ CLI
@pytest.fixture()
def tiny_table(tmp_path):
    xs = np.arange(121) * 0.5e-3
    N = (0.5 + np.clip(100 * (xs - 0.02), 0, 2.0))[None, :].repeat(9, 0)
    t = FrictionTable.from_dense(Grid(9, 121, 0.5e-3, 0.5e-3), {"normal_force": N},
                                 {"normal_force": choose_quantization(N, "uint16")}, {})
    path = tmp_path / "t.npz"
    t.save(path)
    dev = tmp_path / "dev.toml"
    dev.write_text('[device]\nname = "test"\ntick_rate = "10 kHz"\naudio_rate = "48 kHz"\n'
                   'cursor_gain = "80 mm/(N*s)"\n'
                   '[pad]\nmass = 1.0e-6\nstiffness = 2000.0\ndamping = 0.01\n'
                   '[friction]\nmu_s = 0.5\nmu_k = 0.3\n[burst]\ngain = "0.25 1/N"\n')
    return t, path, dev


def test_cli_play_writes_wav_trace_plot(tiny_table, tmp_path, capsys):
    table, path, dev = tiny_table
    out, tr, png = tmp_path / "out.wav", tmp_path / "tr.npz", tmp_path / "p.png"
    rc = main(["play", str(path), "--device", str(dev), "--stroke", "0,2 -> 60,2 @ 20mm/s", "--model", "exact",
               "--rate", "10kHz", "-o", str(out), "--trace-out", str(tr), "--plot", str(png)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "stick-slip events" in text and "clipped 0" in text
    d = read_trace(tr)
    assert d["table_checksum"] == table.checksum and d["model"] == "exact"
    n = d["t"].size
    assert n == 30001 and np.isclose(d["t"][-1], 3.0)
    for name in ("x", "y", "normal_force", "friction_force", "state", "lateral_x", "lateral_y",
                 "skin_stretch", "vx", "vy"):
        assert d[name].shape == (n,)
    assert set(np.unique(d["state"])) <= {0, 1}
    assert d["event_time"].size == d["event_amplitude"].size > 50
    assert np.allclose(d["y"], 2e-3)
    samples, rate = read_wav(out)
    assert rate == 48000 and samples.size == int(3.0 * 48000) + 1
    # audible: bursts on a 300 Hz carrier (the event train combs the spectrum: most energy within +-100 Hz)
    assert np.sqrt(np.mean(samples ** 2)) > 0.01
    power = np.abs(np.fft.rfft(samples * np.hanning(samples.size))) ** 2
    freq = np.fft.rfftfreq(samples.size, 1 / rate)
    assert power[(freq > 200) & (freq < 400)].sum() > 0.8 * power.sum()
    assert png.stat().st_size > 1000
    # raw npz is readable without this package
    with np.load(tr) as z:
        assert str(z["table_checksum"][0]).startswith("sha256:")


def test_cli_play_int16_trace_and_force(tiny_table, tmp_path):
    _, path, dev = tiny_table
    csv = tmp_path / "c.csv"
    csv.write_text("t,x,y\n" + "\n".join(f"{i * 0.01},{i * 0.5},2" for i in range(100)))
    out = tmp_path / "o.wav"
    assert main(["play", str(path), "--device", str(dev), "--cursor-csv", str(csv), "--model", "jump",
                 "--sample-format", "int16", "-o", str(out)]) == 0
    with wave.open(str(out)) as w:
        assert w.getnframes() == int(0.99 * 48000) + 1
    fcsv = tmp_path / "f.csv"
    fcsv.write_text("\n".join(f"{i / 5000},0.5" for i in range(5001)))
    assert main(["play", str(path), "--device", str(dev), "--force-csv", str(fcsv), "--start", "0,2",
                 "-o", str(out), "--json"]) == 0


def test_cli_burst_gain_scales_the_audio(tiny_table, tmp_path, capsys):
    _, path, dev = tiny_table
    peaks = []
    for gain in ("0.1", "0.2"):
        out = tmp_path / f"g{gain}.wav"
        assert main(["play", str(path), "--device", str(dev), "--stroke", "0,2 -> 60,2 @ 20mm/s",
                     "--burst-gain", gain, "-o", str(out)]) == 0
        peaks.append(np.abs(read_wav(out)[0]).max())
    assert np.isclose(peaks[1], 2 * peaks[0], rtol=1e-6)
    assert main(["play", str(path), "--stroke", "0,2 -> 60,2 @ 20mm/s", "--burst-gain", "-1",
                 "-o", str(tmp_path / "x.wav")]) == 2
    assert "gain" in capsys.readouterr().err


@pytest.mark.parametrize("extra,match", [
    (["--stroke", "0,2 -> 0,2 @ 20mm/s"], "zero length"),
    (["--stroke", "0,2 -> 60,2 @ 0mm/s"], "speed must be > 0"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--rate", "50Hz"], "100 Hz..192 kHz"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--rate", "200kHz"], "100 Hz..192 kHz"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--model", "verlet"], "unknown model"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--sample-format", "mp3"], "--sample-format"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--model", "euler", "--rate", "1kHz"], "diverged"),
    (["--stroke", ""], "needs a speed"),
    (["--stroke", "0,2 -> 6e4,2 @ 1mm/s"], "ticks"),
    (["--stroke", "0,2 -> 60,2 @ 0.01mm/s", "--rate", "100Hz"], "audio of 6000 s"),  # 2.9e8 samples at 48 kHz
    (["--cursor-csv", ""], "no such file"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--plot", "PLOT.xyz"], "suffix"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--plot", "/nonexistent-dir/p.png"], "does not exist"),
    (["--stroke", "0,2 -> 60,2 @ 20mm/s", "--trace-out", "/nonexistent-dir/t.npz"], "does not exist"),
])
def test_cli_play_bad_inputs(tiny_table, tmp_path, capsys, extra, match):
    _, path, dev = tiny_table
    extra = [str(tmp_path / a) if a.startswith("PLOT") else a for a in extra]
    rc = main(["play", str(path), "--device", str(dev), "-o", str(tmp_path / "x.wav"),
               "--trace-out", str(tmp_path / "x.npz"), *extra])
    err = capsys.readouterr().err
    assert rc == 2 and match in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    # no output at all, not even a temporary file: all outputs are written or none
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dev.toml", "t.npz"]


def test_cli_play_missing_channel_and_bad_mu(tmp_path, capsys):
    g = Grid(1, 10, 1e-3, 1e-3)
    t = FrictionTable.from_dense(g, {"friction_scale": np.ones((1, 10))},
                                 {"friction_scale": choose_quantization(np.ones(10), "uint8")}, {})
    t.save(tmp_path / "t.npz")
    rc = main(["play", str(tmp_path / "t.npz"), "--stroke", "0,0 -> 5,0 @ 10mm/s", "-o", str(tmp_path / "x.wav")])
    assert rc == 2 and "normal_force" in capsys.readouterr().err
    dev = tmp_path / "d.toml"
    dev.write_text("[friction]\nmu_s = 0.3\nmu_k = 0.5\n")
    g2 = FrictionTable.from_dense(g, {"normal_force": np.ones((1, 10))},
                                  {"normal_force": choose_quantization(np.ones(10), "uint8")}, {})
    g2.save(tmp_path / "n.npz")
    rc = main(["play", str(tmp_path / "n.npz"), "--device", str(dev), "--stroke", "0,0 -> 5,0 @ 10mm/s",
               "-o", str(tmp_path / "x.wav")])
    assert rc == 2 and "mu_k" in capsys.readouterr().err


def test_cli_study_imaizumi(capsys):
    assert main(["study", "imaizumi", "--duration", "0.2s", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert len(rows) == 10
    assert {r["finger_speed_m_s"] for r in rows} == {0.1, 0.04}
    for r in rows:
        assert 0 < r["mean_friction_n"] <= r["max_friction_n"] <= 2.1 * 1.0 + 1e-9
    still = [r for r in rows if r["stimulus"].startswith("#0") and r["finger_speed_m_s"] == 0.1][0]
    # steady sliding at 0.1 m/s: mu = mu_k + (mu_s - mu_k) exp(-a v / W) + b v / W
    mu = 1.4 + 0.7 * np.exp(-55 * 0.1) + 1.9 * 0.1
    assert np.isclose(still["mean_friction_n"], mu, rtol=1e-6)
    assert main(["study", "imaizumi", "--duration", "0.2s"]) == 0
    assert "#4 9 Hz 1.25 mm" in capsys.readouterr().out
    assert main(["study", "konyo"]) == 2


def test_runtime_imports_nothing_from_the_authoring_side():
    import subprocess
    import sys
    code = ("import sys, shapedisplay.render.renderer, shapedisplay.reports.imaizumi, shapedisplay.render.sinks\n"
            "print(sorted(m for m in sys.modules if m.startswith('shapedisplay')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    mods = {m.split(".")[1] for m in eval(out) if m.count(".") >= 1}
    assert mods <= {"render", "table", "reports", "units", "errors", "atomic", "extensions"}, mods
