"""The ``stribeck`` model's plain curve: closed-form stick; slip by Taylor steps (default tolerance) or by
exponential Rosenbrock steps (looser tolerances), re-stick on the zero of the relative speed.

Checked against independent answers: a tight ``solve_ivp`` Radau run with
event functions (no closed form exists for the Stribeck slip; the error bound
scales with the slip tolerance), and the closed form of the linear curve
(``a = 0``: ``mu = mu_s + b |vr| / W``, an oscillator in slip; with ``b < 0``
the negative slope self-excites it, as the Stribeck drop does; exact for
every tolerance). Property tests: finite and bounded outputs, stick friction
within the static limit, and event times that do not depend on how the ticks
cut the stroke (within the tolerance).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from shapedisplay.table.devices import DeviceProfile, FrictionParams, PadParams
from shapedisplay.reports.peers import stribeck_ivp
from shapedisplay.render.models import get_model, run_kernel, simulate_pad
from shapedisplay.reports.imaizumi import IMAIZUMI_FRICTION, IMAIZUMI_PAD


@pytest.mark.parametrize("hz,amp,v,duration", [(9.0, 1.25e-3, 0.1, 0.15), (0.0, 0.0, 0.04, 0.12)])
def test_plain_curve_matches_tight_radau(hz, amp, v, duration):
    ref = stribeck_ivp("Radau", 1e-11, m=1e-4, k=1e3, c=1.0, mu_s=2.1, mu_k=1.4, a=55.0, b=1.9, W=1.0, V=v, amp=amp,
                       omega=2 * math.pi * hz, t_end=duration)
    assert ref.status == "ok" and ref.event_time.size >= 2
    for rate in (1000, 10_000):
        r = simulate_pad("stribeck", V=v, N=1.0, pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION, tick_rate=rate,
                         duration=duration, contactor_hz=hz, contactor_amplitude_m=amp)
        assert r.event_time.size == ref.event_time.size
        # Radau at rtol 1e-11 is itself good to ~1e-11 s here; the kernel's error is below that
        assert np.max(np.abs(r.event_time - ref.event_time)) < 1e-9
        assert np.allclose(r.event_amplitude, ref.event_amplitude, rtol=1e-8, atol=0)


def _viscous_belt_events(m, k, b, mus, W, V, n):
    """Stick-slip of a block on a belt with ``mu = mu_s + b |vr| / W`` (``a = 0``), by its closed form.

    Stick: ``u = u_r - V (t - t_r)``, breakaway when ``|k u| = mu_s W``. Slip
    with relative velocity ``vr = u' + V`` of sign ``s``:
    ``m u'' + b u' + k u = -s mu_s W - b V``, an underdamped oscillator about
    ``u_eq``; at the first zero of vr the block sticks if ``|k u| <= mu_s W``,
    else it slips back (``s = -sign(k u)``).
    """
    sig = 0.5 * b / m
    wd = math.sqrt(k / m - sig * sig)
    t, u, out = 0.0, 0.0, []
    while len(out) < n:
        t += (u + mus * W / k) / V              # stick until k u = -mu_s W
        u = -mus * W / k
        out.append(t)
        s, v0 = 1.0, -V                          # vr = 0 at breakaway; the spring pulls the block back
        while True:
            ueq = -(s * mus * W + b * V) / k
            y0 = u - ueq

            def vr(tau, y0=y0, v0=v0):
                e = math.exp(-sig * tau)
                return e * (v0 * math.cos(wd * tau) - (k / m * y0 + sig * v0) / wd * math.sin(wd * tau)) + V

            # s vr rises from 0, then falls through 0 within the first period: bracket it on a fine grid
            grid = np.linspace(1e-9, 2 * math.pi / wd, 20001)
            vals = s * np.array([vr(g) for g in grid])
            cross = np.flatnonzero((vals[:-1] > 0) & (vals[1:] <= 0))
            assert cross.size, "no re-stick within a period (steady sliding)"
            lo, hi = grid[cross[0]], grid[cross[0] + 1]
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                if s * vr(mid) > 0:
                    lo = mid
                else:
                    hi = mid
            tau = 0.5 * (lo + hi)
            e = math.exp(-sig * tau)
            u = ueq + e * (y0 * math.cos(wd * tau) + (v0 + sig * y0) / wd * math.sin(wd * tau))
            t += tau
            v0 = -V
            if abs(k * u) <= mus * W:
                break
            s = -1.0 if k * u > 0 else 1.0
    return np.array(out)


def test_default_steps_hold_on_a_pad_with_almost_no_sliding_damping():
    """The contactor stroke with c = 0 and b = 0.05 N s/m (35 breakaways in 0.5 s) at 100 Hz ticks, default
    tolerance: every event within 1e-9 s of Radau at rtol 1e-11. A 0.2 ms Taylor step whose last terms were small
    ran into the collapse to re-stick (its speed 3.2e-3 m/s off at its end); the re-stick came 0.51 us late and the
    events drifted up to 19.5 us. Each step's polynomial is now checked against the equation of motion at its end
    (measured now: within 1.2e-11 s)."""
    pad = PadParams(1.0e-4, 1.0e3, 0.0)
    dev = DeviceProfile(pad=pad, friction=IMAIZUMI_FRICTION, extra={"stribeck": {"a": 55.0, "b": 0.05}})
    ref = stribeck_ivp("Radau", 1e-11, m=1e-4, k=1e3, c=0.0, mu_s=2.1, mu_k=1.4, a=55.0, b=0.05, W=1.0, V=0.1,
                       amp=1.25e-3, omega=2 * math.pi * 9.0, t_end=0.5)
    assert ref.status == "ok" and ref.event_time.size >= 30
    model = get_model("stribeck", dev, contactor_hz=9.0, contactor_amplitude_m=1.25e-3)
    r = simulate_pad(model, V=0.1, N=1.0, pad=pad, friction=IMAIZUMI_FRICTION, tick_rate=100, duration=0.5)
    assert r.event_time.size == ref.event_time.size
    assert np.max(np.abs(r.event_time - ref.event_time)) < 1e-9


@pytest.mark.parametrize("c,b", [(0.0, 0.05), (0.2, 0.2)])
def test_exponential_steps_keep_their_bound_where_the_sliding_pad_is_underdamped(c, b):
    """The contactor stroke on pads whose sliding is underdamped (c + b < 2 sqrt(k m) = 0.63 N s/m; 35 and 27
    breakaways in 0.5 s), 1e-8 to 1e-3 at 100 Hz and 1 kHz ticks: every event within 10 tolerances of the mean
    event interval of the default tolerance's (itself within 1.2e-11 s of Radau on the first pad). Three faults
    moved events by up to 58 us (first pad) and 2.9 ms (second), or lost them, at 100 Hz: a step where the curve
    fell by more than e^37 left E exactly zero for the rest of the slip (the rise of the friction towards mu_s
    before the next re-stick unseen); steps of a whole
    tick over a pad oscillating at 0.5 kHz missed its collapse to re-stick between their sign checks; a landing
    whose zero lay closer than the shortest step went to the linearised steps, which re-stuck 0.1 us early.
    Measured now: at most 8.7 tolerances of the interval (at 1e-8)."""
    pad = PadParams(1.0e-4, 1.0e3, c)
    dev = DeviceProfile(pad=pad, friction=IMAIZUMI_FRICTION, extra={"stribeck": {"a": 55.0, "b": b}})
    for rate in (100, 1000):
        def events(tol):
            model = get_model("stribeck", dev, contactor_hz=9.0, contactor_amplitude_m=1.25e-3, tolerance=tol)
            return simulate_pad(model, V=0.1, N=1.0, pad=pad, friction=IMAIZUMI_FRICTION, tick_rate=rate,
                                duration=0.5).event_time
        ref = events(None)
        assert ref.size >= 25
        interval = float(np.mean(np.diff(ref)))
        for tol in (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 4e-4, 1e-3):
            et = events(tol)
            assert et.size == ref.size, (rate, tol, et.size)
            assert np.max(np.abs(et - ref)) <= 10 * tol * interval, (rate, tol, np.max(np.abs(et - ref)))


@pytest.mark.parametrize("hz,amp,v,duration", [(9.0, 1.25e-3, 0.1, 0.25), (0.0, 0.0, 0.04, 0.12)])
def test_exponential_steps_match_tight_radau_within_their_tolerance(hz, amp, v, duration):
    """Looser tolerances (exponential Rosenbrock slip steps): event errors bounded by, and shrinking with, the tolerance."""
    ref = stribeck_ivp("Radau", 1e-11, m=1e-4, k=1e3, c=1.0, mu_s=2.1, mu_k=1.4, a=55.0, b=1.9, W=1.0, V=v, amp=amp,
                       omega=2 * math.pi * hz, t_end=duration)
    assert ref.status == "ok" and ref.event_time.size >= 2
    scale = float(np.mean(np.diff(ref.event_time)))
    worst = {}
    for tol in (1e-8, 1e-7, 1e-5, 1e-4):
        # (at 1e-8 a breakaway's first step, whose start has zero rate of relative speed to rounding, was once
        # cut to a few ulps by the touch check and the slip then ran 12 ns ahead: the tight end checks that)
        for rate in (100, 1000, 10_000):
            r = simulate_pad("stribeck", V=v, N=1.0, pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION, tick_rate=rate,
                             duration=duration, contactor_hz=hz, contactor_amplitude_m=amp, tolerance=tol)
            assert r.event_time.size == ref.event_time.size
            err = float(np.max(np.abs(r.event_time - ref.event_time)))
            # measured: ~0.15 tol s on the contactor case (mean interval 55 ms); bound 10 tol intervals
            assert err <= 10 * tol * scale, (tol, rate, err)
            assert np.allclose(r.event_amplitude, ref.event_amplitude, rtol=100 * tol, atol=0)
            worst[tol] = max(worst.get(tol, 0.0), err)
    if hz:
        # the contactor case's slip is nonlinear enough that the error follows the tolerance
        assert worst[1e-8] < worst[1e-7] < worst[1e-5] < worst[1e-4]


def test_every_tolerance_the_report_tries_keeps_its_event_bound():
    """The accuracy report's contactor stroke at each of its slip tolerances and tick rates: event times within 10
    tolerances of the mean event interval of a tight Radau run (1e-9 s for the default Taylor steps), amplitudes
    within 100 tolerances. The report compares each setting's cost with scipy's at equal error, so the bound
    must hold for every setting it may pick, the loosest ones included."""
    from shapedisplay.reports.accuracy import STRIBECK_TOLERANCES, build_cases
    case = next(c for c in build_cases(False) if c.name == "stribeck_contactor")
    p = case.params
    hz, amp, v = case.contactor["hz"], case.contactor["amplitude_m"], float(case.V(0.0))
    ref = stribeck_ivp("Radau", 1e-11, m=p["m"], k=p["k"], c=p["c"], mu_s=p["mu_s"], mu_k=p["mu_k"], a=p["a"],
                       b=p["b"], W=1.0, V=v, amp=amp, omega=2 * math.pi * hz, t_end=case.duration)
    assert ref.status == "ok" and ref.event_time.size >= 8
    scale = float(np.mean(np.diff(ref.event_time)))
    for tol in STRIBECK_TOLERANCES:
        for rate in case.rates:
            r = simulate_pad("stribeck", V=v, N=1.0, pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION, tick_rate=rate,
                             duration=case.duration, contactor_hz=hz, contactor_amplitude_m=amp, tolerance=tol)
            assert r.event_time.size == ref.event_time.size, (tol, rate)
            err = float(np.max(np.abs(r.event_time - ref.event_time)))
            # measured: 0.01-0.07 tolerances of the interval from 3e-9 to 1e-3 (100 Hz, 1 and 10 kHz)
            bound = 1e-9 if tol is None else 10 * tol * scale
            assert err <= bound, (tol, rate, err, bound)
            assert np.allclose(r.event_amplitude, ref.event_amplitude, rtol=100 * (tol or 1e-9), atol=0), (tol, rate)


def test_loose_tolerances_keep_the_contactor_period_error_a_fraction_of_the_tolerance():
    """The contactor stroke at 100 Hz: the largest relative error of the intervals between events, against Radau,
    within a fifth of the tolerance at the loose end. The slip step extrapolates its two passes' correction to
    their limit (Aitken); with the second pass's value alone the error was 0.45 and 0.58 tolerances at 3e-4 and
    4e-4 (measured now: 0.03-0.04 from 1e-4 to 1e-3). The report's cheapest setting at each error level rests on
    this."""
    ref = stribeck_ivp("Radau", 1e-10, m=1e-4, k=1e3, c=1.0, mu_s=2.1, mu_k=1.4, a=55.0, b=1.9, W=1.0, V=0.1,
                       amp=1.25e-3, omega=2 * math.pi * 9.0, t_end=0.5)
    assert ref.status == "ok" and ref.event_time.size >= 8
    dref = np.diff(ref.event_time)
    for tol in (1e-4, 2e-4, 3e-4, 4e-4, 1e-3):
        r = simulate_pad("stribeck", V=0.1, N=1.0, pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION, tick_rate=100,
                         duration=0.5, contactor_hz=9.0, contactor_amplitude_m=1.25e-3, tolerance=tol)
        assert r.event_time.size == ref.event_time.size, tol
        err = float(np.max(np.abs(np.diff(r.event_time) - dref) / dref))
        assert err <= 0.2 * tol, (tol, err)


def test_period_error_stays_a_fraction_of_the_tolerance_up_to_the_loosest_on_a_lighter_damped_pad():
    """The contactor stroke on the Imaizumi pad with a twentieth of its damping (c = 0.05 N s/m), 100 Hz: the
    relative error of the intervals between events within half the tolerance from 1e-5 to 1e-3. The speed part
    of an exponential step's error is measured against the speed the pad reaches (mu_s W / (c + b) where the sliding
    pad is overdamped); against the free oscillation's mu_s W / sqrt(k m) an error before the fold went unseen
    and the periods were 3.1 tolerances off at 1e-3 (0.14-0.31 below it). Measured now: 0.10-0.39."""
    ref = stribeck_ivp("Radau", 1e-10, m=1e-4, k=1e3, c=0.05, mu_s=2.1, mu_k=1.4, a=55.0, b=1.9, W=1.0, V=0.1,
                       amp=1.25e-3, omega=2 * math.pi * 9.0, t_end=0.5)
    assert ref.status == "ok" and ref.event_time.size >= 8
    dref = np.diff(ref.event_time)
    pad = PadParams(1.0e-4, 1.0e3, 0.05)
    for tol in (1e-5, 1e-4, 4e-4, 1e-3):
        r = simulate_pad("stribeck", V=0.1, N=1.0, pad=pad, friction=IMAIZUMI_FRICTION, tick_rate=100,
                         duration=0.5, contactor_hz=9.0, contactor_amplitude_m=1.25e-3, tolerance=tol)
        assert r.event_time.size == ref.event_time.size, tol
        err = float(np.max(np.abs(np.diff(r.event_time) - dref) / dref))
        assert err <= 0.5 * tol, (tol, err)


@pytest.mark.parametrize("tol", [None, 1e-6, 1e-3])
def test_linear_curve_matches_its_closed_form(tol):
    """Exact for every tolerance: an exponential step solves the linear curve's slip in closed form."""
    dev = DeviceProfile(pad=PadParams(1.0, 1.0, 0.0), friction=FrictionParams(1.0, 0.5),
                        extra={"stribeck": {"a": 0.0, "b": -0.1}}, velocity_range=(1e-6, 2.0))
    expect = _viscous_belt_events(1.0, 1.0, -0.1, 1.0, 1.0, 0.2, 4)
    for rate in (100, 1000):
        r = simulate_pad(get_model("stribeck", dev, tolerance=tol), V=0.2, N=1.0, pad=dev.pad, friction=dev.friction,
                         tick_rate=rate, duration=expect[-1] + 0.5)
        assert r.event_time.size == expect.size
        assert np.max(np.abs(r.event_time - expect)) < 1e-9
        assert np.allclose(r.event_amplitude, dev.burst.gain * 1.0, rtol=1e-12)


