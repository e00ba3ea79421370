"""Study presets (``shapedisplay study NAME -o DIR``) against closed forms, and constant-N tables."""
import json
import math
import os

import numpy as np
import pytest

from shapedisplay.table.devices import load_device
from shapedisplay.errors import InputError, TableError
from shapedisplay.reports.presets import STUDIES, STUDY_STICK_LIMIT, run_study, study_conditions
from shapedisplay.cli.main import main

PAD = load_device("handheld-stick").pad          # the published Konyo pad
B = 0.25                                         # 1/N, the handheld profile's burst gain
V = 0.020                                        # m/s, the presets' stroke speed


def qs_period(mus, muk, n, v=V):
    """Stick-slip period of the Konyo pad at constant speed, quasi-static closed form.

    The stick loads the spring from the re-stick force
    f_r = mu_k N - (mu_s - mu_k) N exp(-zeta pi / sqrt(1 - zeta^2)) (the damped
    overshoot of the slip) to mu_s N at k V per second; the slip lasts about
    half a damped period pi / omega_d.
    """
    z = PAD.zeta
    wd = math.sqrt(PAD.stiffness / PAD.mass) * math.sqrt(1 - z * z)
    f_r = muk * n - (mus - muk) * n * math.exp(-z * math.pi / math.sqrt(1 - z * z))
    return (mus * n - f_r) / (PAD.stiffness * v) + math.pi / wd, f_r


