"""Pad kernels against exact answers: closed-form periods, tick-rate invariance, energy."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st
from numba import njit
from scipy.integrate import solve_ivp

from shapedisplay.devices import FrictionParams, PadParams
from shapedisplay.errors import InputError, ModelError
from shapedisplay.runtime import pads
from shapedisplay.runtime.layouts import PAD_PARAMS, PAD_STATE
from shapedisplay.runtime.models import MODELS, JumpModel, simulate_pad

KONYO = PadParams(1.0e-6, 2000.0, 0.01)


def reference_period(pad, mu_s, mu_k, N, V):
    """Stick-slip period from an independent fine-step integration of the slip phase.

    Slip from breakaway (k x + c V = mu_s N, x' = V) is integrated with
    DOP853 at rtol 1e-12 until x' returns to V; the stick time to the next
    breakaway is then (mu_s N - f_restick) / (k V).
    """
    m, k, c = pad.mass, pad.stiffness, pad.damping
    xb = (mu_s * N - c * V) / k

    def rhs(t, z):
        return [z[1], (mu_k * N - c * z[1] - k * z[0]) / m]

    def back(t, z):
        return z[1] - V
    back.direction = 1.0
    back.terminal = True
    sol = solve_ivp(rhs, (1e-9, 1e-2), [xb, V], method="DOP853", rtol=1e-12, atol=1e-16,
                    events=back, max_step=1e-6, first_step=1e-10)
    # start just after the breakaway so the tangent start is not an event
    t_slip = sol.t_events[0][0]
    x_r = sol.y_events[0][0][0]
    f_r = k * x_r + c * V
    return t_slip + (mu_s * N - f_r) / (k * V)


@pytest.mark.parametrize("V,N", [(0.05, 2.0), (0.02, 1.0), (0.2, 3.0)])
def test_exact_stick_period_matches_independent_integration(V, N):
    r = simulate_pad("exact", V=V, N=N, pad=KONYO, friction=FrictionParams(0.5, 0.3),
                     tick_rate=10_000, duration=0.1)
    ref = reference_period(KONYO, 0.5, 0.3, N, V)
    periods = np.diff(r.event_time)[1:]
    assert len(periods) >= 3
    assert np.all(np.abs(periods - ref) <= 0.005 * ref)
    # in fact it is exact to the reference's precision
    assert np.all(np.abs(periods - ref) <= 1e-6 * ref)


def test_exact_period_undamped_closed_form():
    """c = 0: f_restick = (2 mu_k - mu_s) N and slip = a known fraction of a cycle."""
    pad = PadParams(1e-6, 2000.0, 0.0)
    N, V, mus, muk = 2.0, 0.05, 0.5, 0.3
    w = math.sqrt(pad.stiffness / pad.mass)
    A0 = (mus - muk) * N / pad.stiffness          # offset from equilibrium at breakaway
    # y = A0 cos wt + V/w sin wt ; v = V cos wt - A0 w sin wt; back to V at wt = 2pi - 2 atan(A0 w / V)
    ts = (2 * math.pi - 2 * math.atan2(A0 * w, V)) / w
    f_r = (2 * muk - mus) * N
    period = ts + (mus * N - f_r) / (pad.stiffness * V)
    r = simulate_pad("exact", V=V, N=N, pad=pad, friction=FrictionParams(mus, muk), tick_rate=2000, duration=0.1)
    assert np.allclose(np.diff(r.event_time), period, rtol=1e-9, atol=0)


def test_exact_event_times_do_not_depend_on_tick_rate():
    runs = [simulate_pad("exact", V=0.05, N=2.0, pad=KONYO, tick_rate=rate, duration=0.2)
            for rate in (1000, 2000, 5000, 10000)]
    base = runs[0].event_time
    assert len(base) > 20
    for r in runs[1:]:
        assert len(r.event_time) == len(base)
        assert np.max(np.abs(r.event_time - base)) <= 1e-9
        assert np.allclose(r.event_amplitude, runs[0].event_amplitude, rtol=1e-9)


def test_several_events_inside_one_tick():
    r = simulate_pad("exact", V=0.5, N=2.0, pad=KONYO, tick_rate=100, duration=0.1)
    per_tick = np.bincount(np.floor(r.event_time * 100 + 1e-9).astype(int))
    assert per_tick.max() >= 5
    ref = simulate_pad("exact", V=0.5, N=2.0, pad=KONYO, tick_rate=10_000, duration=0.1)
    assert np.max(np.abs(r.event_time - ref.event_time)) <= 1e-9


def test_burst_amplitude_is_elastic_force_at_breakaway():
    pad = KONYO
    V, N, mus = 0.05, 2.0, 0.5
    r = simulate_pad("exact", V=V, N=N, pad=pad, friction=FrictionParams(mus, 0.3), tick_rate=1000, duration=0.05)
    # A = B (mu_s N - c x') with x' = V at breakaway, B = 1
    assert np.allclose(r.event_amplitude, mus * N - pad.damping * V, rtol=1e-12)


def test_energy_balance_per_tick():
    """Work by friction on the pad = change of stored energy + damper loss, every tick."""
    for V, N in ((0.05, 2.0), (0.3, 1.0)):
        r = simulate_pad("exact", V=V, N=N, pad=KONYO, tick_rate=1000, duration=0.05)
        m, k = KONYO.mass, KONYO.stiffness
        E = 0.5 * k * r.x ** 2 + 0.5 * m * r.v ** 2
        lhs = r.work_friction[2:]
        rhs = np.diff(E)[1:] + r.work_damping[2:]
        scale = np.abs(r.work_friction).max()
        assert np.max(np.abs(lhs - rhs)) <= 1e-9 * scale
        assert np.all(r.work_damping >= 0)


@settings(max_examples=25, deadline=None)
@given(V=st.floats(-0.5, 0.5), N=st.floats(0.0, 8.0), dmu=st.floats(0.0, 0.4),
       zeta=st.floats(0.0, 1.5), rate=st.sampled_from([100, 1000, 10_000, 96_000]))
def test_friction_never_exceeds_static_limit(V, N, dmu, zeta, rate):
    c = zeta * 2 * math.sqrt(KONYO.stiffness * KONYO.mass)
    pad = PadParams(KONYO.mass, KONYO.stiffness, c)
    for model in ("exact", "jump"):
        r = simulate_pad(model, V=V, N=N, pad=pad, friction=FrictionParams(0.5, 0.5 - dmu),
                         tick_rate=rate, duration=0.02)
        assert np.all(np.isfinite(r.friction_force))
        # first tick: the pad takes the surface speed, f = c V may exceed a tiny mu_s N
        assert np.all(np.abs(r.friction_force[1:]) <= 0.5 * N * (1 + 1e-9) + 1e-15)


def test_euler_and_rk4_diverge_at_1khz_where_exact_does_not():
    for name in ("euler", "rk4"):
        with pytest.raises(ModelError, match="diverged"):
            simulate_pad(name, V=0.05, N=2.0, pad=KONYO, tick_rate=1000, duration=0.05)
        r = simulate_pad(name, V=0.05, N=2.0, pad=KONYO, tick_rate=1000, duration=0.05, on_divergence="report")
        assert r.diverged_at is not None and np.all(np.isfinite(r.friction_force))
    ok = simulate_pad("exact", V=0.05, N=2.0, pad=KONYO, tick_rate=1000, duration=0.05)
    assert ok.diverged_at is None and len(ok.event_time) > 3
    # rk4 is stable once h * omega_n < 2.8 (96 kHz: 0.47)
    r = simulate_pad("rk4", V=0.05, N=2.0, pad=KONYO, tick_rate=96_000, duration=0.02)
    assert r.diverged_at is None


@pytest.mark.parametrize("c", [0.01, 0.0])
def test_delta_mu_zero_slips_once_then_slides(c):
    pad = PadParams(1e-6, 2000.0, c)
    for model in ("exact", "jump"):
        r = simulate_pad(model, V=0.05, N=2.0, pad=pad, friction=FrictionParams(0.5, 0.5),
                         tick_rate=1000, duration=0.3)
        assert len(r.event_time) == 1, model
        assert np.all(r.state[-100:] == 1)
        assert np.allclose(r.friction_force[-100:], 1.0)


def test_exact_phase_cap_is_the_c_runtimes():
    """The exact and jump kernels cut a tick at the cap the C runtime derives, PHASES_BASE + 4 h omega / pi
    (omega damped, or natural when the pad is not under-damped), never above MAX_EVENTS_PER_TICK; the
    re-stick polish takes at most as many steps as the C runtime's."""
    import re
    from pathlib import Path
    from shapedisplay.runtime import pads
    h_src = (Path(pads.__file__).parent.parent / "runtime_c" / "sd_runtime.h").read_text()
    assert int(re.search(r"#define SD_PHASES_BASE (\d+)", h_src).group(1)) == pads.PHASES_BASE
    assert int(re.search(r"#define SD_MAX_EVENTS_PER_TICK (\d+)L", h_src).group(1)) == pads.MAX_EVENTS_PER_TICK
    assert int(re.search(r"#define SD_POLISH_MAX (\d+)", h_src).group(1)) == pads.POLISH_MAX
    w = math.sqrt(2000.0 / 1e-6)
    assert pads.phase_cap(1e-6, 0.0, 2000.0, 1e-4) == 32 + int(1e-4 * 4 * w / math.pi)     # c = 0
    wd = math.sqrt(2000.0 / 1e-6 - (0.5 * 0.01 / 1e-6) ** 2)
    assert pads.phase_cap(1e-6, 0.01, 2000.0, 1e-2) == int(32 + 1e-2 * 4 * wd / math.pi)
    assert pads.phase_cap(1e-6, 1.0, 2000.0, 1e-2) == int(32 + 1e-2 * 4 * w / math.pi)                 # over-damped
    assert pads.phase_cap(1e-6, 0.01, 2000.0, 1e3) == pads.MAX_EVENTS_PER_TICK
    assert pads.phase_cap(1e-6, 0.01, 2000.0, math.nan) == pads.MAX_EVENTS_PER_TICK


@pytest.mark.parametrize("rev", [40, 41])
def test_exact_undamped_equal_coefficients_reversal_closed_form(rev):
    """c = 0, mu_k = mu_s (the degenerate pad): breakaway at 50 mm/s, then the surface reverses at a tick
    boundary during the slip. In closed form (undamped arcs): the friction turns at once (the relative
    velocity is reversed), the pad reaches the surface speed beyond the static limit, so the friction turns
    back and the pad returns to the surface speed at the mirror point of its arc, inside the limit, and
    sticks until the force reaches the other limit. The kernel follows this to round-off, with no tick
    cut; it used to step through zero-length phases with the friction along the relative motion and
    re-stick microseconds late."""
    from shapedisplay.devices import load_device
    from shapedisplay.runtime.models import get_model, run_kernel
    m, k, thr, U = 1e-6, 2000.0, 0.3, 0.05
    w = math.sqrt(k / m)
    n = 200
    t = np.arange(n) * 1e-4
    V = np.where(np.arange(n) < rev, U, -U)
    ones = np.ones(n)
    dev = load_device(None).with_(pad=PadParams(m, k, 0.0), friction=FrictionParams(0.6, 0.6))
    S, f, ph, x, v, wf, wd, et, ea = run_kernel(get_model("exact", dev), t, V, 0.5 * ones, 0.6 * ones,
                                                0.6 * ones, ones)
    assert S["truncated"] == 0 and et.size == 2
    # closed form
    tR = t[rev - 1]
    tau = tR - thr / (k * U)                          # since the breakaway (x = thr / k, v = U)
    x0, v0 = thr / k + U / w * math.sin(w * tau), U * math.cos(w * tau)
    y0 = x0 + thr / k                                 # slip about -thr / k until v = -U
    a = (math.acos(-U / math.hypot(v0, w * y0)) - math.atan2(w * y0, v0)) % (2 * math.pi)
    x1 = -thr / k + y0 * math.cos(a) + v0 / w * math.sin(a)
    yp = x1 - thr / k
    assert k * x1 > thr                               # beyond the limit: the friction turns back
    t2 = tR + a / w + 2 * math.atan(w * yp / U) / w    # back at -U at the mirror point, f = thr - k yp
    tb = t2 + (2 * thr - k * yp) / (k * U)
    assert et[0] == pytest.approx(thr / (k * U), abs=1e-15)
    assert abs(et[1] - tb) < 1e-12
    assert np.all(ph[rev:int(tb / 1e-4)] == 0.0)


def test_v_zero_long_stick_no_creep():
    r = simulate_pad("exact", V=0.0, N=2.0, pad=KONYO, tick_rate=1000, duration=0.5)
    assert len(r.event_time) == 0 and np.all(r.state == 0) and np.all(r.x == 0)


def test_normal_force_zero_is_finite():
    r = simulate_pad("exact", V=0.05, N=0.0, pad=KONYO, tick_rate=1000, duration=0.05)
    assert np.all(np.isfinite(r.friction_force)) and np.all(r.friction_force[1:] == 0)
    assert len(r.event_time) <= 1


def test_velocity_reversal_breaks_away_both_ways():
    n = 2001
    V = np.where(np.arange(n) < 1000, 0.05, -0.05)
    r = simulate_pad("exact", V=V, N=2.0, pad=KONYO, tick_rate=10_000)
    t_rev = 1000 / 10_000
    assert np.any(r.event_time < t_rev) and np.any(r.event_time > t_rev)
    assert r.friction_force[990] > 0 > r.friction_force[-1]
    assert np.all(np.abs(r.friction_force[1:]) <= 1.0 + 1e-12)


def test_jump_within_stated_bound():
    checked = 0
    for zeta in (0.0, 0.112, 0.3, 0.6):
        c = zeta * 2 * math.sqrt(2000.0 * 1e-6)
        pad = PadParams(1e-6, 2000.0, c)
        for V, N in ((0.02, 0.5), (0.05, 2.0), (0.2, 0.5), (0.5, 0.5), (0.5, 2.0)):
            r = V * pad.stiffness / (0.2 * N * pad.omega_n)
            kw = dict(V=V, N=N, pad=pad, friction=FrictionParams(0.5, 0.3), tick_rate=10_000, duration=0.05)
            e = simulate_pad("exact", **kw)
            j = simulate_pad("jump", **kw)
            assert (len(e.event_time) > 1) == (len(j.event_time) > 1)
            if len(e.event_time) > 3 and r <= JumpModel.BOUND_R_MAX:
                pe = np.diff(e.event_time)[1:].mean()
                pj = np.diff(j.event_time)[1:].mean()
                assert abs(pj - pe) / pe <= JumpModel.BOUND_PER_R * r + 1e-9
                checked += 1
    assert checked >= 12


def test_jump_restick_force_limit_formula():
    """V -> 0: f_r = mu_k N - delta_mu N exp(-zeta pi / sqrt(1 - zeta^2))."""
    m, k, c = 1e-6, 2000.0, 0.01
    N, mus, muk = 2.0, 0.5, 0.3
    zeta = c / (2 * math.sqrt(k * m))
    xb = mus * N / k
    _, xr = pads.jump_restick(m, c, k, 1.0, xb, 1e-9, muk, N)
    expect = muk * N - (mus - muk) * N * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))
    assert abs(k * xr - expect) <= 1e-6 * N


