"""Accuracy report: error against run time (work-precision) of every renderer setting.

For each case (:data:`CASES`), every renderer model at several tick rates
(and, for the table case, table resolutions and quantizations) and the scipy
peers (``solve_ivp`` Radau/BDF/LSODA with event functions, several
tolerances; :mod:`.peers`) are run on the same input. Each run is compared
with the case's reference:

* Konyo-pad cases: the ``exact`` model (event roots to ~1e-13 s; its events
  do not depend on the tick rate), cross-checked against Radau at rtol 1e-12
  (the discrepancy is reported); the belt benchmark also against its closed
  form;
* the Stribeck cases (contactor, belt; no closed form): Radau at rtol 1e-12
  (1e-10 in quick mode), cross-checked against the ``stribeck`` kernel
  (Taylor slip steps at its own tolerance).

Errors (:func:`.common.event_errors`): event-time RMS and max after matching,
missing and spurious events, relative stick-period error, burst-amplitude
error, and the normalised RMS error of the burst waveform. Costs: CPU
seconds per simulated second (minimum over several runs after a warm-up; the
renderer settings run :meth:`Renderer.render`, i.e. lookup, model and burst
synthesis), and for renderer settings the p50/p99 time of one online
:meth:`Renderer.step` against the tick budget ``1 / tick_rate``.
"""
from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from shapedisplay.atomic import prepare_output_dir
from shapedisplay.errors import ShapeDisplayError
from shapedisplay.reports import common
from shapedisplay.reports.peers import PEER_METHODS, konyo_ivp, stribeck_ivp

KONYO = dict(m=1.0e-6, k=2000.0, c=0.01, mu_s=0.5, mu_k=0.3)
IMAIZUMI = dict(m=1.0e-4, k=1.0e3, c=1.0, mu_s=2.1, mu_k=1.4, a=55.0, b=1.9)
BELT = dict(m=1.0, k=1.0, c=0.0, mu_s=1.0, mu_k=0.5)
#: The belt with Stribeck friction ``mu = mu_k + (mu_s - mu_k) exp(-a |v|/W) + b |v|/W`` (negative slope at 0.2 m/s).
BELT_STRIBECK = dict(BELT, a=3.0, b=0.1)
#: Slip tolerances the ``stribeck`` model runs at (None: its default, Taylor steps at 1e-13; the looser ones take
#: exponential Rosenbrock steps as long as the accuracy allows), in full and quick mode.
STRIBECK_TOLERANCES = (None, 3e-9, 1e-8, 3e-8, 1e-6, 3e-6, 1e-5, 3e-5, 1e-4, 2e-4, 3e-4, 4e-4, 1e-3)
STRIBECK_TOLERANCES_QUICK = (None, 1e-5, 3e-4)
#: A setting counts as "within 1 %" if its worst relative period error is at most this and no event is missing
#: or spurious.
PERIOD_TOL = 0.01


# ================================================================ cases
@dataclass
class Case:
    """One accuracy case.

    ``kind`` is "konyo" (Konyo-type pad, exact reference) or "stribeck".
    ``V(t)``, ``N(t)`` are the continuous inputs seen by the scipy peers
    (with discontinuities at ``breaks``); ``cursor(rate)`` gives the cursor
    path the renderer plays; ``table(setting)`` the table it plays it over.
    """

    name: str
    title: str
    kind: str
    params: dict
    duration: float
    V: object
    N: object
    breaks: tuple = ()
    models: tuple = ()
    rates: tuple = ()
    tables: tuple = ((None, None),)     # (dx m, quantize) per setting; None = flat table
    tolerances: tuple = (None,)          # stribeck slip tolerances per setting; None = the model's default
    closed_form: dict | None = None
    contactor: dict | None = None
    notes: str = ""
    extra: dict = field(default_factory=dict)


def _belt_closed_form(p, N, V):
    """Closed-form stick-slip of the undamped block on a belt (Coulomb), from rest at x = 0.

    Stick lasts ``2 dmu N / (k V)``; the slip is half an oscillation about
    ``mu_k N / k`` plus the arc where the block is slower than the belt:
    ``t_slip = (pi + 2 atan(V k / (omega dmu N))) / omega``.
    """
    w = math.sqrt(p["k"] / p["m"])
    dmu = p["mu_s"] - p["mu_k"]
    t_stick = 2 * dmu * N / (p["k"] * V)
    t_slip = (math.pi + 2 * math.atan(V * p["k"] / (w * dmu * N))) / w
    return {"first_event_s": p["mu_s"] * N / (p["k"] * V), "period_s": t_stick + t_slip,
            "stick_s": t_stick, "slip_s": t_slip, "amplitude_N": p["mu_s"] * N}


def _tent(l1, l2, n1, n2):
    l3 = 2 * l2 - l1
    kk = (n2 - n1) / (l2 - l1)

    def f(x):
        x = np.asarray(x, dtype=np.float64)
        return np.where(x < l1, n1, np.where(x < l2, n1 + kk * (x - l1),
                                             np.where(x < l3, n2 - kk * (x - l2), n1)))
    return f, l3


