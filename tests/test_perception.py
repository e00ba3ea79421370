"""The legibility check (``check --perception``): verdicts on known cases, the contrast a scene asks for,
the published figures against docs/perception.md, the closed forms, and the command's interface."""
from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

import pytest

from shapedisplay.author import perception as P
from shapedisplay.author.scene import SceneError, load_scene
from shapedisplay.cli.main import main
from shapedisplay.reports.perception import check_perception

ROOT = Path(__file__).resolve().parent.parent
PHONE = ROOT / "assets" / "scenes" / "phone.toml"


def scene(tmp_path, widgets: str, device: str = '"handheld-stick"', n_base: str = "1 N",
          canvas: str = 'size = "120x60 mm"', name: str = "s.toml", extra: str = "") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(f"""
        [canvas]
        {canvas}
        [device]
        profile = {device}
        [mapping]
        n_base = "{n_base}"
        """) + textwrap.dedent(widgets) + extra, encoding="utf-8")
    return p


def button(wid, x, strength, ramp="3 mm", size="20x20 mm", kind="button"):
    return f"""
        [[widget]]
        id = "{wid}"
        type = "{kind}"
        position = "{x},20 mm"
        size = "{size}"
        ramp = "{ramp}"
        {strength}
        """


def widget(rep, wid):
    return next(w for w in rep["widgets"] if w["id"] == wid)


def pair(rep, a, b):
    return next(p for p in rep["pairs"] if {p["a"], p["b"]} == {a, b})


# ------------------------------------------------------------------ Done-means cases
def test_buttons_3_0_and_3_1_N_feel_alike_under_one_jnd(tmp_path):
    rep = check_perception(scene(tmp_path, button("a", 10, 'force = "3.0 N"') + button("b", 50, 'force = "3.1 N"')))
    p = pair(rep, "a", "b")
    assert p["verdict"] == "feel-alike" and p["contrast_jnd"] < 1.0
    line = [w for w in rep["warnings"] if "feel-alike" in w]
    assert len(line) == 1 and "'a'" in line[0] and "'b'" in line[0] and "JND" in line[0]


def test_buttons_3_0_and_4_5_N_do_not(tmp_path):
    rep = check_perception(scene(tmp_path, button("a", 10, 'force = "3.0 N"') + button("b", 50, 'force = "4.5 N"')))
    p = pair(rep, "a", "b")
    assert p["verdict"] == "distinct" and p["contrast_jnd"] >= 1.0
    assert not [w for w in rep["warnings"] if "feel-alike" in w]


def test_thin_low_ridge_is_not_detectable_at_the_fast_speed(tmp_path):
    """A 0.5 mm ridge of 0.2 N: on a position-input device the fast stroke crosses it too quickly."""
    rid = """
        [[widget]]
        id = "r"
        type = "ridge"
        from = "60,10 mm"
        to = "60,50 mm"
        width = "0.5 mm"
        force_step = "0.2 N"
        """
    rep = check_perception(scene(tmp_path, rid, device='"linear-slider"', n_base="0.5 N",
                                 canvas='size = "120x60 mm"\nresolution = "0.1 mm"'))
    w = widget(rep, "r")
    assert w["detectable_by_speed"]["fast"] is False
    assert "not detectable" in w["verdicts"]
    assert any("not detectable" in m and "'r'" in m and "(fast)" in m for m in rep["warnings"])


def test_long_ramp_at_0_15_N_per_mm_is_saturated(tmp_path):
    p = scene(tmp_path, button("ramp", 20, 'force_step = "3.75 N"', ramp="25 mm", size="80x50 mm").replace(
        '"20,20 mm"', '"20,5 mm"'), device='"linear-slider"')
    rep = check_perception(p)
    w = widget(rep, "ramp")
    assert "saturated" in w["verdicts"]
    assert w["rise"]["span_m"] == pytest.approx(25e-3, rel=0.02)
    assert w["rise"]["rate_n_per_m"] == pytest.approx(150.0, rel=0.02)
    assert any("saturated" in m and "'ramp'" in m for m in rep["warnings"])


def test_short_ramp_is_not_saturated(tmp_path):
    rep = check_perception(scene(tmp_path, button("b", 20, 'force_step = "1.5 N"', ramp="10 mm", size="40x30 mm"),
                                 device='"linear-slider"'))
    assert "saturated" not in widget(rep, "b")["verdicts"]


