"""Your own study: a full-factorial grid of bumps, stroked across their centres (``shapedisplay study grid``).

Each condition is a 1-D bump: ``n_base`` on a flat lead-in of
:data:`GRID_LEAD`, a flank rising over ``ramp`` to ``n_top``, a flat top of
``width`` (0: a tent, the profile of the ``bump`` preset), the falling flank
and a flat lead-out. It is compiled with the presets' table builder, then a
stroke from x = 0 to the end of the profile at ``speed`` (through the bump's
centre) is played with ``model`` on the handheld stick's pad with static
friction ``mu_s`` and kinetic friction ``mu_s - delta_mu``.

The conditions are the product of every factor's levels (:data:`FACTORS`;
a factor not given keeps its default); each is played once and written as
``<id>.wav`` and ``<id>.npz``. The trials are every condition ``repeat``
times in an order shuffled by ``numpy.random.default_rng(seed)``;
``trials.csv`` lists them in presentation order (:data:`TRIAL_COLUMNS`, then
the summary numbers of :mod:`shapedisplay.reports.presets`) and
``manifest.json`` records the design. The folder is written whole or not at
all, like the presets' (:func:`shapedisplay.atomic.replace_dir`).

Light at import (the CLI's help lists the factors): numpy, the table builders
and the renderer load on first use.
"""
from __future__ import annotations

import math
from collections import namedtuple

from shapedisplay.errors import InputError, did_you_mean

GRID_FORMAT = "shapedisplay-study-grid-1"
#: Flat length before and after the bump, m (as the bump preset).
GRID_LEAD = 0.010
#: Sample spacing of the compiled profiles, m (as the profile presets).
GRID_DX = 1e-4
#: Limits checked before anything runs.
MAX_TRIALS = 10_000
MAX_CONDITIONS = 1_000
MAX_STROKE_S = 60.0          # s, one condition's stroke
MAX_STIMULI_S = 600.0        # s, all conditions' strokes together (WAV + trace: about 0.35 MB per second)
#: The device whose pad, burst and tick rate every condition uses.
GRID_DEVICE = "handheld-stick"


class Factor(namedtuple("Factor", "name unit column default help")):
    """A factor of the grid: its unit (None for a name), trials.csv column and default level (as typed)."""

    __slots__ = ()


FACTORS = {f.name: f for f in (
    Factor("n_top", "N", "n_top_N", "4.5N", "normal force on top of the bump"),
    Factor("n_base", "N", "n_base_N", "0.5N", "normal force around the bump"),
    Factor("ramp", "m", "ramp_m", "20mm", "length of each flank, from n_base to n_top"),
    Factor("width", "m", "width_m", "0mm", "length of the flat top between the flanks, 0 for a tent"),
    Factor("speed", "m/s", "speed_m_s", "20mm/s", "stroke speed"),
    Factor("mu_s", "1", "mu_s", "0.5", "static friction coefficient"),
    Factor("delta_mu", "1", "delta_mu", "0.2", "mu_s - mu_k"),
    Factor("model", None, "model", "exact", "renderer model"),
)}

#: trials.csv columns before the summary numbers.
TRIAL_COLUMNS = ("trial", "condition", "repetition", *(f.column for f in FACTORS.values()), "wav", "trace",
                 "duration_s")

GridPlan = namedtuple("GridPlan", "levels given conditions trials repeat seed")
GridPlan.__doc__ = """The design of a grid, before anything runs.

``levels``: factor -> levels (SI floats, model names), every factor;
``given``: the factors that were given; ``conditions``: list of
``(id, {factor: value})`` in factorial order (the first factor of
:data:`FACTORS` varies slowest); ``trials``: list of ``(trial, condition
index, repetition)`` in presentation order (all 1-based but the index).
"""

GridResult = namedtuple("GridResult", "plan rows conditions folder manifest")
GridResult.__doc__ = """What :func:`run_grid` produced.

``rows``: one dict per trial in presentation order (the columns of
trials.csv); ``conditions``: one summary dict per condition; ``folder`` and
``manifest``: None unless written.
"""


# ----------------------------------------------------------------- levels
def _level(factor: Factor, value, label: str):
    """One level of ``factor``: a string with its unit (or a model name), or an SI number."""
    if factor.unit is None:
        from shapedisplay.render.models import MODELS
        name = value.strip() if isinstance(value, str) else None
        if name not in MODELS:
            raise InputError(f"`{label}`: unknown model {value!r}{did_you_mean(str(value), MODELS)}; "
                             f"valid: {', '.join(sorted(MODELS))}")
        return name
    if isinstance(value, str):
        from shapedisplay.units import parse_quantity
        if not value.strip():
            raise InputError(f"`{label}`: empty level (write {factor.name}=V1,V2,... e.g. "
                             f"{factor.name}={factor.default})")
        v = parse_quantity(value.strip(), factor.unit, label)
    elif isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        v = float(value)
    else:
        raise InputError(f"`{label}`: a level must be a quantity such as '{factor.default}' (got {value!r})")
    positive = factor.name in ("n_top", "n_base", "ramp", "speed", "mu_s")
    if (positive and not v > 0) or v < 0:
        raise InputError(f"`{label}`: {factor.name} must be {'> 0' if positive else '>= 0'} (got {value!r})")
    return v


