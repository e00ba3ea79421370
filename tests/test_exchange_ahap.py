"""AHAP (Apple Core Haptics) and drive-CSV exports of a played stroke."""
import copy
import json

import numpy as np
import pytest

from shapedisplay.errors import InputError
from shapedisplay.exchange.ahap import (MAX_CURVE_POINTS, ahap_document, ahap_of_result, check_ahap,
                                        drive_envelope, sharpness_of_carrier, write_drive_csv)
from shapedisplay.render.cursor import parse_stroke
from shapedisplay.render.renderer import Renderer
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
from shapedisplay.cli.main import main


def tent_table(tmp_path=None):
    xs = np.arange(241) * 0.25e-3
    nf = np.interp(xs, [0, 0.015, 0.030, 0.045, 0.060], [0.5, 0.5, 2.5, 0.5, 0.5])[None, :]
    t = FrictionTable.from_dense(Grid(1, xs.size, 0.25e-3, 0.25e-3), {"normal_force": nf},
                                 {"normal_force": choose_quantization(nf, "float64")})
    if tmp_path is not None:
        return t.save(tmp_path / "tent.npz")
    return t


@pytest.fixture(scope="module")
def played():
    r = Renderer(tent_table(), model="jump")
    return r, r.render(parse_stroke("0:60mm @ 30mm/s", r.tick_rate))


def curve_values(doc):
    """The HapticIntensityControl curve as absolute (t, value) points."""
    pts = []
    for item in doc["Pattern"]:
        c = item.get("ParameterCurve")
        if c:
            pts += [(c["Time"] + p["Time"], p["ParameterValue"]) for p in c["ParameterCurveControlPoints"]]
    return np.array(pts)


def test_one_transient_per_burst_with_intensity_from_amplitude(played):
    r, res = played
    doc = ahap_of_result(res, r.device.burst.carrier_hz)
    check_ahap(doc)
    tr = [e["Event"] for e in doc["Pattern"] if e.get("Event", {}).get("EventType") == "HapticTransient"]
    assert len(tr) == res.event_time.size > 20
    times = np.array([e["Time"] for e in tr])
    np.testing.assert_allclose(times, res.event_time - res.t[0], atol=1e-6)
    inten = np.array([e["EventParameters"][0]["ParameterValue"] for e in tr])
    np.testing.assert_allclose(inten, np.minimum(1.0, res.event_amplitude), atol=1e-6)
    sharp = {e["EventParameters"][1]["ParameterValue"] for e in tr}
    assert sharp == {round(sharpness_of_carrier(300.0), 6)}
    assert sharpness_of_carrier(80.0) == 0.0 and sharpness_of_carrier(320.0) == 1.0
    assert sharpness_of_carrier(160.0) == pytest.approx(0.5)


def test_envelope_curves_follow_the_drive_within_tolerance(played):
    r, res = played
    tol = 0.02
    doc = ahap_document(res.event_time, res.event_amplitude, res.audio, res.audio_rate, 300.0,
                        t0=float(res.t[0]), tolerance=tol)
    pts = curve_values(doc)
    curves = [e["ParameterCurve"] for e in doc["Pattern"] if "ParameterCurve" in e]
    assert all(2 <= len(c["ParameterCurveControlPoints"]) <= MAX_CURVE_POINTS for c in curves)
    # consecutive curves join: each starts where the previous one ended
    for a, b in zip(curves, curves[1:]):
        end = a["Time"] + a["ParameterCurveControlPoints"][-1]["Time"]
        assert b["Time"] == pytest.approx(end, abs=2e-6)
        assert b["ParameterCurveControlPoints"][0]["ParameterValue"] == a["ParameterCurveControlPoints"][-1]["ParameterValue"]
    t, env = drive_envelope(res.audio, res.audio_rate, 300.0)
    g = env / env.max()
    rebuilt = np.interp(t, pts[:, 0], pts[:, 1])
    assert np.max(np.abs(rebuilt - g)) <= tol + 2e-6
    # the continuous events cover the stroke
    cont = [e["Event"] for e in doc["Pattern"] if e.get("Event", {}).get("EventType") == "HapticContinuous"]
    assert sum(c["EventDuration"] for c in cont) == pytest.approx((res.audio.size - 1) / res.audio_rate, abs=1e-5)