def test_registry_and_bad_inputs():
    assert set(MODELS) == {"exact", "jump", "karnopp", "stribeck", "euler", "rk4", "tanh"}
    with pytest.raises(InputError, match="did you mean 'exact'"):
        simulate_pad("exakt")
    with pytest.raises(ModelError, match="mass"):
        simulate_pad("exact", pad=PadParams(0.0, 2000.0, 0.01))
    with pytest.raises(ModelError, match="stiffness"):
        simulate_pad("exact", pad=PadParams(1e-6, -1.0, 0.01))
    with pytest.raises(ModelError, match="mu_k"):
        simulate_pad("exact", friction=FrictionParams(0.3, 0.5))
    for rate in (50, 200_000, float("nan")):
        with pytest.raises(InputError, match="tick_rate"):
            simulate_pad("exact", tick_rate=rate)
    with pytest.raises(InputError, match="`N`"):
        simulate_pad("exact", N=-1.0)
    with pytest.raises(InputError, match="finite"):
        simulate_pad("exact", V=np.array([0.0, np.nan]))


def test_stribeck_converges_with_substep_and_tick_rate():
    from shapedisplay.runtime.studies import IMAIZUMI_FRICTION, IMAIZUMI_PAD
    for hz, amp, v in ((9.0, 1.25e-3, 0.1), (0.0, 0.0, 0.04)):
        runs = []
        for rate, hsub in ((10_000, 2e-6), (10_000, 5e-7), (2000, 2e-6)):
            r = simulate_pad("stribeck", V=v, N=1.0, pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION, tick_rate=rate,
                             duration=0.5, contactor_hz=hz, contactor_amplitude_m=amp, substep_s=hsub)
            keep = r.t >= 0.2
            runs.append((np.abs(r.friction_force[keep]).mean(), r.event_time))
            assert np.all(np.abs(r.friction_force) <= 2.1 * (1 + 1e-9))
        for mean, ev in runs[1:]:
            assert abs(mean - runs[0][0]) <= 1e-3 * runs[0][0]
            assert ev.size == runs[0][1].size and np.max(np.abs(ev - runs[0][1])) <= 1e-5