def _plateau(tmp_path, limit: str):
    dev = tmp_path / "dev.toml"
    text = (ROOT / "shapedisplay/table/data/devices/linear-slider.toml").read_text()
    dev.write_text(text + f'max_stick_period = "{limit}"\n' if limit != "off" else text, encoding="utf-8")
    return check_perception(scene(tmp_path, button("p", 20, 'force = "6 N"', size="40x40 mm").replace(
        '"20,20 mm"', '"20,10 mm"'), device='"dev.toml"'))


def test_6_N_plateau_without_a_stick_period_limit_is_not_continuous(tmp_path):
    rep = _plateau(tmp_path, "off")
    w = widget(rep, "p")
    assert "not continuous" in w["verdicts"]
    assert w["longest_stick_s"]["slow"] > rep["rules"]["continuity_limit_s"]
    assert any("not continuous" in m and "'p'" in m for m in rep["warnings"])


def test_6_N_plateau_with_the_limit_on_is_continuous(tmp_path):
    rep = _plateau(tmp_path, "20 ms")
    w = widget(rep, "p")
    assert "continuous" in w["verdicts"] and "not continuous" not in w["verdicts"]
    assert w["longest_stick_s"]["slow"] <= 20e-3 + 1e-3


@pytest.mark.parametrize("device", ['"handheld-stick"', '"linear-slider"'])
def test_contrast_3_jnd_compiles_to_a_force_measured_at_3_jnd(tmp_path, device):
    p = scene(tmp_path, button("c", 30, 'contrast = "3 jnd"'), device=device)
    sc = load_scene(p)
    asked = sc.perception["contrast"]["c"]
    assert asked["jnd"] == 3.0 and asked["against"] == "flat ground" and asked["cue"] == "burst_amplitude"
    assert sc.widget("c").params["height"] == pytest.approx((asked["force_n"] - 1.0) / 1e3)
    rep = check_perception(sc)
    w = widget(rep, "c")
    assert w["contrast_jnd"] == pytest.approx(3.0, abs=0.1)
    assert w["contrast_asked"]["force_n"] == asked["force_n"]


def test_contrast_over_another_widget_and_below_ground(tmp_path):
    text = (button("a", 5, 'force = "2.5 N"') + button("b", 35, 'contrast = "2 jnd over a"')
            + button("d", 65, 'contrast = "1.5 jnd"', kind="dent"))
    p = scene(tmp_path, text, n_base="2 N")
    sc = load_scene(p)
    assert sc.perception["contrast"]["b"]["reference_n"] == pytest.approx(2.5)
    assert sc.perception["contrast"]["d"]["force_n"] < 2.0
    rep = check_perception(sc)
    assert pair(rep, "a", "b")["contrast_jnd"] == pytest.approx(2.0, abs=0.1)
    assert widget(rep, "d")["contrast_jnd"] == pytest.approx(1.5, abs=0.1)


@pytest.mark.parametrize("text, words", [
    ('contrast = "3 jnd"\n        force = "2 N"', "conflicts with"),
    ('contrast = "three"', "must look like"),
    ('contrast = "2 jnd over nobody"', "names no widget 'nobody'"),
    ('contrast = "0 jnd"', "0 < jnd <= 100"),
])
def test_contrast_errors_name_the_key(tmp_path, text, words):
    with pytest.raises(SceneError, match=re.escape(words)) as e:
        load_scene(scene(tmp_path, button("a", 10, text)))
    assert "widget[0]" in str(e.value)


def test_contrast_is_refused_on_a_ridge_and_in_a_cycle(tmp_path):
    rid = '[[widget]]\nid = "r"\ntype = "ridge"\nfrom = "5,5 mm"\nto = "50,5 mm"\ncontrast = "2 jnd"\n'
    with pytest.raises(SceneError, match="sets the strength of a button, dent, well only"):
        load_scene(scene(tmp_path, rid))
    cyc = button("a", 10, 'contrast = "1 jnd over b"') + button("b", 50, 'contrast = "1 jnd over a"')
    with pytest.raises(SceneError, match="cycle"):
        load_scene(scene(tmp_path, cyc))


