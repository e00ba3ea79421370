"""Shared pieces of the reports: event matching, error measures, timing, JSON, progress, plots.

Plain functions on arrays; no report logic. All times in seconds.
"""
from __future__ import annotations

import json
import math
import os
import sys
import time

import numpy as np

from shapedisplay.atomic import write_text
from shapedisplay.errors import require


# ================================================================ events and errors
def match_events(ref, got, window):
    """Pair events of ``got`` with events of ``ref`` one to one.

    Parameters
    ----------
    ref, got : ndarray (n,), (m,), float64
        Sorted event times, s.
    window : float
        Largest accepted time difference, s.

    Returns
    -------
    pairs : ndarray (p, 2), int64
        Indices (i into ``ref``, j into ``got``), sorted by ``i``.
    missing : int
        Reference events with no partner.
    spurious : int
        Events of ``got`` with no partner.
    """
    ref = np.asarray(ref, dtype=np.float64)
    got = np.asarray(got, dtype=np.float64)
    if ref.size == 0 or got.size == 0:
        return np.zeros((0, 2), dtype=np.int64), int(ref.size), int(got.size)
    pos = np.searchsorted(got, ref)
    cand = []
    for i, p in enumerate(pos):
        for j in (p - 1, p):
            if 0 <= j < got.size:
                d = abs(got[j] - ref[i])
                if d <= window:
                    cand.append((d, i, j))
    cand.sort()
    used_i, used_j, pairs = set(), set(), []
    for _, i, j in cand:
        if i in used_i or j in used_j:
            continue
        used_i.add(i)
        used_j.add(j)
        pairs.append((i, j))
    pairs.sort()
    arr = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return arr, int(ref.size - len(pairs)), int(got.size - len(pairs))


def match_window(ref_times, duration):
    """Matching window: a third of the shortest reference interval (or of the run if < 2 events), s."""
    ref_times = np.asarray(ref_times)
    if ref_times.size >= 2:
        return float(np.min(np.diff(ref_times))) / 3.0
    return duration / 3.0


def event_errors(ref_t, ref_a, got_t, got_a, window):
    """Errors of one run against the reference events.

    Returns a dict: ``matched``, ``missing``, ``spurious``, ``event_rms_s``,
    ``event_max_s`` (over matched events), ``period_rel_rms`` and
    ``period_rel_max`` (relative error of the intervals between consecutive
    matched events), ``amplitude_rel_rms`` (RMS amplitude error over matched
    events, relative to the RMS reference amplitude). Values that cannot be
    computed (no matched events, fewer than two) are ``None``.
    """
    pairs, missing, spurious = match_events(ref_t, got_t, window)
    out = {"ref_events": int(len(ref_t)), "events": int(len(got_t)), "matched": int(len(pairs)),
           "missing": missing, "spurious": spurious, "event_rms_s": None, "event_max_s": None,
           "period_rel_rms": None, "period_rel_max": None, "amplitude_rel_rms": None}
    if len(pairs) == 0:
        return out
    i, j = pairs[:, 0], pairs[:, 1]
    d = np.asarray(got_t)[j] - np.asarray(ref_t)[i]
    out["event_rms_s"] = float(np.sqrt(np.mean(d * d)))
    out["event_max_s"] = float(np.max(np.abs(d)))
    ra = np.asarray(ref_a)[i]
    ga = np.asarray(got_a)[j]
    den = math.sqrt(float(np.mean(ra * ra)))
    if den > 0:
        out["amplitude_rel_rms"] = float(math.sqrt(float(np.mean((ga - ra) ** 2))) / den)
    consec = (np.diff(i) == 1) & (np.diff(j) == 1)
    if np.any(consec):
        dr = np.diff(np.asarray(ref_t)[i])[consec]
        dg = np.diff(np.asarray(got_t)[j])[consec]
        rel = np.abs(dg - dr) / dr
        out["period_rel_rms"] = float(np.sqrt(np.mean(rel * rel)))
        out["period_rel_max"] = float(np.max(rel))
    return out