def test_stribeck_premax_variant_is_finite_and_counts_region_exits():
    from shapedisplay.runtime.studies import IMAIZUMI_FRICTION, IMAIZUMI_PAD
    r = simulate_pad("stribeck", V=0.04, N=1.0, pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION, tick_rate=1000,
                     duration=0.3, variant="premax", contactor_hz=6.0, contactor_amplitude_m=1.25e-3)
    assert np.all(np.isfinite(r.friction_force))
    # "stick" = inside the pre-maximum region; each exit from it is an event
    exits = np.sum((r.state[1:] == 1) & (r.state[:-1] == 0))
    assert abs(r.event_time.size - exits) <= 1
    # mu(v) never exceeds its maximum: p d = 2.0 at the corner, Stribeck part <= mu_s + b*v
    assert np.abs(r.friction_force).max() <= 2.1 + 2.0 * 0.2
    with pytest.raises(InputError, match="variant"):
        simulate_pad("stribeck", variant="tanh")


@pytest.mark.parametrize("m,k,c,N,V,mus,muk,rate", [
    # undamped pad without normal force: free oscillation, grazes the surface speed every period
    (0.0028598650146535636, 306.77299536664776, 0.0, 0.0, -1.444e-4, 0.4785, 0.4785, 192_000),
    # nearly undamped stiff pad, tiny delta_mu
    (4.04e-05, 3.58e8, 1.42e-05, 0.152, -0.029, 0.43874, 0.43830, 10_000),
    # critically damped pad
    (1e-6, 2000.0, 2 * math.sqrt(2000.0 * 1e-6), 2.0, 0.05, 0.5, 0.3, 1000),
    # heavily over-damped pad
    (1e-6, 2000.0, 5.0, 2.0, 0.05, 0.5, 0.3, 1000),
])
def test_extreme_pads_finish_with_bounded_output(m, k, c, N, V, mus, muk, rate):
    for model in ("exact", "jump"):
        r = simulate_pad(model, V=V, N=N, pad=PadParams(m, k, c), friction=FrictionParams(mus, muk),
                         tick_rate=rate, duration=0.05)
        assert np.all(np.isfinite(r.friction_force))
        assert np.all(np.abs(r.friction_force[1:]) <= mus * N * (1 + 1e-9) + abs(c * V) * (N == 0))