def build_cases(quick: bool) -> list[Case]:
    """The accuracy cases (fewer and shorter in quick mode)."""
    models = ("exact", "jump", "euler", "rk4")
    rates = (1000.0, 10000.0, 96000.0) if quick else (1000.0, 4000.0, 10000.0, 48000.0, 96000.0)
    cases = []
    vn = ((0.05, 2.0),) if quick else ((0.02, 2.0), (0.05, 2.0), (0.1, 4.0))
    for V0, N0 in vn:
        cases.append(Case(
            f"konyo_V{V0 * 1e3:g}mm_N{N0:g}", f"Konyo pad, V = {V0 * 1e3:g} mm/s, N = {N0:g} N", "konyo",
            dict(KONYO), 0.1 if quick else 0.2, (lambda t, V0=V0: V0), (lambda t, N0=N0: N0),
            models=models, rates=rates, extra={"V": V0, "N": N0}))
    # back-and-forth stroke: cursor loop at 1 kHz, speed held per millisecond
    Tst = 0.2 if quick else 0.4
    V0 = 0.06

    def Vrev(t, V0=V0, T=Tst):
        j = math.floor(t * 1000.0 + 1e-9)
        return V0 * math.sin(2 * math.pi * (j + 0.5) / 1000.0 / T)
    cases.append(Case(
        "reversal", f"back-and-forth stroke, {V0 * 1e3:g} mm/s peak, period {Tst:g} s (1 kHz cursor)", "konyo",
        dict(KONYO), Tst, Vrev, (lambda t: 2.0), breaks=tuple(np.arange(1, int(round(Tst * 1000))) / 1000.0),
        models=models + ("karnopp",), rates=rates[:2] if quick else rates,
        notes="karnopp applies here: it re-sticks when the finger speed falls below v_T = 12.5 mm/s "
              "(at a reversal); at constant speed it slides for ever after the first breakaway",
        extra={"V_peak": V0, "N": 2.0, "period_s": Tst}))
    # stroke over a compiled tent bump (published: N1 0.5 N, L = 20 mm, k = 0.15 N/mm)
    l1, l2, n1, n2 = 0.01, 0.03, 0.5, 3.5
    Nx, l3 = _tent(l1, l2, n1, n2)
    Vb = 0.04
    L = 0.06
    dur = L / Vb
    if quick:
        tables = ((1e-4, "float64"), (2e-3, "float64"), (1e-4, "uint8"))
    else:
        tables = tuple((dx, q) for dx in (1e-4, 5e-4, 2e-3) for q in ("float64", "uint16", "uint8"))
    cases.append(Case(
        "bump_table", "stroke at 40 mm/s over a compiled tent bump (N 0.5 -> 3.5 N over 20 mm)", "konyo",
        dict(KONYO), dur, (lambda t: Vb), (lambda t: float(Nx(Vb * t))),
        breaks=(l1 / Vb, l2 / Vb, l3 / Vb), models=("exact", "jump"),
        rates=(1000.0, 10000.0), tables=tables,
        extra={"l1": l1, "l2": l2, "l3": l3, "n1": n1, "n2": n2, "V": Vb, "length": L, "N_of_x": Nx}))
    # Imaizumi pad on a vibrating contactor (stimulus #4: 9 Hz, 1.25 mm; finger at 0.1 m/s)
    cases.append(Case(
        "stribeck_contactor", "Stribeck pad on a 9 Hz 1.25 mm contactor, finger at 0.1 m/s, W = 1 N", "stribeck",
        dict(IMAIZUMI), 0.25 if quick else 0.5, (lambda t: 0.1), (lambda t: 1.0), models=("stribeck",),
        tolerances=STRIBECK_TOLERANCES_QUICK if quick else STRIBECK_TOLERANCES,
        rates=(1000.0,) if quick else (100.0, 1000.0, 10000.0),
        contactor={"hz": 9.0, "amplitude_m": 1.25e-3}))
    # block on a moving belt (Coulomb), closed-form stick-slip period
    Vbelt, Nbelt = 0.2, 1.0
    cases.append(Case(
        "belt_coulomb", "block on a moving belt (m = 1 kg, k = 1 N/m, c = 0, mu_s 1, mu_k 0.5, 0.2 m/s)", "konyo",
        dict(BELT), 40.0 if quick else 90.0, (lambda t: Vbelt), (lambda t: Nbelt), models=models,
        rates=(100.0, 1000.0) if quick else (100.0, 1000.0, 10000.0),
        closed_form=_belt_closed_form(BELT, Nbelt, Vbelt), extra={"V": Vbelt, "N": Nbelt}))
    cases.append(Case(
        "belt_stribeck", "block on a moving belt with Stribeck friction (a = 3 s/m, b = 0.1 s/m, 0.2 m/s)",
        "stribeck", dict(BELT_STRIBECK), 30.0 if quick else 60.0, (lambda t: Vbelt), (lambda t: Nbelt),
        models=("stribeck",), rates=(100.0, 1000.0),
        tolerances=STRIBECK_TOLERANCES_QUICK if quick else STRIBECK_TOLERANCES,
        contactor={"hz": 0.0, "amplitude_m": 0.0}, extra={"V": Vbelt, "N": Nbelt}))
    return cases


# ================================================================ building blocks
def _device(case: Case):
    from shapedisplay.table.devices import BurstParams, DeviceProfile, FrictionParams, PadParams
    p = case.params
    extra = {"karnopp": {"spring": f"{p['k']} N/m"}}
    if case.kind == "stribeck":
        extra["stribeck"] = {"a": p["a"], "b": p["b"]}
    return DeviceProfile(name=f"report-{case.name}", pad=PadParams(p["m"], p["k"], p["c"]),
                         friction=FrictionParams(p["mu_s"], p["mu_k"]), burst=BurstParams(gain=1.0),
                         normal_force_range=(0.0, 20.0), velocity_range=(1e-6, 2.0), extra=extra)


def _table(case: Case, dx, quantize, device):
    """Table the renderer plays: a flat table at N (konyo/stribeck cases) or the compiled tent bump."""
    from shapedisplay.author.compile import CompileOptions, compile_heightfield
    from shapedisplay.author.forces import MappingOptions
    from shapedisplay.author.sources import from_array, tent_profile
    if dx is None:
        hf = from_array(np.zeros((1, 4)), 1e-3)
        mp = MappingOptions(n_base=float(case.N(0.0)), n_gain=1.0)
        return compile_heightfield(hf, device, mp, CompileOptions(quantize="float64")).table
    e = case.extra
    hf = tent_profile(e["l1"], e["l2"], e["length"], n1=e["n1"], n2=e["n2"], dx=dx)
    mp = MappingOptions(n_base=e["n1"], n_gain=1000.0)
    return compile_heightfield(hf, device, mp, CompileOptions(quantize=quantize)).table


