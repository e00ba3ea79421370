"""Pad models (the C engine's ticks) against exact answers: closed-form periods and slip phases, tick-rate
invariance, independent integrations."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from shapedisplay.table.devices import BurstParams, FrictionParams, PadParams, load_device
from shapedisplay.errors import InputError, ModelError
from shapedisplay.render.models import MODELS, JumpModel, get_model, run_kernel, simulate_pad

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


def _slip_closed_form(pad, force, x0, v0, h):
    """State ``(x, v)`` after ``h`` s of the pad ``m x'' = force - c x' - k x`` from ``(x0, v0)``: the matrix
    exponential of the affine system (the closed-form damped oscillator under constant kinetic friction)."""
    m, k, c = pad.mass, pad.stiffness, pad.damping
    M = np.array([[0.0, 1.0, 0.0], [-k / m, -c / m, force / m], [0.0, 0.0, 0.0]])
    x, v, _ = expm(M * h) @ np.array([x0, v0, 1.0])
    return x, v


@pytest.mark.parametrize("pad", [KONYO, PadParams(1e-6, 2000.0, 0.0), PadParams(1e-6, 2000.0, 0.03)])
@pytest.mark.parametrize("V,N", [(0.05, 2.0), (0.3, 1.0)])
def test_exact_slip_ticks_are_the_closed_form_damped_oscillator(pad, V, N):
    """Every tick that the exact model spends in slip from start to end (no event inside) carries the pad's
    state as the damped oscillator under the constant kinetic friction ``mu_k N`` does (matrix exponential),
    and reports that friction; every tick spent stuck holds ``f = k x + c V`` with ``x' = V``."""
    rate = 192_000.0
    r = simulate_pad("exact", V=V, N=N, pad=pad, friction=FrictionParams(0.5, 0.3), tick_rate=rate, duration=0.05)
    h = 1.0 / rate
    tick_of_event = np.ceil(r.event_time * rate - 1e-6).astype(int)
    has_event = np.zeros(r.t.size, bool)
    has_event[tick_of_event] = True
    slip = np.flatnonzero((r.state[1:] == 1) & (r.state[:-1] == 1) & ~has_event[1:]) + 1
    assert r.event_time.size >= 4 and slip.size >= 30
    xs, vs = np.abs(r.x).max(), np.abs(r.v).max()
    for i in slip:
        x, v = _slip_closed_form(pad, 0.3 * N, r.x[i - 1], r.v[i - 1], h)
        assert abs(r.x[i] - x) <= 1e-11 * xs and abs(r.v[i] - v) <= 1e-11 * vs, i
    np.testing.assert_allclose(r.friction_force[slip], 0.3 * N, rtol=1e-12)
    stuck = np.flatnonzero((r.state[1:] == 0) & (r.state[:-1] == 0) & ~has_event[1:]) + 1
    assert stuck.size > 50
    np.testing.assert_allclose(r.x[stuck] - r.x[stuck - 1], V * h, rtol=1e-9)
    np.testing.assert_allclose(r.friction_force[stuck], pad.stiffness * r.x[stuck] + pad.damping * V,
                               rtol=1e-12, atol=1e-12 * N)


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


#: m = 0.1 g, omega_n = 4.5 krad/s, zeta = 0.56: forward Euler is stable for h < 2 zeta / omega_n (250 us),
#: RK4 for h omega_n below ~2.8 (626 us, less with damping)
HEAVY = PadParams(1e-4, 2000.0, 0.5)


@pytest.mark.parametrize("name", ["euler", "rk4"])
def test_explicit_steps_stable_below_their_step_limit_and_diverge_above(name):
    """The heavy pad: at 10 kHz (h omega_n = 0.45) both explicit steps stay bounded and stick-slip; at 1 kHz
    (h omega_n = 4.5) both blow up, which is reported (time within the run, outputs finite)."""
    kw = dict(V=0.05, N=2.0, pad=HEAVY, friction=FrictionParams(0.5, 0.3), duration=0.2)
    ok = simulate_pad(name, tick_rate=10_000, **kw)
    assert ok.diverged_at is None and ok.event_time.size >= 30
    assert np.all(np.abs(ok.friction_force[1:]) <= 0.5 * 2.0 * (1 + 1e-9) + 0.5 * 0.05)
    bad = simulate_pad(name, tick_rate=1000, on_divergence="report", **kw)
    assert bad.diverged_at is not None and 0.0 < bad.diverged_at <= bad.t[-1]
    assert np.all(np.isfinite(bad.friction_force))


