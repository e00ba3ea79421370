"""Pruning never changes what the renderer plays: scene tables vs their dense equivalents."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from shapedisplay.render.cursor import parse_stroke
from shapedisplay.render.renderer import Renderer
from shapedisplay.author.scene import compile_scene, load_scene, select_state
from shapedisplay.table.model import FrictionTable

SCENES = Path(__file__).resolve().parent.parent / "assets" / "scenes"

# strokes over the phone: up the screen at x = 62 mm (toggle, slider track, two app buttons, top ridge);
# along the slider (detents and thumb); a poly-line over the call button, the toggle and three app buttons
PHONE_STROKES = ("62,2 -> 62,156 @ 30mm/s",
                 "2,66 -> 78,66 @ 20mm/s",
                 "2,36 -> 78,36 -> 78,100 -> 2,100 @ 60mm/s")


def dense_equivalent(table: FrictionTable, name: str) -> FrictionTable:
    """The scene compiled densely, without pruning, coded like ``table``.

    Heights of the whole canvas, slopes and forces computed on the whole canvas
    (``test_scene._dense_reference``, independent of the compiler's blocks,
    margins and shared patches), stored as one block with the same
    quantization. Pruning must not change one code of it.
    """
    from test_scene import _dense_reference
    ref = _dense_reference(load_scene(SCENES / f"{name}.toml"))
    return FrictionTable.from_dense(table.grid, {n: np.atleast_2d(ref[n]) for n in table.channels},
                                    dict(table.quant), table.meta)


def assert_same_play(a, b):
    np.testing.assert_array_equal(a.event_time, b.event_time)
    np.testing.assert_array_equal(a.event_amplitude, b.event_amplitude)
    np.testing.assert_array_equal(a.normal_force, b.normal_force)
    np.testing.assert_array_equal(a.friction_force, b.friction_force)
    np.testing.assert_array_equal(a.audio, b.audio)


@pytest.fixture(scope="module")
def phone():
    res = compile_scene(SCENES / "phone.toml")
    return res.table, dense_equivalent(res.table, "phone")


def test_dense_equivalent_holds_the_same_values_and_is_big(phone):
    t, d = phone
    for n in t.channels:
        np.testing.assert_array_equal(d.dense(n), t.dense(n))
    assert d.stored_bytes > 3 * t.stored_bytes   # same coding, every sample stored
    assert t.stored_bytes <= 0.10 * t.dense_bytes


@pytest.mark.parametrize("model", ["exact", "jump"])
def test_phone_plays_the_same_events_as_its_dense_table(phone, model):
    t, d = phone
    ra, rb = Renderer(t, model=model), Renderer(d, model=model)
    total = 0
    for stroke in PHONE_STROKES:
        cp = parse_stroke(stroke, ra.tick_rate)
        a, b = ra.render(cp), rb.render(cp)
        assert_same_play(a, b)
        total += a.event_time.size
    assert total > 100  # the strokes really cross widgets and stick-slip


def test_online_steps_match_the_dense_table(phone):
    t, d = phone
    ra, rb = Renderer(t, model="jump"), Renderer(d, model="jump")
    cp = parse_stroke(PHONE_STROKES[0], ra.tick_rate)
    for x, y in zip(cp.x, cp.y):
        assert ra.step(x, y) == rb.step(x, y)
        np.testing.assert_array_equal(ra.last, rb.last)
    assert ra.event_count == rb.event_count > 0


def test_widgets_change_what_is_played(phone):
    """Guard against a vacuous comparison: the slopes and heights of the widgets matter."""
    t, _ = phone
    flat = FrictionTable.from_dense(t.grid, {n: np.full((t.grid.rows, t.grid.cols), t.background[n])
                                             for n in t.channels}, dict(t.quant), t.meta)
    cp = parse_stroke(PHONE_STROKES[0], 10_000)
    a, b = Renderer(t, model="jump").render(cp), Renderer(flat, model="jump").render(cp)
    assert not np.array_equal(a.event_time, b.event_time)


def test_toggle_state_selected_at_runtime_plays_like_the_compiled_state(tmp_path):
    src = (SCENES / "phone.toml").read_text().replace('state = "off"', 'state = "on"')
    (tmp_path / "phone_on.toml").write_text(src)
    on = compile_scene(tmp_path / "phone_on.toml").table
    off = compile_scene(SCENES / "phone.toml").table
    switched = select_state(off, "wifi", "on")
    cp = parse_stroke("48,36 -> 78,36 @ 20mm/s", 10_000)   # along the toggle
    a, b = Renderer(switched, model="exact").render(cp), Renderer(on, model="exact").render(cp)
    assert_same_play(a, b)
    c = Renderer(off, model="exact").render(cp)
    assert not np.array_equal(a.event_time, c.event_time)


@pytest.mark.parametrize("name, stroke", [("media-player", "0,0 -> 160,0 @ 20mm/s"),
                                          ("keypad", "2,64 -> 68,64 -> 68,28 @ 30mm/s"),
                                          ("map", "2,40 -> 118,40 @ 40mm/s")])
def test_other_scenes_play_the_same_as_dense(name, stroke):
    t = compile_scene(SCENES / f"{name}.toml").table
    d = dense_equivalent(t, name)
    for n in t.channels:
        np.testing.assert_array_equal(t.dense(n), d.dense(n), err_msg=n)
    ra, rb = Renderer(t, model="jump"), Renderer(d, model="jump")
    cp = parse_stroke(stroke, ra.tick_rate)
    a, b = ra.render(cp), rb.render(cp)
    assert_same_play(a, b)
    assert a.event_time.size > 0
