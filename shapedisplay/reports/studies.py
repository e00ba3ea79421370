"""Study presets: conditions, summaries, plots and the runner (see :mod:`shapedisplay.reports.presets`)."""
from __future__ import annotations

import csv
import fnmatch
import io
import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from shapedisplay.atomic import atomic_path, replace_dir, write_text
from shapedisplay.table.devices import DeviceProfile, FrictionParams, load_device
from shapedisplay.errors import FileFormatError, InputError, unknown_key
from shapedisplay.reports.presets import STUDY_STICK_LIMIT, Study, get_study

STUDY_FORMAT = "shapedisplay-study-1"
#: Stroke speed of the ramp, bump and friction presets, m/s.
STUDY_SPEED = 0.020
N1 = 0.5          # N, the published base force


@dataclass(frozen=True)
class Condition:
    """One condition of a study.

    Attributes
    ----------
    name : str
        File stem, unique within the study.
    params : dict
        Independent variables (JSON numbers and strings), in the manifest and summary.
    device : DeviceProfile
    table : callable () -> FrictionTable
    cursor : callable (tick_rate Hz) -> CursorPath
    model, model_options, max_stick_period
        Renderer settings (max_stick_period in s, None = the device's).
    window : (float, float)
        Analysed time span, s.
    regions : dict name -> (x_lo, x_hi)
        Stroke regions (m along x) summarised separately (``<name>_*`` columns).
    """

    name: str
    params: dict
    device: DeviceProfile
    table: Callable
    cursor: Callable
    model: str = "exact"
    model_options: dict = field(default_factory=dict)
    max_stick_period: float | None = None
    window: tuple = (0.0, math.inf)
    regions: dict = field(default_factory=dict)


@dataclass
class StudyResult:
    """What :func:`run_study` produced: summary rows and, if written, the folder and manifest."""

    study: Study
    rows: list
    folder: Path | None = None
    manifest: dict | None = None


# ----------------------------------------------------------------- tables and inputs
def constant_table(n: float, device: DeviceProfile, length: float = 0.2):
    """A flat 1-D table of constant normal force ``n`` (N): N is the header's ``n_base``.

    Compiled with a slope-only mapping (the slope of a flat surface is stored,
    ``normal_force`` is not), so the runtime plays N from the header.
    """
    from shapedisplay.author.compile import compile_heightfield
    from shapedisplay.author.forces import MappingOptions
    from shapedisplay.author.heightfield import HeightField

    dx = 1e-3
    cols = int(round(length / dx))
    hf = HeightField(np.zeros((1, cols)), dx, dx, 0.5 * dx, 0.5 * dx, f"flat, N = {n:g} N", {})
    return compile_heightfield(hf, device, MappingOptions.parse("slope", n_base=n)).table


def _profile_table(hf, device: DeviceProfile):
    from shapedisplay.author.compile import compile_heightfield
    from shapedisplay.author.forces import MappingOptions

    mapping = MappingOptions(n_base=hf.meta["n_base"], n_gain=hf.meta["n_gain"])
    return compile_heightfield(hf, device, mapping).table


def stick_force_input(device: DeviceProfile, speed: float, duration: float, tick_rate: float):
    """Constant pointing-stick force ``speed / alpha`` for ``duration`` s: the cursor moves at ``speed`` m/s."""
    from shapedisplay.render.cursor import force_input

    rate = 5000.0 if not device.force_sample_rate_hz else device.force_sample_rate_hz
    n = int(round(duration * rate)) + 1
    f = np.full(n, speed / device.cursor_gain)
    return force_input(f, device.cursor_gain, rate, tick_rate, source=f"stick force {f[0]:.4g} N")


def line_stroke(x0: float, x1: float, speed: float, tick_rate: float):
    from shapedisplay.render.cursor import parse_stroke

    return parse_stroke(f"{x0 * 1e3:.6g}:{x1 * 1e3:.6g}mm @ {speed * 1e3:.6g} mm/s", tick_rate)


def _stick_device(name: str = "handheld-stick", n_max: float | None = None) -> DeviceProfile:
    d = load_device(name)
    if n_max is not None and d.normal_force_range[1] < n_max:
        d = d.with_(normal_force_range=(d.normal_force_range[0], n_max))
    return d


