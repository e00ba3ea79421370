"""Reactive widgets and moving surfaces in the engine, against their definitions (docs/reactive.md).

Each test compiles a small scene, plays a cursor path with a press force through the C engine
(``Renderer``) and checks the outcome exactly: the tick a press and a release fire at, the normal force
a toggle plays before and after it flips (the other state's table value, read from a table switched
with ``select_state``), where a dragged thumb ends and the value and detent ticks it reports, the
stick-slip events of a finger on a moving surface (none when it moves with the finger; those of a
still surface stroked at twice the speed, and the closed-form stick period, when it moves against
it), and a click's drive, audio and friction transient sample for sample.
"""
import math

import numpy as np
import pytest

from shapedisplay.author.scene.compiler import compile_scene, select_state
from shapedisplay.render import Renderer
from shapedisplay.render.cursor import CursorPath, parse_stroke

RATE = 10_000.0

SCENE = """
[canvas]
size = "{size}"
resolution = "0.5 mm"
[device]
profile = "handheld-stick"
[mapping]
n_base = "1 N"
n_gain = "1 N/mm"
"""


def compile_text(tmp_path, widgets: str, size="80x40 mm", name="s"):
    p = tmp_path / f"{name}.toml"
    p.write_text(SCENE.format(size=size) + widgets)
    return compile_scene(p).table


def still(x, y, press, rate=RATE):
    """A cursor resting at (x, y) m with the press force ``press`` (N) per tick."""
    press = np.asarray(press, dtype=np.float64)
    n = press.size
    return CursorPath(np.arange(n) / rate, np.full(n, x), np.full(n, y), rate, "still", press)


BUTTON = """
[[widget]]
id = "b"
type = "button"
center = "20,20 mm"
size = "20x20 mm"
height = "1 mm"
press = "2 N release 1 N"
click = "{click}"
"""


def test_press_fires_at_the_crossing_tick_and_releases_only_below_the_hysteresis_level(tmp_path):
    table = compile_text(tmp_path, BUTTON.format(click="off"))
    # 0 -> 3 N, down to 1.5 N (between the levels: still pressed), up to 3 N (no second press), down to 0
    press = np.concatenate([np.linspace(0, 3, 301), np.linspace(3, 1.5, 200), np.linspace(1.5, 3, 200),
                            np.linspace(3, 0, 301)])
    r = Renderer(table, model="jump", tick_rate=RATE)
    res = r.render(still(0.020, 0.020, press))
    k_press = int(np.flatnonzero((press[1:] >= 2.0) & (press[:-1] < 2.0))[0]) + 1
    k_release = int(np.flatnonzero(press < 1.0)[np.flatnonzero(press < 1.0) > k_press][0])
    assert list(res.event_kind) == ["press", "release"] and set(res.event_widget) == {"b"}
    assert res.event_t[0] == pytest.approx(k_press / RATE, abs=1e-12)
    assert res.event_t[1] == pytest.approx(k_release / RATE, abs=1e-12)
    np.testing.assert_array_equal(res.press, press)
    # the same press beside the button: nothing
    assert r.render(still(0.060, 0.020, press)).event_kind.size == 0


def test_a_press_already_above_the_threshold_does_not_press_a_widget_the_finger_slides_onto(tmp_path):
    table = compile_text(tmp_path, BUTTON.format(click="off"))
    r = Renderer(table, model="jump", tick_rate=RATE)
    res = r.render(parse_stroke("2,20 -> 25,20 @ 20mm/s press 3N", RATE))
    assert res.event_kind.size == 0


TOGGLE = """
[[widget]]
id = "t"
type = "toggle"
center = "40,20 mm"
size = "40x16 mm"
state = "off"
height = "1.5 mm"
click = "burst 0.5 10ms"
"""


def test_toggle_plays_the_other_states_table_value_from_the_tick_after_the_flip(tmp_path):
    """A still finger on the 'on' knob: N is the 'off' table's value up to the flip tick, the 'on' table's
    value (select_state) from the next tick; a second press flips it back."""
    table = compile_text(tmp_path, TOGGLE)
    x, y = 0.050, 0.020                             # 3/4 of the toggle: the 'on' knob
    press = np.zeros(2000)
    press[500:700] = 3.0
    press[1200:1400] = 3.0
    r = Renderer(table, model="jump", tick_rate=RATE)
    res = r.render(still(x, y, press))
    n_off = Renderer(table, model="jump", tick_rate=RATE).render(still(x, y, np.zeros(50))).normal_force[-1]
    on = select_state(table, "t", "on")
    n_on = Renderer(on, model="jump", tick_rate=RATE).render(still(x, y, np.zeros(50))).normal_force[-1]
    assert n_on > n_off + 0.5
    N = res.normal_force
    assert (N[:501] == n_off).all() and (N[501:1201] == n_on).all() and (N[1201:] == n_off).all()
    kinds = [(k, float(v)) for k, v in zip(res.event_kind, res.event_value) if k == "toggle"]
    assert kinds == [("toggle", 1.0), ("toggle", 0.0)]
    t_toggle = res.event_t[res.event_kind == "toggle"]
    np.testing.assert_allclose(t_toggle, [500 / RATE, 1200 / RATE], atol=1e-12)


