"""Where rendered output goes: WAV files, ``.npz`` traces and plots.

Runtime side: imports nothing from the authoring side. Every file is
written atomically (:func:`shapedisplay.atomic.atomic_path`).

* :func:`write_wav` — mono WAV, 32-bit float (IEEE, format tag 3) or 16-bit
  PCM; readable by any audio tool (16-bit also by Python's ``wave``).
* :func:`write_trace` / :func:`read_trace` — the per-tick trace of a render
  as a plain ``.npz`` (readable with ``numpy.load``): ``t`` (s), ``x``,
  ``y`` (m), ``vx``, ``vy`` (m/s), ``normal_force``, ``friction_force`` (N),
  ``state`` (0 stick, 1 slip, at tick end), ``lateral_x``, ``lateral_y`` (N),
  ``skin_stretch`` (m), ``event_time`` (s), ``event_amplitude`` (the
  stick-slip events and their bursts), ``press`` (N, the press force of
  each tick), the reaction events of reactive widgets (docs/reactive.md)
  ``event_kind`` (str: press, release, click, toggle, value, grab, drop),
  ``event_widget`` (str, the widget's id), ``event_t`` (s) and
  ``event_value``, plus ``table_checksum``, ``model``, ``tick_rate``,
  ``audio_rate``, ``clipped`` and ``burst_policy``.
* :func:`plot_trace` — N(x), friction, slip fraction and event rate over
  stated windows, and bursts along the stroke, with the widgets crossed
  shaded (needs matplotlib: the ``plot`` extra).
"""
from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np

from shapedisplay.atomic import atomic_path
from shapedisplay.errors import FileFormatError, InputError, unknown_key

SAMPLE_FORMATS = ("float32", "int16")
TRACE_ARRAYS = ("t", "x", "y", "vx", "vy", "normal_force", "friction_force", "state", "lateral_x", "lateral_y",
                "skin_stretch", "event_time", "event_amplitude")
#: The reaction events of a trace (docs/reactive.md): kind and widget id (strings), time (s) and value, one per
#: event, beside the stick-slip ``event_time`` (whose meaning they leave alone); and the press of each tick.
REACTION_ARRAYS = ("event_kind", "event_widget", "event_t", "event_value")
TRACE_FORMAT = "shapedisplay-trace-1"
#: File suffixes :func:`plot_trace` writes (matplotlib back ends without extra packages).
PLOT_FORMATS = ("png", "pdf", "svg", "eps", "ps")


def write_wav(path, samples, rate, sample_format: str = "float32") -> Path:
    """Write mono ``samples`` (float, full scale [-1, 1]) to a WAV file.

    Parameters
    ----------
    path : str or PathLike
    samples : ndarray (n,), float
        Values outside [-1, 1] are limited (renderers already report
        clipping; this is a last guard). NaN is refused.
    rate : float
        Sample rate, Hz (integer after rounding, 1 Hz .. 4294967295 Hz).
    sample_format : {"float32", "int16"}

    Returns
    -------
    Path of the file written.
    """
    if sample_format not in SAMPLE_FORMATS:
        raise unknown_key("sample format", sample_format, SAMPLE_FORMATS)
    a = np.asarray(samples, dtype=np.float64)
    if a.ndim != 1:
        raise InputError(f"WAV samples must be one channel, shape (n,) (got {a.shape})")
    if not np.all(np.isfinite(a)):
        raise InputError("WAV samples hold NaN or infinite values")
    r = float(rate)
    if not (math.isfinite(r) and 1 <= round(r) < 2 ** 32):
        raise InputError(f"WAV `rate` must be a positive number of Hz (got {rate!r})")
    r = int(round(r))
    a = np.clip(a, -1.0, 1.0)
    if sample_format == "int16":
        data = np.round(a * 32767.0).astype("<i2").tobytes()
        tag, bits = 1, 16
    else:
        data = a.astype("<f4").tobytes()
        tag, bits = 3, 32
    block = bits // 8
    fmt = struct.pack("<HHIIHH", tag, 1, r, r * block, block, bits)
    chunks = b"fmt " + struct.pack("<I", len(fmt)) + fmt
    if tag == 3:  # non-PCM formats carry a fact chunk with the frame count
        chunks += b"fact" + struct.pack("<II", 4, a.size)
    chunks += b"data" + struct.pack("<I", len(data)) + data
    if len(data) % 2:
        chunks += b"\0"
    blob = b"RIFF" + struct.pack("<I", 4 + len(chunks)) + b"WAVE" + chunks
    with atomic_path(path) as tmp:
        tmp.write_bytes(blob)
    return Path(path)