def _levels(factor: Factor, values, label: str) -> list:
    if isinstance(values, str):
        values = values.split(",")
    elif not isinstance(values, (list, tuple)):
        values = [values]
    if not values:
        raise InputError(f"`{label}`: no levels (write {factor.name}=V1,V2,... e.g. {factor.name}={factor.default})")
    out = []
    for v in values:
        lv = _level(factor, v, label)
        if lv in out:
            raise InputError(f"`{label}`: level {v!r} is given twice (each level once; --repeat repeats trials)")
        out.append(lv)
    return out


def _factor(name, label: str) -> Factor:
    if name not in FACTORS:
        raise InputError(f"`{label}`: unknown grid factor {name!r}{did_you_mean(str(name), FACTORS)}; "
                         f"valid: {', '.join(FACTORS)}")
    return FACTORS[name]


def parse_factor(text: str) -> tuple:
    """``"NAME=V1,V2,..."`` (the CLI's ``--factor``) -> ``(name, levels)``; errors name ``--factor TEXT``."""
    label = f"--factor {text}"
    name, sep, values = text.partition("=")
    if not sep:
        raise InputError(f"`{label}`: write NAME=V1,V2,... (e.g. n_top=2N,3N,4N)")
    f = _factor(name.strip(), label)
    if not values.strip():
        raise InputError(f"`{label}`: no levels (write {f.name}=V1,V2,... e.g. {f.name}={f.default})")
    return f.name, _levels(f, values, label)


def _whole(value, name: str, low: int, high: int) -> int:
    import numbers

    if isinstance(value, str) and value.strip().lstrip("+").isdigit():
        value = int(value)
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        value = int(value)
    if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
        raise InputError(f"`{name}` must be a whole number within {low}..{high} (got {value!r})")
    return value


def plan_grid(factors: dict, repeat=1, seed=0) -> GridPlan:
    """Check a design and lay out its conditions and trial order (nothing runs).

    Parameters
    ----------
    factors : dict name -> list of levels
        Names from :data:`FACTORS`; levels as strings with units (``"2N"``,
        ``"5mm"``, ``"20mm/s"``, ``"exact"``) or SI numbers; a string holds
        one level or several separated by commas.
    repeat : int
        Trials per condition (>= 1).
    seed : int
        Seed of ``numpy.random.default_rng`` for the presentation order (>= 0).
    """
    import itertools

    import numpy as np

    if not isinstance(factors, dict):
        raise InputError(f"`factors` must be a dict of factor name -> levels (got {type(factors).__name__})")
    repeat = _whole(repeat, "repeat", 1, MAX_TRIALS)
    seed = _whole(seed, "seed", 0, 2 ** 63 - 1)
    levels = {}
    for name, values in factors.items():
        f = _factor(name, f"factors[{name!r}]")
        levels[f.name] = _levels(f, values, f"factors[{name!r}]")
    given = [n for n in FACTORS if n in levels]
    levels = {n: levels[n] if n in levels else _levels(f, f.default, n) for n, f in FACTORS.items()}
    n_cond = math.prod(len(v) for v in levels.values())
    if n_cond > MAX_CONDITIONS or n_cond * repeat > MAX_TRIALS:
        raise InputError(f"the grid has {n_cond} conditions x `repeat` {repeat} = {n_cond * repeat} trials; "
                         f"at most {MAX_CONDITIONS} conditions and {MAX_TRIALS} trials")
    from shapedisplay.table.devices import load_device
    v_lo, v_hi = load_device(GRID_DEVICE).velocity_range
    width = max(2, len(str(n_cond)))
    conditions, total = [], 0.0
    for i, combo in enumerate(itertools.product(*levels.values())):
        p = dict(zip(levels, combo))
        if p["n_top"] < p["n_base"]:
            raise InputError(f"factor n_top = {p['n_top']:g} N is below factor n_base = {p['n_base']:g} N: "
                             "a bump rises from n_base to n_top (give n_top >= n_base)")
        if p["delta_mu"] > p["mu_s"]:
            raise InputError(f"factor delta_mu = {p['delta_mu']:g} exceeds factor mu_s = {p['mu_s']:g}: "
                             "mu_k = mu_s - delta_mu must be >= 0")
        if not v_lo <= p["speed"] <= v_hi:
            raise InputError(f"factor speed = {p['speed'] * 1e3:g} mm/s is outside the {GRID_DEVICE} device's "
                             f"range {v_lo * 1e3:g}..{v_hi * 1e3:g} mm/s")
        dur = stroke_length(p) / p["speed"]
        if dur > MAX_STROKE_S:
            raise InputError(f"a stroke over ramp {p['ramp'] * 1e3:g} mm, width {p['width'] * 1e3:g} mm at speed "
                             f"{p['speed'] * 1e3:g} mm/s lasts {dur:.4g} s; at most {MAX_STROKE_S:g} s")
        total += dur
        conditions.append((f"c{i + 1:0{width}d}", p))
    if total > MAX_STIMULI_S:
        raise InputError(f"the grid's {n_cond} strokes last {total:.4g} s together; at most {MAX_STIMULI_S:g} s "
                         "(fewer levels, or shorter bumps or faster strokes)")
    cells = [c for c in range(n_cond) for _ in range(repeat)]
    order = np.random.default_rng(seed).permutation(len(cells))
    seen = [0] * n_cond
    trials = []
    for t, k in enumerate(order):
        c = cells[k]
        seen[c] += 1
        trials.append((t + 1, c, seen[c]))
    return GridPlan(levels, given, conditions, trials, repeat, seed)