def _run(V, N, rate, split, hz, amp, tol=None):
    """run_kernel on inputs held per tick of ``1 / rate`` s, each tick cut into ``split`` ticks; plus (V, N) per tick."""
    model = get_model("stribeck", DeviceProfile(pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION),
                      contactor_hz=hz, contactor_amplitude_m=amp, tolerance=tol)
    n = V.size * split + 1
    t = np.arange(n) / (rate * split)
    ones = np.ones(n)
    Vt = np.concatenate([[0.0], np.repeat(V, split)])
    Nt = np.concatenate([[N[0]], np.repeat(N, split)])
    return run_kernel(model, t, Vt, Nt, 2.1 * ones, 1.4 * ones, ones), Vt, Nt


#: Loads the tick-cut property covers: none, or at least 10 mN. Below that the curve's drop happens over
#: relative speeds of ``W / a`` (1e-12 m/s at 1e-10 N), faster than any Taylor step resolves: the kernel
#: then takes linearised steps (bounded and finite, checked on the whole range, but not tolerance-exact).
_LOADS = st.one_of(st.just(0.0), st.floats(0.01, 3.0))
_CONTACTORS = st.sampled_from([(0.0, 0.0), (9.0, 1.25e-3), (3.0, 1.25e-3)])


def _assert_finite_and_within_the_curve(run, hz, amp):
    """Finite outputs, phases 0/1, increasing event times, no truncated tick, friction within the curve."""
    (st_, f, phase, x, v, et, ea), Vt, Nt = run
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(x)) and np.all(np.isfinite(v))
    assert set(np.unique(phase)) <= {0.0, 1.0}
    assert np.all(np.diff(et) > 0) and np.all(np.isfinite(ea)) and np.all(ea >= 0)
    assert st_["truncated"] == 0
    # friction never exceeds the curve's largest value: mu_s W in stick, W mu(|vr|) <= mu_s W + b |vr| in slip
    vr = np.abs(v) + np.abs(Vt) + amp * 2 * math.pi * hz
    assert np.all(np.abs(f) <= 2.1 * Nt + 1.9 * vr + 1e-9)
    stuck = phase == 0.0
    assert np.all(np.abs(f[stuck]) <= 2.1 * Nt[stuck] * (1 + 1e-9) + 1e-12)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.3, 0.3), st.floats(0.0, 3.0)), min_size=3, max_size=12), _CONTACTORS)