def read_wav(path):
    """Read a mono WAV written by :func:`write_wav`; returns ``(samples float64, rate)``."""
    p = Path(path)
    try:
        blob = p.read_bytes()
    except FileNotFoundError:
        raise FileFormatError(f"WAV '{p}': no such file") from None
    if blob[:4] != b"RIFF" or blob[8:12] != b"WAVE":
        raise FileFormatError(f"WAV '{p}': not a RIFF/WAVE file")
    pos, fmt, data = 12, None, None
    while pos + 8 <= len(blob):
        cid, size = blob[pos:pos + 4], struct.unpack("<I", blob[pos + 4:pos + 8])[0]
        body = blob[pos + 8:pos + 8 + size]
        if cid == b"fmt ":
            fmt = struct.unpack("<HHIIHH", body[:16])
        elif cid == b"data":
            data = body
        pos += 8 + size + (size % 2)
    if fmt is None or data is None:
        raise FileFormatError(f"WAV '{p}': missing fmt or data chunk")
    tag, ch, rate, _, _, bits = fmt
    if ch != 1:
        raise FileFormatError(f"WAV '{p}': expected 1 channel (got {ch})")
    if tag == 3 and bits == 32:
        return np.frombuffer(data, "<f4").astype(np.float64), rate
    if tag == 1 and bits == 16:
        return np.frombuffer(data, "<i2").astype(np.float64) / 32767.0, rate
    raise FileFormatError(f"WAV '{p}': unsupported format tag {tag} with {bits} bits")


def write_trace(path, result, table_checksum: str = "") -> Path:
    """Write the per-tick trace of a :class:`~shapedisplay.render.renderer.RenderResult` (.npz, atomic)."""
    arrays = {}
    for name in TRACE_ARRAYS:
        a = np.asarray(getattr(result, name))
        arrays[name] = a.astype(np.int8) if name == "state" else a.astype(np.float64)
    press = getattr(result, "press", None)
    arrays["press"] = (np.zeros(arrays["t"].size) if press is None else np.asarray(press, dtype=np.float64))
    for name in REACTION_ARRAYS:
        a = np.asarray(getattr(result, name, ()))
        arrays[name] = a.astype(str) if name in ("event_kind", "event_widget") else a.astype(np.float64)
    if arrays["event_widget"].size and arrays["event_widget"].dtype.itemsize // 4 > 256:
        raise InputError("trace: a widget id longer than 256 characters cannot be written")
    arrays["table_checksum"] = np.array([str(table_checksum)])
    arrays["model"] = np.array([str(result.model)])
    arrays["burst_policy"] = np.array([str(getattr(result, "burst_policy", ""))])
    arrays["format"] = np.array([TRACE_FORMAT])
    arrays["tick_rate"] = np.array(float(result.tick_rate))
    arrays["audio_rate"] = np.array(float(result.audio_rate))
    arrays["clipped"] = np.array(int(result.clipped))
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
    return Path(path)


#: Most ticks (and events) a trace file may hold: the renderer's limit of one offline render.
MAX_TRACE_TICKS = 10_000_000
#: Most events per tick a trace may record on average (stick-slip fires several per tick at speed).
_EVENTS_PER_TICK = 8
#: Most bytes of arrays one trace file may make the reader hold.
MAX_TRACE_BYTES = 1 << 30
_TRACE_STRINGS = ("table_checksum", "model", "burst_policy", "format")
_TRACE_SCALARS = {"tick_rate": ("f8",), "audio_rate": ("f8",), "clipped": ("i8", "i4")}
_EVENT_ARRAYS = ("event_time", "event_amplitude")
_TEXT = tuple(f"U{k}" for k in range(1, 257))