def test_distinct_from_pairs_are_checked_and_unknown_ids_refused(tmp_path):
    text = button("a", 10, 'force = "3.0 N"') + button("d", 50, 'force = "0.6 N"', kind="dent").replace(
        'ramp = "3 mm"', 'ramp = "3 mm"\n        distinct_from = ["a"]')
    rep = check_perception(scene(tmp_path, text, n_base="1 N"))
    p = pair(rep, "a", "d")
    assert p["why"] == "distinct_from" and p["verdict"] == "distinct"
    bad = button("a", 10, 'force = "3 N"\n        distinct_from = ["ab"]')
    with pytest.raises(SceneError, match="names no widget 'ab'"):
        load_scene(scene(tmp_path, bad))


def test_stretch_at_the_ceiling_is_flagged_on_a_skin_stretch_device(tmp_path):
    text = button("hi", 10, 'force = "1.5 N"') + button("lo", 50, 'force = "1.2 N"')
    rep = check_perception(_stretch_scene(tmp_path, text))
    assert rep["model"] == "karnopp" and [c["cue"] for c in rep["cues"]][:2] == ["burst_amplitude", "friction_force"]
    assert "stretch" in widget(rep, "hi")["verdicts"] and "stretch" not in widget(rep, "lo")["verdicts"]
    assert widget(rep, "hi")["skin_stretch_max_m"] == pytest.approx(0.75e-3)
    assert any(m.startswith("stretch: 'hi'") for m in rep["warnings"])


def _stretch_scene(tmp_path, text):
    p = scene(tmp_path, text, device='"skin-stretch-tactor"')
    p.write_text(p.read_text().replace('n_base = "1 N"', 'n_base = "1 N"\nskin_stretch = "0.55 mm"'))
    return p


# ------------------------------------------------------------------ against the closed forms
def test_flat_ground_and_plateau_agree_with_the_jump_model_closed_forms(tmp_path):
    rep = check_perception(scene(tmp_path, button("p", 30, 'force = "3 N"', size="30x30 mm"),
                                 device='"linear-slider"'))
    from shapedisplay.table.devices import load_device
    dev = load_device("linear-slider")
    for sp, g in rep["ground"].items():
        v = g["speed_m_s"]
        assert g["measured"]
        assert g["friction_mean_n"] == pytest.approx(P.mean_friction(g["normal_force_n"], v, dev), rel=0.01)
        assert g["stick_period_s"] == pytest.approx(P.stick_period(g["normal_force_n"], v, dev), rel=0.01)
        assert g["burst_amplitude"] == pytest.approx(P.burst_amplitude(g["normal_force_n"], v, dev), rel=1e-6)
    w = widget(rep, "p")
    n_top = w["normal_force_n"]["top"]
    assert n_top == pytest.approx(3.0, abs=0.02)
    v = rep["speeds_m_s"]["typical"]
    assert w["friction_mean_n"]["top"] == pytest.approx(P.mean_friction(n_top, v, dev), rel=0.02)
    assert w["level"]["burst_amplitude"] == pytest.approx(P.burst_amplitude(n_top, v, dev), rel=1e-3)


def test_cue_arithmetic():
    c = P.Cue("x", weber=0.25)
    assert c.jnds(1.0, 1.25) == pytest.approx(1.0)
    assert c.jnds(2.0, 2.0 * 1.25 ** 3) == pytest.approx(3.0)
    assert c.level_at(2.0, -2) == pytest.approx(2.0 / 1.25 ** 2)
    assert P.Cue("s", step=0.27e-3).jnds(0.1e-3, 0.64e-3) == pytest.approx(2.0)
    assert P.friction_weber(0.2) == pytest.approx(0.28)
    assert P.friction_weber(0.8) == pytest.approx(0.1875)
    assert P.friction_weber(0.5) == pytest.approx((0.087 + 0.118) / 2 / 0.5)
    assert P.AMPLITUDE_WEBER == pytest.approx(10 ** (2.5 / 20) - 1)


def test_speeds_of_a_pointing_stick_come_from_its_gain():
    from shapedisplay.table.devices import load_device
    sp, why = P.exploration_speeds(load_device("handheld-stick"))
    assert [sp[k] for k in P.SPEED_NAMES] == pytest.approx([0.080, 0.1048, 0.120])
    assert "alpha" in why
    sp, _ = P.exploration_speeds(load_device("linear-slider"))
    assert [sp[k] for k in P.SPEED_NAMES] == pytest.approx([0.023, 0.053, 0.080])


# ------------------------------------------------------------------ the figures and the docs
def _doc_figures() -> dict:
    text = (ROOT / "docs" / "perception.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\|\s*`([\w.]+)`\s*\|\s*([^|]+?)\s*\|\s*([^|]+?)\s*\|[^|]*\|\s*([^|]+?)\s*\|\s*$", text, re.M)
    return {k: (v, u, src) for k, v, u, src in rows}