def test_envelope_of_one_burst_peaks_at_the_end_of_the_rise():
    """Exact answer: one burst at 10 ms, A = 0.5, 300 Hz. The carrier is at a zero crossing at the end of the
    5 ms rise (sin(3 pi) = 0), so the largest |drive| is at the next carrier peak, tau = 7/(4 f):
    0.5 * (1 - (tau - 5 ms) / 30 ms)^2 = 0.4726 (the envelope is the drive's peak, not the ideal A)."""
    rate, f = 48_000.0, 300.0
    t = np.arange(int(0.06 * rate)) / rate
    tau = t - 0.010
    env = np.where(tau < 0, 0, np.where(tau < 0.005, tau / 0.005, np.clip(1 - (tau - 0.005) / 0.030, 0, 1) ** 2))
    drive = 0.5 * env * np.sin(2 * np.pi * f * np.clip(tau, 0, None))
    te, e = drive_envelope(drive, rate, f)
    tau_pk = 7 / (4 * f)
    assert e.max() == pytest.approx(0.5 * (1 - (tau_pk - 0.005) / 0.030) ** 2, rel=1e-3)
    assert abs(te[np.argmax(e)] - (0.010 + tau_pk)) <= 0.5 / f
    assert e[te < 0.009].max() == 0.0 and e[te > 0.0465].max() < 1e-3


def test_check_ahap_refuses_wrong_keys_and_ranges(played):
    r, res = played
    good = ahap_of_result(res, 300.0)
    tr = next(i for i, e in enumerate(good["Pattern"]) if e.get("Event", {}).get("EventType") == "HapticTransient")
    cv = next(i for i, e in enumerate(good["Pattern"]) if "ParameterCurve" in e)

    def broken(edit):
        d = copy.deepcopy(good)
        edit(d)
        return d

    cases = {
        "HapticIntensity": broken(lambda d: d["Pattern"][tr]["Event"]["EventParameters"][0].update(ParameterValue=1.5)),
        "EventType": broken(lambda d: d["Pattern"][tr]["Event"].update(EventType="Transient")),
        "Time": broken(lambda d: d["Pattern"][tr]["Event"].update(Time=-0.1)),
        "1..16 points": broken(lambda d: d["Pattern"][cv]["ParameterCurve"]["ParameterCurveControlPoints"].extend(
            [{"Time": 9.0, "ParameterValue": 0.0}] * 16)),
        "HapticIntensityControl": broken(lambda d: d["Pattern"][cv]["ParameterCurve"]["ParameterCurveControlPoints"][0]
                                         .update(ParameterValue=-0.2)),
        "top-level keys": broken(lambda d: d.update(Extra=1)),
        "Version": broken(lambda d: d.update(Version="1")),
        "EventDuration": broken(lambda d: d["Pattern"].append(
            {"Event": {"Time": 0.0, "EventType": "HapticContinuous", "EventDuration": 31.0, "EventParameters": []}})),
    }
    for needle, doc in cases.items():
        with pytest.raises(InputError, match=needle):
            check_ahap(doc)


def test_envelope_off_writes_transients_only(played):
    r, res = played
    doc = ahap_of_result(res, 300.0, envelope=False)
    kinds = {e["Event"]["EventType"] if "Event" in e else "curve" for e in doc["Pattern"]}
    assert kinds == {"HapticTransient"}


def test_drive_csv_round_trips_the_audio(played, tmp_path):
    r, res = played
    p = write_drive_csv(tmp_path / "d.csv", res.audio, res.audio_rate)
    lines = p.read_text().splitlines()
    assert lines[0] == "t_s,drive" and len(lines) == res.audio.size + 1
    data = np.loadtxt(p, delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 1], res.audio, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(data[:, 0], np.arange(res.audio.size) / res.audio_rate, rtol=1e-8)


def test_play_cli_writes_ahap_and_csv_or_nothing(tmp_path, capsys):
    t = tent_table(tmp_path)
    out = tmp_path / "o.wav"
    code = main(["play", str(t), "--stroke", "0:60mm @ 30mm/s", "-o", str(out), "--ahap", str(tmp_path / "o.ahap"),
                 "--drive-csv", str(tmp_path / "o.csv")])
    assert code == 0 and "transients" in capsys.readouterr().out
    doc = json.loads((tmp_path / "o.ahap").read_text())
    check_ahap(doc)
    assert doc["Metadata"]["Transients"] > 20
    # an AHAP into a missing folder: nothing written at all
    for f in ("o.wav", "o.ahap", "o.csv"):
        (tmp_path / f).unlink()
    code = main(["play", str(t), "--stroke", "0:60mm @ 30mm/s", "-o", str(out), "--ahap",
                 str(tmp_path / "nope" / "o.ahap"), "--drive-csv", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert code == 2 and "nope" in err and len(err.strip().splitlines()) == 1
    assert not out.exists() and not (tmp_path / "o.csv").exists()
    # an AHAP or CSV named like the table or the WAV is refused before anything is played
    before = t.read_bytes()
    for argv in (["--ahap", str(t)], ["--drive-csv", str(out)]):
        code = main(["play", str(t), "--stroke", "0:60mm @ 30mm/s", "-o", str(out), *argv])
        err = capsys.readouterr().err
        assert code == 2 and ("is the input" in err or "also the output" in err), err
    assert t.read_bytes() == before and not out.exists()