# ----------------------------------------------------------------- presets
def _friction_conditions(duration=None):
    dur = 1.0 if duration is None else duration
    conds = []
    for dev_name, kind in (("handheld-stick", "stick"), ("linear-slider", "slider")):
        base = load_device(dev_name)
        table = constant_table(2.0, base)
        for dmu in (0.1, 0.2, 0.3):
            for i in range(10):
                mus = round(0.375 + 0.025 * i, 3)
                dev = base.with_(friction=FrictionParams(mus, round(mus - dmu, 3)))
                if kind == "stick":
                    cursor = (lambda rate, d=dev: stick_force_input(d, STUDY_SPEED, dur, rate))
                else:
                    cursor = (lambda rate: line_stroke(0.0, STUDY_SPEED * dur, STUDY_SPEED, rate))
                conds.append(Condition(
                    f"{kind}-mus{mus:.3f}-dmu{dmu:.1f}",
                    {"device": dev_name, "mu_s": mus, "delta_mu": dmu, "mu_k": round(mus - dmu, 3),
                     "normal_force_n": 2.0, "speed_m_s": STUDY_SPEED},
                    dev, (lambda t=table: t), cursor, window=(0.1 * dur, dur)))
    return conds


def _slope_conditions(duration=None):
    from shapedisplay.author.sources import ramp_profile

    dev = _stick_device()
    conds = []
    lead, tail = 0.010, 0.020
    for L_mm in (5, 10, 15, 20, 25, 30):
        for k_n_mm in (0.05, 0.10, 0.15):
            L = L_mm * 1e-3
            k = k_n_mm * 1e3
            l1, l2 = lead, lead + L
            l3 = l2 + tail
            hf = ramp_profile(l1, l2, l3, n1=N1, k=k, dx=1e-4)
            n2 = N1 + k * L
            table = _profile_table(hf, dev)
            dur = l3 / STUDY_SPEED
            for limit in (None, STUDY_STICK_LIMIT):
                tag = "off" if limit is None else f"{limit * 1e3:g}ms"
                conds.append(Condition(
                    f"ramp-L{L_mm:02d}mm-k{k_n_mm:.2f}-limit-{tag}",
                    {"span_mm": L_mm, "rate_n_per_mm": k_n_mm, "n1_n": N1, "n2_n": round(n2, 6),
                     "max_stick_period_s": 0.0 if limit is None else limit, "speed_m_s": STUDY_SPEED},
                    dev, (lambda t=table: t),
                    (lambda rate, d=dur: stick_force_input(dev, STUDY_SPEED, d, rate)),
                    max_stick_period=0.0 if limit is None else limit,
                    regions={"base": (0.002, l1), "top": (l2 + 0.002, l3)}))
    return conds


def _bump_conditions(duration=None):
    from shapedisplay.author.sources import tent_profile

    dev = _stick_device(n_max=N1 + 6.0 + 0.5)
    conds = []
    lead = 0.010
    cases = [(dn, 20) for dn in (2, 3, 4, 5, 6)] + [(4, L) for L in (10, 15, 25, 30)]
    for dn, L_mm in cases:
        L = L_mm * 1e-3
        l1, l2 = lead, lead + L
        l3 = l2 + L
        l4 = l3 + lead
        hf = tent_profile(l1, l2, l4, n1=N1, n2=N1 + dn, dx=1e-4)
        table = _profile_table(hf, dev)
        dur = l4 / STUDY_SPEED
        conds.append(Condition(
            f"tent-dN{dn}N-L{L_mm:02d}mm",
            {"delta_n_n": dn, "span_mm": L_mm, "n1_n": N1, "n2_n": N1 + dn, "rate_n_per_mm": round(dn / L_mm, 6),
             "speed_m_s": STUDY_SPEED},
            dev, (lambda t=table: t), (lambda rate, d=dur: stick_force_input(dev, STUDY_SPEED, d, rate)),
            regions={"base": (0.002, l1), "top": (l2 - 0.1 * L, l2 + 0.1 * L)}))
    return conds


IMAIZUMI_SETTLE = 0.2     # s of settling before the statistics


def _imaizumi_conditions(duration=None, variant="stribeck"):
    from shapedisplay.reports.imaizumi import IMAIZUMI_SPEEDS, IMAIZUMI_STIMULI

    dur = 1.0 if duration is None else duration
    dev = load_device("lateral-contactor")
    table = constant_table(1.0, dev.with_(outputs=("burst",)))
    conds = []
    for speed in IMAIZUMI_SPEEDS:
        for label, hz, amp in IMAIZUMI_STIMULI:
            total = IMAIZUMI_SETTLE + dur
            conds.append(Condition(
                f"stim{label[1]}-{speed * 1e3:g}mm-s",
                {"stimulus": label, "frequency_hz": hz, "amplitude_m": amp, "finger_speed_m_s": speed,
                 "load_n": 1.0, "variant": variant},
                dev, (lambda t=table: t),
                (lambda rate, s=speed, T=total: line_stroke(0.0, s * T, s, rate)),
                model="stribeck", model_options={"variant": variant, "contactor_hz": hz,
                                                 "contactor_amplitude_m": amp},
                window=(IMAIZUMI_SETTLE, total)))
    return conds