def read_trace(path, required=TRACE_ARRAYS) -> dict:
    """Read a trace written by :func:`write_trace` into a dict of arrays and scalars.

    The file goes through the bounded ``.npz`` reader (entry names, sizes and
    ``.npy`` headers checked before anything is inflated; at most
    :data:`MAX_TRACE_TICKS` ticks). Every float array must be finite, the
    per-tick arrays of one length, ``state`` 0 or 1. ``required`` names the
    arrays that must be present (others of :data:`TRACE_ARRAYS` are read
    when present).

    Raises :class:`FileFormatError` for a missing, unreadable, foreign or damaged file.
    """
    from shapedisplay.table.container import NpzReader

    p = Path(path)
    label = f"trace '{p}'"
    if p.is_dir() or not p.is_file():
        raise FileFormatError(f"{label}: no such file" if not p.exists() else f"{label}: is a directory")
    names = (*TRACE_ARRAYS, "press", *REACTION_ARRAYS, *_TRACE_STRINGS, *_TRACE_SCALARS)
    out: dict = {}
    with NpzReader(p, label, None, max_entries=len(names) + 1, error=FileFormatError) as z:
        missing = [n for n in required if n not in z]
        if missing:
            if "header" in z:
                raise FileFormatError(f"{label}: this is a table, not a trace (use it as the input)")
            raise FileFormatError(f"{label}: lacks arrays {missing}; not a shapedisplay trace")
        unknown = sorted(set(z.entries) - set(names))
        if unknown:
            raise FileFormatError(f"{label}: unexpected entry '{unknown[0]}'; not a shapedisplay trace")
        spent = 0
        for n in (n for n in TRACE_ARRAYS if n in z):
            cap = MAX_TRACE_TICKS * (_EVENTS_PER_TICK if n in _EVENT_ARRAYS else 1)
            cap = min(cap, max(0, MAX_TRACE_BYTES - spent) // 8)
            out[n] = z.read_array(n, ("i1", "u1", "i4", "i8", "f8") if n == "state" else ("f8", "f4"), cap,
                                  ndim=1)
            spent += out[n].nbytes
        if "press" in z:
            out["press"] = z.read_array("press", ("f8", "f4"), min(MAX_TRACE_TICKS, max(0, MAX_TRACE_BYTES - spent) // 8),
                                        ndim=1)
            spent += out["press"].nbytes
        for n in REACTION_ARRAYS:           # reaction events (a trace written before them has none)
            if n in z:
                cap = min(MAX_TRACE_TICKS, max(0, MAX_TRACE_BYTES - spent) // 1024)
                out[n] = z.read_array(n, _TEXT if n in ("event_kind", "event_widget") else ("f8", "f4"), cap, ndim=1)
                spent += out[n].nbytes
        for n in _TRACE_STRINGS:
            if n in z:
                a = z.read_array(n, tuple(f"U{k}" for k in range(1, 257)), 1)
                if a.size != 1:
                    raise FileFormatError(f"{label}: '{n}' must hold one string (got {a.size})")
                out[n] = str(a.reshape(-1)[0])
        for n, dtypes in _TRACE_SCALARS.items():
            if n in z:
                v = z.read_array(n, dtypes, 1, shape=()).item()
                out[n] = int(v) if n == "clipped" else float(v)
    check_trace_arrays(out, label)
    return out


def check_trace_arrays(d: dict, label: str, error=FileFormatError) -> None:
    """The rules of a trace's arrays (read from a file or built in memory); raises ``error`` naming ``label``.

    Ticks >= 1, per-tick arrays of one length, as many event amplitudes as
    event times, floats finite, ``state`` 0 or 1, ``t`` not decreasing, rates
    finite and > 0, ``clipped`` >= 0.
    """
    n = d["t"].size
    if n < 1:
        raise error(f"{label}: holds no ticks")
    for name in (n for n in TRACE_ARRAYS if n in d):
        a = d[name]
        want = d["event_time"].size if name in _EVENT_ARRAYS and "event_time" in d else n
        if name in _EVENT_ARRAYS and "event_time" not in d:
            want = a.size
        if a.size != want:
            raise error(f"{label}: array '{name}' has {a.size} values; "
                                  f"'{'event_time' if name in _EVENT_ARRAYS else 't'}' has {want}")
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            raise error(f"{label}: array '{name}' holds NaN or infinite values")
    if "press" in d:
        if d["press"].size != n or not np.isfinite(d["press"]).all() or (d["press"] < 0).any():
            raise error(f"{label}: array 'press' must hold one finite force >= 0 per tick ({n})")
    got = [k for k in REACTION_ARRAYS if k in d]
    if got:
        sizes = {d[k].size for k in got}
        if len(got) != len(REACTION_ARRAYS) or len(sizes) != 1:
            raise error(f"{label}: the reaction arrays {', '.join(REACTION_ARRAYS)} must all be present, of one length")
        for k in ("event_t", "event_value"):
            if not np.isfinite(d[k]).all():
                raise error(f"{label}: array '{k}' holds NaN or infinite values")
        from shapedisplay.render.layouts import EVENT_KINDS
        bad = sorted(set(map(str, d["event_kind"])) - set(EVENT_KINDS))
        if bad:
            raise error(f"{label}: 'event_kind' holds {bad[0]!r}; kinds are {', '.join(EVENT_KINDS)}")
    if "state" in d and not np.all((d["state"] == 0) | (d["state"] == 1)):
        raise error(f"{label}: 'state' must be 0 (stick) or 1 (slip)")
    if np.any(np.diff(d["t"]) < 0):
        raise error(f"{label}: times 't' must not decrease")
    for name in ("tick_rate", "audio_rate"):
        if name in d and not (math.isfinite(d[name]) and d[name] > 0):
            raise error(f"{label}: '{name}' must be finite and > 0 (got {d[name]!r})")
    if "clipped" in d and d["clipped"] < 0:
        raise error(f"{label}: 'clipped' must be >= 0 (got {d['clipped']})")


def check_plot_path(path) -> str:
    """Check that a plot can be written to ``path``: a suffix from :data:`PLOT_FORMATS` and matplotlib installed.

    Returns the format (the suffix without the dot). Cheap enough to call before a long render.
    """
    fmt = Path(path).suffix.lstrip(".").lower()
    if fmt not in PLOT_FORMATS:
        raise InputError(f"plot '{path}': the file suffix must be one of "
                         f"{', '.join('.' + f for f in PLOT_FORMATS)} (got {Path(path).suffix or 'none'!r})")
    from shapedisplay.errors import require
    require("matplotlib", "plot", "plotting")
    return fmt


def plot_trace(path, result, title: str | None = None, widgets=None) -> Path:
    """Plot N(x), friction force, slip density and bursts along the stroke (PNG/PDF/SVG by suffix).

    ``result`` is a RenderResult or a dict from :func:`read_trace`. The slip
    panel shows, over consecutive time windows stated on its axis, the
    fraction of ticks ending in slip and the stick-slip event rate
    (:func:`shapedisplay.render.strokes.slip_density`). ``widgets`` (a table's
    :func:`~shapedisplay.table.widgets.widget_map`) shades the stretches
    of the stroke inside each widget, labelled with its id
    (:func:`shapedisplay.render.strokes.widget_spans`). The PNG carries no
    timestamp or version: the same stroke gives the same bytes.
    Needs matplotlib (``pip install 'shapedisplay[plot]'``).
    """
    fmt = check_plot_path(path)
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.transforms import blended_transform_factory

    from shapedisplay.render.strokes import arc_length, slip_density, widget_spans

    get = (lambda n: result[n]) if isinstance(result, dict) else (lambda n: getattr(result, n))
    t = np.asarray(get("t"))
    x = np.asarray(get("x"))
    y = np.asarray(get("y"))
    s = arc_length(x, y) * 1e3
    et = np.asarray(get("event_time"))
    ea = np.asarray(get("event_amplitude"))
    es = np.interp(et, t, s) if et.size else et
    rate = float(get("tick_rate")) if not isinstance(result, dict) or "tick_rate" in result else 0.0
    rate = rate if math.isfinite(rate) else 0.0
    period = 1.0 / rate if rate > 0 else (float(np.median(np.diff(t))) if t.size > 1 else 1.0)
    dens = slip_density(t, get("state"), et, period)
    ds = np.interp(dens.edges, t, s)          # window edges as distances along the stroke
    spans = widget_spans(x, y, widgets or [])

    fig, ax = plt.subplots(5, 1, figsize=(9, 9.5), sharex=True, layout="constrained",
                           gridspec_kw={"height_ratios": [1.0, 1.0, 0.8, 0.8, 1.0]})
    ax[0].plot(s, get("normal_force"), color="k")
    ax[0].set_ylabel("N (N)")
    ax[1].plot(s, get("friction_force"), color="tab:blue", lw=0.8)
    ax[1].set_ylabel("friction (N)")
    win = dens.window_label()
    ax[2].stairs(100.0 * dens.slip_fraction, ds, fill=True, color="tab:orange", alpha=0.85)
    ax[2].set_ylabel(f"slip, % of ticks\n({win})")
    ax[2].set_ylim(0, max(1.0, 1.15 * 100.0 * float(dens.slip_fraction.max(initial=0.0))))
    ax[3].stairs(dens.event_rate, ds, fill=True, color="tab:purple", alpha=0.85)
    ax[3].set_ylabel(f"stick-slip events/s\n({win})")
    ax[3].set_ylim(0, max(1.0, 1.15 * float(dens.event_rate.max(initial=0.0))))
    ax[4].vlines(es, 0, ea, color="tab:red", lw=0.6)
    ax[4].set_ylabel("burst amplitude")
    ax[4].set_xlabel("distance along the stroke (mm)")
    for a in ax:
        a.margins(x=0.01)
    kinds = np.asarray(result.get("event_kind", ()) if isinstance(result, dict) else getattr(result, "event_kind", ()))
    if kinds.size:                            # reaction events (docs/reactive.md): a line each, labelled on top
        rt = np.asarray(get("event_t"), dtype=np.float64)
        rw = np.asarray(get("event_widget"))
        rs = np.interp(rt, t, s)
        colours = {"press": "tab:green", "release": "tab:olive", "click": "tab:red", "toggle": "tab:purple",
                   "value": "tab:gray", "grab": "tab:blue", "drop": "tab:cyan"}
        top = blended_transform_factory(ax[4].transData, ax[4].transAxes)
        labelled = 0
        for k, w, sk in zip(kinds, rw, rs):
            for a in ax:
                a.axvline(sk, color=colours.get(str(k), "k"), lw=0.7, ls=":", zorder=1)
            if str(k) != "value" and labelled < 40:
                ax[4].text(sk, 0.98, f"{k} {w}", transform=top, rotation=90, ha="right", va="top", fontsize=6,
                           color=colours.get(str(k), "k"))
                labelled += 1
    if spans:
        shades = ("#d9e6f2", "#f2e6d9")
        label_at = blended_transform_factory(ax[0].transData, ax[0].transAxes)
        for i, sp in enumerate(spans):
            s0, s1 = sp["s0"] * 1e3, sp["s1"] * 1e3
            for a in ax:
                a.axvspan(s0, s1, color=shades[i % 2], zorder=0, lw=0)
            ax[0].text(0.5 * (s0 + s1), 1.02 + 0.09 * (i % 2), sp["id"], transform=label_at, ha="center",
                       va="bottom", fontsize=8, clip_on=False)
    model = get("model") if not isinstance(result, dict) else result.get("model", "")
    slip_pct = 100.0 * float(np.mean(np.asarray(get("state")) != 0)) if t.size else 0.0
    head = title or (f"{model}: {et.size} bursts over {s[-1]:.3g} mm, {t[-1] - t[0]:.3g} s; "
                     f"slip {slip_pct:.1f} % of ticks")
    if spans:
        head += "\nshaded: widgets crossed (ids above)"
    if kinds.size:
        head += f"; dotted: {kinds.size} reaction events (press, click, toggle, ...)"
    fig.suptitle(head, fontsize=11)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, format=fmt, metadata=_PLOT_METADATA.get(fmt))
    plt.close(fig)
    return Path(path)


#: Metadata written into plots: no software version, no creation date (the same data gives the same bytes).
_PLOT_METADATA = {"png": {"Software": None}, "svg": {"Date": None, "Creator": None},
                  "pdf": {"CreationDate": None, "ModDate": None, "Producer": None, "Creator": None}}