SLIDER = """
[[widget]]
id = "s"
type = "slider"
position = "10,10 mm"
size = "54x14 mm"
value = 0.25
thumb_size = "10 mm"
height = "1.2 mm"
detents = 7
detent_height = "0.4 mm"
detent_width = "2 mm"
press = "2 N"
"""


@pytest.mark.parametrize("x1_mm", [47.0, 70.0, 12.0])
def test_dragged_thumb_sits_at_the_clamped_cursor_minus_the_grab_offset(tmp_path, x1_mm):
    """Grab the thumb 1.5 mm right of its centre, drag to x1 (inside the track, beyond its right end, beyond
    its left end): the thumb centre is clamp(x1 - 1.5 mm) on the track, `value` its place along it, one detent
    tick per detent passed."""
    table = compile_text(tmp_path, SLIDER)
    sl = next(e for e in table.meta["scene"]["reactions"] if e["id"] == "s")["slider"]
    track0, length, c0 = sl["track0_m"], sl["track_len_m"], sl["thumb_m"]
    assert c0 == pytest.approx(track0 + 0.25 * length)
    x0 = c0 + 1.5e-3
    r = Renderer(table, model="jump", tick_rate=RATE)
    r.reset()
    path = parse_stroke(f"{x0 * 1e3!r},17 -> {x0 * 1e3 + 0.1!r},17 @ 20mm/s; press 3N 20ms; "
                        f"-> {x1_mm!r},17 @ 20mm/s press 3N; press 0N 10ms", RATE)
    for x, y, p in zip(path.x, path.y, path.press):
        r.step(x, y, p)
    ev = r.reactions()
    st = r.widget_states()["s"]
    held = np.flatnonzero(path.press > 0)
    grab = path.x[held[0]] - c0                   # the cursor at the press minus the thumb centre
    x1 = path.x[held[-1]]                         # the cursor at the last tick pressed (x1, one tick short)
    assert x1 == pytest.approx(x1_mm * 1e-3, abs=2.5e-6)
    want = min(max(x1 - grab, track0), track0 + length)
    assert st["thumb"] == pytest.approx(want, abs=1e-12)
    assert st["value"] == pytest.approx((want - track0) / length, abs=1e-12)
    assert st["grabbed"] == 0 and st["dx"] == pytest.approx(want - c0, abs=1e-12)
    kinds = [e.kind for e in ev]
    assert kinds[:2] == ["press", "grab"] and kinds[-3:] == ["release", "value", "drop"]
    assert ev[-2].value == pytest.approx(st["value"], abs=1e-12)
    detents = sl["detent0_m"] + sl["detent_step_m"] * np.arange(sl["detents"])
    passed = int(np.sum((detents > min(c0, want)) & (detents <= max(c0, want))))
    ticks = [e for e in ev if e.kind == "click"]
    assert len(ticks) == passed and passed > 0
    assert sorted(e.value for e in ticks) == sorted(float(k) for k in
                                                    np.flatnonzero((detents > min(c0, want)) & (detents <= max(c0, want))) + 1)
    # the thumb stays where it was dropped: N is highest there on a stroke along the track
    res = Renderer(table, model="jump", tick_rate=RATE).render(parse_stroke("10,17 -> 64,17 @ 50mm/s", RATE))
    assert res.x[int(np.argmax(res.normal_force))] == pytest.approx(c0, abs=0.6e-3)   # a fresh renderer: at rest


def test_a_press_on_the_track_beside_the_thumb_does_not_grab(tmp_path):
    table = compile_text(tmp_path, SLIDER)
    r = Renderer(table, model="jump", tick_rate=RATE)
    res = r.render(still(0.055, 0.017, np.r_[np.zeros(10), np.full(100, 3.0), np.zeros(10)]))
    assert list(res.event_kind) == ["press", "release"]