# ----------------------------------------------------------------- summaries
def summarize(res, cond: Condition) -> dict:
    """Summary numbers of one rendered condition (see the module docstring)."""
    t = res.t
    lo, hi = cond.window
    keep = (t >= lo - 1e-12) & (t <= hi + 1e-12)
    row = {"condition": cond.name, **cond.params}
    row.update(_stats(res, keep, (res.event_time >= lo - 1e-12) & (res.event_time <= hi + 1e-12), ""))
    row["clipped"] = int(res.clipped)
    for name, (xa, xb) in cond.regions.items():
        sel = (res.x >= xa) & (res.x < xb)
        ex = np.interp(res.event_time, t, res.x) if res.event_time.size else res.event_time
        row.update(_stats(res, sel, (ex >= xa) & (ex < xb), f"{name}_"))
        row[f"{name}_normal_force_n"] = float(np.mean(res.normal_force[sel])) if sel.any() else math.nan
    return row


def _stats(res, ticks, events, prefix: str) -> dict:
    et = res.event_time[events]
    ea = res.event_amplitude[events]
    tt = res.t[ticks]
    span = float(tt[-1] - tt[0]) if tt.size > 1 else 0.0
    d = np.diff(et)
    f = np.abs(res.friction_force[ticks])
    return {
        f"{prefix}events": int(et.size),
        f"{prefix}event_rate_hz": et.size / span if span > 0 else math.nan,
        f"{prefix}stick_period_s": float(np.median(d)) if d.size else math.nan,
        f"{prefix}longest_stick_s": float(d.max()) if d.size else math.nan,
        f"{prefix}burst_amplitude": float(np.median(ea)) if ea.size else math.nan,
        f"{prefix}mean_friction_n": float(f.mean()) if f.size else math.nan,
        f"{prefix}max_friction_n": float(f.max()) if f.size else math.nan,
    }


# ----------------------------------------------------------------- plots
def _figure(nrows, ncols=1, h=3.2):
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(nrows, ncols, figsize=(9, h * nrows), squeeze=False, layout="constrained")
    return plt, fig, ax


def _save(plt, fig, path):
    try:
        with atomic_path(path) as tmp:          # flushed and renamed whole: never a partial plot under its name
            fig.savefig(tmp, dpi=100, format=Path(path).suffix[1:] or "png",
                        metadata={"Software": None})      # no version stamped in: same data, same bytes
    finally:
        plt.close(fig)


def _plot_friction(rows, path):
    plt, fig, ax = _figure(2)
    for (dev, style) in (("handheld-stick", "-o"), ("linear-slider", "--x")):
        for dmu in (0.1, 0.2, 0.3):
            r = [x for x in rows if x["device"] == dev and x["delta_mu"] == dmu]
            if not r:
                continue
            mus = [x["mu_s"] for x in r]
            ax[0, 0].plot(mus, [1e3 * x["stick_period_s"] for x in r], style, label=f"{dev}, dmu {dmu}")
            ax[1, 0].plot(mus, [x["burst_amplitude"] for x in r], style, label=f"{dev}, dmu {dmu}")
    ax[0, 0].set_ylabel("stick period (ms)")
    ax[1, 0].set_ylabel("burst amplitude A")
    ax[1, 0].set_xlabel("mu_s")
    ax[0, 0].legend(fontsize=7, ncol=2)
    ax[0, 0].set_title("friction study: N = 2 N, 20 mm/s")
    _save(plt, fig, path)


