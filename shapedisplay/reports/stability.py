"""Stability report: stiff and extreme parameters, and where each method stops being trustworthy.

Sweeps (:func:`build_sweeps`) cover pad mass down to 1e-9 kg, stiffness up to
1e5 N/m, damping from 0 to beyond critical, N 0-20 N, V 1e-6-2 m/s,
delta_mu = 0, mu_s up to 3, tick rates 100 Hz-96 kHz, the naive explicit
baselines around their theoretical step limits, the Stribeck pad on both
sides of its negative-slope threshold, tables with height steps (walls),
cursor jumps and quantization, and inputs that must be rejected.

Per case (:func:`run_case`):

* **finite** — every output finite;
* **friction bound** — ``|f| <= mu_s N`` every tick (Stribeck pad: the
  largest friction the curve allows over the speeds reached);
* **energy bounded** — ``0.5 k x^2 + 0.5 m v^2`` never exceeds a bound
  derived from the slip phase (:func:`energy_bound`);
* **slip not amplified** — for ``euler``/``rk4`` the free modes of the pad
  within a slip phase do not grow from tick to tick
  (:func:`slip_mode_growth`, which measures ``|R(h lambda)|`` itself); for
  the other models the slip energy does not grow (:func:`slip_energy_growth`);
* **event counts converge** — the stick-to-slip counts at ``2 r`` and
  ``4 r`` (capped at 192 kHz; same input path) agree within one event or
  2 %; the count error at ``r`` itself is recorded (``event_count_rel_error``:
  the accuracy cost of the coarse tick, e.g. a table sampled once per tick);
* **verdict** — ``rejected`` (a clear one-line error, recorded), else
  ``numerically unstable`` if any check fails (the method and step are
  recorded), else ``physically self-excited`` where the Stribeck pad,
  started in steady sliding, leaves it at every substep (step-size
  convergence; compared with the criterion ``c + W mu'(V) < 0``), else
  ``stable``. The Stribeck pad's convergence check refines its substep
  (:data:`STRIBECK_SUBSTEPS`), which the tick rate does not set.

The explicit baselines are also compared with linear stability theory:
the step is stable if the amplification factor ``|R(h lambda)| <= 1`` for
the slip-phase eigenvalue ``lambda = omega_n (-zeta + i sqrt(1 - zeta^2))``
(forward Euler ``R(z) = 1 + z``, i.e. ``h < 2 zeta / omega_n``; RK4 the
quartic Taylor polynomial, ``h < ~2.8 / omega_n`` for small zeta).
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
from shapedisplay.reports.peers import stribeck_mu

VERDICTS = ("stable", "physically self-excited", "numerically unstable", "rejected")
#: Models the renderer uses by default for the Konyo pad (must never give NaN/inf).
DEFAULT_MODELS = ("exact", "jump")
KONYO = dict(m=1.0e-6, k=2000.0, c=0.01, mu_s=0.5, mu_k=0.3, N=2.0, V=0.05, rate=10000.0)


# ================================================================ theory
def amplification(method, z):
    """Amplification factor ``|R(z)|`` of one explicit step (z = h lambda, complex)."""
    if method == "euler":
        return abs(1 + z)
    return abs(1 + z + z * z / 2 + z ** 3 / 6 + z ** 4 / 24)


def theory_stable(method, h, omega_n, zeta) -> bool:
    """Linear stability of an explicit step on the slip phase of a pad (omega_n rad/s, zeta)."""
    if zeta >= 1.0:
        lam = [omega_n * (-zeta + s * math.sqrt(zeta * zeta - 1)) for s in (1, -1)]
    else:
        lam = [omega_n * complex(-zeta, math.sqrt(1 - zeta * zeta))]
    return all(amplification(method, h * lm) <= 1.0 + 1e-12 for lm in lam)


def theory_limit(method, zeta) -> float:
    """Largest stable ``h omega_n`` of an explicit method at damping ratio zeta (bisection)."""
    lo, hi = 0.0, 10.0
    if theory_stable(method, hi, 1.0, zeta):
        return math.inf
    if not theory_stable(method, 1e-9, 1.0, zeta):
        return 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if theory_stable(method, mid, 1.0, zeta):
            lo = mid
        else:
            hi = mid
    return lo


def energy_bound(m, k, c, mu_s, N, V) -> float:
    """Bound on ``0.5 k x^2 + 0.5 m v^2`` (J) for a pad with Coulomb stick-slip.

    In stick ``|k x| <= mu_s N + c |V|``; a slip starts with
    ``|k (x - x_eq)| <= 2 mu_s N + c |V|`` and ``v = V`` and its energy about
    ``x_eq`` only decreases (c >= 0). Twice that, plus the worst offset
    ``mu_k N / k``, bounds every state; a factor 4 covers sign flips.
    """
    F = 3.0 * mu_s * N + c * abs(V)
    e = 0.5 * F * F / k + 0.5 * m * (abs(V) + F / math.sqrt(k * m)) ** 2
    return 4.0 * e + 1e-30


def stribeck_slope(c, W, mu_s, mu_k, a, b, v):
    """``c + W mu'(v)`` of the plain Stribeck curve at relative speed v (N s/m); < 0: self-excited."""
    if W <= 0:
        return c
    return c + (-(mu_s - mu_k) * a * math.exp(-a * v / W) + b)