@settings(max_examples=30, deadline=None)
@given(logm=st.floats(-8, -2), logk=st.floats(1, 6), zeta=st.floats(0, 3), N=st.floats(0, 10),
       V=st.floats(-1, 1), mus=st.floats(0.05, 1.0), ratio=st.sampled_from([0.0, 0.5, 0.99, 1.0]))
def test_exact_bounded_for_random_pads(logm, logk, zeta, N, V, mus, ratio):
    m, k = 10.0 ** logm, 10.0 ** logk
    c = zeta * 2 * math.sqrt(k * m)
    r = simulate_pad("exact", V=V, N=N, pad=PadParams(m, k, c), friction=FrictionParams(mus, mus * ratio),
                     tick_rate=1000, duration=0.02)
    assert np.all(np.isfinite(r.friction_force)) and np.all(np.isfinite(r.event_amplitude))
    assert np.all(np.abs(r.friction_force[1:]) <= mus * N * (1 + 1e-9) + (abs(c * V) if N == 0 else 0.0))


@settings(max_examples=15, deadline=None)
@given(V=st.floats(0.002, 0.5), N=st.floats(0.2, 6.0), dmu=st.floats(0.02, 0.3), zeta=st.floats(0.0, 0.9))
def test_exact_event_times_tick_rate_invariant_random(V, N, dmu, zeta):
    c = zeta * 2 * math.sqrt(2000.0 * 1e-6)
    kw = dict(V=V, N=N, pad=PadParams(1e-6, 2000.0, c), friction=FrictionParams(0.5, 0.5 - dmu), duration=0.03)
    a = simulate_pad("exact", tick_rate=1000, **kw)
    b = simulate_pad("exact", tick_rate=7000, **kw)
    # the first tick has zero speed in both runs, so the same stroke starts at t = 0
    n = min(a.event_time.size, b.event_time.size)
    assert abs(a.event_time.size - b.event_time.size) <= 1      # an event may fall past the shorter end
    assert np.all(np.abs(a.event_time[:n] - b.event_time[:n]) <= 1e-9)


