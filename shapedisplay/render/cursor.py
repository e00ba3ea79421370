"""Cursor input: strokes, recorded traces and pointing-stick force input.

Everything becomes a :class:`CursorPath`: tick times (s) and cursor
positions x, y (m) on the table grid.

Stroke syntax (coordinates in mm on the table grid; unit optional)
------------------------------------------------------------------
``"0,10 -> 60,10 -> 60,30 @ 20 mm/s"``
    a polyline through the points at constant speed;
``"0,2 <-> 60,2 @ 20mm/s x3"``
    back and forth: ``A <-> B`` is ``A -> B -> A``; ``xN`` repeats the
    whole path N times (only closed paths, i.e. ending where they start,
    may be repeated);
``"0:60mm @ 50 mm/s"``
    1-D shorthand: along x from 0 to 60 mm at y = 0;
``"0,2 -> 60,2 <-> 30,2 @ 10 mm/s"``
    ``<->`` may appear once anywhere: the path up to it is run, then the
    part after it, then everything back to the start.

The speed is required and must be > 0; the path must have positive length.

Segments and presses
--------------------
A stroke is one or more **segments joined by** ``;``, played one after the
other; the cursor goes on from where the last segment left it:

``"62,30 -> 62,60 @ 30mm/s; press 2N 150ms; 62,60 -> 90,60 @ 20mm/s"``
    move, then hold the cursor still at 62,60 and press with 2 N for
    150 ms, then move on (not pressing);
``"10,5 -> 40,5 @ 20mm/s press 2N"``
    a move segment may end in ``press F``: the cursor moves while pressing
    with force F the whole segment (``x3 press 1N`` with a repeat);
``"-> 90,60 @ 20mm/s"``
    a move segment may leave out its first point: it starts where the
    cursor is;
``"press 2N 150ms at 62,60"``
    a press segment names where it presses with ``at x,y`` (required when
    it is the first segment; elsewhere it must be where the cursor is).

A move segment must start where the previous segment ended (a stroke never
jumps); ``press 0N 100ms`` holds still without pressing. The press force
(N, along z, what a pointing stick measures beside the tangential force)
is :attr:`CursorPath.press`: the force of the segment each tick falls in (a
tick on a boundary belongs to the later segment; the last tick to the last
segment), None for a stroke without any ``press``.

The cursor is sampled at ``t_i = i / tick_rate`` until it reaches the end
(it rests on the end point for the remainder of the last tick).

One offline path holds at most :data:`MAX_TICKS` ticks (1000 s at 10 kHz,
about 2.5 GB of per-tick arrays in a render); a longer stroke or trace is
refused before anything is allocated (split it, or play it tick by tick
with :meth:`~shapedisplay.render.renderer.Renderer.step`).
"""
from __future__ import annotations

import csv
import math
import os
import re
from dataclasses import dataclass

import numpy as np

from shapedisplay.errors import FileFormatError, InputError
from shapedisplay.units import parse_quantity
from shapedisplay.table.devices import check_tick_rate

#: Most ticks one offline cursor path may hold.
MAX_TICKS = 10_000_000
#: Largest cursor coordinate accepted, metres. A tactile display is centimetres wide; beyond
#: a kilometre a position is a unit mistake or garbage, and products such as V*t lose precision.
MAX_POSITION_M = 1e3
#: Fastest stroke accepted, m/s (a finger moves at most a few m/s; this is far beyond).
MAX_SPEED_M_S = 1e3
#: Largest CSV recording read (trace or force file), bytes: MAX_TICKS rows of ~60 characters.
MAX_CSV_BYTES = 600 * 1024 * 1024
#: Largest press force accepted, N (a finger presses a stick with a few newtons).
MAX_PRESS_N = 1e3