# ================================================================ cases
@dataclass
class Case:
    """One stability case (parameters; ``kind`` "pad", "stribeck", "table" or "bad")."""

    sweep: str
    kind: str
    model: str
    params: dict
    axes: tuple = ()
    extra: dict = field(default_factory=dict)


def _pad_case(sweep, model, axes, **over):
    p = dict(KONYO)
    p.update(over)
    return Case(sweep, "pad", model, p, axes)


def build_sweeps(quick: bool) -> list[Case]:
    """All stability cases (coarser grids in quick mode)."""
    cases = []
    g = (lambda full, q: q if quick else full)
    # A: mass x stiffness (c keeps the published value, so zeta moves too)
    for model in DEFAULT_MODELS:
        for m in np.logspace(-9, -3, g(7, 4)):
            for k in np.logspace(1, 5, g(6, 4)):
                cases.append(_pad_case("mass_stiffness", model, ("m", "k"), m=float(m), k=float(k)))
    # B: damping ratio x tick rate
    rates = g((100.0, 300.0, 1000.0, 3000.0, 10000.0, 30000.0, 96000.0), (100.0, 1000.0, 10000.0, 96000.0))
    zetas = g((0.0, 0.05, 0.11, 0.3, 0.7, 1.0, 1.5, 3.0), (0.0, 0.11, 1.0, 3.0))
    for model in DEFAULT_MODELS:
        for z in zetas:
            for r in rates:
                c = 2 * z * math.sqrt(KONYO["k"] * KONYO["m"])
                cases.append(_pad_case("damping_rate", model, ("zeta", "rate"), c=c, rate=r, zeta=z))
    # C: normal force x speed
    for model in DEFAULT_MODELS:
        for N in g((0.0, 0.01, 0.1, 0.5, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0), (0.0, 0.1, 2.0, 20.0)):
            for V in np.logspace(-6, math.log10(2.0), g(10, 5)):
                cases.append(_pad_case("force_speed", model, ("N", "V"), N=N, V=float(V)))
    # D: mu_s x delta_mu (delta_mu = 0 included)
    for model in DEFAULT_MODELS:
        for mus in g((0.1, 0.3, 0.5, 1.0, 2.0, 3.0), (0.1, 1.0, 3.0)):
            for frac in g((0.0, 0.05, 0.2, 0.4, 0.7, 1.0), (0.0, 0.4, 1.0)):
                cases.append(_pad_case("friction", model, ("mu_s", "delta_mu"), mu_s=mus, mu_k=mus * (1 - frac),
                                       delta_mu=mus * frac))
    # E: explicit baselines across their theoretical step limits (zeta fixed, omega_n via the mass)
    for model in ("euler", "rk4"):
        for z in g((0.11, 0.5), (0.11,)):
            for m in np.logspace(-6, -2, g(9, 5)):
                for r in g((100.0, 300.0, 1000.0, 3000.0, 10000.0, 30000.0, 96000.0), (100.0, 1000.0, 10000.0,
                                                                                        96000.0)):
                    c = 2 * z * math.sqrt(KONYO["k"] * m)
                    cases.append(_pad_case("explicit_step", model, ("h_omega_n", "zeta"), m=float(m), c=c, rate=r,
                                           zeta=z))
    # E': the explicit baselines on the published Konyo pad at every tick rate
    for model in ("euler", "rk4", "exact", "jump"):
        for r in (100.0, 300.0, 1000.0, 3000.0, 10000.0, 30000.0, 48000.0, 96000.0):
            cases.append(_pad_case("konyo_rate", model, ("rate", "model"), rate=r))
    # F: Stribeck pad (contactor still): speed x damping, two loads
    for W in g((0.5, 1.0, 4.0), (1.0,)):
        for c in g((0.0, 0.3, 1.0, 3.0, 10.0, 40.0), (0.0, 1.0, 40.0)):
            for V in np.logspace(-4, math.log10(2.0), g(8, 4)):
                p = dict(m=1e-4, k=1e3, c=c, mu_s=2.1, mu_k=1.4, a=55.0, b=1.9, N=W, V=float(V), rate=1000.0)
                cases.append(Case("stribeck", "stribeck", "stribeck", p, ("V", "c")))
    # G: tables with height steps (walls), cursor jumps, quantization
    for model in DEFAULT_MODELS:
        for step_mm in g((0.5, 2.0, 8.0), (2.0, 8.0)):
            for q in g(("float64", "uint16", "uint8"), ("float64", "uint8")):
                for r in g((100.0, 1000.0, 10000.0, 96000.0), (1000.0, 96000.0)):
                    for jump in g((False, True), (True,)):
                        cases.append(Case("tables", "table", model,
                                          dict(KONYO, step_mm=step_mm, quantize=q, rate=r, cursor_jump=jump),
                                          ("step_mm", "rate")))
    # H: inputs that must be rejected with a clear error
    nan = float("nan")
    inf = float("inf")
    bad = [("mass 0", dict(m=0.0)), ("negative mass", dict(m=-1e-6)), ("infinite stiffness", dict(k=inf)),
           ("negative damping", dict(c=-0.01)), ("mu_k > mu_s", dict(mu_k=0.6)), ("mu_s = 0", dict(mu_s=0.0)),
           ("negative N", dict(N=-1.0)), ("NaN N", dict(N=nan)), ("infinite V", dict(V=inf)),
           ("NaN V", dict(V=nan)), ("tick rate 50 Hz", dict(rate=50.0)), ("tick rate 400 kHz", dict(rate=4e5)),
           ("NaN heights", dict(heights="nan")), ("infinite heights", dict(heights="inf")),
           ("empty height map", dict(heights="empty")), ("one-pixel height map", dict(heights="one"))]
    for label, over in bad:
        p = dict(KONYO)
        p.update(over)
        cases.append(Case("bad_input", "bad", "exact", p, ("case", "model"), {"label": label}))
    return cases