def test_v_to_zero_sticks_exactly_until_the_closed_form_breakaway():
    """V = 0.2 mm/s: the spring stretches as V t (no creep, no slip) until k V t + c V = mu_s N."""
    V, N = 2e-4, 2.0
    t_b = (0.5 * N - KONYO.damping * V) / (KONYO.stiffness * V)          # 2.499995 s
    for model in ("exact", "jump"):
        r = simulate_pad(model, V=V, N=N, pad=KONYO, friction=FrictionParams(0.5, 0.3), tick_rate=1000,
                         duration=3.0)
        assert r.event_time.size == 1 and abs(r.event_time[0] - t_b) <= 1e-12, model
        before = r.t < t_b
        assert np.all(r.state[before] == 0)
        assert np.allclose(r.x[before], V * r.t[before], rtol=1e-12, atol=1e-18)


def test_imaizumi_study_matches_quasi_static_sliding_and_rises_as_relative_speed_nears_zero():
    """At 100 mm/s stimuli #0-#3 never stick: the pad follows the finger and the mean friction is the
    cycle average of mu(|V - x_c'|) W. #4 (contactor peak 71 mm/s) brings the relative speed close to zero,
    the negative Stribeck slope makes the pad stick-slip, and the friction rises most."""
    from shapedisplay.runtime.studies import imaizumi_study
    rows = [r for r in imaizumi_study(duration=1.0) if r["finger_speed_m_s"] == 0.1]
    th = np.linspace(0.0, 2 * np.pi, 200_001)[:-1]
    for r in rows[:4]:
        vr = np.abs(0.1 - r["amplitude_m"] * 2 * np.pi * r["frequency_hz"] * np.cos(th))
        mu = 1.4 + 0.7 * np.exp(-55 * vr) + 1.9 * vr
        assert r["events"] == 0 and abs(r["mean_friction_n"] - mu.mean()) <= 2e-4 * mu.mean(), r
    mean = [r["mean_friction_n"] for r in rows]
    assert mean[0] < mean[1] and abs(mean[1] - mean[2]) <= 1e-4 < mean[3] - mean[2] and mean[3] < mean[4]
    assert rows[4]["events"] > 0 and rows[4]["max_friction_n"] == pytest.approx(2.1, rel=1e-3)


def test_tanh_regularised_friction_error_against_exact():
    """tanh option: periods converge to exact as eps -> 0; creep below breakaway; |f| <= mu_s N."""
    kw = dict(V=0.05, N=2.0, pad=KONYO, friction=FrictionParams(0.5, 0.3), tick_rate=10_000, duration=0.1)
    ex = simulate_pad("exact", **kw)
    p_ex = np.diff(ex.event_time)[1:].mean()
    err = {}
    for eps, hsub in ((1e-3, 1e-6), (1e-4, 1e-6), (1e-5, 1e-7)):
        r = simulate_pad("tanh", eps_m_s=eps, substep_s=hsub, **kw)
        assert r.event_time.size == ex.event_time.size
        p = np.diff(r.event_time)[1:]
        assert np.ptp(p) <= 1e-8                                  # a clean limit cycle, no chattering
        err[eps] = abs(p.mean() - p_ex) / p_ex
        assert np.all(np.abs(r.friction_force) <= 0.5 * 2.0 * (1 + 1e-6))
        # creep: before the first breakaway the pad slips at 0 < V - v < 2 eps, the spring lags V t
        before = r.t < r.event_time[0]
        assert np.all(r.x[before][1:] < 0.05 * r.t[before][1:])
        assert np.all((0.05 - r.v[before][1:] > 0) & (0.05 - r.v[before][1:] < 2 * eps))
    assert err[1e-3] > 3e-3 and err[1e-3] > err[1e-4] > err[1e-5]      # measured 5.5e-3, 8e-4, 8e-5
    assert err[1e-5] < 2e-4
    # the first breakaway comes late by the creep: the spring lags V t by about the creep distance
    late = simulate_pad("tanh", eps_m_s=1e-3, **kw).event_time[0] - ex.event_time[0]
    assert 0 < late < 1e-3
    with pytest.raises(InputError, match="eps_m_s"):
        simulate_pad("tanh", eps_m_s=0.0)


@settings(max_examples=15, deadline=None)
@given(logm=st.floats(-8, -2), logk=st.floats(1, 6), zeta=st.floats(0, 3), N=st.floats(0, 10),
       V=st.floats(-1, 1), mus=st.floats(0.05, 1.0), ratio=st.sampled_from([0.0, 0.5, 1.0]))
def test_tanh_bounded_for_random_pads(logm, logk, zeta, N, V, mus, ratio):
    m, k = 10.0 ** logm, 10.0 ** logk
    r = simulate_pad("tanh", V=V, N=N, pad=PadParams(m, k, zeta * 2 * math.sqrt(k * m)),
                     friction=FrictionParams(mus, mus * ratio), tick_rate=1000, duration=0.02)
    assert np.all(np.isfinite(r.friction_force)) and np.all(np.isfinite(r.x))
    assert np.all(np.abs(r.friction_force) <= mus * N * (1 + 1e-6) + 1e-15)


def _restick_located(m, c, k, s, xb, V, muk, N):
    """jump_restick deciding the peak condition by locating the velocity peak (no shortcut)."""
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    if disc >= -1e-10 * wn2:
        return math.inf, xb
    wd = math.sqrt(-disc)
    xeq = s * muk * N / k
    y0 = xb - xeq
    tp = math.pi / wd
    e = math.exp(-sig * tp)
    yp = -e * y0
    vp = -e * V
    ap = -2.0 * sig * vp - wn2 * yp
    if s * ap <= 0.0:
        return math.inf, xb
    tz1 = pads._next_acc_zero(m, c, k, y0, V, 0.0)
    if tz1 == math.inf:
        return math.inf, xb
    _, vpk = pads.osc(m, c, k, y0, V, tz1 + math.pi / wd)
    if s * (vpk - V) < 0.0:
        return math.inf, xb
    dt = (V - vp) / ap
    if abs(dt) * wd > 0.5 * math.pi:
        return math.inf, xb
    return tp + dt, xeq + yp + vp * dt + 0.5 * ap * dt * dt