def test_module_figures_equal_the_cited_table_in_the_docs():
    doc = _doc_figures()
    assert set(doc) == set(P.FIGURES), set(doc) ^ set(P.FIGURES)
    for key, fig in P.FIGURES.items():
        value, unit, source = doc[key]
        if fig.value is None:
            assert value in ("—", "-", "not stored"), key
        else:
            assert float(value) == pytest.approx(fig.value, rel=1e-12), key
        assert unit.strip("`") == fig.unit, key
        assert fig.source.split(",")[0] in source, key


def test_weber_fractions_are_the_cited_jnds_over_mu():
    for mu in (0.2, 0.8):
        w = P.figure(f"friction_weber_{'low' if mu == 0.2 else 'high'}_mu")
        assert P.figure(f"friction_jnd_mu_{mu}") / mu == pytest.approx(w, abs=0.005)
    from shapedisplay.author.forces import EXPONENTS
    assert P.figure("exponent_bumpiness") == EXPONENTS["bumpiness"] == 0.76
    assert P.figure("exponent_friction") == EXPONENTS["friction"] == 1.26


# ------------------------------------------------------------------ the command
def test_check_perception_phone_text_and_json(capsys):
    assert main(["check", str(PHONE), "--perception"]) == 0
    out = capsys.readouterr().out
    assert "perception: device 'handheld-stick'" in out
    warn = [line for line in out.splitlines() if line.startswith("warning:")]
    assert any("feel-alike" in w and "'app-1'" in w and "'call'" in w for w in warn)
    assert main(["check", str(PHONE), "--perception", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    ids = [w["id"] for w in d["widgets"]]
    assert ids[:2] == ["frame", "app-1"] and len(ids) == 11
    for w in d["widgets"]:
        assert {"id", "contrast_jnd", "verdicts"} <= set(w)
        assert set(w["verdicts"]) <= {"detectable", "not detectable", "continuous", "not continuous",
                                      "saturated", "stretch"}
    for p in d["pairs"]:
        assert {"a", "b", "contrast_jnd", "verdict"} <= set(p) and p["verdict"] in ("feel-alike", "distinct")
    assert widget(d, "volume")["features"][0]["name"] == "detents"
    assert [f["name"] for f in widget(d, "wifi")["features"]] == ["knob (off)", "knob (on)"]
    assert d["perception"]["vibrotactile_detection"] == P.VIBROTACTILE_UNKNOWN


def test_check_perception_of_a_compiled_table(tmp_path, capsys):
    p = scene(tmp_path, button("a", 10, 'force = "3.0 N"') + button("b", 50, 'force = "3.1 N"'))
    out = tmp_path / "s.npz"
    assert main(["compile", str(p), "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["check", str(out), "--perception"]) == 0
    text = capsys.readouterr().out
    assert any("feel-alike" in line and "'a'" in line and "'b'" in line for line in text.splitlines())


def test_check_lists_the_force_a_contrast_chose(tmp_path, capsys):
    p = scene(tmp_path, button("c", 30, 'contrast = "3 jnd"'))
    assert main(["check", str(p)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"contrast: 'c' 3 jnd \(against flat ground\) -> force \d\.\d+ N \(burst amplitude", out)


def test_compile_of_a_scene_reports_the_check_and_keeps_the_table(tmp_path, capsys):
    """compile runs the legibility check for a scene and prints it with the report; the table is the same without it."""
    import json

    from shapedisplay.cli.main import main
    from shapedisplay.table.model import FrictionTable
    scene = Path(__file__).resolve().parent.parent / "assets" / "scenes" / "keypad.toml"
    assert main(["compile", str(scene), "-o", str(tmp_path / "a.npz")]) == 0
    out = capsys.readouterr().out
    assert "perception: device" in out and "JND" in out
    assert main(["compile", str(scene), "-o", str(tmp_path / "b.npz"), "--no-perception", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert "perception" not in rep
    assert main(["compile", str(scene), "-o", str(tmp_path / "c.npz"), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert {w["id"] for w in rep["perception"]["widgets"]} == {w["id"] for w in rep["widgets"]}
    assert FrictionTable.load(tmp_path / "a.npz").checksum == FrictionTable.load(tmp_path / "b.npz").checksum