# ================================================================ running
def _device(p, stribeck=False):
    from shapedisplay.table.devices import BurstParams, DeviceProfile, FrictionParams, PadParams
    extra = {"stribeck": {"a": p["a"], "b": p["b"]}} if stribeck else {}
    return DeviceProfile(name="stability", pad=PadParams(p["m"], p["k"], p["c"]),
                         friction=FrictionParams(p["mu_s"], p["mu_k"]), burst=BurstParams(gain=1.0),
                         normal_force_range=(0.0, 20.0), velocity_range=(1e-6, 2.0), extra=extra)


def _duration(p, quick):
    """Simulated time: a few stick-slip periods where they are short, capped by the tick budget."""
    k, N, V = p["k"], max(p["N"], 1e-9), max(abs(p["V"]), 1e-12)
    t_stick = 2 * p["mu_s"] * N / (k * V)
    dur = min(max(4 * t_stick, 0.02), 0.05 if quick else 0.1)
    return dur


def _run_pad(p, model_name, rate, duration, stribeck=False, substep_s=None):
    """Run a pad model at constant V and N.

    Konyo-type models start stuck with the spring relaxed. The ``stribeck``
    model starts in steady sliding at relative speed V (spring at
    ``-mu(V) W / k``) with the pad speed perturbed by 1 % of V, so a
    negative friction slope shows up as a growing oscillation that ends in
    stick-slip, and a positive one as a decaying perturbation.
    """
    from shapedisplay.render.models import get_model, run_kernel
    from shapedisplay.errors import InputError
    from shapedisplay.table.devices import check_tick_rate
    rate = check_tick_rate(rate)
    for name in ("N", "V"):
        if not math.isfinite(p[name]):
            raise InputError(f"`{name}` must be finite (got {p[name]!r})")
    if p["N"] < 0:
        raise InputError(f"`N` must be >= 0 N (got {p['N']})")
    dev = _device(p, stribeck)
    opts = {"substep_s": substep_s} if substep_s is not None else {}
    model = get_model(model_name, dev, **opts)
    n = int(round(duration * rate)) + 1
    t = np.arange(n) / rate
    ones = np.ones(n)
    V = p["V"] * ones
    state = None
    if stribeck:
        state = model.new_state()
        mu = stribeck_mu(abs(p["V"]), p["N"], p["mu_s"], p["mu_k"], p["a"], p["b"]) if p["N"] > 0 else 0.0
        sgn = 1.0 if p["V"] >= 0 else -1.0
        state["phase"] = 1.0
        state["x"] = -sgn * mu * p["N"] / p["k"]
        state["v"] = 0.01 * p["V"]
        state["s"] = -sgn
        state["f"] = -sgn * mu * p["N"]
    else:
        V[0] = 0.0
    S, f, st, x, v, et, ea = run_kernel(model, t, V, p["N"] * ones, p["mu_s"] * ones, p["mu_k"] * ones,
                                                ones, state=state)
    return {"f": f, "x": x, "v": v, "state": st, "events": int(et.size), "blow": float(S["diverged"]),
            "blow_t": float(S["diverged_at"]), "ev_a": ea}


def slip_energy_growth(p, r) -> float:
    """Largest growth factor of the slip energy over one slip phase (1.0 = no growth).

    In a slip of a Konyo-type pad with c >= 0 the energy about the slip
    equilibrium, ``0.5 k (x - f/k)^2 + 0.5 m v^2`` (``f = s mu_k N``), can
    only decrease; an explicit step with ``|R(h lambda)| > 1`` makes it grow
    (a stable one wobbles it by O(h omega_n)). Compared between the first and
    last tick of each slip phase (same sign). Recorded with every case; the
    verdict uses :func:`slip_mode_growth` where the modes are defined.
    """
    f, x, v = r["f"], r["x"], r["v"]
    k, m = p["k"], p["m"]
    E = 0.5 * k * (x - f / k) ** 2 + 0.5 * m * v * v
    worst = 1.0
    for i, j in _slip_groups(r):
        if E[i] > 0:
            worst = max(worst, float(E[j] / E[i]))
    return worst