_pad_m = st.floats(1e-7, 1e-2)
_pad_k = st.floats(1.0, 1e6)
_zeta = st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 1e-6, 0.5, 0.99, 0.999999, 1.0]))


@settings(max_examples=400, deadline=None)
@given(m=_pad_m, k=_pad_k, zeta=_zeta, s=st.sampled_from([-1.0, 1.0]),
       xb_f=st.floats(-3.0, 3.0), V=st.one_of(st.floats(-2.0, 2.0), st.sampled_from([0.0, 1e-12, -1e-9, 0.02])),
       muk=st.floats(0.0, 1.5), N=st.floats(0.0, 10.0))
def test_jump_restick_shortcut_decides_as_locating_the_peak(m, k, zeta, s, xb_f, V, muk, N):
    """The closed-form bound on the velocity peak (pads._restick_peak_reaches) gives jump_restick's
    outcome bit for bit as locating the peak does, and whenever it decides, it decides the same."""
    c = 2.0 * zeta * math.sqrt(k * m)
    xb = xb_f * N / k
    got = pads.jump_restick(m, c, k, s, xb, V, muk, N)
    want = _restick_located(m, c, k, s, xb, V, muk, N)
    assert np.float64(got[0]).tobytes() == np.float64(want[0]).tobytes()
    assert np.float64(got[1]).tobytes() == np.float64(want[1]).tobytes()
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    if disc < -1e-10 * wn2:
        wd = math.sqrt(-disc)
        y0 = xb - s * muk * N / k
        ok = pads._restick_peak_reaches(sig, wn2, wd, math.exp(-sig * (math.pi / wd)), s, y0, V)
        if ok != 0:
            tz1 = pads._next_acc_zero(m, c, k, y0, V, 0.0)
            _, vpk = pads.osc(m, c, k, y0, V, tz1 + math.pi / wd)
            assert (ok > 0) == (s * (vpk - V) >= 0.0)


def test_jump_restick_shortcut_decides_the_konyo_slips():
    """On the published pad the bound decides every slip of a stroke (no peak to locate)."""
    m, k, c = 1e-6, 2000.0, 0.01
    sig, wn2 = 0.5 * c / m, k / m
    wd = math.sqrt(wn2 - sig * sig)
    e = math.exp(-sig * (math.pi / wd))
    N, mus, muk = 2.0, 0.5, 0.3
    for V in (1e-4, 0.02, 0.05, 0.1, 0.3, -0.02):
        s = 1.0 if V > 0 else -1.0
        y0 = (s * mus * N - c * V) / k - s * muk * N / k
        assert pads._restick_peak_reaches(sig, wn2, wd, e, s, y0, V) == 1


# ---------------------------------------------------------------- exact model: the re-stick fast paths
def _longdouble_restick(m, c, k, y0, v0, V, t):
    """An independent re-stick root: Newton's method on the closed-form under-damped velocity in numpy's
    long double (80-bit on x86-64), from ``t``. Returns ``(t, y, v)`` rounded to double."""
    L = np.longdouble
    m, c, k, y0, v0, V, t = (L(q) for q in (m, c, k, y0, v0, V, t))
    sig = c / (2 * m)
    wn2 = k / m
    wd = np.sqrt(wn2 - sig * sig)
    B = (wn2 * y0 + sig * v0) / wd

    def state(t):
        e, cs, sn = np.exp(-sig * t), np.cos(wd * t), np.sin(wd * t)
        return e * (y0 * cs + (v0 + sig * y0) / wd * sn), e * (v0 * cs - B * sn)
    for _ in range(12):
        y, v = state(t)
        t = t - (v - V) / (-(c * v + k * y) / m)
    y, v = state(t)
    return float(t), float(y), float(v)


def _check_against_walk(fast, walk, m, c, k, y0, v0, V):
    """The fast path's outcome against the bracket walk (slip_search) and the long-double root."""
    assert fast[0] == walk[0]
    if fast[0] != 1 or walk[1] == 0.0:
        # no crossing in the span (both give the state at its end by one osc call), or the relative
        # velocity already past zero at the start (both give the start)
        assert fast == walk
        return
    t, y, v = fast[1:]
    wn = math.sqrt(k / m)
    vamp = math.hypot(v0, wn * y0) + abs(V)
    a = abs(c * v + k * y) / m
    # the walk polishes to its own tolerance, 1e-16 s + 1e-15 t
    tol_t = 2.0 * (1e-16 + 1e-15 * walk[1])
    assert abs(t - walk[1]) <= tol_t
    assert abs(y - walk[2]) <= abs(v) * tol_t + 1e-14 * vamp / wn
    assert abs(v - walk[3]) <= a * tol_t + 1e-14 * vamp
    if fast != walk and np.finfo(np.longdouble).eps < 1e-18:
        # where it did not hand over to the walk, the fast path ends within rounding of the root: a few
        # ulps of t (or of v over the slope there)
        tt, yt, vt = _longdouble_restick(m, c, k, y0, v0, V, t)
        slack = 8 * np.spacing(vamp) / a
        assert abs(t - tt) <= 8 * np.spacing(tt) + slack
        assert abs(y - yt) <= 16 * np.spacing(vamp / wn) + abs(v) * slack
        assert abs(v - vt) <= 4 * np.spacing(vamp)


