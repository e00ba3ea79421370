"""Strokes with segments joined by ';' and presses, and the press column of cursor recordings.

The interface: ``press F T`` holds the cursor still and presses with force F for time T; a move
segment may end in ``press F`` to move while pressing; segments play one after the other from where
the last one left the cursor. Checked against the segment durations worked out by hand.
"""
import numpy as np
import pytest

from shapedisplay.errors import InputError
from shapedisplay.render.cursor import CursorPath, load_force_csv, load_trace_csv, parse_stroke


def test_press_segment_holds_the_cursor_and_presses_for_its_time():
    cp = parse_stroke("62,30 -> 62,60 @ 30mm/s; press 2N 150ms; 62,60 -> 90,60 @ 20mm/s", 10_000)
    # 30 mm at 30 mm/s = 1 s, 150 ms still, 28 mm at 20 mm/s = 1.4 s: 2.55 s, 25 501 ticks
    assert cp.t.size == 25_501 and cp.tick_rate == 10_000
    on = np.flatnonzero(cp.press)
    assert on[0] == 10_000 and on.size == 1_500              # ticks 1.0 s .. 1.15 s (a boundary: the later segment)
    np.testing.assert_array_equal(cp.press[on], 2.0)
    assert (cp.x[on] == 0.062).all() and (cp.y[on] == 0.060).all()
    assert cp.x[-1] == pytest.approx(0.090) and cp.y[-1] == pytest.approx(0.060)
    # the moves around it: constant speed, no jump
    step = np.hypot(np.diff(cp.x), np.diff(cp.y))
    assert step.max() <= 30e-3 / 10_000 * (1 + 1e-9)


def test_move_while_pressing_and_continuing_segments():
    cp = parse_stroke("10,5 -> 40,5 @ 20mm/s press 2N", 1000)
    assert cp.t.size == 1501 and (cp.press == 2.0).all()
    cp = parse_stroke("press 1.5N 100ms at 5,5; -> 10,5 @ 10mm/s; press 0N 50ms; -> 10,8 @ 10mm/s press 1N", 1000)
    assert cp.t.size == 100 + 500 + 50 + 300 + 1
    np.testing.assert_array_equal(cp.press[:100], 1.5)
    assert (cp.press[100:650] == 0).all() and (cp.press[650:] == 1.0).all()
    assert cp.x[0] == 0.005 and cp.x[-1] == pytest.approx(0.010) and cp.y[-1] == pytest.approx(0.008)


def test_one_move_without_press_is_sampled_as_before():
    """A single move segment: the same ticks as strokes always had (arc length = time x speed), no press."""
    cp = parse_stroke("0,10 -> 60,10 -> 60,30 @ 20 mm/s", 1000)
    t = np.arange(4001) / 1000
    s = np.minimum(t * 0.02, 0.08)
    np.testing.assert_array_equal(cp.x, np.interp(s, [0, 0.06, 0.08], [0, 0.06, 0.06]))
    assert cp.press is None


@pytest.mark.parametrize("text,match", [
    ("press 2N 100ms", "names where it presses"),
    ("0,0 -> 10,0 @ 10mm/s; 20,0 -> 30,0 @ 10mm/s", "never jumps"),
    ("0,0 -> 10,0 @ 10mm/s; press 2N 100ms at 3,3", "never jumps"),
    ("0,0 -> 10,0 @ 10mm/s;; press 2N 100ms", "empty segment"),
    ("0,0 -> 10,0 @ 10mm/s; press 2N", "cannot read the press segment"),
    ("0,0 -> 10,0 @ 10mm/s; press 2N 0ms", "time > 0"),
    ("0,0 -> 10,0 @ 10mm/s press -1N", "within 0..1000 N"),
    ("0,0 -> 10,0 @ 10mm/s press 2", "needs a unit"),
    ("-> 10,0 @ 10mm/s", "must start with a point"),
    ("0,0 -> 10,0 @ 10mm/s; 10,0 -> 10,0 @ 10mm/s", "segment 2 has zero length"),
])
def test_bad_press_strokes(text, match):
    with pytest.raises(InputError, match=match):
        parse_stroke(text, 1000)


def test_cursor_csv_press_column(tmp_path):
    t = np.arange(0, 1.0, 0.001)
    press = np.where(t > 0.5, 2.0, 0.0)
    p = tmp_path / "rec.csv"
    np.savetxt(p, np.c_[t, 30 * t, 2 + 0 * t, press], delimiter=",", header="t,x,y,press", comments="")
    cp = load_trace_csv(p)
    np.testing.assert_array_equal(cp.press, press)
    r = cp.resample(2000)
    np.testing.assert_allclose(r.press, np.interp(r.t, t, press))
    np.savetxt(p, np.c_[t, 30 * t, 2 + 0 * t], delimiter=",", header="t,x,y", comments="")
    assert load_trace_csv(p).press is None


def test_force_csv_fz_is_the_press(tmp_path):
    t = np.arange(0, 1.0, 0.001)
    p = tmp_path / "stick.csv"
    np.savetxt(p, np.c_[t, 0.25 + 0 * t, 0 * t, 1.0 + t], delimiter=",", header="t,fx,fy,fz", comments="")
    cp = load_force_csv(p, 0.08, 1000)
    np.testing.assert_allclose(cp.press, 1.0 + cp.t)


def test_press_array_is_checked():
    t = np.arange(3) / 1000
    with pytest.raises(InputError, match="press"):
        CursorPath(t, t, t, 1000, "x", np.array([0, -1.0, 0]))
    with pytest.raises(InputError, match="shape"):
        CursorPath(t, t, t, 1000, "x", np.zeros(2))