#: Substeps of the ``stribeck`` model in the stability sweep (the step-size convergence check), s.
STRIBECK_SUBSTEPS = (2e-6, 1e-6, 0.5e-6)


def _perturbation_growth(r, p) -> float:
    """Largest pad-speed deviation from steady sliding over the last quarter of a run / the initial 1 % of V."""
    v = r["v"]
    tail = v[3 * v.size // 4:]
    return float(np.max(np.abs(tail))) / max(0.01 * abs(p["V"]), 1e-300)


def _self_excited(r, p) -> bool:
    """Steady sliding left on its own: the run reached stick-slip, or the 1 % perturbation at least doubled."""
    return bool(r["events"] > 0 or _perturbation_growth(r, p) > 2.0)


def _slip_groups(r):
    """Index ranges (i, j), j > i, of ticks in one slip phase with one friction sign."""
    st, f = r["state"], r["f"]
    out = []
    i, n = 0, st.size
    while i < n:
        if st[i] != 1:
            i += 1
            continue
        j = i
        while j + 1 < n and st[j + 1] == 1 and f[j + 1] == f[i]:
            j += 1
        if j > i:
            out.append((i, j))
        i = j + 1
    return out


def slip_mode_growth(p, r):
    """Largest growth factor per tick of the pad's free modes within a slip phase (None if not measurable).

    In a slip the deviation ``e = (x - f/k, v)`` from the slip equilibrium
    obeys ``e' = J e`` with ``J = [[0, 1], [-k/m, -c/m]]``. Forward Euler and
    RK4 advance it by ``R(h J)``, which shares ``J``'s eigenvectors, so each
    modal amplitude grows by exactly ``|R(h lambda)|`` per tick: the measured
    factor is the theory's amplification factor, with no within-oscillation
    wobble (unlike the energy). None where ``J`` is (nearly) defective
    (zeta ~ 1) or no slip lasted two ticks. Only for models that take one
    step per tick and locate no event inside it (``euler``, ``rk4``).
    """
    k, m, c = p["k"], p["m"], p["c"]
    J = np.array([[0.0, 1.0], [-k / m, -c / m]])
    lam, vec = np.linalg.eig(J)
    if np.linalg.cond(vec) > 1e6:
        return None
    inv = np.linalg.inv(vec)
    x, v, f = r["x"], r["v"], r["f"]
    worst = None
    for i, j in _slip_groups(r):
        ci = inv @ np.array([x[i] - f[i] / k, v[i]])
        cj = inv @ np.array([x[j] - f[j] / k, v[j]])
        big = np.max(np.abs(ci))
        for a, b in zip(np.abs(ci), np.abs(cj)):
            if big > 0 and a > 1e-9 * big:
                g = float((b / a) ** (1.0 / (j - i)))
                worst = g if worst is None else max(worst, g)
    return worst


def _higher(rate):
    from shapedisplay.table.devices import TICK_RATE_RANGE
    return [min(2 * rate, TICK_RATE_RANGE[1]), min(4 * rate, TICK_RATE_RANGE[1])]


def _count_converged(counts):
    """Counts at r, 2r, 4r converge if the two finest agree within one event or 2 %."""
    n_hi = counts[-1]
    return abs(counts[-2] - n_hi) <= max(1, 0.02 * n_hi)


def _count_error(counts):
    """Relative difference of the count at the case's own rate from the finest count."""
    return abs(counts[0] - counts[-1]) / max(counts[-1], 1)


def run_case(case: Case, quick: bool) -> dict:
    """Run one case and return its record (parameters, checks, verdict)."""
    p = dict(case.params)
    rec = {"sweep": case.sweep, "model": case.model, "kind": case.kind,
           "params": {k: (v if not isinstance(v, float) or math.isfinite(v) else str(v)) for k, v in p.items()},
           "finite": None, "friction_bounded": None, "energy_bounded": None, "event_counts": None,
           "events_converge": None, "verdict": None, "reason": "", "step_s": None, "h_omega_n": None}
    rec.update({k: v for k, v in case.extra.items()})
    try:
        if case.kind == "bad":
            _run_bad(p)
            rec["verdict"] = "stable"
            rec["reason"] = "bad input was accepted"
            return rec
        if case.kind == "table":
            return _run_table_case(case, rec, quick)
        return _run_pad_case(case, rec, quick)
    except ShapeDisplayError as exc:
        rec["verdict"] = "rejected"
        rec["reason"] = str(exc)
        return rec


def _run_bad(p):
    from shapedisplay.author.compile import compile_heightfield
    from shapedisplay.author.sources import from_array
    h = p.get("heights")
    if h is not None:
        arr = {"nan": np.array([[0.0, np.nan, 0.0]]), "inf": np.array([[0.0, np.inf, 0.0]]),
               "empty": np.zeros((0, 0)), "one": np.zeros((1, 1))}[h]
        compile_heightfield(from_array(arr, 1e-3))
        return
    _run_pad(p, "exact", p["rate"], 0.01)


def _run_pad_case(case, rec, quick):
    p = case.params
    stribeck = case.kind == "stribeck"
    rate = p["rate"]
    # the Stribeck pad starts in steady sliding: a fixed span shows the perturbation grow or decay
    dur = (0.05 if quick else 0.1) if stribeck else _duration(p, quick)
    m, k, c = p["m"], p["k"], p["c"]
    wn = math.sqrt(k / m)
    zeta = c / (2 * math.sqrt(k * m))
    rec.update(step_s=1.0 / rate, h_omega_n=wn / rate, omega_n=wn, zeta=zeta, duration_s=dur)
    if case.model in ("euler", "rk4"):
        rec["theory_stable"] = theory_stable(case.model, 1.0 / rate, wn, zeta)
        rec["theory_limit_h_omega_n"] = theory_limit(case.model, zeta)
    if stribeck:
        # the tick rate does not set the Stribeck model's step (its substeps do): refine the substep
        subs = list(STRIBECK_SUBSTEPS)
        runs = [_run_pad(p, case.model, rate, dur, True, substep_s=h) for h in subs]
        rec.update(step_s=subs[0], substeps_s=subs)
    else:
        runs = [_run_pad(p, case.model, r, dur) for r in [rate] + _higher(rate)]
    r0 = runs[0]
    finite = all(np.all(np.isfinite(r["f"])) and np.all(np.isfinite(r["x"])) and np.all(np.isfinite(r["v"]))
                 for r in runs)
    W = p["N"]
    if stribeck:
        vmax = max(float(np.max(np.abs(r["v"] + p["V"]))) for r in runs) if finite else math.inf
        mu_hi = max(p["mu_s"], stribeck_mu(vmax, W, p["mu_s"], p["mu_k"], p["a"], p["b"])) if W > 0 else 0.0
        fbound = mu_hi * W
    else:
        fbound = p["mu_s"] * W
    fmax = float(np.max(np.abs(r0["f"]))) if finite else math.inf
    fb_ok = fmax <= fbound * (1 + 1e-9) + 1e-12
    if stribeck:
        # the spring-damper force is what the contact carries; energy about rest with the same bound form
        eb = energy_bound(m, k, c, max(p["mu_s"], fbound / W if W > 0 else 0.0), W, p["V"])
    else:
        eb = energy_bound(m, k, c, p["mu_s"], W, p["V"])
    E = 0.5 * k * r0["x"] ** 2 + 0.5 * m * r0["v"] ** 2 if finite else np.array([math.inf])
    e_ok = bool(finite and np.max(E) <= eb)
    counts = [r["events"] for r in runs]
    conv = _count_converged(counts)
    blow = any(r["blow"] for r in runs[:1])
    growth = 1.0 if (stribeck or not finite) else slip_energy_growth(p, r0)
    # one explicit step per tick: tick-end states of a slip follow R(h J) exactly (the event-locating models
    # may re-stick and break away inside a tick, so only their energy is checked)
    mode = slip_mode_growth(p, r0) if (finite and case.model in ("euler", "rk4")) else None
    if mode is not None:
        # modal amplitudes grow by exactly |R(h lambda)| per tick: any growth is the linear instability
        grows = mode > 1.0 + 1e-7
    else:
        # a stable explicit step still wobbles the energy by O(h omega_n) within an oscillation: tolerate that much
        grows = growth > 1.0 + wn / rate + 1e-6
    rec["slip_energy_growth"] = growth
    rec["slip_mode_growth_per_tick"] = mode
    if case.model in ("euler", "rk4"):
        rec["theory_amplification"] = max(
            amplification(case.model, lm / rate) for lm in np.linalg.eigvals(np.array([[0.0, 1.0], [-k / m, -c / m]])))
    rec["linear_instability_detected"] = bool(blow or grows)
    rec.update(finite=bool(finite), friction_bounded=bool(fb_ok), friction_max_N=fmax, friction_limit_N=fbound,
               energy_bounded=e_ok, energy_max_J=float(np.max(E)) if finite else None, energy_limit_J=eb,
               event_counts=counts, events_converge=bool(conv),
               event_count_rel_error=_count_error(counts),
               diverged=bool(blow), diverged_at_s=r0["blow_t"] if blow else None)
    if stribeck:
        sl = stribeck_slope(c, W, p["mu_s"], p["mu_k"], p["a"], p["b"], abs(p["V"]))
        rec["stribeck_slope_Ns_per_m"] = sl
        growing = [_self_excited(r, p) for r in runs]
        rec["self_excitation_by_substep"] = growing
        rec["perturbation_growth"] = _perturbation_growth(r0, p) if finite else None
        if finite and len(set(growing)) > 1:
            conv = False
            rec["events_converge"] = False
    else:
        rec["event_count_rates"] = [rate] + _higher(rate)
    fails = []
    if blow:
        fails.append(f"diverged at t = {r0['blow_t']:.3g} s")
    if not finite:
        fails.append("non-finite output")
    if not fb_ok:
        fails.append(f"|friction| {fmax:.3g} N > limit {fbound:.3g} N")
    if not e_ok:
        fails.append("energy not bounded")
    if grows:
        fails.append(f"free modes grow x{mode:.6g} per tick within a slip phase" if mode is not None
                     else f"slip energy grows x{growth:.3g} within a slip phase")
    if not conv:
        fails.append(f"event counts {counts} (or growth of the sliding perturbation) do not converge as the "
                     f"substep falls" if stribeck else
                     f"event counts {counts} do not converge as the tick rate rises")
    h = rec["step_s"]
    if fails:
        rec["verdict"] = "numerically unstable"
        rec["reason"] = f"{case.model} at h = {1e6 * h:.4g} us (h*omega_n = {wn * h:.3g}): " + "; ".join(fails)
    elif stribeck and growing[0]:
        rec["verdict"] = "physically self-excited"
        rec["reason"] = (f"steady sliding at V is unstable at every substep {subs} s (perturbation x"
                         f"{rec['perturbation_growth']:.3g}, stick-slip events {counts}); "
                         f"c + W mu'(V) = {sl:.3g} N s/m")
    else:
        rec["verdict"] = "stable"
    return rec


def _run_table_case(case, rec, quick):
    from shapedisplay.author.compile import CompileOptions, compile_heightfield
    from shapedisplay.author.forces import MappingOptions
    from shapedisplay.render.cursor import CursorPath
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.author.sources import step_edge
    p = case.params
    dev = _device(p)
    hf = step_edge(p["step_mm"] * 1e-3, (0.04, 0.004), 2e-4)
    res = compile_heightfield(hf, dev, MappingOptions(n_base=0.5, n_gain=1000.0),
                              CompileOptions(quantize=p["quantize"]))
    table = res.table
    rate = p["rate"]
    rec.update(step_s=1.0 / rate, walls=int(res.report["walls"]["count"]))

    def path(r):
        dur = 0.5
        n = int(round(dur * r)) + 1
        t = np.arange(n) / r
        x = 0.002 + 0.06 * t       # 60 mm/s across the step
        y = np.full(n, 0.002)
        if p["cursor_jump"]:
            # teleports: 15 mm back at 1/3, 25 mm forward at 2/3 (one tick each)
            x = x + np.where(t >= dur / 3, -0.015, 0.0) + np.where(t >= 2 * dur / 3, 0.025, 0.0)
        return CursorPath(t, x, y, r, "stability stroke")
    counts = []
    rr = None
    base = path(rate)
    for r in [rate] + _higher(rate):
        # the finer runs play the same input (the base path resampled), so a teleport spans the same time
        out = Renderer(table, device=dev, model=case.model, tick_rate=r).render(base if r == rate else
                                                                               base.resample(r))
        counts.append(int(out.event_time.size))
        if rr is None:
            rr = out
    finite = bool(np.all(np.isfinite(rr.friction_force)) and np.all(np.isfinite(rr.audio)))
    lim = rr.mu_s * rr.normal_force
    fb_ok = bool(np.all(np.abs(rr.friction_force) <= lim * (1 + 1e-9) + 1e-12))
    conv = _count_converged(counts)
    rec.update(finite=finite, friction_bounded=fb_ok, energy_bounded=None,
               energy_note="renderer outputs carry no pad state; |friction| bound checked instead",
               event_counts=counts, events_converge=bool(conv),
               event_count_rel_error=_count_error(counts),
               max_speed_m_s=float(np.max(np.abs(rr.vx))))
    fails = [w for w, ok in (("non-finite output", finite), ("|friction| above mu_s N", fb_ok),
                             (f"event counts {counts} do not converge", conv)) if not ok]
    if fails:
        rec["verdict"] = "numerically unstable"
        rec["reason"] = f"{case.model} at h = {1e6 / rate:.4g} us: " + "; ".join(fails)
    else:
        rec["verdict"] = "stable"
    return rec


# ================================================================ the report
def run(out_dir, quick=False, progress=True, plots=True, stream=None) -> dict:
    """Run the stability report; write ``stability.json``, ``stability.md`` and verdict-map PNGs."""
    out_dir = prepare_output_dir(out_dir)
    stream = stream if stream is not None else sys.stderr
    cases = build_sweeps(quick)
    bar = common.Progress(len(cases), "stability", stream=stream, enabled=progress)
    t0 = time.perf_counter()
    recs = []
    for case in cases:
        recs.append(run_case(case, quick))
        bar.update(1, f"{case.sweep} {case.model}")
    bar.close()
    summary = {v: sum(1 for r in recs if r["verdict"] == v) for v in VERDICTS}
    dm = [r for r in recs if r["model"] in DEFAULT_MODELS and r["kind"] != "bad"]
    nonfinite_default = sum(1 for r in dm if r["finite"] is False)
    unstable_default = sum(1 for r in dm if r["verdict"] == "numerically unstable")
    expl = [r for r in recs if r.get("theory_stable") is not None]
    agree = sum(1 for r in expl if r["theory_stable"] != r["linear_instability_detected"])
    bad = [r for r in recs if r["kind"] == "bad"]
    strib = [r for r in recs if r["kind"] == "stribeck" and r.get("stribeck_slope_Ns_per_m") is not None]
    strib_agree = sum(1 for r in strib if (r["stribeck_slope_Ns_per_m"] < 0)
                      == (r["verdict"] == "physically self-excited"))
    konyo_expl = {f"{r['model']} {r['params']['rate'] / 1000:g} kHz": r["verdict"]
                  for r in recs if r["sweep"] == "konyo_rate"}
    report = {
        "report": "stability", "quick": bool(quick), "elapsed_s": time.perf_counter() - t0,
        "summary": {"cases": len(recs), "verdicts": summary, **summary,
                    "default_models": list(DEFAULT_MODELS),
                    "default_model_cases": len(dm),
                    "default_model_nonfinite": nonfinite_default,
                    "default_model_numerically_unstable": unstable_default,
                    "explicit_cases": len(expl), "explicit_agree_with_theory": agree,
                    "stribeck_cases": len(strib), "stribeck_agree_with_slope_criterion": strib_agree,
                    "bad_inputs": len(bad), "bad_inputs_rejected": sum(1 for r in bad if r["verdict"] == "rejected"),
                    "konyo_pad_by_rate": konyo_expl,
                    "theory_limits_h_omega_n": {
                        f"{m} zeta={z}": theory_limit(m, z) for m in ("euler", "rk4") for z in (0.11, 0.5)},
                    "konyo_pad": {"omega_n": math.sqrt(KONYO["k"] / KONYO["m"]),
                                  "zeta": KONYO["c"] / (2 * math.sqrt(KONYO["k"] * KONYO["m"]))}},
        "checks": {
            "finite": "every output finite at every tick",
            "friction_bounded": "|friction| <= mu_s N (Stribeck: the largest mu of the curve over the speeds reached)",
            "energy_bounded": "0.5 k x^2 + 0.5 m v^2 (J) never above energy_limit_J (see energy_bound)",
            "events_converge": "stick-to-slip counts at 2r and 4r (<= 192 kHz, same input) agree within 1 event or 2 %; "
                           "event_count_rel_error = |n(r) - n(4r)| / n(4r)",
            "null": "check not applicable (rejected input; renderer cases carry no pad energy)"},
        "cases": recs}
    return common.write_report(report, out_dir, "stability", markdown, _plots if plots else None)


_COLORS = {"stable": "#2a9d8f", "physically self-excited": "#e9c46a", "numerically unstable": "#e63946",
           "rejected": "#6c757d"}


_DRAW_ORDER = ("stable", "rejected", "physically self-excited", "numerically unstable")


def _plots(rep, out_dir):
    plt = common.pyplot()
    from matplotlib.lines import Line2D
    files = []
    sweeps = {}
    for r in rep["cases"]:
        if r["kind"] == "bad":
            continue
        sweeps.setdefault(r["sweep"], []).append(r)
    for sweep, rs in sweeps.items():
        panels = sorted({_panel(sweep, r) for r in rs})
        fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels) + 1, 4.6), squeeze=False,
                                 layout="constrained")
        for ax, panel in zip(axes[0], panels):
            model = panel[0]
            # worst verdicts drawn last, so a failure is never hidden under a stable case at the same point
            sel = sorted((r for r in rs if _panel(sweep, r) == panel), key=lambda r: _DRAW_ORDER.index(r["verdict"]))
            xs, ys, cs = [], [], []
            for r in sel:
                x, y, xl, yl, logx, logy = _axes(sweep, r)
                xs.append(x)
                ys.append(y)
                cs.append(_COLORS[r["verdict"]])
            ax.scatter(xs, ys, c=cs, s=36, marker="s", edgecolors="k", linewidths=0.3)
            if logx:
                ax.set_xscale("log")
            if logy:
                ax.set_yscale("log")
            if sweep == "explicit_step":
                # over a band around the swept damping ratios (one ratio alone would draw a single point)
                zz = np.linspace(max(0.0, min(ys) - 0.05), max(ys) + 0.05, 50)
                ax.plot([theory_limit(model, z) for z in zz], zz, "k--", lw=1, label="theory limit")
            if sweep == "stribeck":
                # the linear criterion c + W mu'(V) = 0 (steady sliding unstable below the line)
                p0 = sel[0]["params"]
                vv = np.logspace(math.log10(min(xs)), math.log10(max(xs)), 200)
                cc = (p0["mu_s"] - p0["mu_k"]) * p0["a"] * np.exp(-p0["a"] * vv / p0["N"]) - p0["b"]
                ax.plot(vv[cc > 0], cc[cc > 0] + 1e-2, "k--", lw=1)
            ax.set_xlabel(xl)
            ax.set_ylabel(yl)
            ax.set_title(f"{sweep}: {model}" + (f", {panel[1]}" if panel[1] else ""), fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
        handles = [Line2D([], [], marker="s", ls="", color=c, label=v) for v, c in _COLORS.items()]
        if sweep == "explicit_step":
            handles.append(Line2D([], [], ls="--", color="k", label="theory limit"))
        if sweep == "stribeck":
            handles.append(Line2D([], [], ls="--", color="k", label="c + W mu'(V) = 0"))
        # below the panels, in as many rows as the width needs (one panel: three columns)
        fig.legend(handles=handles, loc="outside lower center", ncol=len(handles) if len(panels) > 1 else 3,
                   fontsize=7)
        name = f"stability_{sweep}.png"
        common.save_figure(fig, os.path.join(out_dir, name))
        files.append(name)
    return files


def _panel(sweep, r):
    """Panel of a verdict map: the model, and for the Stribeck sweep the load (one map per W)."""
    if sweep == "stribeck":
        return (r["model"], f"W = {r['params']['N']:g} N")
    return (r["model"], "")


def _axes(sweep, r):
    p = r["params"]
    if sweep == "mass_stiffness":
        return p["m"], p["k"], "pad mass kg", "stiffness N/m", True, True
    if sweep == "damping_rate":
        return p["rate"], p["zeta"] + 1e-3, "tick rate Hz", "damping ratio zeta (+1e-3)", True, True
    if sweep == "force_speed":
        return p["V"], p["N"] + 1e-2, "V m/s", "N (+0.01) N", True, True
    if sweep == "friction":
        return p["mu_s"], p["delta_mu"], "mu_s", "delta_mu", False, False
    if sweep == "explicit_step":
        return r["h_omega_n"], p["zeta"], "h * omega_n", "zeta", True, False
    if sweep == "konyo_rate":
        return p["rate"], r["h_omega_n"], "tick rate Hz", "h * omega_n", True, True
    if sweep == "stribeck":
        return p["V"], p["c"] + 1e-2, "finger speed V m/s", "damping c (+0.01) N s/m", True, True
    if sweep == "tables":
        return p["rate"], p["step_mm"], "tick rate Hz", "step height mm", True, True
    return 0, 0, "", "", False, False


def markdown(rep) -> str:
    s = rep["summary"]
    L = ["# Stability report", "",
         f"Mode: {'quick' if rep['quick'] else 'full'}; {s['cases']} cases in {rep['elapsed_s']:.0f} s. "
         "Every case with its parameters, checks and verdict is in `stability.json`.", "",
         common.md_table(["verdict", "cases"], [[v, s["verdicts"][v]] for v in VERDICTS]), "",
         f"* Default models ({', '.join(s['default_models'])}): {s['default_model_cases']} cases, "
         f"{s['default_model_nonfinite']} with NaN/inf, {s['default_model_numerically_unstable']} numerically "
         f"unstable.",
         f"* Explicit baselines: the verdict agrees with linear stability theory in "
         f"{s['explicit_agree_with_theory']} of {s['explicit_cases']} cases.",
         f"* Stribeck pad started in steady sliding: the verdict (self-excited when the sliding perturbation grows "
         f"at every substep {', '.join(f'{h * 1e6:g}' for h in STRIBECK_SUBSTEPS)} us) agrees with the linear "
         f"criterion c + W mu'(V) < 0 in {s['stribeck_agree_with_slope_criterion']} of {s['stribeck_cases']} cases.",
         f"* Bad inputs rejected with a clear error: {s['bad_inputs_rejected']} of {s['bad_inputs']}.", "",
         "## The published Konyo pad by tick rate", "",
         f"omega_n = {s['konyo_pad']['omega_n']:.4g} rad/s, zeta = {s['konyo_pad']['zeta']:.3g}; theory: forward "
         f"Euler needs h*omega_n < {s['theory_limits_h_omega_n']['euler zeta=0.11']:.3g}, RK4 "
         f"h*omega_n < {s['theory_limits_h_omega_n']['rk4 zeta=0.11']:.3g} (zeta 0.11).", "",
         common.md_table(["model and rate", "verdict"], list(s["konyo_pad_by_rate"].items())), "",
         "## Checks", ""]
    L += [f"* `{k}`: {v}" for k, v in rep["checks"].items()]
    L += ["", "## Verdict maps", ""]
    L += [f"![{f}]({f})" for f in rep.get("plots", [])]
    L += ["", "## Rejected inputs", ""]
    L.append(common.md_table(["case", "error"], [[r.get("label", r["sweep"]), r["reason"]]
                                                 for r in rep["cases"] if r["kind"] == "bad"]))
    L += ["", "## Numerically unstable cases (first 40)", ""]
    un = [r for r in rep["cases"] if r["verdict"] == "numerically unstable"][:40]
    L.append(common.md_table(["sweep", "model", "reason"], [[r["sweep"], r["model"], r["reason"]] for r in un]))
    return "\n".join(L) + "\n"


def terminal_summary(rep) -> str:
    s = rep["summary"]
    rows = [[v, s["verdicts"][v]] for v in VERDICTS]
    rows.append(["default models NaN/inf", s["default_model_nonfinite"]])
    rows.append(["explicit agree w/ theory", f"{s['explicit_agree_with_theory']}/{s['explicit_cases']}"])
    rows.append(["Stribeck agree w/ c+W mu'<0", f"{s['stribeck_agree_with_slope_criterion']}/{s['stribeck_cases']}"])
    rows.append(["bad inputs rejected", f"{s['bad_inputs_rejected']}/{s['bad_inputs']}"])
    for k, v in s["konyo_pad_by_rate"].items():
        if k.startswith(("euler 1 kHz", "rk4 1 kHz", "exact 1 kHz", "jump 1 kHz")):
            rows.append([f"Konyo pad, {k}", v])
    return common.text_table(["verdict", f"cases (of {s['cases']})"], rows)
