"""What charts along a played stroke show, in numpy only: distance, slip density, widgets crossed.

A renderer ticking at 10 kHz marks a tick "slip" when the pad is slipping at
its end; a slip of the published pad lasts about 70 us, so drawing the
per-tick state over a stroke of thousands of ticks gives a solid band that
says nothing about where slips happen. The charts show instead, over
consecutive time windows of a stated length:

* the fraction of ticks that end in slip (the summary's ``slip_fraction`` is
  the same count over the whole stroke), and
* the stick-slip event rate (events per second; every burst starts at one).

Charts along a stroke of a scene table also mark the widgets the cursor
crosses: :func:`widget_spans` clips the cursor path (piecewise linear between
ticks) against each widget's bounding box exactly.

Distances are along the cursor path in metres; times in seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Windows per stroke aimed at by :func:`density_window` (the window is rounded up to 1, 2 or 5 x 10^k s).
DENSITY_WINDOWS = 150


def arc_length(x, y) -> np.ndarray:
    """Distance travelled along the path at each point, shape (n,), units of ``x`` and ``y``."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.size == 0:
        return np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])


def density_window(duration: float, tick_period: float, windows: int = DENSITY_WINDOWS) -> float:
    """Window length (s) for a stroke of ``duration`` s: about ``windows`` windows, rounded up to
    1, 2 or 5 x 10^k s and never shorter than 10 ticks."""
    target = max(float(duration) / max(int(windows), 1), 10.0 * float(tick_period), 1e-9)
    exp = math.floor(math.log10(target))
    for m in (1.0, 2.0, 5.0, 10.0):
        w = m * 10.0 ** exp
        if w >= target * (1 - 1e-12):
            return w
    return 10.0 ** (exp + 1)    # pragma: no cover - the loop always returns


@dataclass
class SlipDensity:
    """Slip fraction and event rate over consecutive windows of a stroke.

    Attributes
    ----------
    window : float
        Window length, s.
    edges : ndarray of shape (n + 1,), float64
        Window boundaries, s (the first is the first tick's time; the last
        window ends one tick period after the last tick).
    slip_fraction : ndarray of shape (n,), float64
        Fraction of the window's ticks that end in slip, 0..1.
    event_rate : ndarray of shape (n,), float64
        Stick-slip events per second in the window.
    ticks, events : ndarray of shape (n,), int64
        Ticks and events counted in each window.
    """

    window: float
    edges: np.ndarray
    slip_fraction: np.ndarray
    event_rate: np.ndarray
    ticks: np.ndarray
    events: np.ndarray

    @property
    def centres(self) -> np.ndarray:
        """Middle time of each window, s."""
        return 0.5 * (self.edges[:-1] + self.edges[1:])

    def window_label(self) -> str:
        """The window length as a chart states it ("20 ms windows")."""
        w = self.window
        text = f"{w * 1e3:g} ms" if w < 1 else f"{w:g} s"
        return f"{text} windows"


def slip_density(t, state, event_time, tick_period: float, window: float | None = None) -> SlipDensity:
    """Slip fraction and event rate of a stroke over consecutive windows.

    Parameters
    ----------
    t : ndarray of shape (n,), float64
        Tick times, s, increasing.
    state : ndarray of shape (n,)
        0 stick / 1 slip at the end of each tick.
    event_time : ndarray of shape (m,), float64
        Stick-to-slip transition times, s.
    tick_period : float
        1 / tick rate, s: the last tick covers ``[t[-1], t[-1] + tick_period)``.
    window : float, optional
        Window length, s; default :func:`density_window`.

    Returns
    -------
    SlipDensity
        Window ``i`` covers ``[edges[i], edges[i + 1])``; a tick counts in the
        window holding its time, an event in the window holding its time. The
        last window ends with the stroke (it may be shorter than the others,
        and its rate divides by the part it covers).
    """
    t = np.asarray(t, dtype=np.float64)
    state = np.asarray(state)
    et = np.asarray(event_time, dtype=np.float64)
    if t.size == 0:
        z = np.zeros(0)
        return SlipDensity(float(window or 0.0), np.zeros(1), z, z, z.astype(np.int64), z.astype(np.int64))
    t0, t_end = float(t[0]), float(t[-1]) + float(tick_period)
    if window is None:
        window = density_window(t_end - t0, tick_period)
    n = max(1, math.ceil((t_end - t0) / window - 1e-9))
    edges = t0 + window * np.arange(n + 1, dtype=np.float64)
    edges[-1] = t_end
    tick_bin = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, n - 1)
    ticks = np.bincount(tick_bin, minlength=n)
    slipping = np.bincount(tick_bin, weights=(state != 0).astype(np.float64), minlength=n)
    inside = et[(et >= t0) & (et < t_end)]
    ev_bin = np.clip(np.searchsorted(edges, inside, side="right") - 1, 0, n - 1)
    events = np.bincount(ev_bin, minlength=n)
    span = np.diff(edges)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(ticks > 0, slipping / np.maximum(ticks, 1), 0.0)
        rate = np.where(span > 0, events / np.where(span > 0, span, 1.0), 0.0)
    return SlipDensity(float(window), edges, frac, rate, ticks.astype(np.int64), events.astype(np.int64))