def _cursor(case: Case, rate):
    """Cursor path on the tick grid (x = integral of V; exact for V held per millisecond)."""
    from shapedisplay.render.cursor import CursorPath
    n = int(round(case.duration * rate)) + 1
    t = np.arange(n) / rate
    if case.name == "reversal":
        ms = np.arange(0, int(round(case.duration * 1000)) + 1) / 1000.0
        vms = np.array([case.V(a) for a in ms[:-1]])
        xk = np.concatenate([[0.0], np.cumsum(vms * 1e-3)])
        x = np.interp(t, ms, xk)
    else:
        x = float(case.V(0.0)) * t
    return CursorPath(t, x, np.zeros(n), rate, f"report case {case.name}")


def _reference_inputs(case: Case, rate):
    """Per-tick (t, V, N) for the reference run (N at the tick-motion midpoint, like the renderer)."""
    n = int(round(case.duration * rate)) + 1
    t = np.arange(n) / rate
    tm = np.concatenate([[0.0], 0.5 * (t[1:] + t[:-1])])
    V = np.array([case.V(a) for a in tm])
    V[0] = 0.0
    if case.name == "bump_table":
        N = case.extra["N_of_x"](case.extra["V"] * tm)
    else:
        N = np.array([case.N(a) for a in tm])
    return t, V, N


def reference(case: Case, quick: bool) -> dict:
    """Reference events of a case, with the cross-check and (belt) the closed-form check."""
    from shapedisplay.render.models import get_model, run_kernel
    p = case.params
    out = {}
    if case.kind == "konyo":
        rate = 192000.0 if case.name == "bump_table" else (10000.0 if case.duration < 10 else 1000.0)
        t, V, N = _reference_inputs(case, rate)
        model = get_model("exact", _device(case))
        ones = np.ones_like(t)
        S, *_, et, ea = run_kernel(model, t, V, N, p["mu_s"] * ones, p["mu_k"] * ones, ones)
        out.update(kind="exact", tick_rate=rate, event_time=et, event_amplitude=ea,
                   description=f"'exact' model (event roots by safeguarded Newton to ~1e-15 s) at {rate:g} Hz"
                               + (", N(x) analytic at tick-motion midpoints" if case.name == "bump_table" else ""))
        # cross-check: Radau at rtol 1e-12 over the first events
        k_ev = 2 if quick else 12
        if et.size > 1:
            win = float(et[min(k_ev, et.size - 1)]) + 0.5 * float(np.min(np.diff(et)))
        else:
            win = case.duration
        win = min(win, case.duration)
        t0 = time.process_time()
        pr = konyo_ivp("Radau", 1e-12, m=p["m"], k=p["k"], c=p["c"], mu_s=p["mu_s"], mu_k=p["mu_k"],
                       V=case.V, N=case.N, t_end=win, breaks=case.breaks)
        cpu = time.process_time() - t0
        ref_in = et[et <= win]
        e = common.event_errors(ref_in, ea[et <= win], pr.event_time, pr.event_amplitude,
                                common.match_window(ref_in, win))
        out["cross_check"] = {"method": "Radau", "rtol": 1e-12, "window_s": win, "cpu_s": cpu,
                              "events_compared": e["matched"], "missing": e["missing"], "spurious": e["spurious"],
                              "max_abs_s": e["event_max_s"], "rms_s": e["event_rms_s"], "status": pr.status}
        if case.closed_form:
            cf = case.closed_form
            n = et.size
            exp_t = cf["first_event_s"] + cf["period_s"] * np.arange(n)
            keep = exp_t <= case.duration
            out["closed_form"] = dict(cf)
            out["closed_form"]["events"] = int(keep.sum())
            out["closed_form"]["event_max_abs_s"] = float(np.max(np.abs(et[keep] - exp_t[keep]))) if n else None
            per = float(np.mean(np.diff(et))) if n > 1 else None
            out["closed_form"]["period_rel_error"] = abs(per - cf["period_s"]) / cf["period_s"] if per else None
            out["closed_form"]["amplitude_max_rel_error"] = (
                float(np.max(np.abs(ea - cf["amplitude_N"]))) / cf["amplitude_N"] if n else None)
        return out
    # stribeck: Radau reference, stribeck kernel cross-check
    rtol = 1e-10 if quick else 1e-12
    pr = stribeck_ivp("Radau", rtol, m=p["m"], k=p["k"], c=p["c"], mu_s=p["mu_s"], mu_k=p["mu_k"], a=p["a"],
                      b=p["b"], W=1.0, V=float(case.V(0.0)), amp=case.contactor["amplitude_m"],
                      omega=2 * math.pi * case.contactor["hz"], t_end=case.duration)
    out.update(kind="Radau", rtol=rtol, event_time=pr.event_time, event_amplitude=pr.event_amplitude,
               description=f"solve_ivp Radau at rtol {rtol:g} with stick/slip events (no closed form exists)")
    from shapedisplay.render.models import STRIBECK_TOLERANCE, get_model, run_kernel
    t0 = time.process_time()
    model = get_model("stribeck", _device(case), contactor_hz=case.contactor["hz"],
                      contactor_amplitude_m=case.contactor["amplitude_m"])
    tt = np.arange(int(round(case.duration * 1000.0)) + 1) / 1000.0
    ones = np.ones_like(tt)
    Vt = float(case.V(0.0)) * ones
    Vt[0] = 0.0
    *_, ket, kea = run_kernel(model, tt, Vt, ones, p["mu_s"] * ones, p["mu_k"] * ones, ones)
    cpu = time.process_time() - t0
    e = common.event_errors(pr.event_time, pr.event_amplitude, ket, kea,
                            common.match_window(pr.event_time, case.duration))
    out["cross_check"] = {"method": f"stribeck kernel (Taylor steps, tolerance {STRIBECK_TOLERANCE:g})",
                          "window_s": case.duration,
                          "cpu_s": cpu,
                          "events_compared": e["matched"], "missing": e["missing"], "spurious": e["spurious"],
                          "max_abs_s": e["event_max_s"], "rms_s": e["event_rms_s"], "status": pr.status}
    return out