# ----------------------------------------------------------------- stimuli
def stroke_length(p: dict) -> float:
    """Length of condition ``p``'s profile and stroke, m: lead-in, two flanks, the top, lead-out."""
    return 2 * GRID_LEAD + 2 * p["ramp"] + p["width"]


def bump_profile(p: dict):
    """The height field of condition ``p`` (a tent, or a tent cut flat at ``n_top`` over ``width``)."""
    import dataclasses

    import numpy as np

    from shapedisplay.author.sources import tent_profile

    l1, ramp, w = GRID_LEAD, p["ramp"], p["width"]
    if w == 0:
        return tent_profile(l1, l1 + ramp, l1 + 2 * ramp + GRID_LEAD, n1=p["n_base"], n2=p["n_top"], dx=GRID_DX)
    # the tent rising at the flanks' rate to an apex half the top's width further on, cut at n_top:
    # the same linear flanks, flat over the width
    half = ramp + 0.5 * w
    k = (p["n_top"] - p["n_base"]) / ramp
    hf = tent_profile(l1, l1 + half, l1 + 2 * half + GRID_LEAD, n1=p["n_base"], k=k, dx=GRID_DX)
    cap = (p["n_top"] - p["n_base"]) / hf.meta["n_gain"]
    meta = dict(hf.meta, profile="flat-top bump", n2=p["n_top"], width=w, apex_cut=True)
    return dataclasses.replace(hf, heights=np.minimum(hf.heights, cap), meta=meta,
                               source=f"{hf.source}, cut flat at N2={p['n_top']:g} N over {w * 1e3:g} mm")


def grid_device(p: dict):
    """The handheld stick with condition ``p``'s friction and a force range holding n_base .. n_top."""
    from shapedisplay.reports.studies import _stick_device
    from shapedisplay.table.devices import FrictionParams

    dev = _stick_device(GRID_DEVICE, n_max=p["n_top"])
    lo, hi = dev.normal_force_range
    if p["n_base"] < lo:
        dev = dev.with_(normal_force_range=(p["n_base"], hi))
    return dev.with_(friction=FrictionParams(p["mu_s"], p["mu_s"] - p["delta_mu"]).validate())


def grid_condition(cid: str, p: dict):
    """Condition ``p`` as a preset :class:`~shapedisplay.reports.studies.Condition` (table, stroke, regions).

    Summary regions: ``base`` the lead-in (after 2 mm), ``top`` where N is
    within 10 % of the rise from ``n_top`` (the flat top and a tenth of each flank).
    """
    from shapedisplay.reports.studies import Condition, _profile_table, line_stroke

    dev = grid_device(p)
    length = stroke_length(p)
    centre, half_top = 0.5 * length, 0.5 * p["width"] + 0.1 * p["ramp"]
    table = _profile_table(bump_profile(p), dev)
    return Condition(cid, {FACTORS[n].column: v for n, v in p.items()}, dev, (lambda t=table: t),
                     (lambda rate: line_stroke(0.0, length, p["speed"], rate)), model=p["model"],
                     regions={"base": (0.002, GRID_LEAD), "top": (centre - half_top, centre + half_top)})


def _checksum(table) -> str:
    c = table.checksum
    return c() if callable(c) else c


