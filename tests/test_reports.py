"""Reports: accuracy (work-precision) and stability, their JSON claims, and the pieces they are built from."""
from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pytest

from shapedisplay.reports import common
from shapedisplay.reports.peers import konyo_ivp, stribeck_ivp
from shapedisplay.reports.stability import energy_bound, stribeck_slope, theory_limit, theory_stable
from shapedisplay.cli.main import main


def _strict_load(path):
    """Load JSON refusing NaN/Infinity tokens."""
    def bad(tok):
        raise AssertionError(f"non-finite token {tok} in {path}")
    with open(path) as fh:
        return json.load(fh, parse_constant=bad)


# ================================================================ the two reports, through the CLI
def _run_cli(argv, out):
    """Run the CLI, keeping what it printed to stdout in ``out/terminal.txt``."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(argv) == 0
    (out / "terminal.txt").write_text(buf.getvalue())


@pytest.fixture(scope="module")
def accuracy_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("acc")
    _run_cli(["report", "accuracy", "--quick", "-o", str(out)], out)
    return out, _strict_load(out / "accuracy.json")


@pytest.fixture(scope="module")
def stability_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("stab")
    _run_cli(["report", "stability", "--quick", "-o", str(out)], out)
    return out, _strict_load(out / "stability.json")


def test_accuracy_files(accuracy_report):
    out, rep = accuracy_report
    assert (out / "accuracy.md").read_text().startswith("# Accuracy report")
    names = {c["name"] for c in rep["cases"]}
    assert {"reversal", "bump_table", "stribeck_contactor", "belt_coulomb", "belt_stribeck"} <= names
    assert any(n.startswith("konyo_") for n in names)
    for c in rep["cases"]:
        assert (out / f"accuracy_{c['name']}.png").stat().st_size > 1000
    assert rep["non_finite_replaced"] == [] or all(isinstance(p, str) for p in rep["non_finite_replaced"])


def test_accuracy_methods_and_peers(accuracy_report):
    _, rep = accuracy_report
    models = {s["model"] for c in rep["cases"] for s in c["settings"] if s["family"] == "renderer"}
    assert {"exact", "jump", "karnopp", "stribeck", "euler", "rk4"} <= models
    peers = {s["method"] for c in rep["cases"] for s in c["settings"] if s["family"] == "scipy"}
    assert peers == {"Radau", "BDF", "LSODA"}
    table = [s for c in rep["cases"] if c["name"] == "bump_table" for s in c["settings"] if s["family"] == "renderer"]
    assert len({s["table_dx_m"] for s in table}) >= 2 and len({s["quantize"] for s in table}) >= 2


def test_accuracy_exact_event_time_error(accuracy_report):
    _, rep = accuracy_report
    checked = 0
    for c in rep["cases"]:
        if c["kind"] != "konyo" or c["name"] == "bump_table":
            continue
        for s in c["settings"]:
            if s.get("model") == "exact":
                assert s["status"] == "ok"
                assert s["missing"] == 0 and s["spurious"] == 0
                assert s["event_max_s"] <= 1e-9, (c["name"], s["label"], s["event_max_s"])
                checked += 1
    assert checked >= 4
    assert rep["headline"]["exact_event_max_s"] <= 1e-9
    # the reference agrees with Radau at rtol 1e-12 (cross-check reported, here checked)
    for c in rep["cases"]:
        cc = c["reference"]["cross_check"]
        assert cc["events_compared"] >= 2 and cc["missing"] == 0
        assert cc["max_abs_s"] < 1e-6


def test_accuracy_stribeck_runs_at_several_tolerances(accuracy_report):
    """The ``stribeck`` settings span its slip tolerances; the looser ones stay within a bound that scales with them."""
    from shapedisplay.reports.accuracy import STRIBECK_TOLERANCES_QUICK
    _, rep = accuracy_report
    case = next(c for c in rep["cases"] if c["name"] == "stribeck_contactor")
    runs = [s for s in case["settings"] if s["family"] == "renderer"]
    assert {s["tolerance"] for s in runs} == set(STRIBECK_TOLERANCES_QUICK)
    interval = case["reference"]["mean_interval_s"]
    for s in runs:
        assert s["status"] == "ok" and s["missing"] == 0 and s["spurious"] == 0, s["label"]
        tol = s["tolerance"] or 1e-13
        assert s["event_max_s"] <= max(10 * tol * interval, 1e-9), (s["label"], s["event_max_s"])


def test_accuracy_belt_closed_form(accuracy_report):
    _, rep = accuracy_report
    belt = next(c for c in rep["cases"] if c["name"] == "belt_coulomb")
    cf = belt["reference"]["closed_form"]
    assert cf["period_s"] == pytest.approx(5.0 + math.pi + 2 * math.atan(0.4), rel=1e-15)
    assert cf["event_max_abs_s"] < 1e-9 and cf["period_rel_error"] < 1e-10


def test_terminal_tables_printed(accuracy_report, stability_report):
    # the CLI prints a short table and the list of files written (captured by the fixtures)
    for out, head in ((accuracy_report[0], "equal-error level"), (stability_report[0], "verdict")):
        text = (out / "terminal.txt").read_text()
        assert head in text and "wrote" in text and len(text.splitlines()) < 40


def test_accuracy_speedup_is_measured_ratio(accuracy_report):
    _, rep = accuracy_report
    fl = rep["floors"]
    assert 0 < fl["tick_s"] < 1e-6 and 0 < fl["audio_sample_s"] < 1e-6
    n = 0
    for c in rep["cases"]:
        labels = {x["label"]: x for x in c["settings"]}
        for kind, cost in (("model", "model_cpu_s_per_sim_s"), ("render", "cpu_s_per_sim_s")):
            q = c["summary"]["equal_error"][kind]
            if q is None:
                continue
            assert q["worst"]["speedup"] == min(v["speedup"] for v in q["levels"])
            for v in q["levels"]:
                peer, ren = labels[v["scipy"]], labels[v["renderer"]]
                # both sides are at most as wrong as the level, and no cheaper setting of either is
                assert peer["period_rel_max"] <= v["period_rel_max"] and ren["period_rel_max"] <= v["period_rel_max"]
                assert peer["missing"] == ren["missing"] == 0 and peer["spurious"] == ren["spurious"] == 0
                cheaper_peer = [x for x in c["settings"] if x["family"] == "scipy" and x["status"] == "ok"
                                and x["missing"] == 0 and x["spurious"] == 0 and x["period_rel_max"] is not None
                                and x["period_rel_max"] <= v["period_rel_max"]
                                and x["cpu_s_per_sim_s"] < peer["cpu_s_per_sim_s"]]
                assert not cheaper_peer
                # the ratio is the one of the two recorded timings
                assert v["speedup"] == pytest.approx(peer["cpu_s_per_sim_s"] / ren[cost], rel=1e-12)
                assert v["bound"] == pytest.approx(peer["cpu_s_per_sim_s"] / v["floor_cpu_s_per_sim_s"], rel=1e-12)
                # the floor is at least the per-tick floor at the level's slowest tick rate (the model's: at
                # least its interface's, which reads six rows and writes four per tick)
                assert v["floor_cpu_s_per_sim_s"] >= v["floor_tick_rate"] * fl["tick_s"] * (1 - 1e-12)
                assert ren[cost] > 0
            n += 1
    assert n >= 6
    # both costs are recorded for every renderer setting that ran
    for c in rep["cases"]:
        for x in c["settings"]:
            if x["family"] == "renderer" and x["status"] == "ok":
                assert x["model_cpu_s_per_sim_s"] > 0 and x["ticks"] >= 2


def test_accuracy_failures_are_kept(accuracy_report):
    _, rep = accuracy_report
    konyo = next(c for c in rep["cases"] if c["name"].startswith("konyo_"))
    bad = [s for s in konyo["settings"] if s.get("model") == "euler" and s["tick_rate"] == 1000.0]
    assert bad and bad[0]["status"] == "diverged" and bad[0]["event_rms_s"] is None
    assert bad[0]["cpu_s_per_sim_s"] is not None     # plotted as a marked failure point
    online = [s for s in konyo["settings"] if s.get("model") == "exact"]
    assert all(s["step_p99_s"] > 0 and s["tick_budget_s"] == pytest.approx(1 / s["tick_rate"]) for s in online)
    # the thread's CPU time of a tick is timed inside its wall time, tick by tick
    assert all(0 < s["step_cpu_p99_s"] <= s["step_p99_s"] and s["step_cpu_max_s"] <= s["step_wall_max_s"]
               for s in online)
    assert all(s["step_p99_over_budget"] == pytest.approx(s["step_p99_s"] * s["tick_rate"]) for s in online)


def test_stability_summary_and_cases(stability_report):
    out, rep = stability_report
    assert (out / "stability.md").read_text().startswith("# Stability report")
    s = rep["summary"]
    cases = rep["cases"]
    assert s["cases"] == len(cases) >= 200
    assert sum(s["verdicts"].values()) == len(cases)
    assert set(s["verdicts"]) == {"stable", "physically self-excited", "numerically unstable", "rejected"}
    for v, n in s["verdicts"].items():
        assert n == s[v] == sum(1 for c in cases if c["verdict"] == v)
    for c in cases:
        assert c["verdict"] in s["verdicts"] and isinstance(c["params"], dict)
    for sweep in {c["sweep"] for c in cases if c["kind"] != "bad"}:
        assert (out / f"stability_{sweep}.png").stat().st_size > 1000


def test_stability_sweep_covers_the_extremes(stability_report):
    from shapedisplay.reports.stability import build_sweeps
    assert len(build_sweeps(quick=False)) >= 1000
    _, rep = stability_report
    run = [c for c in rep["cases"] if c["kind"] != "bad"]

    def values(key, kind=None):
        return [c["params"][key] for c in run if key in c["params"] and (kind is None or c["kind"] == kind)]
    assert min(values("m")) <= 1e-9 and max(values("k")) >= 1e5
    z = [c["zeta"] for c in run if c.get("zeta") is not None]
    assert min(z) == 0.0 and max(z) > 1.0
    assert min(values("N")) == 0.0 and max(values("N")) >= 20.0
    assert min(values("V")) <= 1e-6 and max(values("V")) >= 2.0
    assert min(values("delta_mu")) == 0.0 and max(values("mu_s")) >= 3.0
    assert min(values("rate")) <= 100.0 and max(values("rate")) >= 96000.0
    tables = [c for c in run if c["kind"] == "table"]
    assert any(c["params"]["cursor_jump"] for c in tables) and {"float64", "uint8"} <= set(values("quantize"))
    assert all(c["walls"] >= 1 for c in tables)


def test_stability_default_models_never_nan(stability_report):
    _, rep = stability_report
    dm = [c for c in rep["cases"] if c["model"] in ("exact", "jump") and c["kind"] != "bad"]
    assert dm and all(c["finite"] is True for c in dm)
    assert rep["summary"]["default_model_nonfinite"] == 0
    assert all(c["verdict"] == "stable" for c in dm)


def test_stability_euler_unstable_on_konyo_pad_at_1khz(stability_report):
    _, rep = stability_report
    c = next(c for c in rep["cases"] if c["sweep"] == "konyo_rate" and c["model"] == "euler"
             and c["params"]["rate"] == 1000.0)
    assert c["verdict"] == "numerically unstable"
    assert "euler" in c["reason"] and c["step_s"] == pytest.approx(1e-3)
    assert c["theory_stable"] is False


def test_stability_explicit_matches_theory(stability_report):
    _, rep = stability_report
    ex = [c for c in rep["cases"] if c["sweep"] == "explicit_step"]
    assert {c["theory_stable"] for c in ex} == {True, False}
    # the instability starts where theory says: every case on the theory's side of the limit
    assert all(c["theory_stable"] != c["linear_instability_detected"] for c in ex)
    assert rep["summary"]["explicit_agree_with_theory"] == rep["summary"]["explicit_cases"]
    # and the measured growth per tick of the pad's modes is the amplification factor |R(h lambda)| itself
    long_lived = [c for c in ex if c["slip_mode_growth_per_tick"] is not None and c["theory_amplification"] > 0.9]
    assert {c["theory_stable"] for c in long_lived} == {True, False}
    for c in long_lived:
        assert c["slip_mode_growth_per_tick"] == pytest.approx(c["theory_amplification"], rel=1e-6)


def test_stability_verdict_kinds(stability_report):
    _, rep = stability_report
    stri = [c for c in rep["cases"] if c["sweep"] == "stribeck"]
    self_ex = [c for c in stri if c["verdict"] == "physically self-excited"]
    stable = [c for c in stri if c["verdict"] == "stable"]
    assert self_ex and stable and len(self_ex) + len(stable) == len(stri)
    # self-excitation is observed, not assumed: steady sliding leaves on its own at every substep (the step-size
    # convergence that tells it from a numerical blow-up), and only where c + W mu'(V) < 0
    for c in self_ex:
        assert c["stribeck_slope_Ns_per_m"] < 0
        assert c["self_excitation_by_substep"] == [True] * len(c["substeps_s"])
        assert c["perturbation_growth"] > 2 or min(c["event_counts"]) > 0
    for c in stable:
        assert c["stribeck_slope_Ns_per_m"] >= 0
        assert c["self_excitation_by_substep"] == [False] * len(c["substeps_s"])
        assert c["perturbation_growth"] < 1            # the 1 % perturbation decays
    assert rep["summary"]["stribeck_agree_with_slope_criterion"] == rep["summary"]["stribeck_cases"] == len(stri)
    bad = [c for c in rep["cases"] if c["kind"] == "bad"]
    assert bad and all(c["verdict"] == "rejected" and "\n" not in c["reason"] and c["reason"] for c in bad)


# ================================================================ building blocks
def test_match_events_counts_missing_and_spurious():
    ref = np.array([1.0, 2.0, 3.0, 4.0])
    got = np.array([1.01, 2.5, 3.0, 3.02, 9.0])
    pairs, missing, spurious = common.match_events(ref, got, window=0.1)
    assert pairs.tolist() == [[0, 0], [2, 2]]
    assert missing == 2 and spurious == 3
    e = common.event_errors(ref, ref, got, got, 0.1)
    assert e["event_max_s"] == pytest.approx(0.01) and e["event_rms_s"] == pytest.approx(0.01 / math.sqrt(2))


def test_event_errors_exact_period():
    ref = np.arange(1, 11) * 0.5
    got = ref * 1.002                      # every interval 0.2 % long
    e = common.event_errors(ref, np.ones(10), got, 1.1 * np.ones(10), 0.1)
    assert e["period_rel_max"] == pytest.approx(0.002, rel=1e-9)
    assert e["amplitude_rel_rms"] == pytest.approx(0.1, rel=1e-12)
    assert e["missing"] == e["spurious"] == 0


def test_waveform_error_zero_for_identical_and_one_for_silence():
    t = np.array([0.01, 0.05])
    a = np.array([1.0, 0.5])
    assert common.waveform_error(t, a, t, a, 0.1, 1.0) == 0.0
    assert common.waveform_error(t, a, np.zeros(0), np.zeros(0), 0.1, 1.0) == pytest.approx(1.0)


def test_clean_json_replaces_non_finite():
    notes = []
    out = common.clean_json({"a": [1.0, float("nan")], "b": {"c": np.float64(np.inf)}, "d": np.int64(3)}, notes=notes)
    assert out == {"a": [1.0, None], "b": {"c": None}, "d": 3}
    assert notes == ["a[1]", "b.c"]
    json.dumps(out, allow_nan=False)


def test_progress_without_tty():
    buf = io.StringIO()
    p = common.Progress(20, "demo", stream=buf)
    for _ in range(20):
        p.update(1, "x")
    p.close()
    lines = buf.getvalue().splitlines()
    assert 5 <= len(lines) <= 11 and "\r" not in buf.getvalue()
    assert lines[-1].startswith("demo [##############################] 20/20")


def test_theory_limits():
    # forward Euler: h omega_n < 2 zeta; RK4 on the imaginary axis: 2 sqrt(2)
    assert theory_limit("euler", 0.11) == pytest.approx(0.22, rel=1e-9)
    assert theory_limit("rk4", 0.0) == pytest.approx(2 * math.sqrt(2), rel=1e-6)
    wn = math.sqrt(2000 / 1e-6)
    assert not theory_stable("euler", 1e-3, wn, 0.11) and not theory_stable("rk4", 1e-3, wn, 0.11)
    assert theory_stable("rk4", 1 / 96000, wn, 0.11)


def test_stribeck_slope_sign():
    # published Imaizumi pad: c = 1, (mu_s - mu_k) a = 38.5 > c + b near v = 0: self-excited; not at high speed
    assert stribeck_slope(1.0, 1.0, 2.1, 1.4, 55.0, 1.9, 0.0) == pytest.approx(1.0 - 38.5 + 1.9)
    assert stribeck_slope(1.0, 1.0, 2.1, 1.4, 55.0, 1.9, 0.2) > 0


def test_energy_bound_holds_for_exact_model():
    from shapedisplay.render.models import simulate_pad
    r = simulate_pad("exact", V=0.05, N=2.0, tick_rate=96000, duration=0.05)
    E = 0.5 * 2000 * r.x ** 2 + 0.5 * 1e-6 * r.v ** 2
    assert E.max() <= energy_bound(1e-6, 2000.0, 0.01, 0.5, 2.0, 0.05)


def test_konyo_peer_matches_exact_and_belt_closed_form():
    from shapedisplay.table.devices import FrictionParams, PadParams
    from shapedisplay.render.models import simulate_pad
    r = simulate_pad("exact", V=0.05, N=2.0, tick_rate=10000, duration=0.03)
    p = konyo_ivp("LSODA", 1e-10, m=1e-6, k=2000.0, c=0.01, mu_s=0.5, mu_k=0.3, V=lambda t: 0.05,
                  N=lambda t: 2.0, t_end=0.03)
    assert p.status == "ok" and p.event_time.size == r.event_time.size >= 3
    assert np.max(np.abs(p.event_time - r.event_time)) < 1e-8
    # block on a belt: closed-form period (pi + 2 atan(V k / (omega dmu N))) / omega + 2 dmu N / (k V)
    b = simulate_pad("exact", V=0.2, N=1.0, pad=PadParams(1.0, 1.0, 0.0), friction=FrictionParams(1.0, 0.5),
                     tick_rate=100, duration=30.0)
    T = 5.0 + math.pi + 2 * math.atan(0.4)
    assert np.allclose(b.event_time, 5.0 + T * np.arange(b.event_time.size), rtol=0, atol=1e-9)


def test_stribeck_peer_agrees_with_kernel():
    from shapedisplay.table.devices import FrictionParams, PadParams
    from shapedisplay.render.models import simulate_pad
    r = simulate_pad("stribeck", V=0.1, N=1.0, pad=PadParams(1e-4, 1e3, 1.0), friction=FrictionParams(2.1, 1.4),
                     tick_rate=1000, duration=0.12, contactor_hz=9.0, contactor_amplitude_m=1.25e-3, substep_s=5e-7)
    p = stribeck_ivp("LSODA", 1e-9, m=1e-4, k=1e3, c=1.0, mu_s=2.1, mu_k=1.4, a=55.0, b=1.9, W=1.0, V=0.1,
                     amp=1.25e-3, omega=2 * math.pi * 9.0, t_end=0.12)
    assert p.event_time.size == r.event_time.size >= 2
    assert np.max(np.abs(p.event_time - r.event_time)) < 1e-6


def test_cli_output_must_be_directory(tmp_path, capsys):
    f = tmp_path / "file.txt"
    f.write_text("x")
    assert main(["report", "stability", "--quick", "-o", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--output" in err[0]


# ================================================================ plots: nothing cropped, nothing on top of another
def _layout_boxes(fig):
    """Window boxes of every text-like element of a figure: titles, axis labels, tick labels, legends."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes = []
    for t in fig.texts:
        if t.get_text():
            boxes.append((f"figure text {t.get_text()!r}", t.get_window_extent(r)))
    for leg in fig.legends:
        boxes.append(("figure legend", leg.get_window_extent(r)))
    for i, ax in enumerate(fig.axes):
        for name, t in (("title", ax.title), ("xlabel", ax.xaxis.label), ("ylabel", ax.yaxis.label)):
            if t.get_text():
                boxes.append((f"axes {i} {name}", t.get_window_extent(r)))
        if ax.get_legend() is not None:
            boxes.append((f"axes {i} legend", ax.get_legend().get_window_extent(r)))
        (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
        xticks = [t.get_window_extent(r) for t in ax.get_xticklabels() if t.get_text() and t.get_visible()
                  and x0 <= t.get_position()[0] <= x1]      # labels of ticks outside the view are not drawn
        yticks = [t.get_window_extent(r) for t in ax.get_yticklabels() if t.get_text() and t.get_visible()
                  and y0 <= t.get_position()[1] <= y1]
        from matplotlib.transforms import Bbox
        for axis, ticks in (("x", xticks), ("y", yticks)):    # each row of labels its own box
            if ticks:
                boxes.append((f"axes {i} {axis} tick labels", Bbox.union(ticks)))
    return boxes


def _check_layout(fig, name):
    from matplotlib.transforms import Bbox
    boxes = _layout_boxes(fig)
    page = Bbox.from_bounds(0, 0, *fig.canvas.get_width_height())
    for label, b in boxes:      # inside the figure: the saved picture crops nothing
        assert page.x0 - 1 <= b.x0 and b.x1 <= page.x1 + 1 and page.y0 - 1 <= b.y0 and b.y1 <= page.y1 + 1, \
            f"{name}: {label} leaves the figure"
    for i, (la, a) in enumerate(boxes):   # no title, label or legend on another (tick labels of one axes
        for lb, b in boxes[i + 1:]:      # share their box with nothing but their own axes)
            if "tick labels" in la and "tick labels" in lb:
                continue
            same_axes = la.split()[:2] == lb.split()[:2] and la.startswith("axes")
            if same_axes and ("tick labels" in la or "tick labels" in lb) and "legend" not in la + lb:
                continue    # an axis label beside its own tick labels is matplotlib's own placement
            inter = Bbox.intersection(a, b)
            assert inter is None or inter.width * inter.height < 4.0, f"{name}: {la} overlaps {lb}"


@pytest.mark.parametrize("kind", ["accuracy", "stability"])
def test_report_plots_crop_nothing_and_nothing_collides(kind, accuracy_report, stability_report, tmp_path,
                                                        monkeypatch):
    from shapedisplay.reports import accuracy, stability
    rep = (accuracy_report if kind == "accuracy" else stability_report)[1]
    checked = []

    def capture(fig, path):
        _check_layout(fig, path)
        checked.append(path)
        import matplotlib.pyplot as plt
        plt.close(fig)

    monkeypatch.setattr(common, "save_figure", capture)
    (accuracy if kind == "accuracy" else stability)._plots(rep, str(tmp_path))
    assert len(checked) >= 5


def test_report_png_is_byte_stable(stability_report, tmp_path):
    from shapedisplay.reports import stability
    rep = stability_report[1]
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    files = stability._plots(rep, str(tmp_path / "a"))
    stability._plots(rep, str(tmp_path / "b"))
    for f in files:
        data = (tmp_path / "a" / f).read_bytes()
        assert data == (tmp_path / "b" / f).read_bytes() and b"matplotlib version" not in data


def test_equal_error_speedup_on_known_settings():
    from shapedisplay.reports.accuracy import equal_error

    def st(family, label, err, cost, rate=None, model_cost=None):
        return {"family": family, "label": label, "status": "ok", "missing": 0, "spurious": 0,
                "period_rel_max": err, "cpu_s_per_sim_s": cost, "model_cpu_s_per_sim_s": model_cost,
                "tick_rate": rate}
    res = [st("scipy", "A", 1e-3, 10.0), st("scipy", "B", 1e-6, 50.0), st("scipy", "C", 2e-2, 1.0),  # C: > 1 %
           st("renderer", "R1", 5e-3, 0.01, 1000.0, 0.001), st("renderer", "R2", 1e-9, 0.1, 10000.0, 0.02)]
    q = equal_error(res, "cpu_s_per_sim_s", 1e-9, 1e-9)
    lv = {v["period_rel_max"]: v for v in q["levels"]}
    # 1e-9: no scipy setting that accurate; 1e-6: B vs R2; 1e-3: A vs R2 (R1 too wrong); 5e-3: A vs R1
    assert sorted(lv) == [1e-6, 1e-3, 5e-3]
    assert (lv[1e-6]["scipy"], lv[1e-6]["renderer"], lv[1e-6]["speedup"]) == ("B", "R2", pytest.approx(500.0))
    assert (lv[1e-3]["scipy"], lv[1e-3]["renderer"], lv[1e-3]["speedup"]) == ("A", "R2", pytest.approx(100.0))
    assert (lv[5e-3]["scipy"], lv[5e-3]["renderer"], lv[5e-3]["speedup"]) == ("A", "R1", pytest.approx(1000.0))
    assert q["worst"]["period_rel_max"] == 1e-3 and q["best"]["period_rel_max"] == 5e-3
    # the bound at 1e-3: R2's 10 kHz ticks and 48 kHz audio at 1 ns each per simulated second
    assert q["worst"]["bound"] == pytest.approx(10.0 / (10000 * 1e-9 + 48000 * 1e-9))
    assert not q["target_met"] and not q["target_bounded"]
    # the model cost instead of the full render's
    qm = equal_error(res, "model_cpu_s_per_sim_s", 1e-9)
    assert qm["worst"]["speedup"] == pytest.approx(500.0) and qm["worst"]["renderer"] == "R2"
    # a floor so costly that no renderer could reach the target at the worst level
    qb = equal_error(res, "cpu_s_per_sim_s", 1e-6, 1e-6)
    assert qb["target_bounded"] and qb["worst"]["bound"] < 1000
    # the model's own interface as its floor where it costs more than the per-tick floor: asked at the
    # slowest tick rate that reached each level, never below the per-tick floor
    asked = []

    def interface(rate):
        asked.append(rate)
        return 0.05 if rate == 10000.0 else 1e-12
    qi = equal_error(res, "model_cpu_s_per_sim_s", 1e-9, interface=interface)
    lv = {v["period_rel_max"]: v for v in qi["levels"]}
    assert set(asked) == {1000.0, 10000.0}
    assert lv[1e-3]["floor_cpu_s_per_sim_s"] == 0.05 and lv[1e-3]["bound"] == pytest.approx(10.0 / 0.05)
    assert lv[5e-3]["floor_cpu_s_per_sim_s"] == pytest.approx(1000 * 1e-9)
    assert [v["speedup"] for v in qi["levels"]] == [v["speedup"] for v in qm["levels"]]
    # nothing comparable
    assert equal_error([res[0], res[2]], "cpu_s_per_sim_s", 1e-9) is None


def test_stuck_floor_runs_the_model_on_ticks_that_all_stay_stuck():
    """The model alone's second floor is what its name says: the cheapest model over a path on which the pad
    never breaks away (every tick stuck, no event), and a positive CPU time per call."""
    from shapedisplay.reports.common import stuck_floor, stuck_path
    from shapedisplay.render.models import run_kernel
    for n in (2, 9001, 100_001):
        model, inputs = stuck_path(n)
        assert model.name == "jump"
        _, f, phase, x, _, ev_t, _ = run_kernel(model, *inputs)
        assert ev_t.size == 0 and not phase.any() and np.all(np.abs(f) < 1e-3 * inputs[2] * inputs[3])
    assert stuck_floor(9001, runs=1, min_batch_s=0.001) > 0.0


def test_timing_floors_compute_what_they_say():
    """The floors' C loops (``sd_floors.c``) write the values their docstrings name: each tick's input times
    ``h``; whole carrier periods times the envelope, the samples after the last whole period untouched; the
    four interface rows from the six inputs (t, V, N, mu_s, mu_k, gain). Both floors are positive CPU times."""
    lib = common._floors()
    rng = np.random.default_rng(5)
    v, out = rng.normal(size=1001), np.full(1001, np.nan)
    lib.sd_floor_tick(v.ctypes.data, out.ctypes.data, v.size, 1e-3)
    np.testing.assert_array_equal(out, v * 1e-3)
    period, out = rng.normal(size=160), np.full(1001, np.nan)
    lib.sd_floor_audio(out.ctypes.data, out.size, period.ctypes.data, period.size, 0.5)
    np.testing.assert_array_equal(out[:960], np.tile(0.5 * period, 6))
    assert np.isnan(out[960:]).all()
    rows, out = [rng.normal(size=777) for _ in range(6)], np.full((4, 777), np.nan)
    lib.sd_floor_interface(*(r.ctypes.data for r in rows), out.ctypes.data, 777, 0.25)
    t, V, N, mus, muk, gain = rows
    np.testing.assert_array_equal(out, np.array([V, N, mus + muk, gain + t]) * 0.25)
    tick, audio = common.floor_costs(n=1 << 16, runs=1)
    assert tick > 0.0 and audio > 0.0
    assert common.interface_floor(100, runs=1, min_batch_s=0.001) > 0.0


def test_cpu_per_call_reads_the_clock_a_few_times_per_run(monkeypatch):
    """cpu_per_call on a fake CPU clock: each call of fn costs 2 us, each clock read 0.5 us (a system
    call). The per-call figure is the call's cost plus at most a few percent of clock reads, with
    the clock read a few dozen times per run, and a run stops soon after min_batch_s."""
    clock = {"t": 0.0, "reads": 0, "calls": 0}

    def process_time():
        clock["reads"] += 1
        clock["t"] += 0.5e-6
        return clock["t"]

    def fn():
        clock["calls"] += 1
        clock["t"] += 2e-6
        return clock["calls"]

    monkeypatch.setattr(common.time, "process_time", process_time)
    runs, last = common.cpu_per_call(fn, runs=3, min_batch_s=0.02)
    assert len(runs) == 3 and last == clock["calls"]
    assert all(2e-6 <= r <= 2e-6 * 1.01 for r in runs), runs
    assert clock["reads"] <= 3 * 40                        # ~10000 calls per run, not one read per call
    assert clock["calls"] <= 1 + 3 * 0.02 * 1.1 / 2e-6      # the warm-up call and at most ~10 % past each run
    # a slow call (a scipy solve) is still timed over at least min_batch_s
    clock.update(t=0.0, reads=0, calls=0)
    runs, _ = common.cpu_per_call(lambda: clock.update(t=clock["t"] + 7e-3), runs=1, min_batch_s=0.02)
    assert runs[0] == pytest.approx(7e-3, rel=0.05)