SURFACE = """
[[widget]]
id = "belt"
type = "button"
position = "5,5 mm"
size = "60x30 mm"
height = "0.5 mm"
ramp = "2 mm"
corner_radius = "0 mm"
motion = "{v} mm/s {dir}"
"""


def test_surface_moving_with_the_finger_gives_no_stick_slip(tmp_path):
    table = compile_text(tmp_path, SURFACE.format(v=10, dir="+x"))
    r = Renderer(table, model="exact", tick_rate=RATE)
    res = r.render(parse_stroke("20,20 -> 25,20 @ 10mm/s", RATE))
    assert res.event_time.size == 0
    assert np.abs(res.friction_force).max() < 1e-9
    moving = Renderer(table, model="exact", tick_rate=RATE).render(parse_stroke("20,20 -> 25,20 @ 20mm/s", RATE))
    assert moving.event_time.size > 5                # the same stroke faster than the belt: stick-slip


@pytest.mark.parametrize("model", ["jump", "exact"])
def test_surface_moving_against_the_finger_plays_a_still_surface_stroked_at_twice_the_speed(tmp_path, model):
    """Finger +10 mm/s over a belt moving -10 mm/s: the events of a still plateau of the same N stroked at
    20 mm/s (to 1e-12 s), and (jump model) the closed-form stick period of the pad at 20 mm/s."""
    from shapedisplay.author.perception import stick_period
    belt = compile_text(tmp_path, SURFACE.format(v=10, dir="-x"), name="belt")
    plate = compile_text(tmp_path, SURFACE.replace('motion = "{v} mm/s {dir}"\n', ""), name="plate")
    a = Renderer(belt, model=model, tick_rate=RATE).render(parse_stroke("20,20 -> 25,20 @ 10mm/s", RATE))
    b = Renderer(plate, model=model, tick_rate=RATE).render(parse_stroke("20,20 -> 30,20 @ 20mm/s", RATE))
    N = a.normal_force[1:]
    assert np.ptp(N) == 0 and N[0] == b.normal_force[-1]      # a plateau: one N throughout
    n = min(a.event_time.size, b.event_time.size)
    assert n > 20 and abs(a.event_time.size - b.event_time.size) <= 1
    np.testing.assert_allclose(a.event_time[:n], b.event_time[:n], rtol=0, atol=1e-12)
    if model == "jump":
        period = stick_period(float(N[0]), 0.02, Renderer(belt).device)
        np.testing.assert_allclose(np.diff(a.event_time[2:n]), period, rtol=2e-3)


@pytest.mark.parametrize("click", ["burst 0.6 10ms, drop 60% 20ms", "burst 0.3 4ms", "drop 40% 5ms"])
def test_click_drive_and_friction_transient_match_their_definition_sample_for_sample(tmp_path, click):
    """A still finger on a button pressed at tick k: drive A sin(2 pi f tau)(1 - tau/T) for 0 <= tau < T at
    every tick and audio sample (tau from the press tick's time), and N times 1 - D (1 - tau/T_d) for
    0 < tau < T_d, against the same finger not pressing."""
    table = compile_text(tmp_path, BUTTON.format(click=click))
    ck = table.meta["scene"]["reactions"][0]["click"]
    A, f, T, D, Td = ck["gain"], ck["hz"], ck["time_s"], ck["drop"], ck["drop_s"]
    press = np.zeros(600)
    press[100:400] = 3.0
    r = Renderer(table, model="jump", tick_rate=RATE, audio_rate=48_000.0)
    res = r.render(still(0.020, 0.020, press))
    base = r.render(still(0.020, 0.020, np.zeros(600)))
    k = 100
    assert list(res.event_kind[:2]) == ["press", "click"] and res.event_t[1] == pytest.approx(k / RATE, abs=1e-12)
    t = res.t
    tau = t - t[k]
    np.seterr(divide="ignore", invalid="ignore")
    want = np.where((tau >= 0) & (tau < T), A * np.sin(2 * np.pi * f * tau) * (1 - tau / max(T, 1e-300)), 0.0)
    assert res.event_time.size == 0                  # a still finger: no stick-slip burst, the drive is the click
    # drive at every tick
    drive = _drive(r, still(0.020, 0.020, press))
    np.testing.assert_allclose(drive, want, rtol=0, atol=1e-15)
    # audio at every sample
    ta = np.arange(res.audio.size) / 48_000.0
    tau_a = ta - t[k]
    want_a = np.where((tau_a >= 0) & (tau_a < T), A * np.sin(2 * np.pi * f * tau_a) * (1 - tau_a / max(T, 1e-300)), 0.0)
    np.testing.assert_allclose(res.audio, want_a, rtol=0, atol=1e-15)
    # friction transient on N
    g = np.where((tau > 0) & (tau < Td), 1 - D * (1 - tau / Td), 1.0)
    np.testing.assert_allclose(res.normal_force, base.normal_force * g, rtol=1e-15, atol=0)
    assert (res.normal_force[k + 1] < base.normal_force[k + 1]) == (D > 0)