def widget_spans(x, y, widgets) -> list[dict]:
    """Where a cursor path crosses each widget, as distances along the path.

    Parameters
    ----------
    x, y : ndarray of shape (n,), float64
        Cursor positions, metres (the path is straight between them).
    widgets : list of dict
        ``{"id", "bbox_m": [x0, y0, x1, y1]}`` (the table's widget map) or
        ``{"id", "x0", "y0", "x1", "y1"}`` (the preview's outlines), metres.

    Returns
    -------
    list of dict
        ``{"id", "s0", "s1"}`` (metres along the path, ``s0 < s1``), one per
        stretch of the path inside a widget's box (edges included), in order
        of ``s0``; a path that leaves and re-enters a widget gives it two.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.size == 0:
        return []
    s = arc_length(x, y)
    if x.size == 1:
        px, py, dx, dy, seg_len = x, y, np.zeros(1), np.zeros(1), np.zeros(1)
        s_start = s
    else:
        px, py = x[:-1], y[:-1]
        dx, dy = np.diff(x), np.diff(y)
        seg_len = np.diff(s)
        s_start = s[:-1]
    out = []
    for w in widgets:
        box = w.get("bbox_m") if "bbox_m" in w else [w["x0"], w["y0"], w["x1"], w["y1"]]
        bx0, by0, bx1, by1 = (float(v) for v in box)
        lo = np.zeros(px.size)
        hi = np.ones(px.size)
        ok = np.ones(px.size, dtype=bool)
        for p, d, a, b in ((px, dx, min(bx0, bx1), max(bx0, bx1)), (py, dy, min(by0, by1), max(by0, by1))):
            still = d == 0
            ok &= ~still | ((p >= a) & (p <= b))        # a segment parallel to the edges: inside or not
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                ta = np.where(still, -np.inf, (a - p) / np.where(still, 1.0, d))
                tb = np.where(still, np.inf, (b - p) / np.where(still, 1.0, d))
            lo = np.maximum(lo, np.minimum(ta, tb))
            hi = np.minimum(hi, np.maximum(ta, tb))
        ok &= lo <= hi
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            continue
        a_s = s_start[idx] + np.clip(lo[idx], 0.0, 1.0) * seg_len[idx]
        b_s = s_start[idx] + np.clip(hi[idx], 0.0, 1.0) * seg_len[idx]
        # consecutive segments form one span when the path stays inside from one to the next
        joined = (np.diff(idx) == 1) & (hi[idx[:-1]] >= 1.0) & (lo[idx[1:]] <= 0.0)
        breaks = np.flatnonzero(~joined)
        starts = np.concatenate([[0], breaks + 1])
        ends = np.concatenate([breaks, [idx.size - 1]])
        for i0, i1 in zip(starts, ends):
            if b_s[i1] > a_s[i0] or s[-1] == 0:     # a path that only touches a corner crosses nothing
                out.append({"id": str(w.get("id", "")), "s0": float(a_s[i0]), "s1": float(b_s[i1])})
    out.sort(key=lambda d: (d["s0"], d["id"]))
    return out