@example([(0.0, 0.0), (0.25, 1.0), (0.0, 5.960464477539063e-08)], (0.0, 0.0))   # drop too steep for Taylor steps
@example([(0.0, 0.0), (0.25, 1.0), (-0.25, 2.225073858507e-311)], (9.0, 1.25e-3))   # subnormal load
def test_outputs_finite_and_bounded(segments, contactor):
    """Inputs held for 20 ms each, any load down to subnormal ones: finite, friction within the curve."""
    hz, amp = contactor
    V = np.repeat([s[0] for s in segments], 20)
    N = np.repeat([s[1] for s in segments], 20)
    _assert_finite_and_within_the_curve(_run(V, N, 1000.0, 1, hz, amp), hz, amp)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.3, 0.3), _LOADS), min_size=3, max_size=12), _CONTACTORS)
def test_outputs_bounded_and_events_independent_of_tick_cuts(segments, contactor):
    """Inputs held for 20 ms each; ticks of 1 ms, cut in three, give the same events (within the step tolerance)."""
    hz, amp = contactor
    V = np.repeat([s[0] for s in segments], 20)
    N = np.repeat([s[1] for s in segments], 20)
    runs = [_run(V, N, 1000.0, split, hz, amp) for split in (1, 3)]
    for run in runs:
        _assert_finite_and_within_the_curve(run, hz, amp)
    et1, et3 = runs[0][0][-2], runs[1][0][-2]
    assert et1.size == et3.size
    if et1.size:
        # each step's error is below 1e-13 of the pad's scales; a light load (W / a of 0.2 mm/s at 10 mN)
        # takes thousands of short steps, whose errors add up to ~1e-9 s
        assert np.max(np.abs(et1 - et3)) < 1e-8


