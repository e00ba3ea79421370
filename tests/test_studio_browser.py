"""The studio in a real headless Chromium (Debian's ``chromium``, driven by Playwright).

The page loads the phone scene; its hover read-out (the C runtime's lookup in
WebAssembly) equals ``FrictionTable.sample``; a scripted mouse stroke played
by the AudioWorklet (the C runtime in WebAssembly) gives the events and drive
of the Python renderer, and ``shapedisplay play --trace`` on the page's CSV
reproduces them; editing the scene file updates the view without a reload; a
bad scene shows its error at its line; requests without the token are refused.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from studio_helpers import require_chromium

require_chromium()                                        # skips the module without them

from shapedisplay.table.widgets import widget_map  # noqa: E402
from shapedisplay.render import Renderer  # noqa: E402
from shapedisplay.render.cursor import CursorPath, load_trace_csv  # noqa: E402
from shapedisplay.render.native import C_MODELS  # noqa: E402
from shapedisplay.table.model import FrictionTable  # noqa: E402

from studio_helpers import PHONE, studio_page  # noqa: E402

#: Screenshot of the page for the README (copied there when this variable names a folder).
SCREENSHOT_DIR = os.environ.get("SHAPEDISPLAY_SCREENSHOT_DIR")


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    folder = tmp_path_factory.mktemp("studio")
    shutil.copy(PHONE, folder / "phone.toml")
    with studio_page(folder / "phone.toml", "window.studio && studio.shownGeneration !== null") as pg:
        pg.studio.folder = folder
        yield pg


def table_of(page) -> FrictionTable:
    status, body = page.studio.get("/api/table")
    assert status == 200
    return FrictionTable.from_bytes(body)


def test_page_loads_the_phone_scene(page):
    st = page.evaluate("studio.state")
    assert st["source"] == "phone.toml" and st["error"] is None
    assert [w["id"] for w in st["widgets"]][:3] == ["frame", "app-1", "app-2"]
    assert page.evaluate("document.getElementById('map').naturalWidth") == 161          # cols
    assert page.evaluate("document.getElementById('map').naturalHeight") == 321         # rows
    assert "grid: 161 x 321 samples" in page.inner_text("#report")
    assert page.input_value("#channel") == "normal_force"                               # N by default
    assert "id = \"call\"" in page.input_value("#text")
    # the top view is the same way up as the preview: the home well (low y) is drawn near the bottom
    _, y_home = page.evaluate("studio.screenOf(0.040, 0.012)")
    _, y_frame = page.evaluate("studio.screenOf(0.040, 0.152)")
    assert y_home > y_frame
    assert not page.js_errors


def test_hover_readout_equals_table_sample(page):
    table = table_of(page)
    for xm, ym in ((0.015, 0.128), (0.062, 0.036), (0.0407, 0.0657), (0.001, 0.159), (0.031, 0.119)):
        sx, sy = page.evaluate(f"studio.screenOf({xm}, {ym})")
        page.mouse.move(sx, sy)
        page.wait_for_function(f"studio.hoverPos && Math.abs(studio.hoverPos[0] - {xm}) < 1e-3")
        x = float(page.get_attribute("#hover-pos", "data-x"))
        y = float(page.get_attribute("#hover-pos", "data-y"))
        assert abs(x - xm) < 1e-3 and abs(y - ym) < 1e-3
        shown = {td.get_attribute("data-channel"): float(td.get_attribute("data-value"))
                 for td in page.query_selector_all("#readout td.v")}
        assert sorted(shown) == table.channels
        for name, value in shown.items():
            assert value == pytest.approx(float(table.sample(name, x, y)), rel=1e-12, abs=1e-12), name


def _mouse_stroke(page, points, steps=40, pause_ms=12):
    sx, sy = page.evaluate(f"studio.screenOf({points[0][0]}, {points[0][1]})")
    page.mouse.move(sx, sy)
    page.mouse.down()
    for (xa, ya), (xb, yb) in zip(points[:-1], points[1:]):
        ax, ay = page.evaluate(f"studio.screenOf({xa}, {ya})")
        bx, by = page.evaluate(f"studio.screenOf({xb}, {yb})")
        for i in range(1, steps + 1):
            page.mouse.move(ax + (bx - ax) * i / steps, ay + (by - ay) * i / steps)
            page.wait_for_timeout(pause_ms)
    page.mouse.up()


#: JavaScript helpers: a recorded stroke's typed arrays as base64 (Playwright's JSON of long arrays is slow).
PACK = """const b64 = (u8) => { let s = ''; for (let i = 0; i < u8.length; i += 32768)
    s += String.fromCharCode.apply(null, u8.subarray(i, i + 32768)); return btoa(s); };