def waveform_error(ref_t, ref_a, got_t, got_a, duration, scale, audio_rate=8000.0):
    """Normalised RMS error of the burst waveform, ``rms(w - w_ref) / rms(w_ref)``.

    Both event lists are rendered with the default burst (300 Hz carrier,
    5 ms rise, 30 ms decay, retrigger) at ``audio_rate`` after dividing the
    amplitudes by ``scale`` (so nothing clips). None if the reference is silent.
    """
    from shapedisplay.render.bursts import render_bursts

    def synth(t, a):
        order = np.argsort(t, kind="stable")
        w, _ = render_bursts(np.asarray(t)[order], np.asarray(a)[order] / scale, 0.0, duration, audio_rate)
        return w

    wr = synth(ref_t, ref_a)
    wg = synth(got_t, got_a)
    den = float(np.sqrt(np.mean(wr * wr)))
    if den == 0:
        return None
    return float(np.sqrt(np.mean((wg - wr) ** 2)) / den)


# ================================================================ timing
def cpu_time(fn, repeats=3, warmup=True):
    """Minimum CPU time (s, ``time.process_time``) of ``fn()`` over ``repeats`` runs after a warm-up.

    Returns ``(seconds, last_result)``.
    """
    res = fn() if warmup else None
    best = math.inf
    for _ in range(max(1, repeats)):
        t0 = time.process_time()
        res = fn()
        best = min(best, time.process_time() - t0)
    return best, res


def cpu_per_call(fn, runs=3, min_batch_s=0.02, warmup=True):
    """CPU seconds (``time.process_time``) of one call of ``fn()``, measured ``runs`` times.

    Each run calls ``fn`` repeatedly until at least ``min_batch_s`` of CPU
    time has passed and divides by the number of calls, so calls of a few
    microseconds are timed as reliably as calls of a second. The clock is
    read after groups of calls (1, then as many as done so far, at most as
    many as the time left needs), a few dozen times per run: reading the
    process CPU clock is a system call of about 0.5 us, a tenth of a short
    call, and would be counted as part of it if read after every call. The
    same function times the renderer and the scipy peers. Returns ``(list of
    per-call seconds, one per run, last_result)``.
    """
    res = fn() if warmup else None
    out = []
    for _ in range(max(1, runs)):
        calls = 0
        group = 1
        t0 = time.process_time()
        while True:
            for _ in range(group):
                res = fn()
            calls += group
            el = time.process_time() - t0
            if el >= min_batch_s:
                break
            # as many calls again as done so far, fewer when the time left needs fewer
            left = (min_batch_s - el) * calls / el if el > 0.0 else calls
            group = max(1, min(calls, int(left) + 1))
        out.append(el / calls)
    return out, res


_FLOORS = None


def _floors():
    """The engine library (:func:`..runtime.native.library`) with the timing floors' argument types declared.

    The floors are C loops in ``shapedisplay/render/sd_floors.c``, compiled
    into the engine with the runtime's own flags; bound here once.
    """
    global _FLOORS
    if _FLOORS is None:
        import ctypes

        from shapedisplay.render.native import library
        lib = library()
        vp, i64, f64 = ctypes.c_void_p, ctypes.c_int64, ctypes.c_double
        for name, args in (("sd_floor_tick", [vp, vp, i64, f64]),
                           ("sd_floor_audio", [vp, i64, vp, i64, f64]),
                           ("sd_floor_interface", [vp, vp, vp, vp, vp, vp, vp, i64, f64])):
            fn = getattr(lib, name)
            fn.argtypes = args
            fn.restype = None
        _FLOORS = lib
    return _FLOORS