_TOLERANCES = st.sampled_from([3e-9, 1e-6, 1e-4])
#: The tick-cut property compares event counts: at tolerances looser than about 3e-5 a trajectory that only
#: grazes zero relative speed (within the tolerance) may re-stick with one cut and not with another, as
#: scipy's loose tolerances miss or add events; it is checked at the tighter ones.
_CUT_TOLERANCES = st.sampled_from([3e-9, 1e-6, 1e-5])


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.3, 0.3), st.floats(0.0, 3.0)), min_size=3, max_size=12), _CONTACTORS,
       _TOLERANCES)
@example([(0.0, 0.0), (0.25, 1.0), (0.0, 5.960464477539063e-08)], (0.0, 0.0), 1e-4)   # drop too steep for any step
@example([(0.0, 0.0), (0.25, 1.0), (-0.25, 2.225073858507e-311)], (9.0, 1.25e-3), 1e-6)   # subnormal load
def test_exponential_steps_finite_and_bounded(segments, contactor, tol):
    """Exponential slip steps, inputs held for 20 ms each, any load down to subnormal ones: finite, within the curve."""
    hz, amp = contactor
    V = np.repeat([s[0] for s in segments], 20)
    N = np.repeat([s[1] for s in segments], 20)
    _assert_finite_and_within_the_curve(_run(V, N, 1000.0, 1, hz, amp, tol), hz, amp)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.3, 0.3), _LOADS), min_size=3, max_size=12), _CONTACTORS, _CUT_TOLERANCES)