def _plot_slope(rows, path):
    plt, fig, ax = _figure(3)
    for limit, style in ((0.0, "-o"), (STUDY_STICK_LIMIT, "--x")):
        for k in (0.05, 0.10, 0.15):
            r = [x for x in rows if x["max_stick_period_s"] == limit and x["rate_n_per_mm"] == k]
            if not r:
                continue
            n2 = [x["n2_n"] for x in r]
            lab = f"k {k} N/mm, limit {'off' if not limit else f'{limit * 1e3:g} ms'}"
            ax[0, 0].plot(n2, [x["top_burst_amplitude"] for x in r], style, label=lab)
            ax[1, 0].plot(n2, [1e3 * x["top_stick_period_s"] for x in r], style, label=lab)
            ax[2, 0].plot(n2, [x["top_mean_friction_n"] for x in r], style, label=lab)
    ax[0, 0].set_ylabel("plateau burst amplitude")
    ax[1, 0].set_ylabel("plateau stick period (ms)")
    ax[2, 0].set_ylabel("plateau mean friction (N)")
    ax[2, 0].set_xlabel("plateau normal force N2 (N)")
    ax[0, 0].legend(fontsize=7, ncol=2)
    ax[0, 0].set_title("slope-height study: ramp from 0.5 N, 20 mm/s")
    _save(plt, fig, path)


def _plot_bump(rows, path):
    plt, fig, ax = _figure(2)
    a = [x for x in rows if x["span_mm"] == 20]
    b = [x for x in rows if x["delta_n_n"] == 4]
    ax[0, 0].plot([x["delta_n_n"] for x in a], [x["top_burst_amplitude"] for x in a], "-o", label="apex")
    ax[0, 0].plot([x["delta_n_n"] for x in a], [x["base_burst_amplitude"] for x in a], "--x", label="base")
    ax[0, 0].set_xlabel("delta N (N), L = 20 mm")
    ax[1, 0].plot([x["span_mm"] for x in b], [x["top_events"] for x in b], "-o", label="events near the apex")
    ax[1, 0].plot([x["span_mm"] for x in b], [x["events"] for x in b], "--x", label="events over the stroke")
    ax[1, 0].set_xlabel("L (mm), delta N = 4 N")
    ax[0, 0].set_ylabel("burst amplitude")
    ax[1, 0].set_ylabel("events")
    for a_ in ax[:, 0]:
        a_.legend(fontsize=7)
    ax[0, 0].set_title("bump study: tent from 0.5 N, 20 mm/s")
    _save(plt, fig, path)


def _plot_imaizumi(rows, path):
    plt, fig, ax = _figure(1)
    labels = []
    for i, speed in enumerate(sorted({x["finger_speed_m_s"] for x in rows}, reverse=True)):
        r = [x for x in rows if x["finger_speed_m_s"] == speed]
        labels = [x["stimulus"] for x in r]
        pos = np.arange(len(r)) + 0.4 * i
        ax[0, 0].bar(pos, [x["mean_friction_n"] for x in r], width=0.4, label=f"{speed * 1e3:g} mm/s mean")
        ax[0, 0].plot(pos, [x["max_friction_n"] for x in r], "k_", ms=12)
    ax[0, 0].set_xticks(np.arange(len(labels)) + 0.2)
    ax[0, 0].set_xticklabels(labels, fontsize=8)
    ax[0, 0].set_ylabel("friction |F| (N); bars mean, dashes max")
    ax[0, 0].legend(fontsize=8)
    ax[0, 0].set_title("Imaizumi lateral-vibration study, Stribeck pad, W = 1 N")
    _save(plt, fig, path)


def study_conditions(name, duration: float | None = None, only: str | None = None, **options) -> list:
    """The conditions of study ``name``; ``only`` keeps those whose name matches a glob pattern."""
    st = get_study(name)
    if duration is not None and not (math.isfinite(duration) and 0 < duration <= 60):
        raise InputError(f"`duration` must be within 0..60 s (got {duration!r})")
    if options and st.name != "imaizumi":
        raise InputError(f"study '{st.name}' takes no options {sorted(options)} (only 'imaizumi' takes `variant`)")
    if "variant" in options and options["variant"] not in ("stribeck", "premax"):
        raise unknown_key("variant", options["variant"], ("stribeck", "premax"))
    conds = st.build(duration, **options)
    if only:
        conds = [c for c in conds if fnmatch.fnmatchcase(c.name, only)]
        if not conds:
            names = ", ".join(c.name for c in st.build(duration, **options)[:4])
            raise InputError(f"`only` pattern {only!r} matches no condition of study '{st.name}' "
                             f"(names look like {names}, ...)")
    return conds


def _check_out_dir(out_dir) -> Path:
    out = Path(out_dir)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileFormatError(f"output folder '{out_dir}': exists and is not empty; give a new or empty folder "
                              "(nothing is overwritten)")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise FileFormatError(f"output folder '{out_dir}': parent folder '{parent}' does not exist")
    return out