@pytest.mark.parametrize("c", [0.01, 0.0])
def test_delta_mu_zero_slips_once_then_slides(c):
    pad = PadParams(1e-6, 2000.0, c)
    for model in ("exact", "jump"):
        r = simulate_pad(model, V=0.05, N=2.0, pad=pad, friction=FrictionParams(0.5, 0.5),
                         tick_rate=1000, duration=0.3)
        assert len(r.event_time) == 1, model
        assert np.all(r.state[-100:] == 1)
        assert np.allclose(r.friction_force[-100:], 1.0)


@pytest.mark.parametrize("rev", [40, 41])
def test_exact_undamped_equal_coefficients_reversal_closed_form(rev):
    """c = 0, mu_k = mu_s (the degenerate pad): breakaway at 50 mm/s, then the surface reverses at a tick
    boundary during the slip. In closed form (undamped arcs): the friction turns at once (the relative
    velocity is reversed), the pad reaches the surface speed beyond the static limit, so the friction turns
    back and the pad returns to the surface speed at the mirror point of its arc, inside the limit, and
    sticks until the force reaches the other limit. The kernel follows this to round-off, with no tick
    cut; it used to step through zero-length phases with the friction along the relative motion and
    re-stick microseconds late."""
    m, k, thr, U = 1e-6, 2000.0, 0.3, 0.05
    w = math.sqrt(k / m)
    n = 200
    t = np.arange(n) * 1e-4
    V = np.where(np.arange(n) < rev, U, -U)
    ones = np.ones(n)
    dev = load_device(None).with_(pad=PadParams(m, k, 0.0), friction=FrictionParams(0.6, 0.6))
    S, f, ph, x, v, et, ea = run_kernel(get_model("exact", dev), t, V, 0.5 * ones, 0.6 * ones,
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


@pytest.mark.parametrize("name", ["jump", "exact"])
def test_restick_force_at_low_speed_is_the_closed_form_overshoot(name):
    """V -> 0: the pad re-sticks after half a damped period where the spring force is
    f_r = mu_k N - delta_mu N exp(-zeta pi / sqrt(1 - zeta^2)). Started stuck 0.1 ms before breakaway at
    V = 1 um/s (r ~ 1e-7), the stretch one tick later is the re-stick stretch plus V times the stick time."""
    m, k, c = 1e-6, 2000.0, 0.01
    N, mus, muk, V = 2.0, 0.5, 0.3, 1e-6
    dev = load_device(None).with_(pad=PadParams(m, k, c), friction=FrictionParams(mus, muk),
                                  burst=BurstParams(gain=1.0))
    model = get_model(name, dev)
    S0 = model.new_state()
    S0["x"] = (mus * N - c * V) / k - V * 1e-4
    S0["v"] = V
    t = np.array([0.0, 1e-3])
    S, f, ph, x, v, et, ea = run_kernel(model, t, np.full(2, V), np.full(2, N), np.array([mus]), np.array([muk]),
                                        np.ones(1), state=S0)
    assert et.size == 1 and et[0] == pytest.approx(1e-4, abs=1e-12) and ph[1] == 0.0
    zeta = c / (2 * math.sqrt(k * m))
    expect = muk * N - (mus - muk) * N * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))
    got = k * (x[1] - V * (t[1] - et[0]))           # off by k V t_slip = 1.4e-7 N
    assert abs(got - expect) <= 1e-6 * N
    assert abs(f[1] - (k * x[1] + c * V)) <= 1e-12 * N


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
    from shapedisplay.reports.imaizumi import IMAIZUMI_FRICTION, IMAIZUMI_PAD
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
    from shapedisplay.reports.imaizumi import IMAIZUMI_FRICTION, IMAIZUMI_PAD
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
    from shapedisplay.reports.imaizumi import imaizumi_study
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



# ---------------------------------------------------------------- exact model: re-stick against an independent root
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