def floor_costs(n=1 << 20, runs=3):
    """Least work any tick-based renderer does, timed now: ``(s per tick, s per audio sample)``.

    Per tick: read the tick's input and write one output computed from it
    (one multiply). Per audio sample: write one sample, a stored carrier
    period times an envelope value. C loops over ``n`` elements
    (``sd_floor_tick`` and ``sd_floor_audio`` in the engine library, see
    :func:`_floors`), min of ``runs`` runs after a warm-up. A renderer that
    writes its outputs for every tick and every audio sample cannot cost less
    than ``ticks * per_tick + samples * per_sample``; against a solver whose
    cost grows with the number of events and not with the duration this
    bounds the speed-up from above.
    """
    lib = _floors()
    V = np.full(n, 0.02)
    out = np.empty(n)
    period = np.sin(2.0 * math.pi * np.arange(160) / 160.0)      # one 300 Hz period at 48 kHz
    pv, po, pp = V.ctypes.data, out.ctypes.data, period.ctypes.data
    lib.sd_floor_tick(pv, po, 8, 1e-3)
    lib.sd_floor_audio(po, 320, pp, period.size, 0.5)
    bt = ba = math.inf
    for _ in range(max(1, runs)):
        t0 = time.process_time()
        lib.sd_floor_tick(pv, po, n, 1e-3)
        t1 = time.process_time()
        lib.sd_floor_audio(po, n, pp, period.size, 0.5)
        t2 = time.process_time()
        bt, ba = min(bt, t1 - t0), min(ba, t2 - t1)
    return bt / n, ba / (n - n % period.size)


def interface_floor(n, runs=3, min_batch_s=0.02):
    """Least work of the model's interface over ``n`` ticks, timed now: CPU s per call.

    ``run_kernel`` takes six per-tick input rows (t, V, N, mu_s, mu_k, gain)
    and returns four per-tick rows (friction, phase, x, v). The floor is one
    call of a C loop (``sd_floor_interface`` in the engine library, see
    :func:`_floors`) that reads the six input rows and writes four output
    rows, each output a multiply of an input (or of a sum of two), over ``n`` ticks: the call
    itself (through ctypes) included, min of ``runs`` runs of at least
    ``min_batch_s`` each, after a warm-up. Measured at the path's own length
    (a short path's rows stay in cache: the least cost). A model that returns
    those rows cannot cost less than this, whatever its physics.
    """
    lib = _floors()
    n = int(n)
    rows = [np.full(n, 0.5 + k) for k in range(6)]
    out = np.empty((4, n))
    args = (*(r.ctypes.data for r in rows), out.ctypes.data, n, 1e-3)
    per_call, _ = cpu_per_call(lambda: lib.sd_floor_interface(*args), runs=runs, min_batch_s=min_batch_s)
    return min(per_call)


def stuck_floor(n, runs=3, min_batch_s=0.02):
    """Least work of a stick-slip model over ``n`` ticks, timed now: CPU s per call.

    Whatever its physics, a tick model advances its state on every tick: at
    the least, a stuck pad's stretch moves with the surface, the stick force
    follows it and is compared with the static limit, and the tick's outputs
    are written. The floor is ``run_kernel`` with the cheapest model
    (``jump``, whose stuck ticks run in a loop of their own) over ``n`` ticks
    on which the pad never breaks away (the static limit far above any force
    the path reaches): min of ``runs`` runs of at least ``min_batch_s`` each,
    after a warm-up.
    """
    from shapedisplay.render.models import run_kernel
    model, inputs = stuck_path(n)
    per_call, _ = cpu_per_call(lambda: run_kernel(model, *inputs), runs=runs, min_batch_s=min_batch_s)
    return min(per_call)


def stuck_path(n):
    """The model and the ``run_kernel`` inputs ``(t, V, N, mu_s, mu_k, gain)`` of :func:`stuck_floor`: ``n``
    ticks 1 ms apart at 1 mm/s under 1 MN (the stick force after them, k x, stays orders of magnitude below
    the static limit)."""
    from shapedisplay.render.models import get_model
    n = int(n)
    one = np.ones(n)
    return get_model("jump"), (np.arange(n) * 1e-3, np.full(n, 1e-3), np.full(n, 1e6), one, one, one)


def tick_percentiles(samples_ns):
    """p50 and p99 of per-tick times (ns array) in seconds."""
    a = np.asarray(samples_ns, dtype=np.float64) * 1e-9
    return float(np.percentile(a, 50)), float(np.percentile(a, 99))