def test_study_help_lists_every_preset(capsys):
    with pytest.raises(SystemExit) as e:
        main(["study", "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert set(STUDIES) == {"friction", "slope-height", "bump", "imaizumi"}
    for name, st in STUDIES.items():
        assert name in out and st.description[:40] in out


def test_preset_condition_grids():
    fr = study_conditions("friction")
    assert len(fr) == 2 * 3 * 10
    mus = sorted({c.params["mu_s"] for c in fr})
    assert mus[0] == 0.375 and mus[-1] == 0.6 and np.allclose(np.diff(mus), 0.025)
    assert {c.params["device"] for c in fr} == {"handheld-stick", "linear-slider"}
    sh = study_conditions("slope-height")
    assert len(sh) == 6 * 3 * 2
    assert {c.params["max_stick_period_s"] for c in sh} == {0.0, STUDY_STICK_LIMIT}
    bump = study_conditions("bump")
    assert sorted({c.params["delta_n_n"] for c in bump}) == [2, 3, 4, 5, 6]
    assert sorted({c.params["span_mm"] for c in bump if c.params["delta_n_n"] == 4}) == [10, 15, 20, 25, 30]
    assert len(study_conditions("imaizumi")) == 10
    with pytest.raises(InputError, match="matches no condition"):
        study_conditions("bump", only="nothing-*")
    with pytest.raises(InputError, match="takes no options"):
        study_conditions("bump", variant="premax")


@pytest.mark.parametrize("mus, dmu", [(0.45, 0.2), (0.6, 0.1), (0.375, 0.3)])
def test_friction_study_matches_closed_form_stick_period_and_amplitude(mus, dmu):
    res = run_study("friction", duration=0.6, only=f"*-mus{mus:.3f}-dmu{dmu:.1f}")
    assert [r["device"] for r in res.rows] == ["handheld-stick", "linear-slider"]
    period, f_r = qs_period(mus, mus - dmu, 2.0)
    for r in res.rows:
        assert r["events"] >= 10
        # error of the quasi-static closed form: the slip's velocity overshoot at r = V k / (dmu N omega_n) ~ 1e-3
        assert r["stick_period_s"] == pytest.approx(period, rel=1e-3)
        # every burst breaks away at the static limit: A = B (mu_s N - c V)
        assert r["burst_amplitude"] == pytest.approx(B * (mus * 2.0 - PAD.damping * V), rel=1e-9)
        # |f| over a linear ramp from f_r to mu_s N during the stick (the ~70 us slips barely count);
        # at a large delta_mu the overshoot re-sticks with the spring pulling the other way (f_r < 0)
        top = mus * 2.0
        mean_abs = 0.5 * (top + f_r) if f_r >= 0 else 0.5 * (top * top + f_r * f_r) / (top - f_r)
        assert r["mean_friction_n"] == pytest.approx(mean_abs, rel=5e-3)
        assert r["clipped"] == 0
    # the pointing stick (v = alpha f) and the slider stroke play the same constant speed
    a, b = res.rows
    assert a["stick_period_s"] == pytest.approx(b["stick_period_s"], rel=1e-9)


def test_slope_height_study_plateau_matches_the_ramp_closed_form():
    res = run_study("slope-height", only="ramp-L20mm-k0.[01][05]-limit-*")
    assert len(res.rows) == 6
    for r in res.rows:
        n2 = 0.5 + r["rate_n_per_mm"] * 20
        assert r["n2_n"] == pytest.approx(n2)
        assert r["top_normal_force_n"] == pytest.approx(n2, abs=1e-3)
        assert r["base_burst_amplitude"] == pytest.approx(B * (0.5 * 0.5 - PAD.damping * V), rel=1e-9)
        period, _ = qs_period(0.5, 0.3, n2)
        # the burst amplitude keeps the true N with and without the stick-period limit
        assert r["top_burst_amplitude"] == pytest.approx(B * (0.5 * n2 - PAD.damping * V), rel=2e-4)
        if r["max_stick_period_s"] == 0:
            assert r["top_stick_period_s"] == pytest.approx(period, rel=2e-3)
        else:
            # no stick outlasts the limit (an interval between events is one stick plus its ~71 us slip)
            assert r["top_longest_stick_s"] <= STUDY_STICK_LIMIT + 80e-6
            assert r["top_stick_period_s"] <= min(period, STUDY_STICK_LIMIT + 80e-6) * (1 + 1e-9)
    # the limit shortens the sticks of the 2.5 N plateau (21.3 ms) and leaves those at 1.5 N (12.8 ms) alone
    by = {(r["rate_n_per_mm"], r["max_stick_period_s"]): r for r in res.rows}
    assert by[(0.10, STUDY_STICK_LIMIT)]["top_events"] > by[(0.10, 0.0)]["top_events"]
    assert by[(0.05, STUDY_STICK_LIMIT)]["top_events"] == by[(0.05, 0.0)]["top_events"]


def test_slope_height_limit_keeps_the_height_contrast():
    """With the limit at 20 ms the plateaus keep burst amplitudes in proportion to mu_s N2 - c V."""
    res = run_study("slope-height", only="ramp-L*-k0.10-limit-20ms")
    amp = {r["n2_n"]: r["top_burst_amplitude"] for r in res.rows}
    assert sorted(amp) == [1.0, 1.5, 2.0, 2.5, 3.0, 3.5]
    for n2, a in amp.items():
        assert a == pytest.approx(B * (0.5 * n2 - PAD.damping * V), rel=2e-4)
    fr = [r["top_mean_friction_n"] for r in sorted(res.rows, key=lambda r: r["n2_n"])]
    assert np.all(np.diff(fr) > 0)          # the friction still grows with the height


@pytest.mark.parametrize("model", ["exact", "jump"])
def test_stick_period_limit_keeps_amplitudes_3_4_6(model):
    """Constant N = 3, 4, 6 N at 20 mm/s with the limit at 20 ms (natural sticks 25.6-51.1 ms)."""
    from shapedisplay.render import Renderer
    from shapedisplay.reports.presets import constant_table
    from shapedisplay.reports.studies import line_stroke

    dev = load_device("handheld-stick")
    wd = math.sqrt(PAD.stiffness / PAD.mass) * math.sqrt(1 - PAD.zeta ** 2)
    amps = []
    for n in (3.0, 4.0, 6.0):
        r = Renderer(constant_table(n, dev), device=dev, model=model, max_stick_period=0.020)
        res = r.render(line_stroke(0.0, 0.02, V, r.tick_rate))
        assert res.event_time.size >= 45
        # every stick ends at the limit; a period is the stick plus its slip (~pi / omega_d)
        assert np.max(np.diff(res.event_time)) <= 0.020 + 1.01 * math.pi / wd
        assert np.allclose(res.event_amplitude, B * (0.5 * n - PAD.damping * V), rtol=1e-9)
        amps.append(res.event_amplitude.mean())
        free = Renderer(constant_table(n, dev), device=dev, model=model).render(line_stroke(0.0, 0.02, V, r.tick_rate))
        assert np.median(np.diff(free.event_time)) > 0.025
    assert amps[1] / amps[0] == pytest.approx(4 / 3, rel=0.01)
    assert amps[2] / amps[0] == pytest.approx(6 / 3, rel=0.01)


def test_bump_study_bursts_follow_the_tent_profile(tmp_path):
    from shapedisplay.render.sinks import read_trace
    from shapedisplay.author.sources import tent_force

    res = run_study("bump", tmp_path / "bump", only="tent-dN[26]N-L20mm")
    assert [r["condition"] for r in res.rows] == ["tent-dN2N-L20mm", "tent-dN6N-L20mm"]
    for r, cond in zip(res.rows, study_conditions("bump", only="tent-dN[26]N-L20mm")):
        table = cond.table()
        dx, q = table.grid.dx, table.quant["normal_force"].max_error
        tr = read_trace(tmp_path / "bump" / f"{r['condition']}.npz")
        et, ea = tr["event_time"], tr["event_amplitude"]
        xe = np.interp(et, tr["t"], tr["x"])
        n1, dn, L = 0.5, r["delta_n_n"], r["span_mm"] * 1e-3
        n_exact = tent_force(xe, 0.010, 0.010 + L, n1=n1, n2=n1 + dn)
        # the renderer holds N for a tick (looked up at the tick's midpoint): within k V h / 2 of the
        # profile at the event; the cell-centred samples cut the kinks by up to k dx / 2; plus the
        # table's quantization of N
        k = dn / L
        h = 1.0 / cond.device.tick_rate_hz
        tol = B * 0.5 * (k * V * h / 2 + k * dx / 2 + q) * (1 + 1e-9)
        assert np.max(np.abs(ea - B * (0.5 * n_exact - PAD.damping * V))) < tol
        assert r["top_burst_amplitude"] > 0.9 * B * 0.5 * (n1 + dn)
        assert r["max_friction_n"] <= 0.5 * (n1 + dn) + 1e-3


def test_imaizumi_preset_reproduces_the_table_free_study():
    """The preset plays a constant-N table through the renderer; the older study drives the pad directly."""
    from shapedisplay.reports.imaizumi import imaizumi_study

    res = run_study("imaizumi", duration=0.2)
    ref = imaizumi_study(duration=0.2)
    assert len(res.rows) == len(ref) == 10
    for a, b in zip(res.rows, ref):
        assert a["stimulus"] == b["stimulus"] and a["finger_speed_m_s"] == b["finger_speed_m_s"]
        assert a["events"] == b["events"]
        # the renderer differentiates cursor positions (speed exact to ~1e-13); where the pad sticks and
        # slips, the bisected breakaway moves a little with that round-off
        rel = 1e-12 if a["events"] == 0 else 1e-3
        assert a["mean_friction_n"] == pytest.approx(b["mean_friction_n"], rel=rel)
        assert a["max_friction_n"] == pytest.approx(b["max_friction_n"], rel=rel)


def test_cli_study_writes_every_file_and_never_overwrites(tmp_path, capsys):
    from shapedisplay.render.sinks import read_trace, read_wav

    out = tmp_path / "fr"
    assert main(["study", "friction", "-o", str(out), "--only", "*-mus0.500-dmu0.2", "--duration", "0.3s"]) == 0
    text = capsys.readouterr().out
    assert "stick-mus0.500-dmu0.2" in text and "slider-mus0.500-dmu0.2" in text
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(["manifest.json", "summary.csv", "summary.png",
                            "stick-mus0.500-dmu0.2.wav", "stick-mus0.500-dmu0.2.npz",
                            "slider-mus0.500-dmu0.2.wav", "slider-mus0.500-dmu0.2.npz"])
    man = json.loads((out / "manifest.json").read_text())
    assert man["study"] == "friction" and len(man["conditions"]) == 2
    for c in man["conditions"]:
        audio, rate = read_wav(out / c["wav"])
        tr = read_trace(out / c["trace"])
        assert rate == c["audio_rate_hz"] and audio.size > 0.29 * rate
        assert tr["event_time"].size == c["summary"]["events"] + np.sum(tr["event_time"] < 0.03)
        assert c["mu_s"] == 0.5 and c["mu_k"] == 0.3
    csv_lines = (out / "summary.csv").read_text().splitlines()
    assert len(csv_lines) == 3 and csv_lines[0].startswith("condition,")
    # a folder that is not empty is refused, and left as it was
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    assert main(["study", "bump", "-o", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
    assert main(["study", "konyo"]) == 2
    assert main(["study", "friction", "--list", "--only", "slider-*-dmu0.3"]) == 0
    assert len(capsys.readouterr().out.split()) == 10


def test_study_written_twice_leaves_one_complete_folder_and_no_temporary_files(tmp_path):
    from shapedisplay.errors import FileFormatError

    out = tmp_path / "fr"
    only = "stick-mus0.500-dmu0.2"
    expected = sorted(["manifest.json", "summary.csv", "summary.png", f"{only}.wav", f"{only}.npz"])

    def files():
        return {p.name: p.read_bytes() for p in out.iterdir()}

    run_study("friction", out, only=only, duration=0.1)
    first = files()
    assert sorted(first) == expected
    # into the same folder again: refused, the folder as it was
    with pytest.raises(FileFormatError, match="not empty"):
        run_study("friction", out, only=only, duration=0.1)
    assert files() == first
    # into the emptied folder again: the same complete folder, byte for byte
    for p in out.iterdir():
        p.unlink()
    run_study("friction", out, only=only, duration=0.1)
    assert files() == first
    assert [p.name for p in tmp_path.iterdir()] == ["fr"]          # no temporary folder beside it
    mask = os.umask(0o022)
    os.umask(mask)
    assert {oct(p.stat().st_mode & 0o777) for p in out.iterdir()} == {oct(0o666 & ~mask)}
    assert oct(out.stat().st_mode & 0o777) == oct(0o777 & ~mask)
    man = json.loads(first["manifest.json"])
    assert {man["summary"], man["plot"], man["conditions"][0]["wav"], man["conditions"][0]["trace"]} <= set(first)
    assert first["summary.png"][:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------ constant-N tables
def test_slope_only_table_plays_its_constant_normal_force(tmp_path, capsys):
    """`compile --mapping slope` leaves normal_force out; play takes N = n_base from the header."""
    from shapedisplay.render import Renderer, parse_stroke
    from shapedisplay.render.sinks import read_trace
    from shapedisplay.table.model import FrictionTable

    src = tmp_path / "flat.npy"
    np.save(src, np.zeros((1, 80)))
    tab = tmp_path / "t.npz"
    assert main(["compile", str(src), "--size", "80x1mm", "--mapping", "slope", "--n-base", "1.5N",
                 "--device", "linear-slider", "-o", str(tab), "-q"]) == 0
    table = FrictionTable.load(tab)
    assert "normal_force" not in table.channels
    assert main(["play", str(tab), "--stroke", "0:40mm @ 20mm/s", "-o", str(tmp_path / "o.wav"),
                 "--trace-out", str(tmp_path / "o.npz")]) == 0
    tr = read_trace(tmp_path / "o.npz")
    assert np.all(tr["normal_force"] == 1.5)
    period, _ = qs_period(0.5, 0.3, 1.5)
    assert np.median(np.diff(tr["event_time"])) == pytest.approx(period, rel=1e-3)
    # the online path plays the same constant
    r = Renderer(table)
    cp = parse_stroke("0:10mm @ 20mm/s", r.tick_rate)
    off = r.render(cp)
    r.reset()
    for x, y in zip(cp.x, cp.y):
        r.step(x, y)
    assert r.outputs()["normal_force"] == 1.5 and r.event_count == off.event_time.size > 0


def test_table_without_normal_force_or_constant_is_refused():
    from shapedisplay.render import Renderer
    from shapedisplay.table.model import FrictionTable, Grid, choose_quantization

    z = np.zeros((1, 10))
    t = FrictionTable.from_dense(Grid(1, 10, 1e-3, 1e-3), {"grad_x": z}, {"grad_x": choose_quantization(z, "uint8")},
                                 {})
    with pytest.raises(TableError, match="n_base"):
        Renderer(t)
    t.meta["mapping"] = {"n_base": math.nan}
    with pytest.raises(TableError, match="finite"):
        Renderer(t)