# ================================================================ one setting
def _model_settings(case: Case):
    out = []
    for model in case.models:
        for rate in case.rates:
            for dx, q in case.tables:
                for tol in (case.tolerances if model == "stribeck" else (None,)):
                    lab = f"{model} {rate / 1000:g} kHz"
                    if dx is not None:
                        lab += f" dx {dx * 1e3:g} mm {q}"
                    if tol is not None:
                        lab += f" tol {tol:g}"
                    out.append({"family": "renderer", "label": lab, "model": model, "tick_rate": rate,
                                "table_dx_m": dx, "quantize": q, "tolerance": tol})
    return out


def _peer_settings(case: Case, quick):
    tols = (1e-4, 1e-8) if quick else (1e-3, 1e-5, 1e-7, 1e-9)
    methods = PEER_METHODS
    if quick and case.name in QUICK_PEERS:
        methods = QUICK_PEERS[case.name]
    return [{"family": "scipy", "label": f"{m} rtol {r:g}", "method": m, "rtol": r}
            for m in methods for r in tols]


#: Quick mode runs fewer scipy methods where the peers are slow (many events or input segments).
QUICK_PEERS = {"reversal": ("LSODA",), "bump_table": ("LSODA",)}


def _run_renderer(case, s, device, ref, repeats, online_ticks, min_batch_s=0.02):
    from shapedisplay.render.models import run_kernel
    from shapedisplay.render.renderer import Renderer
    opts = {}
    if case.kind == "stribeck":
        opts = {"contactor_hz": case.contactor["hz"], "contactor_amplitude_m": case.contactor["amplitude_m"],
                "tolerance": s["tolerance"]}
    table = _table(case, s["table_dx_m"], s["quantize"], device)
    rend = Renderer(table, device=device, model=s["model"], tick_rate=s["tick_rate"], **opts)
    cur = _cursor(case, s["tick_rate"])
    res = {"status": "ok", "message": ""}
    try:
        runs, rr = common.cpu_per_call(lambda: rend.render(cur), runs=repeats, min_batch_s=min_batch_s)
        cpu = min(runs)
        # the model alone on the same per-tick inputs: the events and per-tick state, what a scipy peer computes
        inputs = rend.model_inputs(cur)
        mruns, _ = common.cpu_per_call(lambda: run_kernel(rend.model, *inputs), runs=repeats, min_batch_s=min_batch_s)
    except ShapeDisplayError as exc:
        t0 = time.process_time()
        try:
            rend.render(cur)
        except ShapeDisplayError:
            pass
        res.update(status="diverged" if "diverged" in str(exc) else "failed", message=str(exc),
                   cpu_s_per_sim_s=(time.process_time() - t0) / case.duration)
        return res, None, None
    res["cpu_s_per_sim_s"] = cpu / case.duration
    res["model_cpu_s_per_sim_s"] = min(mruns) / case.duration
    res["ticks"] = int(cur.t.size)
    if not (np.all(np.isfinite(rr.friction_force)) and np.all(np.isfinite(rr.audio))):
        res.update(status="failed", message="non-finite output")
    if online_ticks <= 0:
        return res, rr.event_time, rr.event_amplitude
    # online step(): per-tick wall time
    n = min(online_ticks, cur.t.size)
    rend.reset()
    xs, ys = cur.x, cur.y
    pc = time.perf_counter_ns
    tc = time.thread_time_ns
    dts = np.empty(n, dtype=np.int64)
    cts = np.empty(n, dtype=np.int64)
    try:
        for i in range(n):
            a = pc()
            c0 = tc()
            rend.step(xs[i], ys[i])
            cts[i] = tc() - c0
            dts[i] = pc() - a
        p50, p99 = common.tick_percentiles(dts)
        c50, c99 = common.tick_percentiles(cts)
        # wall time is what a real-time loop sees, but on a loaded machine it includes the time slices other
        # processes ran in (a few ms each); the thread's CPU time tells the renderer's own cost from that
        res.update(step_p50_s=p50, step_p99_s=p99, tick_budget_s=1.0 / s["tick_rate"],
                   step_p99_over_budget=p99 * s["tick_rate"], step_ticks_timed=int(n),
                   step_cpu_p50_s=c50, step_cpu_p99_s=c99, step_cpu_p99_over_budget=c99 * s["tick_rate"],
                   step_cpu_max_s=float(cts.max()) * 1e-9, step_wall_max_s=float(dts.max()) * 1e-9)
    except ShapeDisplayError as exc:
        res.update(step_p99_s=None, step_note=f"online run stopped: {exc}")
    return res, rr.event_time, rr.event_amplitude