const pack = (s) => { const o = {}; for (const k of ['t', 'x', 'y', 'event_time', 'event_amplitude', 'audio',
    'normal_force', 'friction_force', 'state']) o[k] = {dtype: s[k] instanceof Float32Array ? 'f4' : 'f8',
    data: b64(new Uint8Array(s[k].buffer, s[k].byteOffset, s[k].byteLength))}; return o; };
"""


def _arrays(packed: dict) -> dict:
    import base64
    out = {}
    for k, v in packed.items():
        if isinstance(v, dict) and "dtype" in v:
            out[k] = np.frombuffer(base64.b64decode(v["data"]), "<" + v["dtype"]).astype(np.float64)
        elif k == "wav":
            out[k] = base64.b64decode(v)
        else:
            out[k] = v
    return out


def _assert_same_as_python(rec, table, tick_rate):
    t = np.asarray(rec["t"])
    assert np.array_equal(t, np.arange(t.size) / tick_rate)
    res = Renderer(table, model="exact").render(CursorPath(t, np.asarray(rec["x"]), np.asarray(rec["y"]), tick_rate))
    et = np.asarray(rec["event_time"])
    assert et.size == res.event_time.size and et.size > 20
    assert np.max(np.abs(et - res.event_time)) <= 1e-6
    assert np.allclose(rec["event_amplitude"], res.event_amplitude, rtol=1e-9, atol=1e-12)
    audio = np.asarray(rec["audio"])
    assert audio.size == res.audio.size
    assert np.max(np.abs(audio - res.audio)) < 1e-6                   # recorded as float32
    assert np.allclose(rec["normal_force"], res.normal_force, rtol=1e-12, atol=1e-12)
    assert np.allclose(rec["friction_force"], res.friction_force, rtol=1e-9, atol=1e-9)
    return res


def test_scripted_stroke_offline_and_live_match_the_python_renderer(page, tmp_path):
    table = table_of(page)
    page.click("#feel")
    page.wait_for_function("studio.node !== null && studio.ctx.state === 'running'", timeout=20000)
    page.evaluate("studio.lastStroke = null")
    _mouse_stroke(page, [(0.062, 0.010), (0.062, 0.080), (0.040, 0.125)])
    # the stroke played live by the AudioWorklet (C runtime in WebAssembly) ...
    page.wait_for_function("studio.lastStroke !== null", timeout=20000)
    live = _arrays(page.evaluate(PACK + """(() => { const s = studio.lastStroke;
        return Object.assign(pack(s), {ticks: s.ticks, csv: studio.traceCSV(), wav: b64(new Uint8Array(studio.wav()))});
        })()"""))
    assert live["ticks"] > 1000
    _assert_same_as_python(live, table, 10000.0)
    # ... and the recorded pointer stroke rendered through an OfflineAudioContext
    off = _arrays(page.evaluate(PACK + """(async () => { const p = studio.pointerTicks();
        return pack(await studio.renderOffline(p.x, p.y)); })()"""))
    _assert_same_as_python(off, table, 10000.0)
    # the page's trace CSV replays with the CLI: same events, times within 1e-6 s, same drive
    csv = tmp_path / "stroke.csv"
    csv.write_text(live["csv"])
    tpath = tmp_path / "phone.npz"
    tpath.write_bytes(page.studio.get("/api/table")[1])
    cp = load_trace_csv(csv)
    assert np.array_equal(cp.x, live["x"]) and np.array_equal(cp.y, live["y"])
    r = subprocess.run([sys.executable, "-m", "shapedisplay", "play", str(tpath), "--cursor-csv", str(csv),
                        "-o", str(tmp_path / "replay.wav"), "--trace-out", str(tmp_path / "replay.npz")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "replay.npz") as z:
        et = z["event_time"]
    assert et.size == len(live["event_time"])
    assert np.max(np.abs(et - np.asarray(live["event_time"]))) <= 1e-6
    # ... and the drive: the page's WAV download and the replay's WAV hold the same samples
    from shapedisplay.render.sinks import read_wav
    replay, rate = read_wav(tmp_path / "replay.wav")
    (tmp_path / "page.wav").write_bytes(live["wav"])
    mine, rate2 = read_wav(tmp_path / "page.wav")
    assert rate == rate2 == 48000 and mine.size == replay.size
    assert np.max(np.abs(mine - replay)) < 1e-6
    assert page.is_enabled("#dl-csv") and page.is_enabled("#dl-wav")
    # the stroke chart marks the widgets crossed: spans equal the runs of ticks inside each widget's box
    spans = page.evaluate("studio.chartSpans")
    expected = []
    x, y, t = np.asarray(live["x"]), np.asarray(live["y"]), np.asarray(live["t"])
    for w in widget_map(table):
        x0, y0, x1, y1 = w["bbox_m"]
        inside = np.concatenate([[False], (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1), [False]])
        starts = np.flatnonzero(~inside[:-1] & inside[1:])
        ends = np.flatnonzero(inside[:-1] & ~inside[1:]) - 1
        expected += [(w["id"], t[a], t[b]) for a, b in zip(starts, ends)]
    expected.sort(key=lambda e: e[1])
    assert len(expected) >= 2     # the stroke crosses the wifi toggle and the volume slider at least
    assert [(d["id"], d["t0"], d["t1"]) for d in spans] == [(i, pytest.approx(a), pytest.approx(b))
                                                            for i, a, b in expected]
    if SCREENSHOT_DIR:
        page.mouse.move(*page.evaluate("studio.screenOf(0.040, 0.128)"))
        page.screenshot(path=str(Path(SCREENSHOT_DIR) / "studio-phone.png"))


def test_editing_the_scene_file_updates_the_view(page):
    scene = page.studio.folder / "phone.toml"
    good = scene.read_text()
    gen = page.evaluate("studio.tableGeneration")
    before = page.evaluate("studio.readout(0.015, 0.128).normal_force")
    try:
        scene.write_text(good.replace("level = 3 ", "level = 5 "))
        page.wait_for_function(f"studio.shownGeneration > {gen}",
                               timeout=20000)
        after = page.evaluate("studio.readout(0.015, 0.128).normal_force")
        assert after > before + 0.5                     # app-1 is higher now
        assert page.evaluate("performance.getEntriesByType('navigation').length") == 1      # no reload
        assert after == pytest.approx(float(table_of(page).sample("normal_force", 0.015, 0.128)), rel=1e-12)
    finally:
        scene.write_text(good)
        page.wait_for_function(f"studio.shownGeneration > {gen + 1}", timeout=20000)


def test_bad_scene_shows_its_error_at_its_line(page):
    scene = page.studio.folder / "phone.toml"
    good = scene.read_text()
    gen = page.evaluate("studio.tableGeneration")
    bad = good.replace('track_depth = "0.4 mm"', 'track_depth = "-0.4 mm"')
    line = next(i for i, t in enumerate(bad.splitlines(), 1) if '"-0.4 mm"' in t)
    try:
        scene.write_text(bad)
        page.wait_for_selector("#error:not([hidden])", timeout=20000)
        assert page.get_attribute("#error-where", "data-line") == str(line)
        assert "track_depth" in page.inner_text("#error-text")
        assert page.get_attribute("#gutter .error-line", "data-line") == str(line)
        assert page.evaluate("studio.tableGeneration") == gen              # the last good table keeps playing
        if SCREENSHOT_DIR:
            page.screenshot(path=str(Path(SCREENSHOT_DIR) / "studio-error.png"))
    finally:
        scene.write_text(good)
        page.wait_for_selector("#error", state="hidden", timeout=20000)


def test_requests_without_token_or_from_another_host_are_refused(page):
    base = page.studio.base
    assert page.evaluate(f"fetch('{base}/api/table').then(r => r.status)") == 403
    assert page.evaluate(f"fetch('{base}/api/table?token={page.studio.token}').then(r => r.status)") == 200
    ctx = page.context
    r = ctx.request.get(f"{base}/api/state?token={page.studio.token}",
                        headers={"Host": "rebind.example:" + base.rsplit(":", 1)[1]})
    assert r.status == 403


def test_pointing_stick_mode_moves_the_cursor_at_alpha_f(page):
    page.select_option("#mode", "stick")
    try:
        page.evaluate("studio.lastStroke = null")
        if page.evaluate("studio.node === null"):
            page.click("#feel")
            page.wait_for_function("studio.node !== null && studio.ctx.state === 'running'", timeout=20000)
        ax, ay = page.evaluate("studio.screenOf(0.020, 0.080)")
        bx, _ = page.evaluate("studio.screenOf(0.030, 0.080)")          # drag 10 mm to the right: f = 0.5 N
        page.mouse.move(ax, ay)
        page.mouse.down()
        page.mouse.move(bx, ay, steps=4)
        page.wait_for_timeout(600)
        page.mouse.up()
        page.wait_for_function("studio.lastStroke !== null", timeout=20000)
        s = _arrays(page.evaluate(PACK + "pack(studio.lastStroke)"))
        drag_mm = page.evaluate("studio.lastPointer[studio.lastPointer.length - 2].x - studio.lastPointer[0].x") * 1e3
        alpha = page.evaluate("studio.state.runtime.cursor_gain")                  # m/(N s)
        v = np.diff(s["x"]) * 10000.0
        expected = alpha * 0.05 * drag_mm                                         # 0.05 N per mm of drag
        held = np.abs(v - expected) < 1e-9 * expected
        assert abs(drag_mm - 10) < 0.2 and held.sum() > 2000     # held for most of the 0.6 s at v = alpha f
        assert np.allclose(s["y"], s["y"][0])          # no sideways drag, no sideways motion
    finally:
        page.select_option("#mode", "direct")


def test_saving_in_the_page_editor_writes_the_scene_and_recompiles(page):
    scene = page.studio.folder / "phone.toml"
    good = scene.read_text()
    gen = page.evaluate("studio.tableGeneration")
    try:
        page.fill("#text", good.replace('force = "3.5 N"', 'force = "2.5 N"'))
        page.keyboard.press("Control+s")
        page.wait_for_function(f"studio.shownGeneration > {gen}",
                               timeout=20000)
        assert 'force = "2.5 N"' in scene.read_text()
        assert page.evaluate("studio.readout(0.023, 0.036).normal_force") == pytest.approx(2.5, abs=0.03)
    finally:
        scene.write_text(good)
        page.wait_for_function(f"studio.shownGeneration > {gen + 1}", timeout=20000)


def _start_feel(page):
    if page.evaluate("studio.node === null"):
        page.click("#feel")
        page.wait_for_function("studio.node !== null && studio.ctx.state === 'running'", timeout=20000)


#: A scripted stroke across the phone's wifi toggle and volume slider (8000 ticks at 10 kHz, metres).
SCRIPTED = (np.linspace(0.062, 0.055, 8000), np.linspace(0.010, 0.125, 8000))


def _assert_plays_as_native(rec, table, model):
    """The page's per-tick outputs of a stroke equal the C runtime played natively (Renderer.render) for `model`
    on the same path to round-off (the module links musl's libm, the host glibc's: an ulp here and there);
    stick/slip states and events match one for one."""
    t = np.asarray(rec["t"])
    assert np.array_equal(t, np.arange(t.size) / 10000.0)
    ref = Renderer(table, model=model).render(CursorPath(t, np.asarray(rec["x"]), np.asarray(rec["y"]), 10000.0))
    assert np.allclose(rec["normal_force"], ref.normal_force, rtol=1e-12, atol=1e-12)
    gap = np.abs(rec["friction_force"] - ref.friction_force)
    assert gap.max() <= 1e-9, (model, gap.max(), np.count_nonzero(gap > 1e-9))
    assert np.array_equal(rec["state"], ref.state), model
    et = np.asarray(rec["event_time"])
    assert et.size == ref.event_time.size and et.size >= 1, (model, et.size, ref.event_time.size)
    assert np.max(np.abs(et - ref.event_time)) <= 1e-9, (model, np.max(np.abs(et - ref.event_time)))
    assert np.allclose(rec["event_amplitude"], ref.event_amplitude, rtol=1e-9, atol=1e-12), model
    audio = np.asarray(rec["audio"])
    assert audio.size == ref.audio.size and np.max(np.abs(audio - ref.audio)) < 1e-6      # recorded as float32
    return ref


def test_model_selector_plays_each_offered_model_as_the_native_c_runtime(page):
    """Each model chosen in the page plays a stroke across the phone's buttons (live, and the same path through
    an OfflineAudioContext) as the C runtime played natively from Python; karnopp and stribeck are not exact."""
    table = table_of(page)
    options = page.eval_on_selector_all("#model option", "os => os.map((o) => [o.value, o.disabled])")
    assert options == [[m, False] for m in C_MODELS]
    assert page.input_value("#model") == "exact"                  # the default: the studio's --model
    assert page.evaluate("studio.state.runtime.models") == list(C_MODELS)
    _start_feel(page)
    page.wait_for_function("studio.playingModel === 'exact'", timeout=20000)
    exact_gap = {}
    try:
        for name in C_MODELS:
            if name == "jump":                                    # keyboard: the selector is a plain <select>
                page.focus("#model")
                page.keyboard.press("ArrowDown")
                assert page.input_value("#model") == "jump"
            elif name != "exact":
                page.select_option("#model", name)
            page.wait_for_function(f"studio.playingModel === '{name}'", timeout=20000)
            assert page.evaluate("performance.getEntriesByType('navigation').length") == 1     # no reload
            page.evaluate("studio.lastStroke = null")
            _mouse_stroke(page, [(0.062, 0.010), (0.062, 0.080), (0.040, 0.125)], steps=30)
            page.wait_for_function("studio.lastStroke !== null", timeout=30000)
            live = _arrays(page.evaluate(PACK + """(() => { const s = studio.lastStroke;
                return Object.assign(pack(s), {ticks: s.ticks, model: s.model, csv: studio.traceCSV()}); })()"""))
            assert live["model"] == name and live["ticks"] > 3000
            assert f"--model {name} " in live["csv"]
            # the live stroke replayed through an OfflineAudioContext: the same engine, the same outputs
            off = _arrays(page.evaluate(PACK + """(async () => { const s = studio.lastStroke;
                const r = await studio.renderOffline(s.x, s.y); return Object.assign(pack(r), {model: r.model}); })()"""))
            assert off["model"] == name
            for k in ("t", "x", "y", "normal_force", "friction_force", "state", "event_time", "event_amplitude"):
                assert np.array_equal(off[k], live[k]), (name, k)
            if name != "stribeck":
                _assert_plays_as_native(live, table, name)
            # stribeck's slip on the negative slope of its curve excites itself: an ulp of libm's exp grows
            # over a long stick-slip run, so its check against the native run is the scripted stroke below
            xs, ys = (a.tolist() for a in SCRIPTED)
            scripted = _arrays(page.evaluate(PACK + f"""(async () => {{
                const r = await studio.renderOffline({xs}, {ys}); return Object.assign(pack(r), {{model: r.model}});
                }})()"""))
            assert scripted["model"] == name
            _assert_plays_as_native(scripted, table, name)
            t = np.asarray(live["t"])
            exact = Renderer(table, model="exact").render(CursorPath(t, live["x"], live["y"], 10000.0))
            exact_gap[name] = float(np.max(np.abs(live["friction_force"] - exact.friction_force)))
    finally:
        page.select_option("#model", "exact")
        page.wait_for_function("studio.playingModel === 'exact'", timeout=20000)
    assert exact_gap["exact"] <= 1e-9
    assert exact_gap["karnopp"] > 0.05 and exact_gap["stribeck"] > 0.05      # newtons: another friction law
    assert not page.js_errors
