"""Charts along a stroke: slip density over stated windows and the widgets a stroke crosses, checked by data.

The slip-density series is compared with a direct count over the event list
and the tick states; widget spans with the widgets' boxes for strokes whose
crossings are known in closed form.
"""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shapedisplay.render.strokes import arc_length, density_window, slip_density, widget_spans


def _direct_density(t, state, events, period, window):
    """Window by window with plain Python: ticks and events whose time lies in [a, b)."""
    t0, t_end = t[0], t[-1] + period
    frac, rate, k = [], [], 0
    while t0 + k * window < t_end - 1e-9 * window:
        a, b = t0 + k * window, min(t0 + (k + 1) * window, t_end)
        b = t_end if b > t_end - 1e-9 * window else b
        inside = [i for i in range(len(t)) if a <= t[i] < b or (b == t_end and t[i] >= a and i == len(t) - 1)]
        n = len(inside)
        frac.append(sum(1 for i in inside if state[i]) / n if n else 0.0)
        rate.append(sum(1 for e in events if a <= e < b) / (b - a))
        k += 1
    return np.array(frac), np.array(rate)


def test_slip_density_equals_a_direct_count_over_the_event_list():
    rng = np.random.default_rng(7)
    period = 1e-4
    t = np.arange(2345) * period
    state = (rng.random(t.size) < 0.03).astype(np.int8)
    events = np.sort(rng.uniform(0, t[-1] + period, 311))
    d = slip_density(t, state, events, period, window=0.02)
    frac, rate = _direct_density(t, state, events, period, 0.02)
    assert d.window == 0.02 and d.window_label() == "20 ms windows"
    assert np.allclose(d.slip_fraction, frac, rtol=0, atol=1e-12)
    assert np.allclose(d.event_rate, rate, rtol=1e-12, atol=0)
    # totals: every tick and every event counted once; the tick-weighted mean is the summary's slip fraction
    assert d.ticks.sum() == t.size and d.events.sum() == events.size
    assert np.sum(d.slip_fraction * d.ticks) / d.ticks.sum() == pytest.approx(state.mean(), abs=1e-12)
    assert d.edges[0] == t[0] and d.edges[-1] == pytest.approx(t[-1] + period)


def test_slip_density_of_the_renderer_matches_its_summary_and_events():
    from shapedisplay.render.cursor import parse_stroke
    from shapedisplay.render.renderer import Renderer
    table = _phone_table()
    r = Renderer(table, model="exact", tick_rate=10000.0)
    res = r.render(parse_stroke("62,20 -> 62,80 @ 30mm/s", r.tick_rate))
    d = slip_density(res.t, res.state, res.event_time, 1.0 / res.tick_rate)
    assert d.window == density_window(res.duration + 1e-4, 1e-4)
    assert np.sum(d.slip_fraction * d.ticks) / d.ticks.sum() == pytest.approx(res.summary()["slip_fraction"])
    assert d.events.sum() == res.event_time.size
    frac, rate = _direct_density(res.t, res.state, res.event_time, 1e-4, d.window)
    assert np.allclose(d.slip_fraction, frac) and np.allclose(d.event_rate, rate)


@pytest.mark.parametrize("duration, period, expected", [
    (5.13, 1e-4, 0.05), (1.0, 1e-4, 0.01), (0.003, 1e-4, 0.001), (300.0, 1e-3, 2.0), (0.0, 1e-4, 0.001)])
def test_density_window_is_a_round_number_near_a_150th_of_the_stroke(duration, period, expected):
    assert density_window(duration, period) == pytest.approx(expected)


# ----------------------------------------------------------------- widgets crossed
_PHONE = None


def _phone_table():
    global _PHONE
    if _PHONE is None:
        from pathlib import Path

        from shapedisplay.author.scene import compile_scene
        _PHONE = compile_scene(Path(__file__).resolve().parents[1] / "assets" / "scenes" / "phone.toml").table
    return _PHONE