def _run_peer(case, s, repeats, min_batch_s=0.02):
    p = case.params
    if case.kind == "konyo":
        def fn():
            return konyo_ivp(s["method"], s["rtol"], m=p["m"], k=p["k"], c=p["c"], mu_s=p["mu_s"], mu_k=p["mu_k"],
                             V=case.V, N=case.N, t_end=case.duration, breaks=case.breaks)
    else:
        def fn():
            return stribeck_ivp(s["method"], s["rtol"], m=p["m"], k=p["k"], c=p["c"], mu_s=p["mu_s"],
                                mu_k=p["mu_k"], a=p["a"], b=p["b"], W=1.0, V=float(case.V(0.0)),
                                amp=case.contactor["amplitude_m"], omega=2 * math.pi * case.contactor["hz"],
                                t_end=case.duration)
    runs, pr = common.cpu_per_call(fn, runs=repeats, min_batch_s=min_batch_s, warmup=False)
    cpu = min(runs)
    res = {"status": "ok" if pr.status == "ok" else "failed", "message": pr.message,
           "cpu_s_per_sim_s": cpu / case.duration, "solve_ivp_calls": pr.calls, "nfev": pr.nfev,
           "step_p99_s": None, "step_note": "offline solver: no per-tick step"}
    return res, pr.event_time, pr.event_amplitude


def run_setting(case, s, device, ref, runs_renderer=3, runs_peer=3, min_batch_s=0.02, online_ticks=0):
    """Run one setting of a case (a renderer setting or a scipy peer), time it and score it against ``ref``.

    Returns the setting's dict with its status, costs (CPU s per simulated
    s: ``cpu_s_per_sim_s`` and, for the renderer, ``model_cpu_s_per_sim_s``)
    and errors. ``online_ticks`` > 0 also times that many online ``step()``
    calls (renderer settings).
    """
    et_ref = ref["event_time"]
    window = common.match_window(et_ref, case.duration)
    mean_int = float(np.mean(np.diff(et_ref))) if et_ref.size > 1 else case.duration
    amp_scale = float(np.max(np.abs(ref["event_amplitude"]))) if et_ref.size else 1.0
    if s["family"] == "renderer":
        res, et, ea = _run_renderer(case, s, device, ref, runs_renderer, online_ticks, min_batch_s)
    else:
        res, et, ea = _run_peer(case, s, runs_peer, min_batch_s)
    res = _score(res, ref, et, ea, case.duration, window, amp_scale)
    res["event_rms_rel"] = res["event_rms_s"] / mean_int if res.get("event_rms_s") is not None else None
    if res["status"] == "ok" and res.get("matched", 0) == 0 and et_ref.size:
        res["status"] = "no_events"
    return {**s, **res}


def settings(case: Case, quick: bool) -> list[dict]:
    """Every setting of a case: renderer models, tick rates, tables and tolerances, then the scipy peers."""
    return _model_settings(case) + _peer_settings(case, quick)


def _score(res, ref, et, ea, duration, window, amp_scale):
    if et is None:
        res.update({k: None for k in ("event_rms_s", "event_max_s", "period_rel_rms", "period_rel_max",
                                      "amplitude_rel_rms", "waveform_nrmse")})
        res.update(matched=0, missing=int(ref["event_time"].size), spurious=None)
        return res
    res.update(common.event_errors(ref["event_time"], ref["event_amplitude"], et, ea, window))
    res["waveform_nrmse"] = common.waveform_error(ref["event_time"], ref["event_amplitude"], et, ea, duration,
                                                  amp_scale)
    return res


def qualifies(r) -> bool:
    """Within 1 % period error, nothing missing or spurious, status ok."""
    return (r.get("status") == "ok" and r.get("missing") == 0 and r.get("spurious") == 0
            and r.get("period_rel_max") is not None and r["period_rel_max"] <= PERIOD_TOL)


# ================================================================ the report
def run(out_dir, quick=False, progress=True, plots=True, stream=None) -> dict:
    """Run the accuracy report and write ``accuracy.json``, ``accuracy.md`` and PNGs into ``out_dir``.

    Returns the report dict (as written to JSON).
    """
    out_dir = prepare_output_dir(out_dir)
    stream = stream if stream is not None else sys.stderr
    cases = build_cases(quick)
    plan = [(c, settings(c, quick)) for c in cases]
    total = sum(len(s) + 1 for _, s in plan)
    bar = common.Progress(total, "accuracy", stream=stream, enabled=progress)
    rep_model = 3
    rep_peer = 1 if quick else 3
    batch = 0.005 if quick else 0.02
    online_ticks = 2000 if quick else 20000
    t_start = time.perf_counter()
    floor_tick, floor_audio = common.floor_costs()
    report = {"report": "accuracy", "quick": bool(quick), "period_tolerance": PERIOD_TOL,
              "floors": {"tick_s": floor_tick, "audio_sample_s": floor_audio,
                         "note": "least work of any tick-based renderer, timed in this run (reports.common."
                                 "floor_costs): per tick read the input and write one output; per audio sample "
                                 "write one carrier sample times an envelope; for the model alone at least one "
                                 "call that reads run_kernel's six per-tick input rows and writes its four "
                                 "per-tick output rows over the case's path (reports.common.interface_floor), or run_kernel "
                                 "with the cheapest model over that many ticks with the pad stuck on every one "
                                 "(reports.common.stuck_floor), whichever costs more, timed per case and tick "
                                 "rate"},
              "timing": {"clock": "time.process_time (CPU s), per call: each run repeats the call for at least "
                                  f"{batch:g} s of CPU time",
                         "renderer": f"full render: Renderer.render (lookup + model + burst audio at 48 kHz); "
                                     f"model: run_kernel on the same per-tick inputs (events and per-tick state, "
                                     f"what a peer computes); min of {rep_model} runs after a warm-up call",
                         "scipy": f"solve_ivp with events, min of {rep_peer} run(s) after a warm-up run of each method",
                         "online": "Renderer.step per tick incl. the Python call: wall time (time.perf_counter_ns; "
                                   "on a loaded machine it includes time slices given to other processes) and the "
                                   "thread's CPU time (time.thread_time_ns, step_cpu_*)"},
              "error_definitions": {
                  "event_rms_s / event_max_s": "stick-to-slip times after one-to-one matching within a third of the "
                                               "shortest reference interval",
                  "missing / spurious": "reference events without a partner / run events without a partner",
                  "period_rel_rms / period_rel_max": "relative error of intervals between consecutive matched events",
                  "amplitude_rel_rms": "RMS burst-amplitude error over matched events / RMS reference amplitude",
                  "waveform_nrmse": "rms(burst waveform - reference) / rms(reference), 8 kHz synthesis",
                  "event_rms_rel": "event_rms_s / mean reference interval (the work-precision plot's y axis)",
                  "null": "not computable: the run failed or diverged (see status), or too few matched events"},
              "cases": []}
    _warm_peers()
    for case, case_settings in plan:
        device = _device(case)
        bar.update(0, f"{case.name}: reference")
        ref = reference(case, quick)
        bar.update(1, f"{case.name}: reference")
        et_ref = ref["event_time"]
        mean_int = float(np.mean(np.diff(et_ref))) if et_ref.size > 1 else case.duration
        results = []
        for s in case_settings:
            results.append(run_setting(case, s, device, ref, rep_model, rep_peer, batch, online_ticks))
            bar.update(1, f"{case.name}: {s['label']}")
        summary = _summarise(results, case.duration, floor_tick, floor_audio)
        ref_json = {k: v for k, v in ref.items() if k not in ("event_time", "event_amplitude")}
        ref_json["events"] = int(et_ref.size)
        ref_json["mean_interval_s"] = mean_int
        report["cases"].append({"name": case.name, "title": case.title, "kind": case.kind, "notes": case.notes,
                                "duration_s": case.duration, "params": case.params,
                                "inputs": {k: v for k, v in case.extra.items() if not callable(v)},
                                "reference": ref_json, "settings": results, "summary": summary})
    bar.close()
    report["elapsed_s"] = time.perf_counter() - t_start
    report["headline"] = _headline(report)
    return common.write_report(report, out_dir, "accuracy", markdown, _plots if plots else None)