def _fresh_slip(logm, logk, zeta, N, mus, ratio, V):
    m, k = 10.0 ** logm, 10.0 ** logk
    c = zeta * 2 * math.sqrt(k * m)
    s = 1.0 if V > 0 else -1.0
    x = (s * mus * N - c * V) / k          # the breakaway stretch
    return m, c, k, x - s * mus * ratio * N / k, s


@settings(max_examples=300, deadline=None)
@given(logm=st.floats(-7, -4), logk=st.floats(1, 5), zeta=st.floats(0, 0.6), N=st.floats(0.01, 10),
       mus=st.floats(0.1, 1.5), ratio=st.floats(0.2, 1.0), V=st.floats(-1, 1).filter(lambda v: abs(v) > 1e-5),
       rem=st.floats(0.0, 2.5))
def test_fresh_slip_search_gives_the_bracket_walks_outcome(logm, logk, zeta, N, mus, ratio, V, rem):
    m, c, k, y0, s = _fresh_slip(logm, logk, zeta, N, mus, ratio, V)
    rem *= math.pi / math.sqrt(k / m - (0.5 * c / m) ** 2)
    fast = pads.fresh_slip_search(m, c, k, y0, V, s, rem)
    walk = pads.slip_search(m, c, k, y0, V, V, s, rem, 0.0)
    _check_against_walk(fast, walk, m, c, k, y0, V, V)


@settings(max_examples=300, deadline=None)
@given(logm=st.floats(-7, -4), logk=st.floats(1, 5), zeta=st.floats(0, 0.6), N=st.floats(0.01, 10),
       mus=st.floats(0.1, 1.5), ratio=st.floats(0.2, 1.0), V=st.floats(-1, 1).filter(lambda v: abs(v) > 1e-5),
       elapsed=st.floats(0.0, 1.3), shift=st.floats(-0.1, 0.1), rem=st.floats(0.0, 2.0))
def test_continued_slip_search_gives_the_bracket_walks_outcome(logm, logk, zeta, N, mus, ratio, V, elapsed, shift,
                                                             rem):
    """A slip under way at a tick's start: a fresh slip advanced by ``elapsed`` half periods, its equilibrium
    moved by ``shift`` of the stretch (the normal force changed at the tick boundary)."""
    m, c, k, y0, s = _fresh_slip(logm, logk, zeta, N, mus, ratio, V)
    tp = math.pi / math.sqrt(k / m - (0.5 * c / m) ** 2)
    yb, vb = pads.osc(m, c, k, y0, V, elapsed * tp)
    yb += shift * abs(y0)
    fast = pads.continued_slip_search(m, c, k, yb, vb, V, s, rem * tp)
    walk = pads.slip_search(m, c, k, yb, vb, V, s, rem * tp, 0.0)
    _check_against_walk(fast, walk, m, c, k, yb, vb, V)


def test_konyo_slips_take_the_fast_paths(monkeypatch):
    """The default pad's fresh and continued slips over a range of loads and speeds settle in the fast paths
    (no bracket walk) with the outcome the walk gives."""
    m, k, c = KONYO.mass, KONYO.stiffness, KONYO.damping
    walk = pads.slip_search
    tp = math.pi / math.sqrt(k / m - (0.5 * c / m) ** 2)
    cases = []
    for N in (0.3, 0.5, 1.0, 2.5, 6.0):
        for V in (-0.2, -0.05, 0.01, 0.05, 0.2):
            s = 1.0 if V > 0 else -1.0
            y0 = (s * 0.5 * N - c * V) / k - s * 0.3 * N / k
            for rem in (0.3 * tp, 1.5 * tp, 3.0 * tp):
                cases.append(("fresh", (m, c, k, y0, V, s, rem), (m, c, k, y0, V, V, s, rem, 0.0)))
            for el in (0.2, 0.7, 1.0):
                yb, vb = pads.osc(m, c, k, y0, V, el * tp)
                yb *= 1.001
                cases.append(("continued", (m, c, k, yb, vb, V, s, 2.0 * tp), (m, c, k, yb, vb, V, s, 2.0 * tp, 0.0)))
    expected = [walk(*w) for _, _, w in cases]
    # the fast paths' compiled helpers are built (typed against the real walk) before the walk is replaced
    for kind in ("fresh", "continued"):
        fn = pads.fresh_slip_search if kind == "fresh" else pads.continued_slip_search
        fn.py_func(*next(a for k_, a, _ in cases if k_ == kind))

    def no_walk(*args):
        raise AssertionError("fell back to the bracket walk")
    monkeypatch.setattr(pads, "slip_search", no_walk)
    for (kind, args, wargs), w in zip(cases, expected):
        fn = pads.fresh_slip_search if kind == "fresh" else pads.continued_slip_search
        _check_against_walk(fn.py_func(*args), w, *wargs[:5], wargs[5])


@settings(max_examples=100, deadline=None)
@given(logm=st.floats(-7, -4), logk=st.floats(1, 5), zeta=st.floats(1e-4, 0.95), y0=st.floats(-1e-3, 1e-3),
       v0=st.floats(-1, 1), wt=st.floats(1e-5, 30.0))