def test_widget_spans_of_a_straight_stroke_are_the_widget_extents():
    from shapedisplay.table.widgets import widget_map
    widgets = widget_map(_phone_table())
    assert len(widgets) >= 8
    x_mm, y0_mm, y1_mm = 62.0, 2.0, 156.0
    y = np.linspace(y0_mm, y1_mm, 4001) * 1e-3
    x = np.full_like(y, x_mm * 1e-3)
    spans = widget_spans(x, y, widgets)
    expected = []
    for w in widgets:
        bx0, by0, bx1, by1 = w["bbox_m"]
        if bx0 <= x_mm * 1e-3 <= bx1 and by1 >= y0_mm * 1e-3 and by0 <= y1_mm * 1e-3:
            expected.append((w["id"], max(by0, y0_mm * 1e-3) - y0_mm * 1e-3, min(by1, y1_mm * 1e-3) - y0_mm * 1e-3))
    expected.sort(key=lambda e: e[1])
    assert len(expected) >= 4       # the README stroke crosses several widgets
    assert [s["id"] for s in spans] == [e[0] for e in expected]
    for s, (_, a, b) in zip(spans, expected):
        assert s["s0"] == pytest.approx(a, abs=1e-12) and s["s1"] == pytest.approx(b, abs=1e-12)


def test_widget_spans_diagonal_reentry_and_misses():
    box = [{"id": "b", "x0": 1.0, "y0": 1.0, "x1": 3.0, "y1": 2.0}]
    # diagonal through the box: enters at x = 1 (y = 1), leaves at y = 2 (x = 2)
    spans = widget_spans(np.array([0.0, 4.0]), np.array([0.0, 4.0]), box)
    assert len(spans) == 1
    assert spans[0]["s0"] == pytest.approx(math.sqrt(2)) and spans[0]["s1"] == pytest.approx(2 * math.sqrt(2))
    # there and back along y = 1.5, sampled coarsely: leaves at x = 3, comes back at x = 3 -> two spans
    x = np.array([0.0, 2.0, 5.0, 2.5, 0.0])
    y = np.full(5, 1.5)
    s = arc_length(x, y)
    spans = widget_spans(x, y, box)
    assert [(d["s0"], d["s1"]) for d in spans] == [pytest.approx((1.0, 3.0)), pytest.approx((s[2] + 2.0, s[2] + 4.0))]
    # a stroke that misses, one that only touches a corner, and a cursor at rest inside
    assert widget_spans(np.array([0.0, 5.0]), np.array([3.0, 3.0]), box) == []
    assert widget_spans(np.array([0.0, 2.0]), np.array([2.0, 0.0]), box) == []
    rest = widget_spans(np.array([2.0, 2.0]), np.array([1.5, 1.5]), box)
    assert rest == [{"id": "b", "s0": 0.0, "s1": 0.0}]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=2, max_size=12))
def test_widget_span_length_equals_the_densely_sampled_path_inside(points):
    box = {"id": "w", "x0": -1.0, "y0": -2.0, "x1": 2.0, "y1": 1.5}
    p = np.array(points)
    spans = widget_spans(p[:, 0], p[:, 1], [box])
    # independent: sample every segment densely and count the length of sub-steps whose midpoint is inside
    total, n = 0.0, 4000
    for (xa, ya), (xb, yb) in zip(p[:-1], p[1:]):
        u = (np.arange(n) + 0.5) / n
        mx, my = xa + u * (xb - xa), ya + u * (yb - ya)
        inside = (mx >= -1) & (mx <= 2) & (my >= -2) & (my <= 1.5)
        total += inside.sum() * math.hypot(xb - xa, yb - ya) / n
    seg = max((math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(p[:-1], p[1:])), default=0.0)
    assert sum(d["s1"] - d["s0"] for d in spans) == pytest.approx(total, abs=2 * seg / n * len(p) + 1e-9)
    for d in spans:
        assert 0 <= d["s0"] <= d["s1"] <= arc_length(p[:, 0], p[:, 1])[-1] + 1e-9


# ----------------------------------------------------------------- the plot
def test_play_plot_marks_widgets_and_is_byte_stable(tmp_path):
    pytest.importorskip("matplotlib")
    from PIL import Image

    from shapedisplay.table.widgets import widget_map
    from shapedisplay.render.cursor import parse_stroke
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.render.sinks import plot_trace
    table = _phone_table()
    r = Renderer(table, model="exact", tick_rate=10000.0)
    res = r.render(parse_stroke("62,20 -> 62,80 @ 30mm/s", r.tick_rate))
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    plot_trace(a, res, widgets=widget_map(table))
    plot_trace(b, res, widgets=widget_map(table))
    assert a.read_bytes() == b.read_bytes()
    info = Image.open(a).info
    assert not any("matplotlib" in str(v) for v in info.values())      # no software version stamped in
    # the shaded spans change the picture against the same plot without widgets
    plot_trace(b, res)
    assert a.read_bytes() != b.read_bytes()