def run_study(name, out_dir=None, *, duration: float | None = None, tick_rate: float | None = None,
              only: str | None = None, progress: Callable | None = None, **options) -> StudyResult:
    """Run study ``name`` (see :data:`STUDIES`) and, with ``out_dir``, write its files.

    Parameters
    ----------
    name : str
        A key of :data:`STUDIES`.
    out_dir : str or PathLike, optional
        A new (or empty) folder; everything is written to a temporary folder
        beside it and moved into place only once complete.
    duration : float, optional
        s; stroke length of the constant-speed presets (friction: default 1 s;
        imaizumi: analysed time, default 1 s). The profile presets ignore it.
    tick_rate : float, optional
        Hz; default each device's tick rate.
    only : str, optional
        Glob pattern on condition names (e.g. ``"stick-*-dmu0.2"``).
    progress : callable (i, n, condition name), optional
    **options
        ``variant`` ("stribeck" | "premax") for ``imaizumi``.

    Returns
    -------
    StudyResult
    """
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.render.sinks import check_plot_path, write_trace, write_wav

    st = get_study(name)
    conds = study_conditions(st, duration, only, **options)
    out = _check_out_dir(out_dir) if out_dir is not None else None
    if out is not None:
        check_plot_path("summary.png")           # matplotlib present: refuse before any work
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".part", dir=out.parent)) if out else None
    rows, entries = [], []
    try:
        for i, cond in enumerate(conds):
            if progress is not None:
                progress(i, len(conds), cond.name)
            table = cond.table()
            r = Renderer(table, device=cond.device, model=cond.model, tick_rate=tick_rate,
                         max_stick_period=cond.max_stick_period, **cond.model_options)
            res = r.render(cond.cursor(r.tick_rate))
            row = summarize(res, cond)
            rows.append(row)
            if tmp is not None:
                write_wav(tmp / f"{cond.name}.wav", res.audio, res.audio_rate)
                write_trace(tmp / f"{cond.name}.npz", res, table.checksum)
                entries.append({"name": cond.name, "params": cond.params, "device": cond.device.name,
                                "model": res.model, "tick_rate_hz": res.tick_rate, "audio_rate_hz": res.audio_rate,
                                "max_stick_period_s": r.device.burst.max_stick_period_s,
                                "burst_gain": r.device.burst.gain, "burst_policy": res.burst_policy,
                                "mu_s": r.device.friction.mu_s, "mu_k": r.device.friction.mu_k,
                                "table_checksum": table.checksum, "wav": f"{cond.name}.wav",
                                "trace": f"{cond.name}.npz", "summary": row})
        if tmp is None:
            return StudyResult(st, rows)
        from shapedisplay import __version__
        write_text(tmp / "summary.csv", summary_csv(rows))
        st.draw(rows, tmp / "summary.png")
        manifest = {"format": STUDY_FORMAT, "study": st.name, "title": st.title, "description": st.description,
                    "shapedisplay_version": __version__,
                    "options": {"duration_s": duration, "tick_rate_hz": tick_rate, "only": only, **options},
                    "summary": "summary.csv", "plot": "summary.png", "conditions": entries}
        write_text(tmp / "manifest.json", json.dumps(manifest, indent=2, default=_json_default) + "\n")
        os.chmod(tmp, 0o777 & ~_umask())          # mkdtemp makes 0700; the files get a plain open()'s mode
        if out.exists():
            out.rmdir()                           # empty (checked above)
        replace_dir(tmp, out)                     # the folder flushed, renamed whole, its parent flushed
        tmp = None
        return StudyResult(st, rows, out, manifest)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _json_default(v):
    if isinstance(v, (np.integer,)):
        return int(v)
    if isinstance(v, (np.floating,)):
        return float(v)
    raise TypeError(f"not JSON: {v!r}")


def summary_csv(rows: list) -> str:
    """Rows as CSV text (columns: the union of the rows' keys, in first-seen order)."""
    cols = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.9g}" if isinstance(v, float) else v) for k, v in r.items()})
    return buf.getvalue()


def format_summary(result: StudyResult) -> str:
    """A fixed-width text table of the study's summary columns."""
    cols = ("condition", *result.study.columns)
    cells = [[_cell(r.get(c)) for c in cols] for r in result.rows]
    width = [max(len(c), *(len(x[i]) for x in cells)) if cells else len(c) for i, c in enumerate(cols)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(cols, width))]
    lines += ["  ".join(x.rjust(w) for x, w in zip(row, width)) for row in cells]
    return "\n".join(lines)


def _cell(v) -> str:
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.5g}"
    return "" if v is None else str(v)