def _warm_peers():
    """One short run of each scipy method so imports and first-call costs are not timed."""
    p = KONYO
    for m in PEER_METHODS:
        konyo_ivp(m, 1e-4, m=p["m"], k=p["k"], c=p["c"], mu_s=p["mu_s"], mu_k=p["mu_k"], V=lambda t: 0.05,
                  N=lambda t: 2.0, t_end=0.012)


#: The two costs compared with scipy: the model alone on the renderer's per-tick inputs (the events and the
#: per-tick state: what a peer computes, and more) and the full render (lookup, model and 48 kHz burst audio).
COSTS = {"model": "model_cpu_s_per_sim_s", "render": "cpu_s_per_sim_s"}
#: The speed-up over scipy the renderer is built to reach at equal error, where the floor allows it.
SPEEDUP_TARGET = 1000.0


def equal_error(results, cost, floor_tick, floor_audio=0.0, audio_rate=48000.0, interface=None):
    """Speed-up over the best scipy method at equal error, at every error level both reach.

    A level is the period error ``e`` of a qualifying setting of either
    family (a table case's renderer error is the table's, larger than
    scipy's on the exact input). At ``e`` the best scipy method is the cheapest qualifying scipy setting with
    error <= e (any method, any tolerance), the renderer the cheapest
    qualifying renderer setting with error <= e (any model, tick rate,
    table); the speed-up is the ratio of their costs (``cost``: a key of
    :data:`COSTS`'s values, CPU s per simulated s). ``worst`` is the least
    favourable level: the speed-up that holds at every error both reach.

    Each level also gives ``bound``: the largest speed-up any renderer could
    reach there, scipy's cost over the floor cost of the renderer's tick
    rate (``floor_tick`` s per tick, plus ``floor_audio`` s per sample of
    ``audio_rate`` audio for the full render). scipy's cost grows with the
    number of events, a tick renderer's with the duration: where events
    are few the bound falls below :data:`SPEEDUP_TARGET`. For the model
    alone, ``interface`` (a function of the tick rate giving CPU s per
    simulated s) is the least work of the model itself (:func:`interface_floor`:
    ``run_kernel``'s own inputs and outputs, or its ticks with the pad stuck on
    every one, whichever costs more); the bound uses the larger of the two floors.

    Returns None if no level has a qualifying setting of both families.
    """
    ren = [r for r in results if r["family"] == "renderer" and qualifies(r) and r.get(cost)]
    peers = [r for r in results if r["family"] == "scipy" and qualifies(r)]
    levels = []
    for e in sorted({r["period_rel_max"] for r in peers + ren}):
        ss = [p for p in peers if p["period_rel_max"] <= e]
        rr = [r for r in ren if r["period_rel_max"] <= e]
        if not (ss and rr):
            continue
        sp = min(ss, key=lambda r: r["cpu_s_per_sim_s"])
        rb = min(rr, key=lambda r: r[cost])
        slowest_rate = min(r["tick_rate"] for r in rr)
        floor = slowest_rate * floor_tick + audio_rate * floor_audio
        if interface is not None:
            floor = max(floor, interface(slowest_rate))
        levels.append({"period_rel_max": e, "scipy": sp["label"], "scipy_cpu_s_per_sim_s": sp["cpu_s_per_sim_s"],
                       "renderer": rb["label"], "renderer_cpu_s_per_sim_s": rb[cost],
                       "renderer_period_rel_max": rb["period_rel_max"],
                       "speedup": sp["cpu_s_per_sim_s"] / rb[cost],
                       "floor_tick_rate": slowest_rate, "floor_cpu_s_per_sim_s": floor,
                       "bound": sp["cpu_s_per_sim_s"] / floor if floor > 0 else None})
    if not levels:
        return None
    worst = min(levels, key=lambda v: v["speedup"])
    best = max(levels, key=lambda v: v["speedup"])
    met = worst["speedup"] >= SPEEDUP_TARGET
    bounded = worst["bound"] is not None and worst["bound"] < SPEEDUP_TARGET
    return {"worst": worst, "best": best, "levels": levels, "target": SPEEDUP_TARGET, "target_met": met,
            "target_bounded": bool(bounded and not met)}