def test_damping_work_equals_the_integrated_damper_power(logm, logk, zeta, y0, v0, wt):
    """osc_damping_work (closed form) against composite Gauss-Legendre quadrature of c v(t)^2 over osc."""
    m, k = 10.0 ** logm, 10.0 ** logk
    c = zeta * 2 * math.sqrt(k * m)
    t = wt / math.sqrt(k / m)
    n = 400
    g, w = np.polynomial.legendre.leggauss(8)
    edges = np.linspace(0.0, t, n + 1)
    acc = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        for gi, wi in zip(g, w):
            _, v = pads.osc(m, c, k, y0, v0, 0.5 * (a + b) + 0.5 * (b - a) * gi)
            acc += wi * 0.5 * (b - a) * c * v * v
    energy = 0.5 * m * v0 * v0 + 0.5 * k * y0 * y0
    assume(energy > 1e-250)
    assert abs(pads.osc_damping_work(m, c, k, y0, v0, t) - acc) <= 1e-12 * energy + 1e-12 * acc


@njit(cache=False)
def _exact_tick_by_tick(form, init, params, t, V, N, mus, muk, rows, ev):
    """States after every tick (rows of float64 words) through ``exact_tick`` (``form`` 0) or
    ``exact_tick_prepared`` with the work terms (1) or without (2)."""
    prm = params.view(PAD_PARAMS)[0]
    pc = pads.exact_constants(prm)
    rows[0, :] = init
    n_ev = 0
    for i in range(1, t.shape[0]):
        rows[i, :] = rows[i - 1, :]
        st = rows[i].view(PAD_STATE)[0]
        h = t[i] - t[i - 1]
        if form == 0:
            n_ev = pads.exact_tick(st, prm, t[i - 1], h, V[i], N[i], mus[i], muk[i], 1.0, ev[0], ev[1], n_ev)
        else:
            n_ev = pads.exact_tick_prepared(st, prm, t[i - 1], h, V[i], N[i], mus[i], muk[i], 1.0, ev[0], ev[1],
                                            n_ev, pc, form == 1)
    return n_ev


@settings(max_examples=60, deadline=None)
@given(logm=st.floats(-7, -4), logk=st.floats(1, 5), zeta=st.sampled_from([0.0, 1e-3, 0.05, 0.3, 0.999, 1.0, 3.0]),
       msp=st.sampled_from([0.0, 2e-3]), seed=st.integers(0, 2 ** 32 - 1))
def test_exact_tick_prepared_is_exact_tick_and_without_work_leaves_only_the_work_terms(logm, logk, zeta, msp, seed):
    """The offline loops' form of the exact tick (the pad's constants once per run) gives every state field and
    event of exact_tick bit for bit; without the work terms (the render's form) it leaves only those two
    fields as they were. Random pads (under-, critically, over-damped, undamped), loads, speeds with
    reversals and stops, tick lengths, with and without a maximum stick period."""
    m, k = 10.0 ** logm, 10.0 ** logk
    c = zeta * 2 * math.sqrt(k * m)
    rng = np.random.default_rng(seed)
    n = 400
    t = np.cumsum(rng.choice([1e-5, 1e-4, 1e-3], n) * rng.uniform(0.5, 1.5, n))
    V = np.repeat(rng.choice([0.0, 1.0, -1.0], n // 20) * rng.uniform(1e-3, 0.3, n // 20), 20)
    N = np.repeat(rng.uniform(0.0, 4.0, n // 10), 10)
    mus = np.full(n, 0.5)
    muk = np.repeat(rng.uniform(0.1, 0.5, n // 50), 50)
    params = np.zeros(1, PAD_PARAMS)
    params[0]["mass"], params[0]["stiffness"], params[0]["damping"] = m, k, c
    params[0]["burst_gain"], params[0]["max_stick_period"] = 0.25, msp
    init = pads.new_state()
    init[0]["work_friction"], init[0]["work_damping"] = 7.0, -7.0      # to be left alone without the work terms
    init = init.view(np.float64)
    out = []
    for form in (0, 1, 2):
        rows = np.empty((n, init.size))
        ev = np.zeros((2, 64 * n))
        n_ev = _exact_tick_by_tick(form, init, params.view(np.float64), t, V, N, mus, muk, rows, ev)
        out.append((rows.view(PAD_STATE)[:, 0], ev[:, :n_ev]))
    (ref, ev0), (prep, ev1), (nowork, ev2) = out
    assert ref.tobytes() == prep.tobytes() and ev0.tobytes() == ev1.tobytes()
    assert ev0.tobytes() == ev2.tobytes()
    assert (nowork["work_friction"] == 7.0).all() and (nowork["work_damping"] == -7.0).all()
    for name in PAD_STATE.names:
        if name not in ("work_friction", "work_damping"):
            assert ref[name].tobytes() == nowork[name].tobytes(), name


def test_damping_so_small_that_sigma_underflows_gives_finite_work():
    """A pad with c > 0 whose 0.5 c / m underflows to 0: the damping work takes the limit (no division by 0),
    finite and below c times the integral of the largest v^2."""
    m, k = 1e-2, 10.0
    c = 5e-324
    assert 0.5 * c / m == 0.0 and c > 0.0
    r = simulate_pad("exact", V=1.0, N=0.0, pad=PadParams(m, k, c), friction=FrictionParams(1.0, 0.0),
                     tick_rate=1000, duration=0.02)
    assert np.all(np.isfinite(r.friction_force))
    y0, v0, t = 1e-3, 0.2, 0.3
    w = pads.osc_damping_work(m, c, k, y0, v0, t)
    vmax2 = v0 * v0 + k / m * y0 * y0
    assert 0.0 <= w <= c * vmax2 * t