# ----------------------------------------------------------------- runner
def run_grid(factors: dict, repeat=1, seed=0, out_dir=None, *, tick_rate: float | None = None,
             progress=None) -> GridResult:
    """Run a custom grid (see the module docstring) and, with ``out_dir``, write its folder.

    Parameters
    ----------
    factors, repeat, seed
        As :func:`plan_grid`.
    out_dir : str or PathLike, optional
        A new (or empty) folder: ``trials.csv``, ``manifest.json``, and
        ``<id>.wav`` / ``<id>.npz`` per condition, moved into place only once complete.
    tick_rate : float, optional
        Hz; default the device's.
    progress : callable (i, n, condition id), optional

    Returns
    -------
    GridResult
    """
    import json
    import os
    import shutil
    import tempfile
    from pathlib import Path

    from shapedisplay.atomic import replace_dir, write_text
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.render.sinks import write_trace, write_wav
    from shapedisplay.reports.studies import _check_out_dir, _json_default, _umask, summarize, summary_csv

    plan = plan_grid(factors, repeat, seed)
    out = _check_out_dir(out_dir) if out_dir is not None else None
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".part", dir=out.parent)) if out else None
    summaries, entries = [], []
    try:
        for i, (cid, p) in enumerate(plan.conditions):
            if progress is not None:
                progress(i, len(plan.conditions), cid)
            cond = grid_condition(cid, p)
            table = cond.table()
            r = Renderer(table, device=cond.device, model=cond.model, tick_rate=tick_rate)
            res = r.render(cond.cursor(r.tick_rate))
            row = summarize(res, cond)
            row.update(wav=f"{cid}.wav", trace=f"{cid}.npz", duration_s=stroke_length(p) / p["speed"])
            summaries.append(row)
            if tmp is not None:
                write_wav(tmp / row["wav"], res.audio, res.audio_rate)
                write_trace(tmp / row["trace"], res, _checksum(table))
                entries.append({"id": cid, "params": cond.params, "device": cond.device.name, "model": res.model,
                                "tick_rate_hz": res.tick_rate, "audio_rate_hz": res.audio_rate,
                                "mu_s": r.device.friction.mu_s, "mu_k": r.device.friction.mu_k,
                                "normal_force_range_n": list(cond.device.normal_force_range),
                                "burst_gain": r.device.burst.gain, "table_checksum": _checksum(table),
                                "wav": row["wav"], "trace": row["trace"], "summary": row})
        rows = [_trial_row(t, rep, summaries[c]) for t, c, rep in plan.trials]
        if tmp is None:
            return GridResult(plan, rows, summaries, None, None)
        import numpy as np

        from shapedisplay import __version__
        write_text(tmp / "trials.csv", summary_csv(rows))
        manifest = {"format": GRID_FORMAT, "study": "grid", "shapedisplay_version": __version__,
                    "numpy_version": np.__version__,
                    "factors": plan.given, "levels": plan.levels,
                    "units": {n: f.unit for n, f in FACTORS.items()},
                    "columns": {n: f.column for n, f in FACTORS.items()},
                    "defaults": {n: f.default for n, f in FACTORS.items() if n not in plan.given},
                    "repeat": plan.repeat, "seed": plan.seed,
                    "order": "numpy.random.default_rng(seed).permutation over every condition x repeat",
                    "layout": {"device": GRID_DEVICE, "lead_m": GRID_LEAD, "dx_m": GRID_DX,
                               "stroke": "x = 0 to the profile's end along its centre line, at speed"},
                    "tick_rate_hz": tick_rate, "trials": "trials.csv", "trial_count": len(rows),
                    "conditions": entries}
        write_text(tmp / "manifest.json", json.dumps(manifest, indent=2, default=_json_default) + "\n")
        os.chmod(tmp, 0o777 & ~_umask())          # mkdtemp makes 0700; the files get a plain open()'s mode
        if out.exists():
            out.rmdir()                           # empty (checked above)
        replace_dir(tmp, out)
        tmp = None
        return GridResult(plan, rows, summaries, out, manifest)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _trial_row(trial: int, repetition: int, summary: dict) -> dict:
    row = {"trial": trial, "condition": summary["condition"], "repetition": repetition}
    row.update((k, summary[k]) for k in TRIAL_COLUMNS[3:])
    row.update((k, v) for k, v in summary.items() if k not in row)
    return row


__all__ = ["FACTORS", "Factor", "GridPlan", "GridResult", "TRIAL_COLUMNS", "plan_grid", "run_grid",
           "parse_factor", "bump_profile", "grid_condition", "grid_device", "stroke_length",
           "MAX_TRIALS", "MAX_CONDITIONS", "MAX_STROKE_S", "MAX_STIMULI_S", "GRID_LEAD", "GRID_DX"]