def _reference_slip(m, c, k, y0, V):
    """The first return of the slipping pad's velocity to the surface speed ``V`` (``y0``: offset from the slip
    equilibrium at breakaway, velocity ``V``): ``(t, y)``, or None when the damped oscillation never brings it
    back within one damped period (steady sliding); ``"graze"`` when it only touches ``V`` (undecidable here)."""
    sig, wn2 = 0.5 * c / m, k / m
    wd = math.sqrt(wn2 - sig * sig)
    B = (wn2 * y0 + sig * V) / wd
    tt = np.linspace(0.0, 2 * math.pi / wd, 20_001)[1:]
    g = np.exp(-sig * tt) * (V * np.cos(wd * tt) - B * np.sin(wd * tt)) - V
    scale = abs(V) + math.hypot(V, math.sqrt(wn2) * y0)
    s = math.copysign(1.0, V)
    up = np.flatnonzero(s * g >= 0.0)
    if up.size == 0:
        return None if (s * g).max() < -1e-6 * scale else "graze"
    if (s * g).max() < 1e-6 * scale:
        return "graze"
    t, y, _ = _longdouble_restick(m, c, k, y0, V, V, tt[up[0]])
    return t, y


@settings(max_examples=60, deadline=None)
@given(logm=st.floats(-7, -4), logk=st.floats(1, 5), zeta=st.floats(0, 0.6), N=st.floats(0.05, 10),
       mus=st.floats(0.1, 1.5), ratio=st.floats(0.2, 0.95), V=st.floats(-1, 1).filter(lambda v: abs(v) > 1e-3))
def test_exact_restick_and_period_against_the_long_double_root(logm, logk, zeta, N, mus, ratio, V):
    """Random under-damped pads started stuck shortly before breakaway: the exact model re-sticks when the
    closed-form damped oscillation brings the pad back to the surface speed (root polished in long double),
    at the stretch it has there; it then sticks (stretch growing as V t) until k x + c V reaches the static
    limit again. The next breakaway time, and the stretch of every stuck tick in between, agree with this
    to round-off; where the oscillation never returns to V the pad slides on with no second event."""
    m, k = 10.0 ** logm, 10.0 ** logk
    c = zeta * 2 * math.sqrt(k * m)
    muk = mus * ratio
    s = math.copysign(1.0, V)
    xb = (s * mus * N - c * V) / k                     # breakaway stretch
    ref = _reference_slip(m, c, k, xb - s * muk * N / k, V)
    assume(ref != "graze")
    t0 = min(1e-4, 0.5 * mus * N / (k * abs(V)))      # the breakaway, at most 0.1 ms into the run
    if ref is None:
        period = None
        T = 0.05
    else:
        t_slip, y_r = ref
        x_r = s * muk * N / k + y_r
        assume(abs(k * x_r + c * V) < mus * N * (1 - 1e-9))   # the pad can hold at the re-stick
        period = t_slip + (xb - x_r) / V
        assume(period < 0.4)
        T = t0 + 1.6 * period
    dev = load_device(None).with_(pad=PadParams(m, k, c), friction=FrictionParams(mus, muk),
                                  burst=BurstParams(gain=1.0))
    model = get_model("exact", dev)
    S0 = model.new_state()
    S0["x"], S0["v"] = xb - V * t0, V
    t = np.arange(int(T * 1000) + 2) / 1000.0
    n = t.size
    S, f, ph, x, v, et, ea = run_kernel(model, t, np.full(n, V), np.full(n, N), np.array([mus]),
                                        np.array([muk]), np.ones(1), state=S0)
    assert et[0] == pytest.approx(t0, rel=1e-12)
    if period is None:
        assert et.size == 1 and np.all(ph[1:] == 1.0)
        return
    assert et.size >= 2
    tol = 1e-11 * period + 1e-14
    assert abs(et[1] - (t0 + period)) <= tol, (et[1] - t0, period)
    t_r = t0 + t_slip
    between = (t > t_r + tol) & (t < et[1] - tol)
    assert np.all(ph[between] == 0.0)
    np.testing.assert_allclose(x[between], x_r + V * (t[between] - t_r), rtol=0,
                               atol=1e-11 * abs(xb) + abs(V) * tol)


def test_damping_so_small_that_sigma_underflows_stays_finite():
    """A pad with c > 0 whose 0.5 c / m underflows to 0 plays as the undamped pad: finite, within the limit."""
    m, k = 1e-2, 10.0
    c = 5e-324
    assert 0.5 * c / m == 0.0 and c > 0.0
    for N in (0.0, 1.0):
        r = simulate_pad("exact", V=1.0, N=N, pad=PadParams(m, k, c), friction=FrictionParams(1.0, 0.0),
                         tick_rate=1000, duration=0.02)
        assert np.all(np.isfinite(r.friction_force)) and np.all(np.isfinite(r.x))
        assert np.all(np.abs(r.friction_force[1:]) <= N * (1 + 1e-12) + c)