def interface_floor(duration):
    """``tick rate -> CPU s per simulated s``: the least work of the model alone over a path of ``duration`` s,
    the larger of its interface's rows (:func:`.common.interface_floor`) and of its ticks with the pad stuck
    on every one (:func:`.common.stuck_floor`).

    Timed in the calling run at the path's tick count, once per tick rate.
    """
    seen = {}

    def floor(rate):
        if rate not in seen:
            n = int(round(duration * rate)) + 1
            seen[rate] = max(common.interface_floor(n), common.stuck_floor(n)) / duration
        return seen[rate]
    return floor


def _summarise(results, duration, floor_tick, floor_audio):
    ren = [r for r in results if r["family"] == "renderer" and qualifies(r)]
    peers = [r for r in results if r["family"] == "scipy" and qualifies(r)]
    out = {"qualifying_renderer_settings": len(ren), "qualifying_scipy_settings": len(peers),
           "fastest_within_1pct": None, "best_scipy_within_1pct": None,
           "equal_error": {"model": equal_error(results, COSTS["model"], floor_tick,
                                                 interface=interface_floor(duration)),
                           "render": equal_error(results, COSTS["render"], floor_tick, floor_audio)},
           "failures": sum(1 for r in results if r["status"] != "ok")}
    if ren:
        best = min(ren, key=lambda r: r["cpu_s_per_sim_s"])
        out["fastest_within_1pct"] = {k: best.get(k) for k in ("label", "model", "tick_rate", "table_dx_m",
                                                               "quantize", "tolerance", "cpu_s_per_sim_s",
                                                               "model_cpu_s_per_sim_s",
                                                               "period_rel_max", "event_rms_s", "step_p99_s",
                                                               "step_p99_over_budget", "step_cpu_p99_s",
                                                               "step_cpu_p99_over_budget")}
    if peers:
        bp = min(peers, key=lambda r: r["cpu_s_per_sim_s"])
        out["best_scipy_within_1pct"] = {k: bp.get(k) for k in ("label", "cpu_s_per_sim_s", "period_rel_max",
                                                                "event_rms_s")}
    return out


def _headline(report):
    h = {}
    # the table case's error is the table's (resolution, quantization), not the model's: left out here
    ex = [r for c in report["cases"] if c["kind"] == "konyo" and c["name"] != "bump_table" for r in c["settings"]
          if r.get("model") == "exact" and r.get("event_max_s") is not None]
    h["exact_event_max_s"] = max((r["event_max_s"] for r in ex), default=None)
    h["exact_event_max_s_note"] = "exact model against its reference on every case without a table grid"
    h["exact_missing_or_spurious"] = sum((r["missing"] or 0) + (r["spurious"] or 0) for r in ex)
    h["cross_check_max_abs_s"] = {c["name"]: c["reference"]["cross_check"]["max_abs_s"] for c in report["cases"]}
    for kind in COSTS:
        h[f"speedup_equal_error_{kind}"] = {
            c["name"]: (c["summary"]["equal_error"][kind] or {}).get("worst", {}).get("speedup")
            for c in report["cases"]}
    h["fastest_within_1pct"] = {c["name"]: (c["summary"]["fastest_within_1pct"] or {}).get("label")
                                for c in report["cases"]}
    belt = [c for c in report["cases"] if c["name"] == "belt_coulomb"]
    if belt:
        h["belt_closed_form"] = belt[0]["reference"].get("closed_form")
    return h


# ================================================================ output
def _plots(rep, out_dir):
    plt = common.pyplot()
    files = []
    markers = {"exact": "o", "jump": "s", "karnopp": "D", "stribeck": "o", "euler": "v", "rk4": "^",
               "Radau": "P", "BDF": "X", "LSODA": "*"}
    for case in rep["cases"]:
        fig, ax = plt.subplots(figsize=(8.5, 5.2), layout="constrained")
        ok = [r for r in case["settings"] if r.get("event_rms_rel") is not None]
        vals = [r["event_rms_rel"] for r in ok if r["event_rms_rel"] > 0]
        floor = 1e-16
        top = max(vals + [1e-3]) * 30
        groups = {}
        for r in case["settings"]:
            key = r.get("model") or r.get("method")
            groups.setdefault(key, []).append(r)
        for key, rs in groups.items():
            good = [r for r in rs if r["status"] == "ok" and r.get("event_rms_rel") is not None
                    and r["cpu_s_per_sim_s"]]
            bad = [r for r in rs if r not in good and r.get("cpu_s_per_sim_s")]
            if good:
                ax.loglog([r["cpu_s_per_sim_s"] for r in good], [max(r["event_rms_rel"], floor) for r in good],
                          markers.get(key, "o"), label=key, alpha=0.8,
                          mfc="none" if key in PEER_METHODS else None)
            if bad:
                # the group's own marker, hollow and red, in the failure band: which model failed stays readable
                ax.loglog([r["cpu_s_per_sim_s"] for r in bad], [top] * len(bad), markers.get(key, "o"), ls="",
                          mfc="none", mec="red", mew=1.6, ms=9, label=f"{key}: failed/diverged")
        ax.axhline(top / 3, color="red", lw=0.5, ls=":")
        ax.set_xlabel("CPU seconds per simulated second")
        ax.set_ylabel("event-time RMS error / mean period  (floor 1e-16)")
        ax.set_title(f"{case['title']}\nabove the dotted red line: failed / diverged (at the CPU time until it "
                     "stopped)", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)   # beside the data
        name = f"accuracy_{case['name']}.png"
        common.save_figure(fig, os.path.join(out_dir, name))
        files.append(name)
    return files