@example([(0.0, 0.0), (0.25, 0.0), (0.25, 0.1875)], (0.0, 0.0), 1e-6)   # the relative speed crosses zero twice
@example([(0.0, 0.0), (0.0, 0.25), (-0.25, 0.015625)], (9.0, 1.25e-3), 1e-6)   # in the first tick of a new load
@example([(0.0, 0.0), (0.0, 0.0), (-0.05838320942926317, 0.01171875)], (9.0, 1.25e-3), 1e-6)   # a light load
def test_exponential_steps_events_independent_of_tick_cuts(segments, contactor, tol):
    """Ticks of 1 ms, cut in three, give the same events within a bound that scales with the tolerance.

    Measured: within about 0.1 tolerance (in s) at loads of a newton, 1.3 at the lightest (10 mN, whose curve
    drops over 0.2 mm/s of relative speed).
    """
    hz, amp = contactor
    V = np.repeat([s[0] for s in segments], 20)
    N = np.repeat([s[1] for s in segments], 20)
    runs = [_run(V, N, 1000.0, split, hz, amp, tol) for split in (1, 3)]
    for run in runs:
        _assert_finite_and_within_the_curve(run, hz, amp)
    et1, et3 = runs[0][0][-2], runs[1][0][-2]
    assert et1.size == et3.size
    if et1.size:
        assert np.max(np.abs(et1 - et3)) < 10 * tol