def _drive(r, cursor):
    """The drive of every tick, stepped online."""
    r.reset()
    return np.array([r.step(x, y, p) for x, y, p in zip(cursor.x, cursor.y, cursor.press)])


OBJECT = """
[[widget]]
id = "floor"
type = "groove"
from = "10,20 mm"
to = "70,20 mm"
width = "20 mm"
depth = "0.3 mm"
overlap = "add"

[[widget]]
id = "box"
type = "button"
center = "20,20 mm"
size = "10x10 mm"
height = "1 mm"
ramp = "3 mm"
movable = true
overlap = "add"
"""


def test_dragged_object_follows_the_finger_and_the_finger_feels_the_floor_beneath(tmp_path):
    table = compile_text(tmp_path, OBJECT)
    r = Renderer(table, model="jump", tick_rate=RATE)
    r.reset()
    path = parse_stroke("21,20 -> 21,20.1 @ 20mm/s; press 3N 20ms; -> 51,20.1 @ 20mm/s press 3N; press 0N 10ms", RATE)
    Ns = []
    for x, y, p in zip(path.x, path.y, path.press):
        r.step(x, y, p)
        Ns.append(r.last["normal_force"])
    st = r.widget_states()["box"]
    assert st["dx"] == pytest.approx(0.030, abs=1e-12) and st["dy"] == pytest.approx(0.0, abs=1e-12)
    assert [e.kind for e in r.reactions()] == ["press", "grab", "release", "drop"]
    floor = Renderer(table, model="jump", tick_rate=RATE)
    # while dragged the finger reads the floor (the groove), not the box on it
    n_floor = floor.render(parse_stroke("30,20.1 -> 31,20.1 @ 20mm/s", RATE)).normal_force[-1]
    i = int(np.argmin(np.abs(path.x - 0.031)))
    assert Ns[i] == pytest.approx(n_floor, abs=1e-12)
    # after the drop the box rests at 50 mm: a fresh pass over it there feels it (the renderer keeps its state)
    r2 = Renderer(table, model="jump", tick_rate=RATE)
    res = r2.render(parse_stroke("12,20 -> 60,20 @ 50mm/s", RATE))
    assert res.x[int(np.argmax(res.normal_force))] == pytest.approx(0.020, abs=3e-3)   # at rest in a new run


def test_keyframed_part_moves_and_is_read_where_it_is(tmp_path):
    table = compile_text(tmp_path, """
[[widget]]
id = "hop"
type = "button"
center = "20,20 mm"
size = "10x10 mm"
height = "1 mm"
ramp = "2 mm"
motion = ["0 s: 0,0 mm", "0.1 s: 30,0 mm", "1 s: 30,0 mm"]
""")
    r = Renderer(table, model="jump", tick_rate=RATE)
    at_home = r.render(still(0.020, 0.020, np.zeros(50))).normal_force[-1]
    away = r.render(still(0.050, 0.020, np.zeros(1500))).normal_force
    assert away[100] < at_home - 0.5 and away[-1] == pytest.approx(at_home, abs=1e-9)



def test_a_new_run_can_keep_the_widgets_where_they_are(tmp_path):
    """reset(keep_widgets=True) (sd_react_restart: what the studio does between strokes) keeps a flipped toggle
    flipped; reset() puts it back."""
    table = compile_text(tmp_path, TOGGLE)
    r = Renderer(table, model="jump", tick_rate=RATE)
    r.reset()
    for p in [0.0] * 5 + [3.0] * 5 + [0.0] * 5:
        r.step(0.050, 0.020, p)
    n_on = r.last["normal_force"]
    assert r.widget_states()["t"]["state"] == 1.0
    r.reset(keep_widgets=True)
    r.step(0.050, 0.020)
    r.step(0.050, 0.020)
    assert r.widget_states()["t"]["state"] == 1.0 and r.last["normal_force"] == n_on
    assert r.widget_states()["t"]["pressed"] == 0.0
    r.reset()
    assert r.widget_states()["t"]["state"] == 0.0