# ================================================================ JSON
def clean_json(obj, path="", notes=None):
    """Copy of ``obj`` safe for strict JSON: non-finite floats become None (recorded in ``notes``)."""
    if isinstance(obj, dict):
        return {str(k): clean_json(v, f"{path}.{k}" if path else str(k), notes) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean_json(v, f"{path}[{i}]", notes) for i, v in enumerate(obj)]
    if isinstance(obj, np.ndarray):
        return clean_json(obj.tolist(), path, notes)
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        if not math.isfinite(f):
            if notes is not None:
                notes.append(path)
            return None
        return f
    return obj


def write_json(path, obj):
    """Write ``obj`` as strict JSON (no NaN/Infinity tokens), atomically."""
    write_text(path, json.dumps(obj, indent=1, allow_nan=False) + "\n")


def write_report(report, out_dir, kind, markdown, plots=None):
    """Write ``out_dir/<kind>.json`` (strict JSON), ``<kind>.md`` and, if ``plots`` is given, the PNGs.

    ``report`` is cleaned first (non-finite numbers become None; their paths
    are listed under ``non_finite_replaced``); ``plots(clean, out_dir)``
    returns the PNG file names (stored under ``plots``) and
    ``markdown(clean)`` the summary text. Returns the cleaned report.
    """
    notes = []
    clean = clean_json(report, notes=notes)
    clean["non_finite_replaced"] = notes
    if plots is not None:
        clean["plots"] = plots(clean, out_dir)
    write_json(os.path.join(out_dir, f"{kind}.json"), clean)
    write_text(os.path.join(out_dir, f"{kind}.md"), markdown(clean))
    return clean


# ================================================================ terminal
class Progress:
    """Plain-text progress bar on stderr (works without a TTY: one line per 10 %).

    On a TTY the bar is redrawn in place with a carriage return.
    """

    def __init__(self, total, label, stream=None, enabled=True):
        self.total = max(1, int(total))
        self.label = label
        self.n = 0
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_decile = -1
        self.t0 = time.perf_counter()

    def _bar(self, what=""):
        frac = min(1.0, self.n / self.total)
        filled = int(round(30 * frac))
        el = time.perf_counter() - self.t0
        return f"{self.label} [{'#' * filled}{'.' * (30 - filled)}] {self.n}/{self.total} {el:5.1f}s {what}"

    def update(self, k=1, what=""):
        self.n += k
        if not self.enabled:
            return
        if self.tty:
            self.stream.write("\r" + self._bar(what)[:120].ljust(120))
            self.stream.flush()
            return
        dec = int(10 * min(1.0, self.n / self.total))
        if dec != self._last_decile:
            self._last_decile = dec
            self.stream.write(self._bar(what) + "\n")
            self.stream.flush()

    def close(self):
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()


def text_table(headers, rows):
    """Fixed-width text table (list of str rows)."""
    cells = [[str(h) for h in headers]] + [["" if c is None else str(c) for c in r] for r in rows]
    w = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ["  ".join(c.ljust(w[i]) for i, c in enumerate(r)) for r in cells]
    lines.insert(1, "  ".join("-" * x for x in w))
    return "\n".join(lines)


def md_table(headers, rows):
    """Markdown table."""
    out = ["| " + " | ".join(str(h) for h in headers) + " |", "|" + "---|" * len(headers)]
    for r in rows:
        out.append("| " + " | ".join("" if c is None else str(c) for c in r) + " |")
    return "\n".join(out)


def fmt(v, spec=".3g", none="—"):
    """Format a number or None."""
    if v is None:
        return none
    if isinstance(v, float) and not math.isfinite(v):
        return none
    return format(v, spec)


# ================================================================ plots
def pyplot():
    """matplotlib.pyplot with the Agg backend (optional dependency)."""
    require("matplotlib", "plot", "Report plots")
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, path):
    """Save a figure as PNG atomically and close it.

    The saved area grows to hold everything drawn (nothing cropped), and the
    file carries no software version: the same figure gives the same bytes.
    """
    from shapedisplay.atomic import atomic_path
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight", pad_inches=0.08,
                    metadata={"Software": None})
    import matplotlib.pyplot as plt
    plt.close(fig)