def markdown(rep) -> str:
    """Markdown summary of an accuracy report dict."""
    fl = rep["floors"]
    L = ["# Accuracy report: error against run time", "",
         f"Mode: {'quick' if rep['quick'] else 'full'}; elapsed {rep['elapsed_s']:.0f} s. "
         "Every number is in `accuracy.json`.", "",
         "## Speed-up over scipy at equal error", "",
         "A setting qualifies if its worst relative error of the intervals between consecutive events is at "
         "most 1 % and no event is missing or spurious. At each error level a qualifying setting reaches, "
         "the best scipy method (the cheapest qualifying `solve_ivp` setting at most that error) is compared "
         "with the cheapest qualifying renderer setting at most that error; the table gives the least "
         "favourable level (the speed-up holds at every error both reach). Two renderer costs: the model "
         "alone on the renderer's per-tick inputs (the events and per-tick state — what scipy computes) and "
         "the full render (lookup, model and 48 kHz burst audio). CPU seconds per simulated second, measured "
         "in this run.", "",
         f"Bound: scipy's cost over the least work of any tick renderer at the slowest tick rate that "
         f"reached the error (per tick {common.fmt(fl['tick_s'])} s, per 48 kHz audio sample "
         f"{common.fmt(fl['audio_sample_s'])} s, timed in this run; for the model alone at least one call "
         f"that reads run_kernel's six per-tick input rows and writes its four output rows over the case's "
         f"path, timed in this run). scipy's cost grows with the number of "
         f"events, a tick renderer's with the duration: where events are few, no renderer can reach "
         f"{SPEEDUP_TARGET:g}x.", ""]
    rows = []
    for c in rep["cases"]:
        for kind in COSTS:
            q = c["summary"]["equal_error"][kind]
            if q is None:
                rows.append([c["name"], kind, "—", "—", "—", "—", "—", "—", "—"])
                continue
            w = q["worst"]
            rows.append([c["name"], kind, common.fmt(w["period_rel_max"]), w["scipy"],
                         common.fmt(w["scipy_cpu_s_per_sim_s"]), w["renderer"],
                         common.fmt(w["renderer_cpu_s_per_sim_s"]), common.fmt(w["speedup"], ".0f"),
                         _bound_text(q)])
    L.append(common.md_table(["case", "cost", "error level", "best scipy", "CPU s/s", "renderer", "CPU s/s",
                              "speed-up", "bound"], rows))
    L += ["", "## References and cross-checks", ""]
    rows = []
    for c in rep["cases"]:
        r = c["reference"]
        cc = r["cross_check"]
        rows.append([c["name"], r["description"], r["events"], cc["method"], cc["events_compared"],
                     common.fmt(cc["max_abs_s"])])
    L.append(common.md_table(["case", "reference", "events", "cross-check", "compared", "max abs dt, s"], rows))
    for c in rep["cases"]:
        cf = c["reference"].get("closed_form")
        if cf:
            L += ["", f"Closed form ({c['name']}): period {cf['period_s']:.12g} s; exact reference events differ "
                      f"from it by at most {common.fmt(cf['event_max_abs_s'])} s over {cf['events']} events, "
                      f"period relative error {common.fmt(cf['period_rel_error'])}."]
    for c in rep["cases"]:
        L += ["", f"## {c['name']}: {c['title']}", ""]
        if rep.get("plots"):
            L += [f"![work-precision](accuracy_{c['name']}.png)", ""]
        rows = []
        for r in c["settings"]:
            rows.append([r["label"], r["status"], common.fmt(r.get("cpu_s_per_sim_s")),
                         common.fmt(r.get("step_p99_s")), common.fmt(r.get("step_p99_over_budget"), ".2g"),
                         common.fmt(r.get("step_cpu_p99_over_budget"), ".2g"),
                         common.fmt(r.get("event_rms_s")), common.fmt(r.get("event_max_s")),
                         r.get("missing"), r.get("spurious"), common.fmt(r.get("period_rel_max")),
                         common.fmt(r.get("amplitude_rel_rms")), common.fmt(r.get("waveform_nrmse"))])
        L.append(common.md_table(["setting", "status", "CPU s/s", "step p99 s", "p99/budget", "CPU p99/budget",
                                  "event RMS s",
                                  "event max s", "missing", "spurious", "period err", "ampl err", "wave NRMSE"],
                                 rows))
    L += ["", "Timing: " + "; ".join(f"{k}: {v}" for k, v in rep["timing"].items()), ""]
    return "\n".join(L) + "\n"


def _bound_text(q) -> str:
    """The bound of the least favourable level, marked where it lies below the target."""
    b = q["worst"]["bound"]
    if b is None:
        return "—"
    return common.fmt(b, ".0f") + (" (below target)" if b < q["target"] else "")


def terminal_summary(rep) -> str:
    """Short table for the terminal: the speed-up over scipy at equal error and its bound."""
    rows = []
    for c in rep["cases"]:
        m = c["summary"]["equal_error"]["model"]
        r = c["summary"]["equal_error"]["render"]
        f = c["summary"]["fastest_within_1pct"] or {}
        rows.append([c["name"], f.get("label", "none"), common.fmt(f.get("period_rel_max")),
                     common.fmt(m["worst"]["period_rel_max"]) if m else "—",
                     m["worst"]["scipy"] if m else "—",
                     (common.fmt(m["worst"]["speedup"], ".0f") + " / " + _bound_text(m)) if m else "—",
                     (common.fmt(r["worst"]["speedup"], ".0f") + " / " + _bound_text(r)) if r else "—",
                     common.fmt(c["reference"]["cross_check"]["max_abs_s"])])
    return common.text_table(["case", "fastest within 1%", "period err", "equal-error level", "best scipy there",
                              "model x / bound", "full render x / bound", "cross-check |dt| s"], rows)