def check_ticks(duration: float, rate: float, what: str) -> int:
    """Number of ticks ``floor(duration * rate + 1e-9) + 1`` of a path, refused beyond :data:`MAX_TICKS`."""
    n = duration * rate
    if not (math.isfinite(n) and math.ceil(n) + 1 <= MAX_TICKS):
        raise InputError(f"{what} lasts {duration:.4g} s: {n:.4g} ticks at {rate:g} Hz, more than the "
                         f"{MAX_TICKS:,} ticks of one offline render (split it or lower the tick rate)")
    return int(math.floor(n + 1e-9)) + 1


@dataclass(frozen=True)
class CursorPath:
    """Cursor positions over time.

    Attributes
    ----------
    t : ndarray (n,), float64
        Strictly increasing times, s.
    x, y : ndarray (n,), float64
        Positions on the table grid, m.
    tick_rate : float or None
        Hz when ``t`` is a uniform tick grid, None for raw recorded traces.
    source : str
        Human-readable origin (stroke text, file name).
    press : ndarray (n,), float64, or None
        Press force at each sample, N (along z: what a pointing stick
        measures beside the tangential force; >= 0), or None: not pressing.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    tick_rate: float | None = None
    source: str = ""
    press: np.ndarray | None = None

    def __post_init__(self):
        t = np.asarray(self.t, dtype=np.float64)
        if t.ndim != 1 or t.size < 2:
            raise InputError(f"cursor path '{self.source}' needs at least 2 samples (got {t.size})")
        if self.press is not None:
            f = np.asarray(self.press, dtype=np.float64)
            if f.shape != t.shape:
                raise InputError(f"cursor `press` must have shape {t.shape} (got {f.shape})")
            if not np.all(np.isfinite(f)):
                raise InputError(f"cursor path '{self.source}': `press` holds NaN or infinite values")
            bad = (f < 0) | (f > MAX_PRESS_N)
            if bad.any():
                i = int(np.argmax(bad))
                raise InputError(f"cursor path '{self.source}': `press` must be a force within 0..{MAX_PRESS_N:g} N "
                                 f"(got press[{i}]={f[i]:.6g} N)")
        for name in ("t", "x", "y"):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.shape != t.shape:
                raise InputError(f"cursor `{name}` must have shape {t.shape} (got {a.shape})")
            if not np.all(np.isfinite(a)):
                raise InputError(f"cursor path '{self.source}': `{name}` holds NaN or infinite values")
            if name != "t" and a.size and float(np.max(np.abs(a))) > MAX_POSITION_M:
                i = int(np.argmax(np.abs(a)))
                raise InputError(f"cursor path '{self.source}': `{name}` must be within +-{MAX_POSITION_M:g} m "
                                 f"(got {name}[{i}]={a[i]:.6g} m)")
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0))
            raise InputError(f"cursor path '{self.source}': time must increase strictly "
                             f"(t[{i}]={t[i]!r}, t[{i + 1}]={t[i + 1]!r})")

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def resample(self, tick_rate: float) -> "CursorPath":
        """Linear interpolation onto ``t0 + i / tick_rate`` covering the path."""
        rate = check_tick_rate(tick_rate)
        n = check_ticks(self.duration, rate, f"cursor path '{self.source}'")
        if n < 2:
            raise InputError(f"cursor path '{self.source}' lasts {self.duration:.3g} s, "
                             f"less than one tick at {rate:g} Hz")
        t = self.t[0] + np.arange(n) / rate
        press = None if self.press is None else np.interp(t, self.t, self.press)
        return CursorPath(t, np.interp(t, self.t, self.x), np.interp(t, self.t, self.y), rate, self.source, press)


_POINT = re.compile(r"^\s*(-?[0-9.eE+-]+)\s*(mm)?\s*,\s*(-?[0-9.eE+-]+)\s*(mm)?\s*$")


def _parse_point(text: str, stroke: str):
    m = _POINT.match(text)
    if not m:
        raise InputError(f"stroke {stroke!r}: cannot read point {text.strip()!r}; write 'x,y' in mm, e.g. '0,10'")
    try:
        x, y = float(m.group(1)), float(m.group(3))
    except ValueError:
        raise InputError(f"stroke {stroke!r}: cannot read point {text.strip()!r}; write 'x,y' in mm, e.g. '0,10'") \
            from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"stroke {stroke!r}: point {text.strip()!r} is not finite")
    if max(abs(x), abs(y)) * 1e-3 > MAX_POSITION_M:
        raise InputError(f"stroke {stroke!r}: point {text.strip()!r} lies beyond +-{MAX_POSITION_M:g} m")
    return x * 1e-3, y * 1e-3


_PRESS_TAIL = re.compile(r"^(.*?)\s+press\s+(\S.*)$", re.I)
_PRESS_SEGMENT = re.compile(r"^press\s+(\S+(?:\s*N)?)\s+(\S+(?:\s*[mu]?s)?)(?:\s+at\s+(.+))?$", re.I)


def _press_force(text: str, stroke: str) -> float:
    f = parse_quantity(text.strip(), "N", f"press force of stroke {stroke!r}")
    if not 0 <= f <= MAX_PRESS_N:
        raise InputError(f"stroke {stroke!r}: a press force must be within 0..{MAX_PRESS_N:g} N (got {text.strip()!r})")
    return f


def _move_segment(text: str, stroke: str, rate: float, here):
    """One move segment: ``(points (k, 2) m, speed m/s, press N or None)``; ``here`` is where the cursor
    is (None at the start), used when the segment leaves out its first point."""
    if "@" not in text:
        raise InputError(f"stroke {stroke!r} needs a speed, e.g. '0,10 -> 60,10 @ 20 mm/s'")
    path_txt, _, rest = text.partition("@")
    rest = rest.strip()
    press = None
    m = _PRESS_TAIL.match(rest)
    if m:
        rest, press = m.group(1).strip(), _press_force(m.group(2), stroke)
    repeat = 1
    m = re.match(r"^(.*\S)\s+[xX]\s*([0-9]+)\s*$", rest)
    if m:
        rest, repeat = m.group(1), int(m.group(2))
    speed = parse_quantity(rest.strip(), "m/s", "stroke speed")
    if not speed > 0:
        raise InputError(f"stroke {stroke!r}: speed must be > 0 (got {rest.strip()!r})")
    if speed > MAX_SPEED_M_S:
        raise InputError(f"stroke {stroke!r}: speed must be <= {MAX_SPEED_M_S:g} m/s (got {rest.strip()!r})")
    if repeat < 1:
        raise InputError(f"stroke {stroke!r}: repeat count must be >= 1 (got x{repeat})")
    m1 = re.match(r"^\s*(-?[0-9.eE+-]+)\s*(mm)?\s*:\s*(-?[0-9.eE+-]+)\s*(mm)?\s*$", path_txt)
    if m1:  # 1-D shorthand "x0:x1 mm" along y = 0
        path_txt = f"{m1.group(1)},0 -> {m1.group(3)},0"
    lead = None
    if path_txt.lstrip().startswith("->") or path_txt.lstrip().startswith("<->"):
        if here is None:
            raise InputError(f"stroke {stroke!r}: the first segment must start with a point, e.g. '0,10 -> 60,10'")
        lead = here
        path_txt = path_txt.lstrip()
        path_txt = path_txt[2:] if path_txt.startswith("->") else path_txt
    if path_txt.count("<->") > 1:
        raise InputError(f"stroke {stroke!r}: '<->' may appear only once")
    if "<->" in path_txt:
        before, after = path_txt.split("<->")
        fwd = ([lead] if lead is not None else []) + [_parse_point(p, stroke) for p in before.split("->") if
                                                       lead is None or p.strip()] + \
              [_parse_point(p, stroke) for p in after.split("->")]
        pts = fwd + fwd[-2::-1]
    else:
        pts = ([lead] if lead is not None else []) + [_parse_point(p, stroke) for p in path_txt.split("->")]
    if len(pts) < 2:
        raise InputError(f"stroke {stroke!r} needs at least two points joined by '->' or '<->'")
    if repeat > 1:
        if pts[0] != pts[-1]:
            raise InputError(f"stroke {stroke!r}: 'x{repeat}' repeats only closed paths (use '<->')")
        # the duration is known from one lap: refuse before the repeated points are built
        lap = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(pts, pts[1:]))
        check_ticks(repeat * lap / speed, rate, f"stroke {stroke!r}")
        pts = pts + pts[1:] * (repeat - 1)
    return np.array(pts, dtype=np.float64), speed, press


def parse_stroke(text: str, tick_rate: float) -> CursorPath:
    """Parse a stroke (see module docstring) and sample it at ``tick_rate`` (Hz).

    Returns a :class:`CursorPath` on the tick grid; its ``press`` holds the
    press force of every tick when some segment presses (else None).
    """
    rate = check_tick_rate(tick_rate)
    if not isinstance(text, str) or not text.strip():
        raise InputError(f"stroke {text!r} needs a speed, e.g. '0,10 -> 60,10 @ 20 mm/s'")
    parts = [p.strip() for p in text.split(";")]
    if any(not p for p in parts):
        raise InputError(f"stroke {text!r}: an empty segment between ';' (segments: 'A -> B @ speed', "
                         f"'press 2N 150ms')")
    # each segment: ("move", knots (k, 2) m, arc-length knots, speed, press) or ("press", point, duration, force)
    segs, here, pressing = [], None, False
    for k, part in enumerate(parts):
        m = _PRESS_SEGMENT.match(part)
        if m:
            force = _press_force(m.group(1), text)
            dur = parse_quantity(m.group(2), "s", f"press time of stroke {text!r}")
            if not 0 < dur < math.inf:
                raise InputError(f"stroke {text!r}: a press lasts a time > 0 (got {m.group(2)!r})")
            at = _parse_point(m.group(3), text) if m.group(3) else None
            if here is None and at is None:
                raise InputError(f"stroke {text!r}: a press that starts the stroke names where it presses: "
                                 f"'press {m.group(1)} {m.group(2)} at x,y'")
            if here is not None and at is not None and max(abs(at[0] - here[0]), abs(at[1] - here[1])) > 1e-12:
                raise InputError(f"stroke {text!r}: segment {k + 1} presses at {at[0] * 1e3:g},{at[1] * 1e3:g} mm "
                                 f"but the cursor is at {here[0] * 1e3:g},{here[1] * 1e3:g} mm (a stroke never jumps)")
            here = at if here is None else here
            segs.append(("press", here, dur, force))
            pressing = True
            continue
        if part.lower().startswith("press"):
            raise InputError(f"stroke {text!r}: cannot read the press segment {part!r}; write 'press F T', "
                             f"e.g. 'press 2N 150ms' (optionally 'at x,y')")
        P, speed, force = _move_segment(part, text, rate, here)
        if here is not None and max(abs(P[0, 0] - here[0]), abs(P[0, 1] - here[1])) > 1e-12:
            raise InputError(f"stroke {text!r}: segment {k + 1} starts at {P[0, 0] * 1e3:g},{P[0, 1] * 1e3:g} mm "
                             f"but the cursor is at {here[0] * 1e3:g},{here[1] * 1e3:g} mm (a stroke never jumps; "
                             f"start it with '->' to go on from where the cursor is)")
        seg = np.hypot(np.diff(P[:, 0]), np.diff(P[:, 1]))
        s_knots = np.concatenate([[0.0], np.cumsum(seg)])
        if not float(s_knots[-1]) > 0:
            raise InputError(f"stroke {text!r} has zero length" if len(parts) == 1 else
                             f"stroke {text!r}: segment {k + 1} has zero length")
        segs.append(("move", P, s_knots, speed, force))
        pressing = pressing or force is not None
        here = (float(P[-1, 0]), float(P[-1, 1]))
    durations = [float(sg[2] if sg[0] == "press" else sg[2][-1] / sg[3]) for sg in segs]
    duration = math.fsum(durations)
    check_ticks(duration, rate, f"stroke {text!r}")
    n = int(math.ceil(duration * rate - 1e-9)) + 1
    t = np.arange(n) / rate
    if len(segs) == 1 and segs[0][0] == "move":
        # one move: the arc length is the time times the speed (as strokes have always been sampled)
        _, P, s_knots, speed, force = segs[0]
        s = np.minimum(t * speed, float(s_knots[-1]))
        x = np.interp(s, s_knots, P[:, 0])
        y = np.interp(s, s_knots, P[:, 1])
        press = None if force is None else np.full(n, force)
        return CursorPath(t, x, y, rate, text, press)
    starts = np.concatenate([[0.0], np.cumsum(durations)[:-1]])
    which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segs) - 1)
    x, y, press = np.empty(n), np.empty(n), np.zeros(n)
    for j, sg in enumerate(segs):
        sel = which == j
        if not sel.any():
            continue
        if sg[0] == "press":
            x[sel], y[sel] = sg[1]
            press[sel] = sg[3]
            continue
        _, P, s_knots, speed, force = sg
        s = np.minimum((t[sel] - starts[j]) * speed, float(s_knots[-1]))
        x[sel] = np.interp(s, s_knots, P[:, 0])
        y[sel] = np.interp(s, s_knots, P[:, 1])
        press[sel] = 0.0 if force is None else force
    return CursorPath(t, x, y, rate, text, press if pressing else None)


def _read_csv(path, what: str, ncols: tuple[int, ...]):
    p = os.fspath(path)
    rows = []
    try:
        size = os.stat(p).st_size
        if size > MAX_CSV_BYTES:
            raise FileFormatError(f"{what} '{p}': {size} bytes exceed the limit of {MAX_CSV_BYTES} "
                                  f"(at most {MAX_TICKS:,} rows are played)")
        with open(p, newline="", encoding="utf-8") as fh:
            for r in csv.reader(fh):
                if r and not r[0].lstrip().startswith("#"):
                    if len(rows) > MAX_TICKS or len(r) > 8:
                        raise FileFormatError(f"{what} '{p}': more than {MAX_TICKS:,} rows or 8 columns")
                    rows.append(r)
    except FileNotFoundError:
        raise FileFormatError(f"{what} '{p}': no such file") from None
    except IsADirectoryError:
        raise FileFormatError(f"{what} '{p}': is a directory") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise FileFormatError(f"{what} '{p}': unreadable ({exc})") from None
    header = None
    if rows:
        try:
            [float(v) for v in rows[0]]
        except ValueError:
            header = [h.strip().lower() for h in rows[0]]
            rows = rows[1:]
    if len(rows) < 2:
        raise FileFormatError(f"{what} '{p}': needs at least 2 data rows (got {len(rows)})")
    width = len(rows[0])
    if width not in ncols:
        raise FileFormatError(f"{what} '{p}': expected {' or '.join(map(str, ncols))} columns (got {width})")
    try:
        data = np.array([[float(v) for v in r] for r in rows], dtype=np.float64)
    except ValueError as exc:
        raise FileFormatError(f"{what} '{p}': non-numeric value ({exc})") from None
    except Exception:
        raise FileFormatError(f"{what} '{p}': rows have different numbers of columns") from None
    if data.ndim != 2:
        raise FileFormatError(f"{what} '{p}': rows have different numbers of columns")
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(f"{what} '{p}': row {r + 1} column {c + 1} is NaN or infinite")
    t = data[:, 0]
    if np.any(np.diff(t) <= 0):
        i = int(np.argmax(np.diff(t) <= 0))
        raise InputError(f"{what} '{p}': time must increase strictly (row {i + 1} t={t[i]!r}, "
                         f"row {i + 2} t={t[i + 1]!r})")
    return header, data


def load_trace_csv(path, tick_rate: float | None = None) -> CursorPath:
    """Read a recorded cursor trace: CSV columns ``t, x, y`` and optionally ``press``.

    ``t`` in seconds; ``x``, ``y`` in millimetres on the table grid, or in
    metres if the header names them ``x_m, y_m``; ``press`` the press force
    in newtons (along z, >= 0; the path's :attr:`CursorPath.press`). A
    header row is optional; ``#`` lines are comments. Time must increase
    strictly; NaN is rejected. With ``tick_rate`` the trace is resampled
    onto a uniform tick grid (the renderer does this itself otherwise; the
    press is interpolated linearly like the position).
    """
    header, data = _read_csv(path, "trace", (3, 4))
    scale = 1.0 if header and header[1] in ("x_m", "x [m]") else 1e-3
    press = data[:, 3] if data.shape[1] == 4 else None
    cp = CursorPath(data[:, 0], data[:, 1] * scale, data[:, 2] * scale, None, os.fspath(path), press)
    return cp.resample(tick_rate) if tick_rate is not None else cp


def force_input(forces, alpha: float, force_rate: float, tick_rate: float, start=(0.0, 0.0),
                source: str = "force input") -> CursorPath:
    """Pointing-stick force to cursor motion, ``v = alpha f`` (alpha in m/(N s)).

    Parameters
    ----------
    forces : ndarray (n,) or (n, 2), float64, N
        Force samples (x only, or x and y) at ``force_rate``.
    alpha : float
        Cursor gain, m/(N s) (80 mm/(N s) handheld, 316 mm/(N s) desktop).
    force_rate : float
        Hz of the force samples.
    tick_rate : float
        Hz of the returned path.
    start : (float, float)
        Cursor position at the first sample, m.
    """
    f = np.asarray(forces, dtype=np.float64)
    if f.ndim == 1:
        f = np.stack([f, np.zeros_like(f)], axis=1)
    if f.ndim != 2 or f.shape[1] != 2 or f.shape[0] < 2:
        raise InputError(f"`forces` must have shape (n,) or (n, 2) with n >= 2 (got {np.shape(forces)})")
    if not np.all(np.isfinite(f)):
        raise InputError("`forces` holds NaN or infinite values")
    if not (math.isfinite(alpha) and alpha > 0):
        raise InputError(f"cursor gain `alpha` must be > 0 m/(N*s) (got {alpha!r}); "
                         "set `cursor_gain` in the device profile")
    if not (math.isfinite(force_rate) and force_rate > 0):
        raise InputError(f"`force_rate` must be > 0 Hz (got {force_rate!r})")
    dt = 1.0 / force_rate
    v = alpha * f
    pos = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (v[1:] + v[:-1]) * dt, axis=0)])
    t = np.arange(f.shape[0]) * dt
    cp = CursorPath(t, pos[:, 0] + start[0], pos[:, 1] + start[1], None, source)
    return cp.resample(tick_rate)


def load_force_csv(path, alpha: float, tick_rate: float, start=(0.0, 0.0)) -> CursorPath:
    """Read a force recording (CSV ``t, fx``, ``t, fx, fy`` or ``t, fx, fy, fz``; s and N) and apply ``v = alpha f``.

    The tangential force is integrated on its own (possibly irregular) time
    stamps with the trapezoid rule, then resampled to ``tick_rate``. ``fz``,
    the force along z a pointing stick measures beside the tangential one,
    is the press (:attr:`CursorPath.press`, N >= 0).
    """
    _, data = _read_csv(path, "force file", (2, 3, 4))
    if not (math.isfinite(alpha) and alpha > 0):
        raise InputError(f"cursor gain `alpha` must be > 0 m/(N*s) (got {alpha!r}); "
                         "set `cursor_gain` in the device profile")
    t = data[:, 0]
    f = data[:, 1:3] if data.shape[1] >= 3 else np.stack([data[:, 1], np.zeros(len(t))], axis=1)
    press = data[:, 3] if data.shape[1] == 4 else None
    v = alpha * f
    pos = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None], axis=0)])
    cp = CursorPath(t, pos[:, 0] + start[0], pos[:, 1] + start[1], None, os.fspath(path), press)
    return cp.resample(tick_rate)
