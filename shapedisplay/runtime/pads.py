"""Per-tick numba kernels of the fingerpad / friction models.

Functions for advancing a 1-DOF fingerpad pressed on a moving surface by one
renderer tick, in float64 SI units (m, s, N, kg). Every model's kernel has
one signature, so the offline fast path and the online ``step()`` run the
same code (both through :mod:`.dispatch`, generated from the model
registry):

``n_ev = NAME_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev)``

``st`` : :data:`~.layouts.PAD_STATE` record
    The model state, updated in place (``st.x``, ``st.phase``, ...).
``prm`` : :data:`~.layouts.PAD_PARAMS` record
    Parameters, packed by the model class in :mod:`.models`.
``t0, h`` : float
    Start time of the tick and its length, s.
``V`` : float
    Surface velocity relative to the finger during the tick, m/s (signed
    along the pad axis). Constant within a tick.
``N, mus, muk, gain`` : float
    Normal force (N), effective static/kinetic coefficients and burst-gain
    multiplier for the tick (constant within a tick).
``ev_t, ev_a`` : ndarray (capacity,), float64
    Stick-to-slip event times (s) and burst amplitudes; events beyond the
    capacity are counted but not written (the caller re-runs with more room).

Inputs change only at tick boundaries. In stick the pad then takes the new
surface velocity at once (static friction supplies the impulse; the kinetic
energy changes by m (V1^2 - V0^2) / 2, negligible for a 1e-6 kg pad); in
slip the pad velocity is continuous and only the forcing changes.

Sign conventions
----------------
``x`` is the pad displacement from its rest position relative to the
finger (spring stretch, m); ``v = dx/dt``. The friction force on the pad is
``f``; in stick the pad moves with the surface (``v = V``) and
``f = k x + c V``; in slip ``f = s * mu_k * N`` where ``s`` is the sign of
the friction (opposite to the relative velocity ``v - V``).

The exact model (Konyo pad, phases in closed form)
--------------------------------------------------
Stick is linear in time, so breakaway (``|f|`` reaches ``mu_s N``) is solved
in closed form. Slip is the damped oscillator ``m x'' + c x' + k x = s mu_k N``
solved in closed form (under-, critically and over-damped, and ``c = 0``).
The relative velocity ``w(t) = -s (x'(t) - V)`` is monotone between the zeros
of ``x''`` (closed-form times spaced ``pi / omega_d``), so each interval is
bracketed exactly and the re-stick time polished by safeguarded Newton to
~1e-15 s; this catches double crossings and near-tangent touches inside one
tick. Fresh slips and slips under way at a tick's start usually skip that walk
(:func:`fresh_slip_search`, :func:`continued_slip_search`: the first crossing
located from closed-form extrema, Newton's method and a series end), handing
every case they cannot prove to it. Any number of events may occur per tick; phases run across tick
boundaries without being cut, so event times do not depend on the tick rate.
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from .layouts import PAD_STATE, record

# ----------------------------------------------------------------- state
#: Safety cap on phase changes inside one tick (never reached by physical inputs).
MAX_EVENTS_PER_TICK = 200_000
#: The exact model's cap on phase changes in a tick of length h: PHASES_BASE + h * 4 omega / pi
#: (:func:`phase_cap`; the C runtime's SD_PHASES_BASE).
PHASES_BASE = 32
#: Newton/bisection steps of the exact model's re-stick polish (:func:`_polish`; the C runtime's
#: SD_POLISH_MAX; measured at most 46 in double)
POLISH_MAX = 64
_ADMIT = 1.0 - 1e-9      # re-stick admissible if |f| <= _ADMIT * mu_s N
_ADMIT_TOUCH = 1.0 - 1e-6  # stricter for tangent touches (grazing at the limit is not a re-stick)


def new_state() -> np.ndarray:
    """A fresh state (one-element :data:`~.layouts.PAD_STATE` array): stuck, spring relaxed, no normal-force cap."""
    return record(PAD_STATE, s=1.0)


# ================================================================ oscillator
@njit(cache=True)
def osc(m, c, k, y0, v0, t):
    """Free damped oscillator ``m y'' + c y' + k y = 0`` from (y0, v0).

    Returns ``(y, v)`` at time ``t`` (s). Handles under-, critically and
    over-damped pads, ``c = 0`` and negative ``c`` (used by linearised
    Stribeck steps).
    """
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    if disc < -1e-10 * wn2:
        return _osc_u(sig, wn2, math.sqrt(-disc), y0, v0, t)
    if disc > 1e-10 * wn2:
        sq = math.sqrt(disc)
        if sig >= 0.0:
            r2 = -sig - sq
            r1 = wn2 / r2
        else:
            r1 = -sig + sq
            r2 = wn2 / r1
        p = (v0 - r2 * y0) / (r1 - r2)
        q = y0 - p
        e1 = math.exp(r1 * t)
        e2 = math.exp(r2 * t)
        return p * e1 + q * e2, r1 * p * e1 + r2 * q * e2
    w = sig
    a = y0
    b = v0 + w * y0
    e = math.exp(-w * t)
    return (a + b * t) * e, (b - w * a - w * b * t) * e


@njit(cache=True, inline="always")
def _osc_u(sig, wn2, wd, y0, v0, t):
    """:func:`osc` of an under-damped pad from its constants (``sig = 0.5 c / m``, ``wn2 = k / m``,
    ``wd = sqrt(wn2 - sig^2)``, computed by the expressions :func:`osc` uses): its under-damped branch,
    for callers that keep the constants instead of recomputing them at every call."""
    e = math.exp(-sig * t)
    cs = math.cos(wd * t)
    sn = math.sin(wd * t)
    y = e * (y0 * cs + (v0 + sig * y0) / wd * sn)
    v = e * (v0 * cs - (wn2 * y0 + sig * v0) / wd * sn)
    return y, v


@njit(cache=True)
def osc_damping_work(m, c, k, y0, v0, t):
    """Energy dissipated by the damper, integral of ``c v^2`` over [0, t], J."""
    if c == 0.0 or t <= 0.0:
        return 0.0
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    if disc < -1e-10 * wn2:
        return _damping_work_u(c, sig, wn2, math.sqrt(-disc), y0, v0, t)
    if disc > 1e-10 * wn2:
        sq = math.sqrt(disc)
        r2 = -sig - sq
        r1 = wn2 / r2
        p = (v0 - r2 * y0) / (r1 - r2)
        q = y0 - p
        P = r1 * p
        Q = r2 * q
        i11 = math.expm1(2 * r1 * t) / (2 * r1)
        i22 = math.expm1(2 * r2 * t) / (2 * r2)
        i12 = math.expm1((r1 + r2) * t) / (r1 + r2)
        return c * (P * P * i11 + 2 * P * Q * i12 + Q * Q * i22)
    # critical: composite 2-point Gauss-Legendre on 64 sub-intervals (128 evaluations) of a smooth,
    # non-oscillating integrand
    n = 64
    acc = 0.0
    dt = t / n
    g = 0.5773502691896257
    for i in range(n):
        tm = (i + 0.5) * dt
        for sgn in (-1.0, 1.0):
            _, v = osc(m, c, k, y0, v0, tm + sgn * g * 0.5 * dt)
            acc += v * v
    return c * acc * 0.5 * dt


@njit(cache=True)
def _damping_work_u(c, sig, wn2, wd, y0, v0, t):
    """The under-damped branch of :func:`osc_damping_work` from the pad's constants (as :func:`_osc_u`);
    ``c > 0``, ``t > 0`` (``sig`` may have underflowed to 0)."""
    # v = Re(Z e^{lam t}), lam = -sig + i wd, Z = zr + i zi = v0 + i (wn2 y0 + sig v0)/wd:
    # c v^2 = c (|Z|^2 e^{-2 sig t} + Re(Z^2 e^{2 lam t})) / 2, integrated in closed form; in real
    # arithmetic, with e^{2 lam t} - 1 = (em cos 2 wd t - 2 sin^2 wd t) + i (1 + em) sin 2 wd t,
    # em = expm1(-2 sig t), exact to rounding also for short spans
    zr = v0
    zi = (wn2 * y0 + sig * v0) / wd
    em = math.expm1(-2.0 * sig * t)
    sn = math.sin(wd * t)
    cs = math.cos(wd * t)
    s2 = 2.0 * sn * sn
    er = em * (1.0 - s2) - s2
    ei = (1.0 + em) * (2.0 * sn * cs)
    z2r = zr * zr - zi * zi
    z2i = 2.0 * zr * zi
    if sig != 0.0:
        part1 = 0.5 * (zr * zr + zi * zi) * (-em) / (2.0 * sig)
    else:
        # c > 0 so small against m that 0.5 c / m underflows to 0: -em / (2 sig) is t in the limit
        part1 = 0.5 * (zr * zr + zi * zi) * t
    # Re(Z^2 (e^{2 lam t} - 1) / (2 lam)), |lam|^2 = wn2
    part2 = 0.5 * (-sig * (z2r * er - z2i * ei) + wd * (z2r * ei + z2i * er)) / (2.0 * wn2)
    return c * (part1 + part2)


@njit(cache=True)
def _acc(m, c, k, y, v):
    return -(c * v + k * y) / m


@njit(cache=True, inline="always")
def _acc_zero_phase(sig, wn2, wd, y0, v0):
    """Under-damped free oscillator from (y0, v0): the phase ``th1`` (rad, in (0, pi]) of its first
    acceleration zero after t = 0, the zeros being at ``(th1 + n pi) / wd``; -1 if the acceleration is 0."""
    a0 = -2.0 * sig * v0 - wn2 * y0
    j0 = -2.0 * sig * a0 - wn2 * v0
    bb = (j0 + sig * a0) / wd
    if a0 == 0.0 and bb == 0.0:
        return -1.0
    # a(t) ~ a0 cos(th) + bb sin(th) = R cos(th - phi); zeros at th = phi + pi/2 + n pi
    phi = math.atan2(bb, a0)
    # (phi + pi/2) mod pi (Python's %, the same bits: phi + pi/2 lies in (-pi/2, 3 pi/2], where fmod
    # returns x - pi exactly or x, and % then adds pi to a negative x)
    th1 = phi + 0.5 * math.pi
    if th1 >= math.pi:
        th1 -= math.pi
    elif th1 < 0.0:
        th1 += math.pi
    if th1 < 1e-9 or th1 > math.pi - 1e-9:
        # the zero at t = 0 is the start point itself
        th1 = math.pi if th1 > 1.0 else th1 + math.pi
        if th1 < math.pi:
            th1 = math.pi
    return th1


@njit(cache=True)
def _acc_zero_after(th1, wd, after):
    """First acceleration zero ``(th1 + n pi) / wd`` later than ``after`` (s); inf if ``th1 < 0``."""
    if th1 < 0.0:
        return np.inf
    tz = th1 / wd
    if tz <= after:
        nper = math.floor((after - tz) * wd / math.pi) + 1.0
        tz = (th1 + nper * math.pi) / wd
        while tz <= after:
            tz += math.pi / wd
    return tz


@njit(cache=True)
def _next_acc_zero(m, c, k, y0, v0, after):
    """First time > ``after`` (s) where the free oscillator's acceleration is 0; inf if none."""
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    if disc < -1e-10 * wn2:
        wd = math.sqrt(-disc)
        return _acc_zero_after(_acc_zero_phase(sig, wn2, wd, y0, v0), wd, after)
    a0 = -2.0 * sig * v0 - wn2 * y0
    j0 = -2.0 * sig * a0 - wn2 * v0
    if disc > 1e-10 * wn2:
        sq = math.sqrt(disc)
        if sig >= 0.0:
            r2 = -sig - sq
            r1 = wn2 / r2
        else:
            r1 = -sig + sq
            r2 = wn2 / r1
        p = (v0 - r2 * y0) / (r1 - r2)
        q = y0 - p
        num = -r2 * r2 * q
        den = r1 * r1 * p
        if den == 0.0 or num / den <= 0.0:
            return np.inf
        tz = math.log(num / den) / (r1 - r2)
        return tz if tz > after and tz > 1e-15 else np.inf
    w = sig
    b = v0 + w * y0
    if b == 0.0:
        return np.inf
    tz = (2.0 * b - w * y0) / (w * b)
    return tz if tz > after and tz > 1e-15 else np.inf


@njit(cache=True)
def _w(m, c, k, y0, v0, V, s, t):
    _, v = osc(m, c, k, y0, v0, t)
    return -s * (v - V)


@njit(cache=True)
def _polish(m, c, k, y0, v0, V, s, lo, hi, wlo, whi):
    """Root of w in [lo, hi] with w(lo) = wlo >= 0 > w(hi) = whi: safeguarded Newton, ~1e-16 s.

    Returns ``(t, y, v)``: the root and the oscillator state there. A Newton
    step whose own error (``|w'' / 2 w'| dt^2``, and the next order's
    ``omega^2 |dt|^3 / 6``) is below the tolerance ends the search: its
    end state is the Taylor expansion about the last evaluation (velocity,
    acceleration, jerk), which is exact to rounding over such a step.
    """
    if wlo - whi > 0.0:
        t = lo + (hi - lo) * wlo / (wlo - whi)
    else:
        t = 0.5 * (lo + hi)
    if not (lo < t < hi):
        t = 0.5 * (lo + hi)
    wn2 = k / m
    for _ in range(POLISH_MAX):
        y, v = osc(m, c, k, y0, v0, t)
        wt = -s * (v - V)
        if wt == 0.0:
            return t, y, v
        if wt > 0.0:
            lo = t
        else:
            hi = t
        a = _acc(m, c, k, y, v)
        dw = -s * a
        newton = dw != 0.0
        tn = t - wt / dw if newton else 0.5 * (lo + hi)
        if not (lo < tn < hi):
            tn = 0.5 * (lo + hi)
            newton = False
        d = tn - t
        tol = 1e-16 + 1e-15 * t
        if newton:
            j = -(c * a + k * v) / m
            ad = abs(d)
            if ad <= tol or hi - lo <= 1e-16 + 1e-15 * hi \
                    or (abs(j) * d * d <= 2.0 * abs(a) * tol and wn2 * ad * ad * ad <= 6.0 * tol):
                return tn, y + d * (v + d * (0.5 * a + d * j / 6.0)), v + d * (a + 0.5 * d * j)
        elif abs(d) <= tol or hi - lo <= 1e-16 + 1e-15 * hi:
            y, v = osc(m, c, k, y0, v0, tn)
            return tn, y, v
        t = tn
    t = 0.5 * (lo + hi)
    y, v = osc(m, c, k, y0, v0, t)
    return t, y, v


@njit(cache=True)
def phase_rate(m, c, k):
    """Bound on the phase changes per second of a pad, 4 omega / pi (omega the damped frequency, or the
    natural one when the pad is not under-damped): a stick-slip cycle is two phases and its slip lasts at
    least a quarter of the damped period."""
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    under = disc < -1e-10 * wn2
    return 4.0 * (math.sqrt(-disc) if under else math.sqrt(wn2)) / math.pi


@njit(cache=True)
def phase_cap(m, c, k, h):
    """Phase changes a tick of length ``h`` may take: PHASES_BASE + h * 4 omega / pi, at most
    MAX_EVENTS_PER_TICK (also for NaN); the phases cut by the tick's edges are in the base."""
    n = PHASES_BASE + h * phase_rate(m, c, k)
    return int(n) if n < MAX_EVENTS_PER_TICK else MAX_EVENTS_PER_TICK


@njit(cache=True)
def slip_search(m, c, k, y0, v0, V, s, rem, tmin):
    """Find the first re-stick candidate of a slip phase within ``rem`` seconds.

    Returns ``(kind, t, y, v)``: kind 0 none (t = rem), 1 crossing of the
    relative velocity through zero, 2 near-tangent touch (|w| below a
    round-off tolerance at an extremum); ``y, v`` the oscillator state at
    ``t``. Touches before ``tmin`` are ignored (used to step past a grazing
    touch that was not a re-stick).

    A slip that starts with the relative velocity already past zero by more
    than round-off (``w(0) < -tol``: the surface velocity changed at a tick
    boundary) crosses at once: kind 1 at t = 0.
    """
    tol = 1e-12 * (abs(V) + abs(v0)) + 1e-300
    if -s * (v0 - V) < -tol:
        return 1, 0.0, y0, v0
    # acceleration zeros are pi / omega_d apart: at most rem omega_d / pi + 1 = rem phase_rate / 4 + 1 of
    # them in rem, plus grazing touches stepped over; twice that bounds the loop (then kind 0)
    nmax = 8.0 + rem * phase_rate(m, c, k) * 0.5
    n_cap = int(nmax) if nmax < MAX_EVENTS_PER_TICK else MAX_EVENTS_PER_TICK
    n_it = 0
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    under = disc < -1e-10 * wn2
    wd = math.sqrt(-disc) if under else 0.0
    # quick rejection: |v(t)| bounded by the oscillation envelope
    if sig >= 0.0 and under:
        bv = (wn2 * y0 + sig * v0) / wd
        amp = math.sqrt(v0 * v0 + bv * bv)
        if s * V - amp > 2.0 * tol:
            y, v = osc(m, c, k, y0, v0, rem)
            return 0, rem, y, v
    # under-damped: the acceleration zeros (th1 + n pi) / wd, th1 found once
    th1 = _acc_zero_phase(sig, wn2, wd, y0, v0) if under else 0.0
    ta = 0.0
    wa = 0.0          # w(ta), known once ta > 0 (the last bracket's end)
    while True:
        n_it += 1
        if n_it > n_cap:
            y, v = osc(m, c, k, y0, v0, rem)
            return 0, rem, y, v
        tz = _acc_zero_after(th1, wd, ta) if under else _next_acc_zero(m, c, k, y0, v0, ta)
        interior = tz < rem
        tb = tz if interior else rem
        yb, vb = osc(m, c, k, y0, v0, tb)
        wb = -s * (vb - V)
        graze = interior and wb >= -tol and wb <= tol
        if graze and tb < tmin:
            ta = tb
            wa = wb
            continue
        if wb < 0.0:
            if ta == 0.0:
                # under-damped: osc at t = 0 returns (y0, v0) exactly (exp, cos give 1, sin 0), so w(0) is
                # -s (v0 - V) bit for bit without the call
                wa = -s * (v0 - V) if under else _w(m, c, k, y0, v0, V, s, ta)
            tr, yr, vr = _polish(m, c, k, y0, v0, V, s, ta, tb, wa, wb)
            if interior and wb >= -tol:
                return 2, tr, yr, vr
            return 1, tr, yr, vr
        if wb == 0.0:
            return (2 if interior else 1), tb, yb, vb
        if graze:
            return 2, tb, yb, vb
        if not interior:
            return 0, rem, yb, vb
        ta = tb
        wa = wb


@njit(cache=True, inline="always")
def _restick_end(m, c, k, t, y, v, a, d):
    """End a re-stick root search at the oscillator state ``(y, v)``, acceleration ``a``, at ``t``, where the
    Newton step towards ``v = V`` is ``d`` (s), if the rest of the root and the state there follow from
    the Taylor expansion about ``t`` to rounding.

    The derivatives ``y3 .. y6`` follow from ``y'' = -(c y' + k y) / m``; the root offset is the series
    reversion of ``v(t + x) = V`` to fourth order, ``x = d - A d^2 + (2 A^2 - B) d^3 + (5 A B - 5 A^3 - C)
    d^4`` (``A = y3 / 2a``, ``B = y4 / 6a``, ``C = y5 / 24a``), whose first omitted term, bounded by
    ``(14 A^4 + 21 A^2 |B| + 6 |A C| + 3 B^2 + |y6 / 120a|) |d|^5``, must be below 2.5e-17 of the root
    time (a tenth of its last bit); the state is the Taylor polynomial of order 5 (velocity 4), whose
    remainder is below 1e-17 of the amplitude for ``omega_n |d| <= 1e-3``. Returns ``(ok, t + x, y, v)``;
    ``ok`` False (and the inputs) if the step is too long for that.
    """
    wn2 = k / m
    if not (wn2 * d * d <= 1e-6):
        return False, t, y, v
    c_m = c / m
    d3 = -(c_m * a + wn2 * v)
    d4 = -(c_m * d3 + wn2 * a)
    d5 = -(c_m * d4 + wn2 * d3)
    d6 = -(c_m * d5 + wn2 * d4)
    ia = 1.0 / a
    A = 0.5 * d3 * ia
    B = (1.0 / 6.0) * d4 * ia
    C = (1.0 / 24.0) * d5 * ia
    E = (1.0 / 120.0) * d6 * ia
    A2 = A * A
    d2 = d * d
    nxt = (14.0 * A2 * A2 + 21.0 * A2 * abs(B) + 6.0 * abs(A * C) + 3.0 * B * B + abs(E)) * (d2 * d2 * abs(d))
    if not (nxt <= 2.5e-17 * abs(t + d)):
        return False, t, y, v
    x = d * (1.0 + d * (-A + d * ((2.0 * A2 - B) + d * (5.0 * A * B - 5.0 * A2 * A - C))))
    x2 = 0.5 * x
    x3 = (1.0 / 3.0) * x
    x4 = 0.25 * x
    x5 = 0.2 * x
    yr = y + x * (v + x2 * (a + x3 * (d3 + x4 * (d4 + x5 * d5))))
    vr = v + x * (a + x2 * (d3 + x3 * (d4 + x4 * d5)))
    return True, t + x, yr, vr


@njit(cache=True, inline="always")
def _restick_newton(m, c, k, sig, wn2, wd, y0, v0, V, s, lo, hi, t, y, v, rem):
    """The root of ``w = -s (v - V)`` in ``(lo, hi)``, where w falls monotonically through 0, by Newton's
    method from ``t`` with the oscillator state ``(y, v)`` there (further states by :func:`_osc_u` from
    ``(y0, v0)``; ``sig, wn2, wd`` the under-damped pad's constants) until :func:`_restick_end` ends it; with the outcome against the span ``rem``:
    ``(kind, t, y, v)`` as :func:`slip_search` (1 crossing at ``t < rem``; 0 none within ``rem``, the
    state at ``rem``). Kind -1 if a step left the interval, the root did not settle in 8 evaluations
    or the evaluation at ``rem`` is within rounding of the root (the caller then walks the brackets)."""
    for _ in range(8):
        a = -(c * v + k * y) / m
        if not (s * a > 0.0):
            break
        d = (V - v) / a
        if not (lo < t + d < hi):
            break
        ok, tr, yr, vr = _restick_end(m, c, k, t, y, v, a, d)
        if ok:
            # the root inside (lo, hi) with w' < 0 there, as on the way to it
            if not (lo < tr < hi and s * (c * vr + k * yr) < 0.0):
                break
            if tr < rem:
                return 1, tr, yr, vr
            y, v = _osc_u(sig, wn2, wd, y0, v0, rem)
            if s * (v - V) < 0.0:
                return 0, rem, y, v
            break
        t = t + d
        y, v = _osc_u(sig, wn2, wd, y0, v0, t)
    return -1, 0.0, 0.0, 0.0


@njit(cache=True)
def fresh_slip_search(m, c, k, y0, V, s, rem):
    """:func:`slip_search` of a fresh slip (it starts with the pad at the surface speed, ``v0 = V``, no
    touch to skip): the same outcome, found from half a damped period on.

    An under-damped free oscillator is, half a damped period ``tp = pi / omega_d`` later, ``-e`` times
    its state (``e = exp(-sig tp)``): the slip is at ``(-e y0, -e V)`` at ``tp`` without an evaluation.
    The relative velocity ``w = -s (v - V)`` starts at 0 rising (``w'(0) = -s a0 > 0``) and is
    ``s V (1 + e) > 0`` at ``tp`` with ``w'(tp) = -e w'(0) < 0``: with acceleration zeros ``tp``
    apart, (0, tp) holds exactly one (the peak of w), so w > 0 on (0, tp]; a root ``t*`` in
    ``(tp, 2 tp)`` with ``w' < 0`` there, as at tp, is the first crossing (no acceleration zero
    between). Newton's method from tp (:func:`_restick_newton`) finds it. The crossing is certain and
    not a touch when the trough of w, at most ``s V - D e^2`` (``D`` the velocity amplitude times
    ``omega_d / omega_n``, :func:`_restick_peak_reaches`), is below ``-2 tol``. Anything else --
    not under-damped, ``s V <= 0``, no rise, a start within ~1e-3 rad of phase of an acceleration
    zero, a shallow trough, no settled root, a root within rounding of the span's end -- goes to
    :func:`slip_search`. Outcomes agree with it to rounding (tests/test_runtime_pads.py).
    """
    fast, sig, wn2, wd, tp, e = _fast_path_constants(m, c, k)
    if not fast:
        return slip_search(m, c, k, y0, V, V, s, rem, 0.0)
    return _fresh_slip_u(m, c, k, sig, wn2, wd, tp, e, y0, V, s, rem)


@njit(cache=True)
def _fast_path_constants(m, c, k):
    """``(fast, sig, wn2, wd, tp, e)``: whether the re-stick fast paths apply (an under-damped pad with
    ``sig >= 0``) and their constants (``tp = pi / wd``, ``e = exp(-sig tp)``; 0 where they do not)."""
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    if not (disc < -1e-10 * wn2 and sig >= 0.0):
        return False, sig, wn2, 0.0, 0.0, 0.0
    wd = math.sqrt(-disc)
    tp = math.pi / wd
    return True, sig, wn2, wd, tp, math.exp(-sig * tp)


@njit(cache=True, inline="always")
def _fresh_slip_u(m, c, k, sig, wn2, wd, tp, e, y0, V, s, rem):
    """:func:`fresh_slip_search` of an under-damped pad with ``sig >= 0``, from its constants (``tp = pi / wd``,
    ``e = exp(-sig tp)``, by the same expressions)."""
    tol = 1e-12 * (abs(V) + abs(V)) + 1e-300
    sv = s * V
    if not (sv > 2.0 * tol):
        return slip_search(m, c, k, y0, V, V, s, rem, 0.0)
    a0 = -2.0 * sig * V - wn2 * y0
    j0 = -2.0 * sig * a0 - wn2 * V
    bb = (j0 + sig * a0) / wd
    B = (wn2 * y0 + sig * V) / wd
    R2 = V * V + B * B
    e4 = (e * e) * (e * e)
    lo2 = R2 * (wd * wd / wn2) * e4 * (1.0 - 1e-9)
    sv2 = sv + 2.0 * tol
    if not (s * a0 < 0.0 and a0 * a0 > 1e-6 * (a0 * a0 + bb * bb) and lo2 > sv2 * sv2 * (1.0 + 1e-6)):
        return slip_search(m, c, k, y0, V, V, s, rem, 0.0)
    if rem <= tp:
        # w > 0 on (0, rem]: no crossing in this span (as the evaluation at rem confirms)
        y, v = _osc_u(sig, wn2, wd, y0, V, rem)
        if s * (v - V) < 0.0:
            return 0, rem, y, v
        return slip_search(m, c, k, y0, V, V, s, rem, 0.0)
    kind, tr, yr, vr = _restick_newton(m, c, k, sig, wn2, wd, y0, V, V, s, tp, tp + tp, tp, -e * y0, -e * V, rem)
    if kind < 0:
        return slip_search(m, c, k, y0, V, V, s, rem, 0.0)
    return kind, tr, yr, vr


@njit(cache=True)
def continued_slip_search(m, c, k, y0, v0, V, s, rem):
    """:func:`slip_search` of a slip under way (``w(0) = -s (v0 - V)`` above the round-off tolerance, no
    touch to skip): the same outcome without walking the brackets.

    Under-damped: the acceleration zeros are ``tz1 + n tp`` (``tp = pi / omega_d``, ``tz1`` from
    :func:`_acc_zero_phase`), and there ``|v| = D exp(-sig t)`` (``D`` as in
    :func:`_restick_peak_reaches`), ``v`` having the sign the acceleration had before (that of
    ``a0`` up to ``tz1``) and ``-e`` times its value half a period later. If w falls from the start
    (``s a0 > 0``), its first trough is at ``tz1``; if it rises, ``tz1`` is its peak and ``tz1 + tp``
    the trough. A trough below ``-2 tol`` by a margin far above the rounding of these values holds the
    first crossing, the only root between the trough and the start or peak before it, where w falls
    monotonically. The first guess inverts the half cosine through the peak and the trough (for a fall
    from the start, the peak tp before the trough), ``t = t_pk + acos(1 - 2 r) / omega_d`` with
    ``r = w_pk / (w_pk - w_tr)``, then takes two Newton steps on the damped shape between them (its
    cosine and sine known from the half cosine's, turned by short series: no oscillator evaluation);
    :func:`_restick_newton` finds the root, usually from one evaluation. Anything else (not
    under-damped, w(0) within the tolerance, a start within ~1e-3 rad of an acceleration zero, a
    shallow trough, no settled root, a root within rounding of the span's end) goes to
    :func:`slip_search`. Outcomes agree with it to rounding (tests/test_runtime_pads.py).
    """
    fast, sig, wn2, wd, tp, e = _fast_path_constants(m, c, k)
    if not fast:
        return slip_search(m, c, k, y0, v0, V, s, rem, 0.0)
    return _continued_slip_u(m, c, k, sig, wn2, wd, tp, e, y0, v0, V, s, rem)


@njit(cache=True, inline="always")
def _continued_slip_u(m, c, k, sig, wn2, wd, tp, e, y0, v0, V, s, rem):
    """:func:`continued_slip_search` of an under-damped pad with ``sig >= 0``, from its constants (as
    :func:`_fresh_slip_u`)."""
    tol = 1e-12 * (abs(V) + abs(v0)) + 1e-300
    if not (-s * (v0 - V) > tol):
        return slip_search(m, c, k, y0, v0, V, s, rem, 0.0)
    a0 = -2.0 * sig * v0 - wn2 * y0
    j0 = -2.0 * sig * a0 - wn2 * v0
    bb = (j0 + sig * a0) / wd
    if not (a0 * a0 > 1e-6 * (a0 * a0 + bb * bb)):
        return slip_search(m, c, k, y0, v0, V, s, rem, 0.0)
    tz1 = _acc_zero_phase(sig, wn2, wd, y0, v0) / wd
    B = (wn2 * y0 + sig * v0) / wd
    D = math.sqrt((v0 * v0 + B * B) * (wd * wd / wn2))
    v1 = D * math.exp(-sig * tz1)
    if a0 < 0.0:
        v1 = -v1
    if s * a0 > 0.0:
        # w falls from the start to its trough at tz1 (its peak was tp before)
        lo = 0.0
        t_pk = tz1 - tp
        w_pk = -s * (-v1 / e - V)
        t_tr = tz1
        w_tr = -s * (v1 - V)
    else:
        # w rises to its peak at tz1, then falls to the trough half a period later
        lo = tz1
        t_pk = tz1
        w_pk = -s * (v1 - V)
        t_tr = tz1 + tp
        w_tr = -s * (-e * v1 - V)
        if rem <= tz1:
            y, v = _osc_u(sig, wn2, wd, y0, v0, rem)
            if s * (v - V) < 0.0:
                return 0, rem, y, v
            return slip_search(m, c, k, y0, v0, V, s, rem, 0.0)
    if not (w_tr < -2.0 * tol - 1e-9 * D and w_pk > 0.0):
        return slip_search(m, c, k, y0, v0, V, s, rem, 0.0)
    # the half cosine's root, then two Newton steps on the damped shape between the peak and the trough,
    # v(t_pk + u) = v_pk exp(-sig u) (cos wd u + (sig / wd) sin wd u), v' = -v_pk exp(-sig u) (wn2 / wd) sin wd u:
    # the first from the half cosine's cos and sin, the second from them turned by wd du (short series)
    r = w_pk / (w_pk - w_tr)
    cu = 1.0 - 2.0 * r
    su = 2.0 * math.sqrt(r * (1.0 - r))
    u = math.acos(cu) / wd
    v_pk = V - s * w_pk
    q = sig / wd
    g = wn2 / wd
    eu = math.exp(-sig * u)
    fp = v_pk * eu * g * su
    if fp != 0.0:
        du = (v_pk * eu * (cu + q * su) - V) / fp
        x = wd * du
        if abs(x) < 0.3:
            x2 = x * x
            cx = 1.0 - x2 * (0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0)))
            sx = x * (1.0 - x2 * (1.0 / 6.0 - x2 * (1.0 / 120.0 - x2 * (1.0 / 5040.0))))
            c1 = cu * cx - su * sx
            s1 = su * cx + cu * sx
            e1 = eu * (1.0 - sig * du * (1.0 - 0.5 * sig * du))
            fp1 = v_pk * e1 * g * s1
            if fp1 != 0.0:
                du += (v_pk * e1 * (c1 + q * s1) - V) / fp1
        u += du
    t = t_pk + u
    if not (lo < t < t_tr):
        t = 0.5 * (lo + t_tr)
    y, v = _osc_u(sig, wn2, wd, y0, v0, t)
    kind, tr, yr, vr = _restick_newton(m, c, k, sig, wn2, wd, y0, v0, V, s, lo, t_tr, t, y, v, rem)
    if kind < 0:
        return slip_search(m, c, k, y0, v0, V, s, rem, 0.0)
    return kind, tr, yr, vr


# ================================================================ exact model
@njit(cache=True)
def _record(ev_t, ev_a, n_ev, t, a):
    if n_ev < ev_t.shape[0]:
        ev_t[n_ev] = t
        ev_a[n_ev] = a
    return n_ev + 1


@njit(cache=True)
def _sgn(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@njit(cache=True)
def _stuck_whole_tick(st, prm, h, V, N, mus, work):
    """Fast path shared by the exact and jump ticks: True if the pad stays stuck for the whole tick.

    The stick force is linear in time, so both ends inside the static limit
    means no breakaway in between; the state is then advanced (with the
    friction and damper work of the tick if ``work``). Off while a maximum
    stick period is set.
    """
    if st.phase != 0.0 or prm.max_stick_period != 0.0:
        return False
    k = prm.stiffness
    xe = st.x + V * h
    fa = k * st.x + prm.damping * V
    fe = k * xe + prm.damping * V
    thr = mus * N
    if not (abs(fa) < thr and abs(fe) < thr):
        return False
    if work:
        st.work_friction = fa * V * h + 0.5 * k * V * V * h * h
        st.work_damping = prm.damping * V * V * h
    st.x = xe
    st.v = V
    st.f = fe
    st.n_events = 0
    return True


@njit(cache=True, inline="always")
def _stick_span(f, V, thr, k, tmax, age, rem):
    """Stuck with stick force ``f`` (N): time to the next breakaway within ``rem`` seconds.

    Returns ``(dt, breaks, forced)``: ``breaks`` False means stuck for all of
    ``rem`` (``dt = rem``); ``forced`` means the maximum stick period, not
    the static limit, ended the stick. ``dt = 0`` for a breakaway at once.
    The stick period counts only while the surface moves (``V != 0``): a
    resting finger is never forced to slip.
    """
    if abs(f) > thr * (1.0 + 1e-12) or (abs(f) >= thr and f * V > 0.0 and thr > 0.0) \
            or (thr == 0.0 and f != 0.0):
        return 0.0, True, False
    tb = np.inf
    if V != 0.0:
        tb = (_sgn(V) * thr - f) / (k * V)
        if tb < 0.0:
            tb = 0.0
    tf = np.inf
    if tmax > 0.0 and V != 0.0:
        tf = max(tmax - age, 0.0)
    tn = min(tb, tf)
    if tn >= rem:
        return rem, False, False
    return tn, True, tf < tb


@njit(cache=True, inline="always")
def _breakaway(x, f, V, forced, mus, N, k, c):
    """Slip direction ``s`` and spring stretch ``x`` (m) at a breakaway with stick force ``f``.

    Forced slip (the maximum stick period ended the stick): the stick ends as
    if the static limit had been reached. The spring takes the breakaway
    stretch ``x_b = (s mu_s N - c V) / k`` of the true N at once (the rest
    of its linear loading, ``(mu_s N - |f|) / (k |V|)`` seconds, is
    skipped), so the burst has the amplitude ``A = B (mu_s N - c V)`` of a
    natural breakaway, the slip runs under the true kinetic friction
    ``mu_k N`` and re-sticks where a natural slip does. The limit shortens
    the stick-slip period to ``t_max`` plus the slip (~pi / omega_d) and
    keeps every force of the true N, so the height contrast survives. The
    skipped loading is work done on the pad (counted in the friction work).
    """
    s = _sgn(f)
    if s == 0.0:
        s = _sgn(V) if V != 0.0 else 1.0
    if forced:
        x = (s * mus * N - c * V) / k
    return s, x


@njit(cache=True, inline="always")
def _finish_tick(st, x, phase, s, age, k, c, V, N, muk, nev):
    """Write the end-of-tick state shared by the exact and jump ticks (friction force included)."""
    st.x = x
    st.phase = phase
    st.s = s
    st.age = age
    st.n_events = nev
    if phase == 0.0:
        st.f = k * x + c * V
    else:
        st.f = s * muk * N


@njit(cache=True)
def exact_constants(prm):
    """The exact model's constants of the pad ``prm`` (a PAD_PARAMS record), which every tick of it uses:
    ``(sig, wn2, wd, under, rate, memo_span, fast, tp, e_tp)``.

    ``sig = 0.5 c / m``, ``wn2 = k / m``, ``wd`` the damped frequency (0 unless ``under``, an
    under-damped pad), ``rate`` the bound on phase changes per second (:func:`phase_rate`),
    ``memo_span`` the span beyond which a slip's re-stick search no longer depends on the time left
    (inf unless under-damped), ``fast`` whether the re-stick fast paths apply (``sig >= 0`` too) and
    their constants ``tp = pi / wd`` and ``e_tp = exp(-sig tp)`` (0 where they do not). Computed by the
    expressions :func:`osc`, :func:`phase_cap` and :func:`osc_damping_work` use (the same bits), once
    per tick by :func:`exact_tick` and once per run by the offline loops (:func:`exact_tick_prepared`).
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    under = disc < -1e-10 * wn2
    wd = math.sqrt(-disc) if under else 0.0
    rate = 4.0 * (wd if under else math.sqrt(wn2)) / math.pi
    # under-damped pad: a slip's re-stick search visits acceleration zeros pi / omega_d apart, so its
    # outcome does not depend on the time left in the tick once that exceeds the re-stick time plus
    # one such interval (memo_span); beyond it a repeated slip start reuses the stored outcome
    memo_span = math.pi / wd * (1.0 + 1e-6) if under else np.inf
    fast = under and sig >= 0.0     # the re-stick fast paths apply (their constants: half a period, its decay)
    tp = math.pi / wd if fast else 0.0
    e_tp = math.exp(-sig * tp) if fast else 0.0
    return sig, wn2, wd, under, rate, memo_span, fast, tp, e_tp


@njit(cache=True)
def exact_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    if _stuck_whole_tick(st, prm, h, V, N, mus, True):
        return n_ev
    return exact_tick_prepared(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev, exact_constants(prm), True)


@njit(cache=True, inline="always")
def exact_tick_prepared(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev, pc, work):
    """:func:`exact_tick` for a loop over many ticks of one pad: ``pc`` its :func:`exact_constants`,
    computed once by the caller. With ``work`` False the tick's friction and damper work are not
    computed (``st.work_friction`` and ``st.work_damping`` are left as they were: an offline render
    keeps neither); everything else is :func:`exact_tick`'s, bit for bit. Compiled into its callers
    (the tick loops), with the helpers its ticks call once or a few times (stick span, breakaway, slip
    searches, oscillator evaluation, end of tick): the calls cost about 1.2 ns per tick of the render's
    model stage."""
    if _stuck_whole_tick(st, prm, h, V, N, mus, work):
        return n_ev
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    B = prm.burst_gain * gain
    tmax = prm.max_stick_period
    x = st.x
    v = st.v
    phase = st.phase
    s = st.s
    age = st.age
    wf = 0.0
    wdmp = 0.0
    t = 0.0
    nev0 = n_ev
    it = 0
    tmin = 0.0
    sig, wn2, wd, under, rate, memo_span, fast, tp, e_tp = pc
    n_cap = PHASES_BASE + h * rate
    it_cap = int(n_cap) if n_cap < MAX_EVENTS_PER_TICK else MAX_EVENTS_PER_TICK
    while t < h:
        it += 1
        if it > it_cap:
            st.truncated += 1
            break
        rem = h - t
        if phase == 0.0:
            v = V
            f = k * x + c * V
            dt, brk, forced = _stick_span(f, V, mus * N, k, tmax, age, rem)
            if dt > 0.0:
                if work:
                    wf += (f * V * dt + 0.5 * k * V * V * dt * dt)
                    wdmp += c * V * V * dt
                x += V * dt
                if V != 0.0:
                    age += dt
            if not brk:
                t = h
                break
            t += dt
            f = k * x + c * V
            x0 = x
            s, x = _breakaway(x, f, V, forced, mus, N, k, c)
            if dt > 0.0 and not forced:
                # loaded to the limit within this span: the breakaway stretch in closed form (the summed
                # stick steps differ from it by rounding only), so steady strokes repeat it bit for bit
                x = (s * mus * N - c * V) / k
            if work:
                wf += 0.5 * k * (x * x - x0 * x0)
            n_ev = _record(ev_t, ev_a, n_ev, t0 + t, B * abs(k * x))
            phase = 1.0
            age = 0.0
            continue
        # ---- slip
        F = s * muk * N
        xeq = F / k
        y0 = x - xeq
        fresh = tmin == 0.0 and v == V and mus * N > 0.0
        hit = False
        if fresh and st.memo_valid != 0 and st.memo_s == s and st.memo_x == x and st.memo_v == V \
                and st.memo_muk == muk and st.memo_n == N and rem > st.memo_slip_time + memo_span:
            # slip_search and osc are pure functions of these inputs: the same bits out as last time
            hit = True
            kind = 1
            tr = st.memo_slip_time
            y1 = st.memo_x_restick
            v1 = V             # a crossing: the pad sticks or goes on from the surface speed
        elif fresh and fast:
            kind, tr, y1, v1 = _fresh_slip_u(m, c, k, sig, wn2, wd, tp, e_tp, y0, V, s, rem)
        elif tmin == 0.0 and fast and mus * N > 0.0:
            kind, tr, y1, v1 = _continued_slip_u(m, c, k, sig, wn2, wd, tp, e_tp, y0, v, V, s, rem)
        elif mus * N > 0.0:
            kind, tr, y1, v1 = slip_search(m, c, k, y0, v, V, s, rem, tmin)
        else:
            kind, tr = 0, rem      # no static friction: nothing to stick to
            y1, v1 = osc(m, c, k, y0, v, tr)
        tmin = 0.0
        if not hit:
            if fresh and kind == 1 and rem > tr + memo_span:
                st.memo_valid = 1
                st.memo_s = s
                st.memo_x = x
                st.memo_v = V
                st.memo_muk = muk
                st.memo_n = N
                st.memo_slip_time = tr
                st.memo_x_restick = y1
        if work:
            if under and c != 0.0 and tr > 0.0:
                wdmp += _damping_work_u(c, sig, wn2, wd, y0, v, tr)
            else:
                wdmp += osc_damping_work(m, c, k, y0, v, tr)
            wf += F * (y1 - y0)
        x = y1 + xeq
        v = v1
        t += tr
        if kind == 0:
            t = h
            break
        fst = k * x + c * V
        thr = mus * N
        # Re-stick if static friction holds the pad: the stick force well inside the limit, or at the limit
        # and moving inwards (the stick lasts; at the limit and moving outwards it would end at once, a
        # stick of zero length). No static friction at all (N = 0 or mu_s = 0): never again.
        afs = abs(fst)
        if thr > 0.0 and (afs <= (_ADMIT if kind == 1 else _ADMIT_TOUCH) * thr
                          or (fst * V <= 0.0 and afs <= thr * (1.0 + 1e-12))):
            phase = 0.0
            # re-stick: the pad takes the surface velocity (|v - V| ~ 1e-15 m/s)
            v = V
            age = 0.0
        elif kind == 1:
            # the pad passes the surface speed: the friction turns; after a located crossing the slip goes
            # on from w = 0 (the root's residual |v - V| would otherwise read as a crossing back at once)
            s = -s
            if tr > 0.0:
                v = V
        else:
            # grazing touch that is not a re-stick: keep slipping past it; the
            # next touch or crossing is at least one extremum (pi / omega_d) away
            tmin = 0.5 * math.pi * math.sqrt(m / k)
    st.v = v
    if work:
        st.work_friction = wf
        st.work_damping = wdmp
    _finish_tick(st, x, phase, s, age, k, c, V, N, muk, n_ev - nev0)
    return n_ev


# ================================================================ jump model
@njit(cache=True)
def _restick_peak_reaches(sig, wn2, wd, e, s, y0, V):
    """Decide ``s (v_pk - V) >= 0`` of :func:`jump_restick` without locating the peak, where that is certain.

    The free slip from ``(y0, V)`` (under-damped) has ``v(t) = exp(-sig t) (V cos wd t - B sin wd t)``,
    ``B = (wn2 y0 + sig V) / wd``; at every acceleration zero ``|v| = D exp(-sig t)`` with
    ``D = sqrt(V^2 + B^2) wd / wn`` (there ``tan(wd t + phi) = -sig / wd``), and half a period later
    ``v`` is ``-e`` times its value (``e = exp(-sig pi / wd)``). The first zero ``tz1`` lies in
    ``(0, pi / wd]``, so ``|v(tz1)| >= D e`` and ``|v_pk| = e |v(tz1)| >= D e^2``. Up to ``tz1`` the
    acceleration keeps the sign of ``a0``, so ``v(tz1) - V`` has that sign, and so has ``v(tz1)``
    once ``|v(tz1)| > |V|``; then ``v_pk`` has the sign of ``-a0``. Returns 1 (the peak reaches ``V``)
    or -1 (it does not) when ``|v_pk|`` exceeds ``|V|`` by a relative margin of 1e-6 (far above the
    rounding of either computation), the start lies at least ~1e-3 rad of phase from an
    acceleration zero and ``D e^2`` is not below 1e-3 of the velocity amplitude; 0 otherwise (the
    caller then locates the peak as before). Decides exactly as locating it does.
    """
    a0 = -2.0 * sig * V - wn2 * y0
    j0 = -2.0 * sig * a0 - wn2 * V
    bb = (j0 + sig * a0) / wd
    if not (a0 * a0 > 1e-6 * (a0 * a0 + bb * bb)):
        return 0
    B = (wn2 * y0 + sig * V) / wd
    R2 = V * V + B * B
    e4 = (e * e) * (e * e)
    lo2 = R2 * (wd * wd / wn2) * e4 * (1.0 - 1e-9)
    if not (lo2 > 1e-6 * R2 and lo2 * (1.0 - 1e-6) > V * V):
        return 0
    return 1 if s * a0 < 0.0 else -1


@njit(cache=True)
def jump_restick(m, c, k, s, xb, V, muk, N):
    """Closed-form slip outcome of the quasi-static jump model.

    From breakaway at spring stretch ``xb`` with pad velocity ``V``, the free
    slip ``m x'' + c x' + k x = s mu_k N`` is evaluated at
    ``t_pi = pi / omega_d`` and corrected by one Newton step towards the
    re-stick condition ``x' = V``. Returns ``(slip_time, x_restick)``;
    ``slip_time = inf`` means no re-stick (steady sliding): over-damped pad,
    or the overshoot too small to bring the pad back to the surface speed
    (always the case for delta_mu = 0 with c > 0).
    For V -> 0 this gives ``f_restick = mu_k N - (mu_s - mu_k) N exp(-zeta pi / sqrt(1 - zeta^2))``.
    """
    sig = 0.5 * c / m
    wn2 = k / m
    disc = sig * sig - wn2
    if disc >= -1e-10 * wn2:
        return np.inf, xb
    wd = math.sqrt(-disc)
    xeq = s * muk * N / k
    y0 = xb - xeq
    tp = math.pi / wd
    e = math.exp(-sig * tp)
    yp = -e * y0
    vp = -e * V
    ap = -2.0 * sig * vp - wn2 * yp
    if s * ap <= 0.0:
        return np.inf, xb
    # re-stick exists only if the velocity peak after the first minimum reaches V
    ok = _restick_peak_reaches(sig, wn2, wd, e, s, y0, V)
    if ok < 0:
        return np.inf, xb
    if ok == 0:
        tz1 = _next_acc_zero(m, c, k, y0, V, 0.0)
        if tz1 == np.inf:
            return np.inf, xb
        _, vpk = osc(m, c, k, y0, V, tz1 + math.pi / wd)
        if s * (vpk - V) < 0.0:
            return np.inf, xb
    dt = (V - vp) / ap
    if abs(dt) * wd > 0.5 * math.pi:
        return np.inf, xb
    xr = xeq + yp + vp * dt + 0.5 * ap * dt * dt
    return tp + dt, xr


@njit(cache=True)
def jump_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    if _stuck_whole_tick(st, prm, h, V, N, mus, False):
        return n_ev
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    B = prm.burst_gain * gain
    tmax = prm.max_stick_period
    x = st.x
    phase = st.phase
    s = st.s
    age = st.age
    tsl = st.slip_left
    t = 0.0
    nev0 = n_ev
    it = 0
    it_cap = phase_cap(m, c, k, h)
    while t < h:
        it += 1
        if it > it_cap:
            st.truncated += 1
            break
        rem = h - t
        if phase == 0.0:
            thr = mus * N
            f = k * x + c * V
            dt, brk, forced = _stick_span(f, V, thr, k, tmax, age, rem)
            if dt > 0.0:
                x += V * dt
                if V != 0.0:
                    age += dt
            if not brk:
                t = h
                break
            t += dt
            f = k * x + c * V
            s, x = _breakaway(x, f, V, forced, mus, N, k, c)
            n_ev = _record(ev_t, ev_a, n_ev, t0 + t, B * abs(k * x))
            # jump_restick is a pure function: steady strokes repeat its inputs exactly, so the
            # last result is reused when they do (same bits in, same bits out)
            if st.memo_valid != 0 and st.memo_s == s and st.memo_x == x and st.memo_v == V \
                    and st.memo_muk == muk and st.memo_n == N:
                tsl = st.memo_slip_time
                xr = st.memo_x_restick
            else:
                tsl, xr = jump_restick(m, c, k, s, x, V, muk, N)
                st.memo_valid = 1
                st.memo_s = s
                st.memo_x = x
                st.memo_v = V
                st.memo_muk = muk
                st.memo_n = N
                st.memo_slip_time = tsl
                st.memo_x_restick = xr
            if thr <= 0.0 or abs(k * xr + c * V) > thr:
                tsl = np.inf
            st.x_restick = xr
            phase = 1.0
            age = 0.0
            continue
        # ---- slip: count down the closed-form slip time, or slide steadily
        if tsl == np.inf:
            x = s * muk * N / k
            if s * V <= 0.0:
                phase = 0.0
                age = 0.0
                continue
            t = h
            break
        if tsl > rem:
            tsl -= rem
            t = h
            break
        t += tsl
        tsl = 0.0
        x = st.x_restick
        phase = 0.0
        age = 0.0
    st.v = V
    st.slip_left = tsl
    _finish_tick(st, x, phase, s, age, k, c, V, N, muk, n_ev - nev0)
    return n_ev


# ================================================================ karnopp
@njit(cache=True)
def karnopp_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    """Modified Karnopp virtual spring (Provancher and Sylvester), every event located inside the tick.

    ``st.x`` is the spring stretch ``z`` (finger minus anchor), the friction
    force ``f = k_K z``. Continuous-time rules, with the finger speed ``V``
    and the normal force ``N`` constant within a tick:

    * stuck: ``z' = V``; breakaway (the burst event, amplitude ``B mu_s N``)
      when ``|k_K z|`` reaches ``mu_s N``, at the exact time
      ``t_b = (s mu_s N / k_K - z) / V`` inside the tick;
    * sliding: the force drops to ``mu_k N`` (``z = s mu_k N / k_K``) and
      the anchor is dragged behind the finger while ``|V| >= v_T`` and the
      finger keeps moving in the slip direction ``s``;
    * re-stick, force preserved: when ``|V| < v_T`` (at once after a
      breakaway, so a slow finger plays a sawtooth with period
      ``(mu_s - mu_k) N / (k_K |V|)``, every tooth inside the tick) or when
      the finger reverses (the spring unstretches first). Speed changes
      happen only at tick boundaries, so re-sticks there are exact too.

    Event times therefore do not depend on the tick rate.
    """
    kk = prm.karnopp_spring
    vt = prm.karnopp_v_threshold
    B = prm.burst_gain * gain
    z = st.x
    phase = st.phase
    s = st.s
    nev0 = n_ev
    thr = mus * N
    zk = muk * N / kk            # stretch while sliding (anchor dragged)
    drops = kk * zk < thr        # a breakaway lowers the force (mu_k < mu_s): a slow finger sticks again
    if phase == 1.0 and ((abs(V) < vt and drops) or V * s <= 0.0):
        phase = 0.0              # stuck again, force preserved (slow finger, or a reversal)
    t = 0.0
    it = 0
    while t < h and phase == 0.0:
        it += 1
        if it > MAX_EVENTS_PER_TICK:
            st.truncated += 1
            break
        rem = h - t
        if abs(kk * z) > thr * (1.0 + 1e-12) or (thr == 0.0 and z != 0.0):
            tb = 0.0             # over the limit already (N dropped): breakaway at once
            sb = _sgn(z)
        elif V == 0.0:
            break
        else:
            sb = _sgn(V)
            tb = (sb * thr / kk - z) / V
            if tb < 0.0:
                tb = 0.0
            if tb >= rem:
                z += V * rem
                break
        t += tb
        s = sb
        n_ev = _record(ev_t, ev_a, n_ev, t0 + t, B * thr)
        z = s * zk
        if V * s > 0.0 and (abs(V) >= vt or not drops):
            phase = 1.0          # sliding: the anchor is dragged behind the finger
    if phase == 1.0:
        z = s * zk
    st.x = z
    st.v = V
    st.phase = phase
    st.s = s
    st.f = kk * z
    st.n_events = n_ev - nev0
    return n_ev


# ================================================================ stribeck
# Every Stribeck kernel below is compiled with fused multiply-add allowed (_STRIBECK_FASTMATH: "contract", nothing else:
# no reordering, no assumption that values are finite); a product and a sum then round once where the
# processor has the instruction (physics.md: what that moves). The small functions on the slip's chain are
# forceinline: LLVM in-lines them as the caller compiles (numba's own in-lining tripled the first compile).
_STRIBECK_FASTMATH = {"contract"}


@njit(cache=True, fastmath=_STRIBECK_FASTMATH)
def stribeck_mu(vr_abs, W, mus, muk, a, b, p, d, variant):
    """Friction coefficient of the Imaizumi pad at relative speed |vr| (m/s), load W (N).

    variant 0: ``mu = mu_k + (mu_s - mu_k) exp(-a |vr|/W) + b |vr|/W``;
    variant 1 (pre-maximum static region): ``mu = p |vr|/W`` below
    ``|vr|/W < d``, then the Stribeck curve shifted by ``d``.
    Returns ``(mu, dmu/d|vr|)``.
    """
    if W <= 0.0:
        return 0.0, 0.0
    u = vr_abs / W
    if variant == 1:
        if u < d:
            return p * u, p / W
        u = u - d
    e = math.exp(-a * u)
    return muk + (mus - muk) * e + b * u, (-(mus - muk) * a * e + b) / W


@njit(cache=True, fastmath=_STRIBECK_FASTMATH)
def _contactor(prm, t):
    """Contactor position, velocity and acceleration ``A sin(w t)`` and its derivatives at ``t``."""
    A = prm.contactor_amplitude
    w = prm.contactor_omega
    if A == 0.0:
        return 0.0, 0.0, 0.0
    sn = math.sin(w * t)
    return A * sn, A * w * math.cos(w * t), -A * w * w * sn


# ---------------------------------------------------------------- elementary functions of the kernels' own
@intrinsic
def _f64_from_bits(typingctx, bits):
    """The float64 whose IEEE 754 bits are the int64 ``bits`` (compiled code only)."""
    if not isinstance(bits, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


@intrinsic
def _bits_of_f64(typingctx, x):
    """The IEEE 754 bits of the float64 ``x`` as an int64 (compiled code only)."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


#: :func:`_exp`'s constants: the bits of 2^(j / 256), j = 0 ... 255; 256 / ln 2; ln 2 / 256 split in two
#: (Cody and Waite, fdlibm's split of ln 2: the high part has 32 significant bits, n * hi is exact for
#: |n| < 2^21); 1.5 * 2^52, whose addition rounds x 256 / ln 2 to an integer n in the low bits
_EXP2_256_BITS = np.array([np.float64(2.0 ** (j / 256)).view(np.int64) for j in range(256)], dtype=np.int64)
_INV_LN2_256 = 256.0 / math.log(2.0)
_LN2_256_HI = float.fromhex("0x1.62e42feep-9")
_LN2_256_LO = float.fromhex("0x1.a39ef35793c76p-41")
_EXP_SHIFT = 1.5 * 2.0 ** 52
_EXP_SHIFT_BITS = int(np.float64(_EXP_SHIFT).view(np.int64))


@njit(cache=True, forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _exp(x):
    """``e^x`` of the Stribeck kernels' own, within 1 ulp (measured quicker in the slip steps than libm's).
    ``x = (256 m + j) ln 2 / 256 + r``,
    ``|r| <= ln 2 / 512``: ``2^m 2^(j / 256) (1 + p(r))``, ``p`` the series of ``e^r - 1`` to ``r^4``
    (truncation below 4e-17). Below x = -708 (3.3e-308, near the smallest normal number) 0, above 709.78
    infinite."""
    if x < -708.0:
        return 0.0
    if x > 709.78:
        return math.inf
    kd = x * _INV_LN2_256 + _EXP_SHIFT
    n = _bits_of_f64(kd) - _EXP_SHIFT_BITS
    kd -= _EXP_SHIFT
    r = (x - kd * _LN2_256_HI) - kd * _LN2_256_LO
    r2 = r * r
    p = r + r2 * ((0.5 + r * (1.0 / 6)) + r2 * (1.0 / 24))
    sc = _f64_from_bits(_EXP2_256_BITS[n & 255] + ((n >> 8) << 52))
    return sc + sc * p


#: The minimax polynomials of cos and sin on [-pi/4, pi/4] (fdlibm's __kernel_cos and __kernel_sin, within
#: 1 ulp there) for :func:`_cos_sin`
_COS_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
          -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)
_SIN_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
          2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)


#: pi / 2 split for :func:`_cos_sin`'s reduction (fdlibm's: the high part has 33 significant bits, so n * hi is
#: exact for |n| < 2^20), and 2 / pi
_PIO2_HI = 1.57079632673412561417e+00
_PIO2_LO = 6.07710050650619224932e-11
_INV_PIO2 = 2.0 / math.pi


@njit(cache=True, forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _cos_sin_kernel(x):
    """``(cos x, sin x)`` for |x| <= pi/4 (a little beyond: the reduction's rounding) by the minimax polynomials."""
    C1, C2, C3, C4, C5, C6 = _COS_C
    S1, S2, S3, S4, S5, S6 = _SIN_S
    z = x * x
    w = z * z
    r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6))
    hz = 0.5 * z
    c = 1.0 - hz
    c = c + (((1.0 - c) - hz) + z * r)
    rs = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6)
    return c, x + z * x * (S1 + z * rs)


@njit(cache=True, forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _cos_sin(x):
    """``(cos x, sin x)`` of the Stribeck kernels' own (measured quicker there than libm's): the minimax
    polynomials after a reduction by the nearest
    multiple n pi / 2 (Cody and Waite, |x| < 1.6e6 rad: 250 000 periods, 7.9 h of a 9 Hz contactor; an
    absolute error below 2e-16 + |n| 1e-26), else libm's."""
    if abs(x) <= 0.7853981633974483:
        return _cos_sin_kernel(x)
    if not abs(x) < 1.6e6:
        return math.cos(x), math.sin(x)
    nd = math.floor(x * _INV_PIO2 + 0.5)
    c, s = _cos_sin_kernel((x - nd * _PIO2_HI) - nd * _PIO2_LO)
    q = int(nd) & 3
    if q == 0:
        return c, s
    if q == 1:
        return -s, c
    if q == 2:
        return -c, -s
    return s, -c


# ---------------------------------------------------------------- plain Stribeck curve: Taylor slip steps
#: Highest order of the Taylor slip step (coefficients kept per step; the step picks its order below it).
STRIBECK_MAX_ORDER = 14
_STRIBECK_SAMPLES = 4    # sign checks of the relative speed per step (a touch inside one step is seen)
#: Taylor steps per slip call before the linearised fallback takes over (a load so light that the curve's
#: drop needs steps far shorter than the pad's time scales; bounded work per tick instead of the step cap)
_STRIBECK_MAX_TAYLOR_STEPS = 20_000


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _free_speed_scale(V, A, om, mus, W, k, m):
    """The speed scale of a slip: the drive's speeds plus the free oscillation's ``mu_s W / sqrt(k m)``."""
    return abs(V) + A * om + mus * W / math.sqrt(k * m)


@njit(cache=True, error_model="numpy", fastmath=_STRIBECK_FASTMATH)
def _stribeck_series(prm, W, V, mus, muk, sr, t, u, z, hcap, co):
    """Taylor coefficients of a slip of the plain Stribeck curve about ``t``; returns ``(p, h)``.

    Slip with the relative velocity ``vr = z + V - x_c'(t)`` of sign ``sr``:
    ``u' = z``, ``m z' = -c z - k u - sr W mu(sr vr)``, ``mu(q) = mu_k +
    (mu_s - mu_k) exp(-a q / W) + b q / W``. The normalised coefficients
    (``x_j = x^(j)(t) / j!``) of ``u``, ``z``, ``vr``, the exponent and its
    exponential go to ``co[0..4, j]`` by the recurrences of automatic
    differentiation (``E = exp(g)``: ``j E_j = sum_i i g_i E_(j-i)``; the
    contactor's ``A omega cos(omega t)`` in closed form). ``p`` is the order
    used, ``h`` the step (at most ``hcap``) whose last terms stay below
    ``prm.stribeck_tol`` of the pad's scales: the truncation error of the
    step and of its dense output (the polynomial itself) anywhere inside it.
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    a = prm.stribeck_a
    b = prm.stribeck_b
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    dmu = mus - muk
    C = 0.0
    S = 0.0
    if A != 0.0:
        C = math.cos(om * t)
        S = math.sin(om * t)
    us = 1.0 / (mus * W / k + abs(u) + 1e-300)
    zs = 1.0 / (_free_speed_scale(V, A, om, mus, W, k, m) + abs(z) + 1e-300)
    tol = prm.stribeck_tol
    pmax = STRIBECK_MAX_ORDER
    co[0, 0] = u
    co[1, 0] = z
    cw = A * om
    fric = W > 0.0
    # the exponential's rate; infinite for a vanishing load (the drop to mu_k happens at once: E = 0)
    sa = -a * sr / W if fric else 0.0
    # the drop's force is at most (mu_s - mu_k) W: left out where it is below round-off of the other forces
    # (a vanishing load; its exponential would vary faster than any step resolves)
    drop = fric and math.isfinite(sa) and dmu * W > 1e-17 * (k * abs(u) + c * abs(z) + abs(b * (z + V)) + A * om * k)
    e_prev = 1.0
    p = pmax
    hc = hcap
    hp = 1.0         # hc ** j, kept by multiplication (hc ** (j + 1) after the update below)
    flat = False
    for j in range(pmax + 1):
        r = j & 3
        cj = C if r == 0 else (-S if r == 1 else (-C if r == 2 else S))
        vr = co[1, j] - cw * cj
        cw *= om / (j + 1)
        if j == 0:
            vr += V
        co[2, j] = vr
        if j == pmax:
            break
        if fric:
            # friction -sr W mu = -sr W (mu_k + (mu_s - mu_k) E) - b vr
            E = 0.0
            if drop:
                g = sa * vr
                co[3, j] = g
                if j == 0:
                    E = math.exp(g)
                    if g < -700.0:
                        # far down the curve (E < 1e-304): E stays 0 over a step short enough that the
                        # exponent cannot climb by 100 (its higher terms would only overflow here)
                        flat = True
                        drop = False
                        E = 0.0
                else:
                    acc = 0.0
                    for i in range(1, j + 1):
                        acc += i * co[3, i] * co[4, j - i]
                    E = acc / j
            co[4, j] = E
            fr = -sr * W * ((muk if j == 0 else 0.0) + dmu * E) - b * vr
        else:
            fr = 0.0
        co[0, j + 1] = co[1, j] / (j + 1)
        co[1, j + 1] = (fr - c * co[1, j] - k * co[0, j]) / (m * (j + 1))
        if flat and j == 0:
            # the exponent's rate from the relative acceleration (the contactor's included)
            g1 = sa * (co[1, 1] + A * om * om * S)
            if g1 > 0.0 and 100.0 / g1 < hc:
                hc = 100.0 / g1
                hp = 1.0
        # a short step (the rest of a tick) needs fewer terms: stop once two terms are negligible
        e = max(abs(co[0, j + 1]) * us, abs(co[1, j + 1]) * zs)
        hp_prev = hp
        hp *= hc
        if j >= 3:
            if e * hp <= tol and e_prev * hp_prev <= tol and math.isfinite(co[1, j + 1] + co[0, j + 1]):
                p = j + 1
                # vr's coefficient of the last order
                r = p & 3
                cj = C if r == 0 else (-S if r == 1 else (-C if r == 2 else S))
                co[2, p] = co[1, p] - cw * cj
                return p, hc
        e_prev = e
    # full order: the step from the last two terms (Jorba & Zou); an overflow anywhere reaches the last
    # terms (each order is built from all lower ones) and gives no step
    e1 = max(abs(co[0, p - 1]) * us, abs(co[1, p - 1]) * zs)
    e2 = max(abs(co[0, p]) * us, abs(co[1, p]) * zs)
    if not (math.isfinite(e1) and math.isfinite(e2) and math.isfinite(co[2, p])):
        return p, 0.0
    h1 = (tol / e1) ** (1.0 / (p - 1)) if e1 > 0.0 else math.inf
    h2 = (tol / e2) ** (1.0 / p) if e2 > 0.0 else math.inf
    return p, min(h1, h2, hc)


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _plain_friction(vr_abs, W, mus, muk, a, b):
    """``(W mu, W dmu/d|vr|)`` of the plain Stribeck curve at relative speed ``vr_abs`` (N, N s/m).

    Written without ``b |vr| / W`` so that a vanishing load stays finite
    (the viscous term ``b |vr|`` does not vanish with W).
    """
    if not W > 0.0:
        return 0.0, 0.0
    e = math.exp(-a * vr_abs / W) if vr_abs > 0.0 else 1.0
    return W * (muk + (mus - muk) * e) + b * vr_abs, b - (mus - muk) * a * e


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _horner(co, row, p, tau):
    acc = co[row, p]
    for j in range(p - 1, -1, -1):
        acc = acc * tau + co[row, j]
    return acc


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _horner_d(co, row, p, tau):
    """Value and derivative of the polynomial ``co[row, :p+1]`` at ``tau``."""
    acc = co[row, p]
    d = 0.0
    for j in range(p - 1, -1, -1):
        d = d * tau + acc
        acc = acc * tau + co[row, j]
    return acc, d


@njit(cache=True, error_model="numpy", fastmath=_STRIBECK_FASTMATH)
def _series_root(co, p, sr, lo, hi):
    """Root of ``sr * vr`` (row 2 of ``co``) in ``(lo, hi]`` with ``sr vr(lo) > 0 >= sr vr(hi)``: safeguarded Newton."""
    t = hi
    for _ in range(100):
        f, d = _horner_d(co, 2, p, t)
        f *= sr
        d *= sr
        if f > 0.0:
            lo = t
        else:
            hi = t
        tn = t - f / d if d != 0.0 else 0.5 * (lo + hi)
        if not (lo < tn <= hi):
            tn = 0.5 * (lo + hi)
        if abs(tn - t) <= 1e-16 * (1.0 + abs(t)) or hi - lo <= 1e-17 + 1e-16 * hi:
            return tn
        t = tn
    return hi


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _stick_force(prm, V, ua, xca, Ca, Sa, ta, t):
    """Stuck on the contactor since ``ta`` (stretch ``ua``, contactor at ``xca``, its phase ``(cos, sin)`` there
    ``(Ca, Sa)``): ``(u, z, F, F')`` at ``t``.

    ``F = m x_c'' + c z + k u`` is the friction needed to keep the pad on the contactor. The contactor's
    phase at ``t`` is the one at ``ta`` turned by ``omega (t - ta)`` (a short angle over a tick: no reduction).
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    xc = 0.0
    dxc = 0.0
    ddxc = 0.0
    dddxc = 0.0
    if A != 0.0:
        cd, sd = _cos_sin(om * (t - ta))
        cs = Ca * cd - Sa * sd
        sn = Sa * cd + Ca * sd
        xc = A * sn
        dxc = A * om * cs
        ddxc = -A * om * om * sn
        dddxc = -A * om * om * om * cs
    u = ua + (xc - xca) - V * (t - ta)
    z = dxc - V
    return u, z, m * ddxc + c * z + k * u, m * dddxc + c * ddxc + k * z


@njit(cache=True, error_model="numpy", forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _stribeck_stick(prm, V, thr, ua, ta, te, newton_stop):
    """Stick from ``ta`` (stretch ``ua``) to at most ``te``: the first time ``|F|`` exceeds ``thr``, or ``te``.

    Returns ``(t, broke, u, z, F)`` with the state and the needed friction at
    ``t``. ``F(t)`` is a sinusoid plus a linear function,
    ``|F''| <= A omega^2 sqrt((k - m omega^2)^2 + (c omega)^2)``: most ticks
    are cleared at once by ``|F(te)| + |F'(te)| dt + |F''| dt^2 / 2 <= thr``
    (Taylor's bound back from the end); otherwise pieces whose ends lie below
    ``thr`` by more than ``|F''| dt^2 / 8`` cannot reach it, the others are
    quartered (to 1e-13 s, a grazing touch) and a crossing is polished by
    safeguarded Newton (to ~1e-16 s). ``newton_stop``: a Newton step within
    that ends the polish even where it falls on an end of the bracket (the
    default tolerance's Taylor steps keep the polish as it was, which then
    bisects the bracket down to 1e-16 s: the same root to rounding, at
    about twenty evaluations more per breakaway). An evaluation at a time
    evaluated before (the tick's end, a piece's end where the polish starts,
    the polish's last point) is taken from it.
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    Ca = 1.0
    Sa = 0.0
    if A != 0.0:
        Ca, Sa = _cos_sin(om * ta)
    xca = A * Sa
    fpp = A * om * om * math.sqrt((k - m * om * om) ** 2 + (c * om) ** 2) if A != 0.0 else 0.0
    ue, ze, Fe, dFe = _stick_force(prm, V, ua, xca, Ca, Sa, ta, te)
    dt = te - ta
    if abs(Fe) + abs(dFe) * dt + 0.5 * fpp * dt * dt <= thr:
        return te, False, ue, ze, Fe
    u, z, Fa, _ = _stick_force(prm, V, ua, xca, Ca, Sa, ta, ta)
    if abs(Fa) > thr:
        return ta, True, u, z, Fa
    # (u, z, Fl, dFl) the last evaluation, at tl
    tl = ta
    Fl = Fa
    dFl = 0.0
    x = ta
    tb = te
    broke = False
    for _ in range(100_000):
        if x >= te:
            break
        if dt > te - x:
            dt = te - x
        xb = x + dt
        if xb == te:
            u, z, Fl, dFl = ue, ze, Fe, dFe
        else:
            u, z, Fl, dFl = _stick_force(prm, V, ua, xca, Ca, Sa, ta, xb)
        tl = xb
        Fb = Fl
        if abs(Fb) > thr:
            # crossing in (x, xb]: root of |F| - thr (one crossing: the piece's curvature is small)
            lo = x
            hi = xb
            sg = 1.0 if Fb > 0.0 else -1.0
            tt = hi
            tb = hi
            for _ in range(100):
                if tt != tl:
                    u, z, Fl, dFl = _stick_force(prm, V, ua, xca, Ca, Sa, ta, tt)
                    tl = tt
                f = sg * Fl - thr
                if f > 0.0:
                    hi = tt
                else:
                    lo = tt
                tn = tt - f / (sg * dFl) if dFl != 0.0 else 0.5 * (lo + hi)
                if newton_stop and abs(tn - tt) <= 1e-16 * (1.0 + abs(tt)):
                    # converged (a Newton step within rounding of the root that may fall on the bracket's end)
                    tb = tn
                    break
                if not (lo < tn <= hi):
                    tn = 0.5 * (lo + hi)
                if abs(tn - tt) <= 1e-16 * (1.0 + abs(tt)) or hi - lo <= 1e-16 * (1.0 + abs(hi)):
                    tb = tn
                    break
                tt = tn
                tb = hi
            broke = True
            break
        if max(abs(Fa), abs(Fb)) + 0.125 * fpp * dt * dt <= thr or dt <= 1e-13:
            x = xb
            Fa = Fb
            dt *= 2.0
        else:
            dt *= 0.25
    if not broke:
        tb = x if x < te else te
    if tb != tl:
        u, z, Fl, _ = _stick_force(prm, V, ua, xca, Ca, Sa, ta, tb)
    return tb, broke, u, z, Fl


@njit(cache=True, error_model="numpy", fastmath=_STRIBECK_FASTMATH)
def _stribeck_lin_step(prm, u, z, sr, V, W, mus, muk, t, te):
    """One linearised exponential slip step (the fallback where no accurate step resolves the curve's drop).

    The friction is linearised about the start and the oscillator solved in
    closed form over at most ``prm.substep`` (and half the self-excitation's
    time constant): bounded and finite, not tolerance-exact. Returns
    ``(u, z, sr, stuck, t)``; a zero of the relative speed at the end
    re-sticks (needed friction within ``mu_s W``) or reverses the slip.
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    vr0 = (z - (A * om * math.cos(om * t) if A != 0.0 else 0.0)) + V
    muW, dmuW = _plain_friction(max(sr * vr0, 0.0), W, mus, muk, prm.stribeck_a, prm.stribeck_b)
    ceff = c + dmuW
    hs = min(te - t, prm.substep)
    if ceff < 0.0:
        hs = min(hs, 0.5 * m / (-ceff))
    dxcm = A * om * math.cos(om * (t + 0.5 * hs)) if A != 0.0 else 0.0
    ueq = (-sr * muW - dmuW * (V - dxcm - vr0)) / k
    y1, z = osc(m, ceff, k, u - ueq, z, hs)
    u = y1 + ueq
    t = t + hs if t + hs < te else te
    dxc = A * om * math.cos(om * t) if A != 0.0 else 0.0
    if sr * (z + V - dxc) < 0.0:
        ddxc = -A * om * om * math.sin(om * t) if A != 0.0 else 0.0
        if abs(m * ddxc + c * (dxc - V) + k * u) <= mus * W:
            return u, dxc - V, sr, True, t
        sr = -sr
    return u, z, sr, False, t


#: How far a Taylor step's polynomial may miss the equation of motion at its end before the step is taken again,
#: shorter: the speed's rate of the polynomial against the one the state there implies, times the step, in
#: tolerances of the speed scale. A step truncated as the series prescribes misses by about (p + 1) of its last
#: term, far below this; it catches a step whose last terms are small while the series no longer holds (on a pad
#: with almost no sliding damping a 0.2 ms step ran into the collapse to re-stick, its speed 3.2e-3 m/s off)
_TAYLOR_DEFECT_TOLS = 1e3


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _taylor_defect_ok(prm, co, p, tau, sr, V, W, mus, muk, t, u0, z0):
    """Whether the step's polynomial at ``tau`` satisfies ``m z' = F - c z - k u`` within
    :data:`_TAYLOR_DEFECT_TOLS` tolerances of the speed scale (over the step), with ``(u, z)`` there."""
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    u1 = _horner(co, 0, p, tau)
    z1, zd = _horner_d(co, 1, p, tau)
    vr1 = z1 + V - (A * om * math.cos(om * (t + tau)) if A != 0.0 else 0.0)
    fr = 0.0
    if W > 0.0:
        x = -prm.stribeck_a * sr * vr1 / W
        E = math.exp(x) if x > -700.0 else 0.0
        fr = -sr * W * (muk + (mus - muk) * E) - prm.stribeck_b * vr1
    d = abs(zd - (fr - c * z1 - k * u1) / m) * tau
    zsc = _free_speed_scale(V, A, om, mus, W, k, m) + abs(z0)
    return d <= _TAYLOR_DEFECT_TOLS * prm.stribeck_tol * zsc, u1, z1


@njit(cache=True, error_model="numpy", fastmath=_STRIBECK_FASTMATH)
def _stribeck_taylor_slip(prm, u, z, sr, V, W, mus, muk, t, te):
    """Slip of the plain Stribeck curve from ``t`` to at most ``te`` by Taylor steps.

    Returns ``(u, z, sr, stuck, t)``: ``stuck`` True at a re-stick (the
    relative speed reaches zero, located on the step's polynomial by
    safeguarded Newton, with the needed friction within ``mu_s W``); a zero
    with more friction needed reverses the slip.
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    hmin = 1e-6 * math.sqrt(m / k)
    co = np.empty((5, STRIBECK_MAX_ORDER + 1))     # the step's Taylor coefficients (see _stribeck_series)
    # a step's polynomial checked against the equation of motion where it ends (see _taylor_defect_ok): a step
    # whose last terms are small although the series no longer holds is shortened (hlim) and taken again
    hlim = math.inf
    for it in range(MAX_EVENTS_PER_TICK):
        if t >= te:
            break
        p, hs = _stribeck_series(prm, W, V, mus, muk, sr, t, u, z, min(te - t, prm.substep, hlim), co)
        if not (hs >= hmin) or it >= _STRIBECK_MAX_TAYLOR_STEPS:
            # the series cannot follow the friction curve here (its exponential varies on a time scale far
            # below the pad's: absurd speeds, micronewton loads): a linearised exponential step keeps the
            # state bounded
            u, z, sr, stuck, t = _stribeck_lin_step(prm, u, z, sr, V, W, mus, muk, t, te)
            if stuck:
                return u, z, sr, True, t
            continue
        # first sign change of sr * vr over the step
        lo = 0.0
        flo = sr * co[2, 0]
        root = -1.0
        for i in range(1, _STRIBECK_SAMPLES + 1):
            tau = hs * i / _STRIBECK_SAMPLES
            f = sr * _horner(co, 2, p, tau)
            if f <= 0.0:
                if flo > 0.0:
                    root = _series_root(co, p, sr, lo, tau)
                elif i == 1 and flo == 0.0:
                    root = 0.0      # starting at vr = 0 and moving the other way
                break
            lo = tau
            flo = f
        if root != 0.0:
            tau = hs if root < 0.0 else root
            ok, u1, z1 = _taylor_defect_ok(prm, co, p, tau, sr, V, W, mus, muk, t, u, z)
            if not ok:
                hlim = 0.5 * tau
                continue
            hlim = math.inf
            u = u1
            z = z1
            if root < 0.0:
                t = t + hs if t + hs < te else te
                continue
            t += root
        # relative speed zero: re-stick if the friction needed to follow the contactor is admissible
        ddxc = -A * om * om * math.sin(om * t) if A != 0.0 else 0.0
        dxc = A * om * math.cos(om * t) if A != 0.0 else 0.0
        Fst = m * ddxc + c * (dxc - V) + k * u
        if abs(Fst) <= mus * W:
            return u, dxc - V, sr, True, t
        # more friction needed than the static limit: the slip goes on in the direction the force drives
        srn = -1.0 if Fst > 0.0 else 1.0
        if srn == sr and root == 0.0:
            # a touch of zero at the step's start (a breakaway exactly at the limit): take the step as it is
            u = _horner(co, 0, p, hs)
            z = _horner(co, 1, p, hs)
            t = t + hs if t + hs < te else te
            continue
        sr = srn
    return u, z, sr, False, t


# ---------------------------------------------------------------- plain Stribeck curve: exponential slip steps
#: Tolerances from this one up run the slip by exponential Rosenbrock steps (:func:`_stribeck_exp_slip`);
#: tighter ones by Taylor steps (high order pays off there; the exponential steps' event errors stop falling
#: with the tolerance near 1e-9 of the pad's scales, measured against Radau at rtol 1e-12).
STRIBECK_EXP_MIN_TOL = 3e-9
#: Weight of an exponential step's error estimate: the estimate (the change of the correction between the fits and
#: passes) is of the lower orders; weighted, event times stay within a tolerance of the event interval (measured)
EXP_ERR_WEIGHT = 10.0
#: The weight where the sliding pad is overdamped (c + b >= 2 sqrt(k m)) and the speed's error is measured against
#: the speed it reaches (see _stribeck_exp_slip): stick-slip periods within about half a tolerance (measured against
#: Radau: 0.01-0.10 on the contactor case, 0.01-0.37 with a twentieth of its damping, 3e-9 to 1e-3, 100 Hz to 10 kHz)
EXP_ERR_WEIGHT_OVERDAMPED = 3.0


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _expm1_minus_x(x):
    """``e^x - 1 - x``: its series below |x| = 0.25 (error below 1e-16 of the value; quicker than expm1), else
    through exp (the cancellation costs at most 4e-15 of the value there)."""
    if abs(x) < 0.25:
        # the series' eleven terms in Estrin's grouping: a short chain of dependent operations
        x2 = x * x
        x4 = x2 * x2
        x8 = x4 * x4
        lo = (0.5 + x * (1.0 / 6)) + x2 * (1.0 / 24 + x * (1.0 / 120))
        mid = (1.0 / 720 + x * (1.0 / 5040)) + x2 * (1.0 / 40320 + x * (1.0 / 362880))
        hi = (1.0 / 3628800 + x * (1.0 / 39916800)) + x2 * (1.0 / 479001600)
        return x2 * ((lo + x4 * mid) + x8 * hi)
    return (_exp(x) - 1.0) - x


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _lin_propagator(m, ce, k, h):
    """Propagator of ``m u'' + ce u' + k u = 0`` over ``h``: ``(p11, p12, p21, p22)`` with ``[u, u'](h) = P [u, u'](0)``.

    Any sign of ``ce`` (a negative one is the self-excitation of the
    Stribeck drop); real roots through ``expm1`` (exact to the critically
    damped limit), complex ones through their damped rotation.
    """
    sig = 0.5 * ce / m
    wn2 = k / m
    disc = sig * sig - wn2
    if disc >= 0.0:
        sq = math.sqrt(disc)
        if sig >= 0.0:
            r2 = -sig - sq
            r1 = wn2 / r2
        else:
            r1 = -sig + sq
            r2 = wn2 / r1
        e2 = _exp(r2 * h)
        # r1 - r2 = 2 sq: its reciprocal is computed beside the exponentials, not after them
        x = 2.0 * sq * h
        if x > 0.5:
            d = (_exp(r1 * h) - e2) * (0.5 / sq)    # no cancellation to speak of; exp is quicker than expm1
        else:
            if x < 0.05:
                d = e2 * h * (1.0 + x * (0.5 + x * (1.0 / 6 + x * (1.0 / 24 + x * (1.0 / 120 + x * (
                    1.0 / 720 + x * (1.0 / 5040 + x * (1.0 / 40320 + x * (1.0 / 362880)))))))))
            else:
                d = e2 * h * ((_exp(x) - 1.0) * (1.0 / x))
        return e2 - r2 * d, d, -wn2 * d, e2 + r1 * d
    wd = math.sqrt(-disc)
    e = _exp(-sig * h)
    cs, sn = _cos_sin(wd * h)
    d = e * sn / wd
    return e * cs + sig * d, d, -wn2 * d, e * cs - sig * d


#: Terms of the responses' series in :func:`_poly_basis` at most (|ce| h / m and wn h are at most 6 there) and
#: the reciprocals of n and n (n - 1) it takes
_SERIES_TERMS = 64
_INV_N = tuple([0.0] + [1.0 / n for n in range(1, _SERIES_TERMS)])
_INV_NN = tuple([0.0, 0.0] + [1.0 / (n * (n - 1)) for n in range(2, _SERIES_TERMS)])


#: Below |x| = 1/2 :func:`_phi234` sums phi_4's series (its twelve terms: truncation below 3e-16 of the value)
_PHI4_SERIES = tuple(1.0 / math.factorial(j + 4) for j in range(12))


@njit(cache=True, forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _phi234(x):
    """``(phi_2, phi_3, phi_4)(x)``, ``phi_k(x) = sum_j x^j / (j + k)!`` (``phi_0 = e^x``, ``x phi_(k+1) = phi_k -
    1 / k!``): below |x| = 1/2 phi_4 by its series and the others from it by the recurrence (no cancellation
    there), else from ``e^x`` up the recurrence (within 8.5e-14 of the exact series, the most near |x| =
    1/2)."""
    if abs(x) < 0.5:
        c0, c1, c2, c3, c4, c5, c6, c7, c8, c9, c10, c11 = _PHI4_SERIES
        x2 = x * x
        x4 = x2 * x2
        x8 = x4 * x4
        lo = (c0 + x * c1) + x2 * (c2 + x * c3)
        mid = (c4 + x * c5) + x2 * (c6 + x * c7)
        hi = (c8 + x * c9) + x2 * (c10 + x * c11)
        p4 = (lo + x4 * mid) + x8 * hi
        p3 = x * p4 + 1.0 / 6
        return x * p3 + 0.5, p3, p4
    return _phi234_of_exp(x, _exp(x))


@njit(cache=True, forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _phi234_of_exp(x, ex):
    """:func:`_phi234` at |x| >= 1/2 from ``ex = e^x``."""
    ix = 1.0 / x
    p2 = ((ex - 1.0) * ix - 1.0) * ix
    p3 = (p2 - 0.5) * ix
    return p2, p3, (p3 - 1.0 / 6) * ix


@njit(cache=True, forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _phi_basis(m, h, x1, x2):
    """:func:`_poly_basis`'s responses where the pad's linear part has real roots ``r1, r2`` far apart against the
    step: ``x_i = r_i h``, ``|x1 - x2| >= 1/4``. With the impulse response ``(e^(r1 t) - e^(r2 t)) / (m (r1 -
    r2))``, the response to ``s^p`` is ``u(h) = h^2 p! (phi_(p+1)(x1) - phi_(p+1)(x2)) / (m (x1 - x2))``, its rate
    ``h p! (phi_p(x1) - phi_p(x2)) / (m (x1 - x2))`` and at ``h / 2`` the same at half the arguments times
    ``2^-p``: divided differences of the phi functions, within 5e-13 of the matrix exponential's at that
    distance of the roots (where the polynomial particular solutions lose every digit, and the series takes tens
    of terms)."""
    if abs(x1) >= 1.0:
        # e^x1 as the square of e^(x1 / 2): one exponential for both
        e = _exp(0.5 * x1)
        c2, c3, _ = _phi234_of_exp(0.5 * x1, e)
        a2, a3, a4 = _phi234_of_exp(x1, e * e)
    else:
        a2, a3, a4 = _phi234(x1)
        c2, c3, _ = _phi234(0.5 * x1)
    b2, b3, b4 = _phi234(x2)
    d2, d3, _ = _phi234(0.5 * x2)
    g = h / (m * (x1 - x2))
    return (2.0 * h * g * (a3 - b3), 2.0 * g * (a2 - b2), 0.5 * g * (c2 - d2),
            6.0 * h * g * (a4 - b4), 6.0 * g * (a3 - b3), 0.75 * g * (c3 - d3))


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _basis_in_closed_form(m, ce, wn, h, tol):
    """Whether :func:`_poly_basis` takes a step of ``h`` in closed form (else by the phi functions or its series) at
    tolerance ``tol``.

    The closed form's polynomial particular solutions cancel on a step short
    against the pad's period: the response to ``s^3`` by about
    ``120 (1 / w^4 + sg / w^6 + sg^3 / w^8)`` roundings (``w = wn h``,
    ``sg = |ce| h / m``; the response to ``s^2`` by less). At a breakaway
    (``|ce| / m`` about 3.5e5 1/s) a step of a few microseconds loses every
    digit of it, and the step's error estimate then rejects steps for noise.
    The phi functions or the series are taken there, unless the series would
    need too many terms (``sg`` or ``w`` above 6); the closed form where its
    cancellation stays below a tenth of the tolerance.
    """
    sg = abs(ce) * h / m
    w = wn * h
    if sg > 6.0 or w > 6.0:
        return True
    w2 = w * w
    w4 = w2 * w2
    return 1.3e-13 * (w4 + sg * w2 + sg * sg * sg) < tol * (w4 * w4)


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _poly_basis(m, ce, k, wn, h, lng, r11, r12, r21, r22, eps):
    """Responses from rest of ``m u'' + ce u' + k u = s^2`` and ``= s^3`` (``s = tau / h``) at ``h`` and ``h / 2``.

    Returns ``(u, u', u'_mid)`` of the first, then of the second (a
    forcing ``al2 s^2 + al3 s^3`` responds with their combination).
    ``lng``: the step is long against the pad's time scales: the polynomial
    particular solutions with the homogeneous part by the propagator
    (``r..`` over ``h / 2``, squared for ``h``); otherwise (the closed form
    would cancel, see :func:`_basis_in_closed_form`) by the phi functions
    where the linear part's roots are real and at least 1/4 apart against
    the step (:func:`_phi_basis`: the self-excited steps of a breakaway,
    where the series takes tens of terms), else the
    responses' Taylor series, ``a_n = u_n h^n``, in one loop, to terms
    below ``eps`` of the sum (a hundredth of the slip tolerance).
    """
    if lng:
        p11 = r11 * r11 + r12 * r21
        p12 = r11 * r12 + r12 * r22
        p21 = r21 * r11 + r22 * r21
        p22 = r21 * r12 + r22 * r22
        ik = 1.0 / k
        hm = 0.5 * h
        # s^2: g2 tau^2 + g1 tau + g0
        ih = 1.0 / h
        g2 = ik * ih * ih
        g1 = -2.0 * ce * g2 * ik
        g0 = -(ce * g1 + 2.0 * m * g2) * ik
        u2 = (g2 * h + g1) * h + g0 - p11 * g0 - p12 * g1
        z2 = 2.0 * g2 * h + g1 - p21 * g0 - p22 * g1
        zm2 = 2.0 * g2 * hm + g1 - r21 * g0 - r22 * g1
        # s^3: f3 tau^3 + f2 tau^2 + f1 tau + f0
        f3 = g2 * ih
        f2 = -3.0 * ce * f3 * ik
        f1 = -(2.0 * ce * f2 + 6.0 * m * f3) * ik
        f0 = -(ce * f1 + 2.0 * m * f2) * ik
        u3 = ((f3 * h + f2) * h + f1) * h + f0 - p11 * f0 - p12 * f1
        z3 = (3.0 * f3 * h + 2.0 * f2) * h + f1 - p21 * f0 - p22 * f1
        zm3 = (3.0 * f3 * hm + 2.0 * f2) * hm + f1 - r21 * f0 - r22 * f1
        return u2, z2, zm2, u3, z3, zm3
    sig = 0.5 * ce / m
    disc = sig * sig - wn * wn
    if disc > 0.0:
        sq = math.sqrt(disc)
        if 2.0 * sq * h >= 0.25:
            # real roots far apart against the step: the divided differences of the phi functions
            rb = -sig - sq if sig >= 0.0 else -sig + sq
            return _phi_basis(m, h, rb * h, (wn * wn / rb) * h)
    sg = ce * h / m
    wh = wn * wn * h * h
    a0 = 0.0
    a1 = h * h / (12.0 * m)       # a_4 of s^2
    b0 = 0.0
    b1 = 0.0                      # a_4 of s^3
    u2 = a1
    z2 = 4.0 * a1
    w = 1.0 / 8.0                 # 2^(1-n)
    zm2 = 4.0 * a1 * w
    u3 = 0.0
    z3 = 0.0
    zm3 = 0.0
    fn = 4.0
    for n in range(5, _SERIES_TERMS):
        fn += 1.0
        i1 = _INV_N[n]
        i2 = _INV_NN[n]
        a2 = -(sg * i1 * a1 + wh * i2 * a0)
        b2 = -(sg * i1 * b1 + wh * i2 * b0)
        if n == 5:
            b2 += h * h / (20.0 * m)
        w *= 0.5
        u2 += a2
        z2 += fn * a2
        zm2 += fn * a2 * w
        u3 += b2
        z3 += fn * b2
        zm3 += fn * b2 * w
        a0 = a1
        a1 = a2
        b0 = b1
        b1 = b2
        if abs(a2) * fn <= eps * abs(z2) and abs(b2) * fn <= eps * abs(z3):
            break
    ih = 1.0 / h
    return u2, z2 * ih, zm2 * ih, u3, z3 * ih, zm3 * ih


@njit(cache=True, inline="always", fastmath=_STRIBECK_FASTMATH)
def _landing_refined(hg, htr, lo, hi, q0, qd0, q1, u1, z1, S1, sr, W, muk, dmu, E0, ex, b, c, k, m, A, om, vr1):
    """The next trial step for a landing on ``sr vr = 0``: the regula falsi's ``hg`` polished by Newton on the
    cubic through the trial's ends (``sr vr`` and its rate at 0 and at ``htr``), kept inside ``(lo, hi)``.

    The trial's own cubic is accurate to its fourth order where the secant
    through the bracket is to its first: most landings then need one trial
    less. Falls back to ``hg`` where the cubic's root is not in the bracket.
    """
    F1 = -sr * W * (muk + dmu * E0 * (1.0 + ex)) - b * vr1
    m0 = htr * qd0
    m1 = htr * sr * ((F1 - c * z1 - k * u1) / m + A * om * om * S1)
    s = hg / htr
    for _ in range(6):
        s2 = s * s
        s3 = s2 * s
        p = (q0 * (2.0 * s3 - 3.0 * s2 + 1.0) + m0 * (s3 - 2.0 * s2 + s) + q1 * (3.0 * s2 - 2.0 * s3)
             + m1 * (s3 - s2))
        dp = q0 * (6.0 * s2 - 6.0 * s) + m0 * (3.0 * s2 - 4.0 * s + 1.0) + q1 * (6.0 * s - 6.0 * s2) + m1 * (3.0 * s2 - 2.0 * s)
        if not (dp != 0.0):
            return hg
        ds = p / dp
        s -= ds
        if abs(ds) <= 1e-12 * abs(s):
            break
    h = s * htr
    if lo < h < hi:
        return h
    return hg


@njit(cache=True, error_model="numpy", fastmath=_STRIBECK_FASTMATH)
def _stribeck_exp_slip(prm, u, z, sr, V, W, mus, muk, t, te, C0, S0, h0):
    """Slip of the plain Stribeck curve from ``t`` to at most ``te`` by exponential Rosenbrock steps.

    Each step linearises the friction about the step's start in the relative
    speed (the contactor's motion included) and solves the linear oscillator
    with its constant and sinusoidal forcing in closed form (the pad's fast
    modes, decaying or self-excited, are exact in it); the remainder of the
    friction curve, sampled at the step's midpoint and end and taken as a
    cubic in time through both (zero with its slope at the start), gives the
    correction (its response in closed form), computed twice: along the
    linear solution, then along the corrected one (a Picard pass). The error
    estimate is the second pass's change plus the cubic's change to a
    quadratic through the end, weighted by :data:`EXP_ERR_WEIGHT` (or
    :data:`EXP_ERR_WEIGHT_OVERDAMPED` where the sliding pad is overdamped and
    the speed's scale is the speed it reaches); steps are
    as long as it stays below ``prm.stribeck_tol`` of the pad's scales
    (fourth-order rule; a tick at a time in steady sliding). A step that carries the
    relative speed through zero is shortened to land on the zero (secant
    iterations on the step length), where the re-stick rule applies.

    ``(C0, S0)`` is ``(cos, sin)(omega t)`` of the contactor (``(1, 0)`` for a
    still one), ``h0`` the first step to try (the one the last call proposed;
    0: the rest of the tick). Returns ``(u, z, sr, stuck, t, F, hn)`` with the
    friction force ``F`` at ``t`` and the next step ``hn`` proposed.
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    a = prm.stribeck_a
    b = prm.stribeck_b
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    tol = prm.stribeck_tol
    tol4 = math.sqrt(math.sqrt(tol))   # fourth roots for the step rule (two square roots: a fraction of pow's cost)
    eps_ser = max(1e-2 * tol, 1e-17)   # how far the responses' series runs
    dmu = mus - muk
    if not W > 0.0:
        b = 0.0           # a lifted finger: no friction at all (the viscous term included)
    aw = a / W if W > 0.0 else math.inf
    mw2 = k - m * om * om
    wn = math.sqrt(k / m)
    ik = 1.0 / k
    hmin = 1e-6 * math.sqrt(m / k)
    usc0 = mus * W / k
    # speed scale: the drive's speeds plus the speed the release of the pad's stretch reaches: mu_s W / sqrt(k m)
    # (the free oscillation's), or mu_s W / (c + b) where the sliding pad is overdamped (it never reaches the
    # former: measured against that, an error in z before the fold passed unnoticed and moved the collapse to
    # re-stick by microseconds); the estimate's weight goes with it
    od = c + b >= 2.0 * math.sqrt(k * m)
    zsc0 = abs(V) + A * om + mus * W / (c + b) if od else _free_speed_scale(V, A, om, mus, W, k, m)
    ew = EXP_ERR_WEIGHT_OVERDAMPED if od else EXP_ERR_WEIGHT
    # time scale of the stick-slip cycle: the time the drive takes to stretch the pad to breakaway (none without
    # a drive). Where z changes fast (a breakaway, the collapse to re-stick) an error in z is a shift in time
    # along the path (the fast mode damps it out or the landing on zero takes it as one), weighed against it.
    vd = abs(V) + A * om
    tsc = usc0 / vd if vd > 0.0 else 0.0
    h = min(te - t, prm.substep)
    h_want = h            # the step the error control asks for (h is it cut to the tick's end or a cap)
    if h0 > 0.0:
        h_want = min(h0, prm.substep)
        h = min(h, h_want)
    hn = 0.0
    # friction curve at the start: W (mu_k + dmu E) with E = exp(-a sr vr / W)
    vr0 = z + V - A * om * C0
    E0 = _exp(-aw * max(sr * vr0, 0.0)) if W > 0.0 else 0.0
    # the bracket [lo, hi] of step lengths around a zero of the relative speed (hi < 0: none yet), with sr vr
    # at its ends; vtol: how close to zero a landing must come
    lo = 0.0
    hi = -1.0
    side = 0
    vlo = sr * vr0
    vhi = 0.0
    vtol = 1e-2 * tol * _free_speed_scale(V, A, om, mus, W, k, m)
    # or how close in time: a tenth of the tolerance's time shift (tol * tsc, as in the step's error below). The
    # collapse to re-stick crosses zero at thousands of m/s^2, where vtol alone is a few nanoseconds and the
    # landing's secant steps take several trials more (none without a drive: tsc = 0)
    ttol = 0.1 * tol * tsc
    h_prev = 0.0      # the last accepted step and the cube root of its error (step-size prediction)
    e4_prev = 0.0
    touch_checked = False   # a touch inside a step looked for from this start point already
    for it in range(MAX_EVENTS_PER_TICK):
        if t >= te:
            break
        # linearisation: F(vr) ~ F0 + G (vr - vr0), G = W dmu a E0 / W - b
        F0 = -sr * W * (muk + dmu * E0) - b * vr0
        vrd0 = (F0 - c * z - k * u) / m + A * om * om * S0     # the rate of v_r at the start
        G = a * dmu * E0 - b
        ce = c - G
        # the linear part's roots -sig +- sqrt(sig^2 - k/m) bound the step twice
        sig = 0.5 * ce / m
        sig2 = sig * sig
        wn2 = k / m
        if ce < 0.0:
            # a self-excited step: growth up to e^3 (the error estimate decides the rest; no overflow)
            rgrow = math.sqrt(sig2 + wn2) - sig
            if h * rgrow > 3.0:
                h = 3.0 / rgrow
        if sig2 < wn2:
            # an oscillating linear part (complex roots): at most a quarter of its period per step. The sign checks
            # at the step's quarters and the touch check between its ends see a dip of the relative speed to zero
            # only on steps short against the oscillation: a lightly damped pad sliding fast (the curve's remainder
            # nil, the error estimate with it) otherwise stepped a whole tick over its collapse to re-stick
            wd = math.sqrt(wn2 - sig2)
            if h * wd > 0.5 * math.pi:
                h = 0.5 * math.pi / wd
        if not (h >= hmin) and h < te - t and hi < 0.0:
            # the curve's drop is steeper than any step resolves (a micronewton load): linearised steps (not
            # inside a bracket around a zero of the relative speed: there a short step is a landing's, the zero
            # being that close; the linearised steps' re-stick came a tenth of a microsecond early)
            u, z, sr, stuck, t = _stribeck_lin_step(prm, u, z, sr, V, W, mus, muk, t, te)
            if A != 0.0:
                C0, S0 = _cos_sin(om * t)
            if stuck:
                return u, z, sr, True, t, 0.0, 0.0
            vr0 = z + V - A * om * C0
            E0 = _exp(-aw * max(sr * vr0, 0.0)) if W > 0.0 else 0.0
            h = min(te - t, prm.substep)
            h_want = h
            lo = 0.0
            hi = -1.0
            side = 0
            vlo = sr * vr0
            touch_checked = False
            continue
        # m u'' + ce u' + k u = f0 - G A om cos(om s) (+ the remainder below), s = t + tau
        f0 = F0 - G * (vr0 - V)
        up0 = f0 * ik
        X = 0.0
        Y = 0.0
        if A != 0.0:
            Fc = -G * A * om / (mw2 * mw2 + ce * ce * om * om)
            X = Fc * mw2
            Y = Fc * ce * om
        # the linear solution at the midpoint and the end of the step by its propagator over h / 2 (the square
        # of the one over h / 4; also the responses' below), each by one product from the one before (a shorter
        # chain than four quarter steps), the contactor turned by half the angle; beside them the quarter
        # points: the sign of sr vr at the first three finds a crossing of zero inside the step even where the
        # end is past a second one
        ch, sh = _cos_sin(0.25 * om * h)
        q11, q12, q21, q22 = _lin_propagator(m, ce, k, 0.25 * h)
        r11 = q11 * q11 + q12 * q21
        r12 = q11 * q12 + q12 * q22
        r21 = q21 * q11 + q22 * q21
        r22 = q21 * q12 + q22 * q22
        ch2 = ch * ch - sh * sh
        sh2 = 2.0 * ch * sh
        uh = u - up0 - (X * C0 + Y * S0)
        zh = z - om * (Y * C0 - X * S0)
        um = r11 * uh + r12 * zh
        zm = r21 * uh + r22 * zh
        Cm = C0 * ch2 - S0 * sh2
        Sm = S0 * ch2 + C0 * sh2
        vrm = zm + om * (Y * Cm - X * Sm) + V - A * om * Cm
        ue = r11 * um + r12 * zm
        ze = r21 * um + r22 * zm
        C1 = Cm * ch2 - Sm * sh2
        S1 = Sm * ch2 + Cm * sh2
        cross = 0
        if hi < 0.0:
            # the sign of sr vr at the first three quarters
            q0 = sr * vr0
            Cq = C0 * ch - S0 * sh
            Sq = S0 * ch + C0 * sh
            qa = sr * ((q21 * uh + q22 * zh) + om * (Y * Cq - X * Sq) + V - A * om * Cq)
            qb = sr * vrm
            Cq = Cm * ch - Sm * sh
            Sq = Sm * ch + Cm * sh
            qc = sr * ((q21 * um + q22 * zm) + om * (Y * Cq - X * Sq) + V - A * om * Cq)
            if qa <= 0.0:
                cross = 1
                vhi = qa
                vlo = q0
            elif qb <= 0.0:
                cross = 2
                vhi = qb
                vlo = qa
            elif qc <= 0.0:
                cross = 3
                vhi = qc
                vlo = qb
        u1 = ue + up0 + X * C1 + Y * S1
        z1 = ze + om * (Y * C1 - X * S1)
        vr1 = z1 + V - A * om * C1
        if cross > 0:
            # through zero inside the step: land on the crossing between the quarters around it
            lo = 0.25 * h * (cross - 1)
            hi = 0.25 * h * cross
            side = 0
            h = lo + vlo * (hi - lo) / (vlo - vhi)
            if not (lo < h < hi):
                h = 0.5 * (lo + hi)
            continue
        # the friction curve's remainder at the end and at the midpoint: -sr W dmu E0 (e^x - 1 - x),
        # x = -a sr (vr - vr0) / W; as a forcing al2 s^2 + al3 s^3 (s = tau / h) through both
        x = -aw * sr * (vr1 - vr0) if W > 0.0 else 0.0
        exx = _expm1_minus_x(x)
        ex = exx + x
        xm = -aw * sr * (vrm - vr0) if W > 0.0 else 0.0
        R1 = -sr * W * dmu * E0 * exx if E0 > 0.0 else 0.0
        Rm = -sr * W * dmu * E0 * _expm1_minus_x(xm) if E0 > 0.0 else 0.0
        al3 = 2.0 * R1 - 8.0 * Rm
        al2 = R1 - al3
        # its response from rest (at the end and the midpoint), then once more with the remainder taken along
        # the corrected path (a Picard pass: the remainder was taken along the linear solution)
        lng = _basis_in_closed_form(m, ce, wn, h, tol)
        u2, z2, zm2, u3, z3, zm3 = _poly_basis(m, ce, k, wn, h, lng, r11, r12, r21, r22, eps_ser)
        du = al2 * u2 + al3 * u3
        dz = al2 * z2 + al3 * z3
        dzm = al2 * zm2 + al3 * zm3
        x2 = -aw * sr * (vr1 + dz - vr0) if W > 0.0 else 0.0
        xm2 = -aw * sr * (vrm + dzm - vr0) if W > 0.0 else 0.0
        exx = _expm1_minus_x(x2)
        ex = exx + x2
        R1 = -sr * W * dmu * E0 * exx if E0 > 0.0 else 0.0
        Rm = -sr * W * dmu * E0 * _expm1_minus_x(xm2) if E0 > 0.0 else 0.0
        al3 = 2.0 * R1 - 8.0 * Rm
        al2 = R1 - al3
        du1 = du
        dz1 = dz
        du = al2 * u2 + al3 * u3
        dz = al2 * z2 + al3 * z3
        # the error estimate: the Picard pass's change plus the cubic fit's change to a quadratic through the end
        duq = R1 * u2
        dzq = R1 * z2
        # (u against its scale; z against its scale plus the change of the relative speed over tsc at the step's
        # mean rate: a time shift of tol * tsc)
        eu = (abs(du - duq) + abs(du - du1)) / (usc0 + abs(u))
        ez = (abs(dz - dzq) + abs(dz - dz1)) / (zsc0 + abs(z) + abs(vr1 - vr0) * (tsc / h))
        err = eu if eu > ez else ez
        if not (eu <= err and ez <= err):
            err = math.inf     # not a number in either: shorten
        err *= ew
        if not (err <= tol):
            # too long (or overflowed): shorten by the fourth-order rule
            if err > 0.0 and math.isfinite(err):
                h *= max(0.1, 0.8 * math.sqrt(math.sqrt(tol / err)))
            else:
                h *= 0.1
            h_want = h
            hi = -1.0
            lo = 0.0
            side = 0
            vlo = sr * vr0
            continue
        # the two passes are the first two iterates of the fixed point the correction converges to (from zero:
        # the linear solution): where they contract by kap (|kap| < 1/2), Aitken's extrapolation takes the
        # correction to its limit (the first iterate zero: no extrapolation). The estimate above stays that of the passes.
        ddz = dz - dz1
        if abs(ddz) < 0.5 * abs(dz1):
            fk = ddz / (dz1 - ddz)      # kap / (1 - kap), kap = ddz / dz1
            du += fk * (du - du1)
            dz += fk * ddz
        u1 += du
        z1 += dz
        vr1 = z1 + V - A * om * C1
        q1 = sr * vr1
        landed = False
        if q1 > 0.0 and hi < 0.0 and not touch_checked:
            # a touch of zero inside the step (sr vr falling, then rising again): the cubic through the ends'
            # values and rates; if its minimum lies below zero, end the step there once, where a crossing, if
            # real, is then found and landed on
            m0 = h * sr * ((F0 - c * z - k * u) / m + A * om * om * S0)
            if m0 < 0.0:
                F1 = -sr * W * (muk + dmu * E0 * (1.0 + ex)) - b * vr1
                m1 = h * sr * ((F1 - c * z1 - k * u1) / m + A * om * om * S1)
                if m1 > 0.0:
                    q0 = sr * vr0
                    qa = 6.0 * (q0 - q1) + 3.0 * (m0 + m1)
                    qb = 6.0 * (q1 - q0) - 4.0 * m0 - 2.0 * m1
                    # the root of qa s^2 + qb s + m0 in (0, 1) (one: the rate changes sign there)
                    dq = math.sqrt(max(qb * qb - 4.0 * qa * m0, 0.0))
                    sm = -2.0 * m0 / (qb + dq) if qb >= 0.0 else (dq - qb) / (2.0 * qa) if qa != 0.0 else -m0 / qb
                    if 0.0 < sm < 1.0:
                        s2 = sm * sm
                        s3 = s2 * sm
                        pm = (q0 * (2.0 * s3 - 3.0 * s2 + 1.0) + m0 * (s3 - 2.0 * s2 + sm) + q1 * (3.0 * s2 - 2.0 * s3)
                              + m1 * (s3 - s2))
                        if pm < -vtol:
                            # (a dip within the landing tolerance is none: at a breakaway the start's rate is
                            # zero to rounding, and a step cut to its minimum there would be a few ulps long)
                            touch_checked = True
                            h *= sm
                            continue
        if q1 <= 0.0:
            # through zero: land on it (Illinois-modified regula falsi on the step length)
            if -q1 <= vtol or h - lo <= max(1e-15 * (1.0 + abs(t)), ttol):
                landed = True
            else:
                if side == 1:
                    vlo *= 0.5
                side = 1
                hi = h
                vhi = q1
                h = lo + vlo * (hi - lo) / (vlo - vhi)
                if not (lo < h < hi):
                    h = 0.5 * (lo + hi)
                h = _landing_refined(h, hi, lo, hi, sr * vr0, sr * vrd0, q1, u1, z1, S1, sr, W, muk, dmu, E0, ex, b, c,
                                     k, m, A, om, vr1)
                continue
        elif hi > 0.0:
            # a trial short of the zero found before
            if q1 <= vtol or hi - h <= max(1e-15 * (1.0 + abs(t)), ttol):
                landed = True
            else:
                if side == -1:
                    vhi *= 0.5
                side = -1
                htr = h
                lo = h
                vlo = q1
                h = lo + vlo * (hi - lo) / (vlo - vhi)
                if not (lo < h < hi):
                    h = 0.5 * (lo + hi)
                h = _landing_refined(h, htr, lo, hi, sr * vr0, sr * vrd0, q1, u1, z1, S1, sr, W, muk, dmu, E0, ex, b,
                                     c, k, m, A, om, vr1)
                continue
        # accept the step
        E_start = E0
        t_new = t + h if t + h < te else te
        u = u1
        z = z1
        C0 = C1
        S0 = S1
        t = t_new
        if landed:
            # on the zero of the relative speed: re-stick if the needed friction is admissible
            dxc = A * om * C0
            ddxc = -A * om * om * S0
            Fst = m * ddxc + c * (dxc - V) + k * u
            if abs(Fst) <= mus * W:
                return u, dxc - V, sr, True, t, -Fst, 0.0
            srn = -1.0 if Fst > 0.0 else 1.0
            sr = srn
            vr0 = 0.0
            E0 = 1.0 if W > 0.0 else 0.0
            z = dxc - V
        else:
            # the curve at the corrected end: E0 e^x e^d, d = -a sr dz / W (small: a short series); where the
            # curve fell to below half over the step, e^x = 1 + ex has lost digits to the cancellation (all of
            # them from x < -37 on: E0 then stayed zero for the rest of the slip, and the rise of the friction
            # towards mu_s before the next re-stick went unseen): E at the end afresh
            d = -aw * sr * (dz - dz1) if W > 0.0 else 0.0
            vr0 = vr1
            if ex < -0.5:
                E0 = _exp(-aw * sr * vr1) if W > 0.0 else 0.0
            elif abs(d) < 0.05:
                E0 = E0 * (1.0 + ex) * (1.0 + d * (1.0 + d * (0.5 + d * (1.0 / 6.0 + d * (1.0 / 24.0))))) if W > 0.0 else 0.0
            else:
                E0 = E0 * (1.0 + ex) * _exp(d)
        lo = 0.0
        hi = -1.0
        side = 0
        vlo = sr * vr0
        touch_checked = False
        # next step: the fourth-order rule with Gustafsson's prediction (an error growing from step to step, as
        # in the collapse to re-stick, shortens the next one before it fails), at most twice as long (up to eight
        # times after a step far within the tolerance: the rule itself, the end of a breakaway)
        e4 = math.sqrt(math.sqrt(err))
        if err <= tol * 1.5e-3:
            grow = min(8.0, 0.8 * tol4 / e4) if err > 0.0 else 8.0
        else:
            grow = 0.8 * tol4 / e4
            gmax = 2.0
            if E0 < E_start and not landed:
                # the curve's remainder scales with E: where it fell over the step (the end of a breakaway, the
                # entry to steady sliding) the next step's error falls with it
                grow *= math.sqrt(math.sqrt(E_start / E0)) if E0 > 0.0 else 4.0
                gmax = 8.0
            elif E0 > E_start and not landed and e4_prev == 0.0:
                # and where it rose, the next error rises with it: the first step of a tick has no error before it
                # for the prediction below (the entry from steady sliding into the slow-down before the fold, where
                # the tick's first, long step would fail)
                grow *= math.sqrt(math.sqrt(E_start / E0))
            if e4_prev > 0.0:
                gus = grow * (h / h_prev) * (e4_prev / e4)
                if gus < grow:
                    grow = gus
            grow = min(gmax, max(0.2, grow))
        if t >= te:
            # the next tick starts with the step wanted here (not the rest of the tick this one was cut to), or
            # shorter if this step, cut to at least half of it, asks for less, or if its error asks to shorten
            # (an error growing towards the collapse to re-stick: the wanted step may be ticks old)
            hn = h_want
            if h * grow < hn and (h >= 0.5 * h_want or grow < 1.0):
                hn = h * grow
            break
        h_prev = h
        e4_prev = e4
        h_want = min(h * grow, prm.substep)
        h = min(h_want, te - t)
        if te - t < 1.25 * h and te - t <= prm.substep:
            h = te - t    # up to a quarter longer rather than a sliver to the tick's end
    F = -sr * W * (muk + dmu * E0) - b * (z + V - A * om * C0)
    return u, z, sr, False, t, F, hn


@njit(cache=True, error_model="numpy", forceinline=True, fastmath=_STRIBECK_FASTMATH)
def _stribeck_plain_tick(st, prm, t0, h, V, W, mus, muk, B, ev_t, ev_a, n_ev):
    """The plain Stribeck curve over one tick: stick in closed form, slip by Taylor steps (see stribeck_tick)."""
    k = prm.stiffness
    A = prm.contactor_amplitude
    om = prm.contactor_omega
    u = st.x
    z = st.v
    phase = st.phase
    sr = -st.s if st.s != 0.0 else 1.0
    # the contactor's phase (cos, sin) at time tcs, handed to the exponential slip steps
    Ct = 1.0
    St = 0.0
    tcs = -math.inf
    if phase != 0.0:
        # a new finger speed at the tick start can reverse the relative velocity: friction follows it
        if A != 0.0:
            Ct, St = _cos_sin(om * t0)
        tcs = t0
        vr = z + V - A * om * Ct
        if vr != 0.0:
            sr = 1.0 if vr > 0.0 else -1.0
    t = t0
    te = t0 + h
    thr = mus * W
    F = 0.0
    for _ in range(MAX_EVENTS_PER_TICK):
        if phase == 0.0:
            t, broke, u, z, F = _stribeck_stick(prm, V, thr, u, t, te, prm.stribeck_tol >= STRIBECK_EXP_MIN_TOL)
            if not broke:
                break
            n_ev = _record(ev_t, ev_a, n_ev, t, B * abs(k * u))
            sr = -1.0 if F > 0.0 else 1.0
            phase = 1.0
            continue
        if prm.stribeck_tol >= STRIBECK_EXP_MIN_TOL:
            if tcs != t and A != 0.0:
                Ct, St = _cos_sin(om * t)
            u, z, sr, stuck, t, F, hn = _stribeck_exp_slip(prm, u, z, sr, V, W, mus, muk, t, te, Ct, St,
                                                           st.slip_step if t == t0 else 0.0)
            st.slip_step = hn
        else:
            u, z, sr, stuck, t = _stribeck_taylor_slip(prm, u, z, sr, V, W, mus, muk, t, te)
            F = math.nan
        if stuck:
            phase = 0.0
            continue
        if t < te:
            st.truncated += 1      # the slip's step cap ran out before the end of the tick
        break
    else:
        st.truncated += 1
    if phase == 1.0 and not F == F:
        dxc = A * om * math.cos(om * te) if A != 0.0 else 0.0
        muW, _ = _plain_friction(abs(z + V - dxc), W, mus, muk, prm.stribeck_a, prm.stribeck_b)
        F = -sr * muW
    st.x = u
    st.v = z
    st.phase = phase
    st.s = -sr
    st.f = F
    return n_ev


@njit(cache=True, fastmath=_STRIBECK_FASTMATH)
def _stribeck_slip(prm, u, du, s, V, W, mus, muk, ta, dur):
    """Pre-maximum variant: ``dur`` seconds from ``ta`` by exponential Rosenbrock substeps; returns (u, du, s, F).

    The friction (continuous through zero relative speed in this variant) is
    linearised about the current relative velocity and the linear oscillator
    solved in closed form; on the negative Stribeck slope the step keeps the
    growth factor below e^0.5 (the self-excitation is physical; the step only
    resolves it).
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    t = ta
    tend = ta + dur
    F = 0.0
    # the contactor velocity and the friction curve at the start of a substep are those at the end of the
    # one before (same time, same state): computed once
    _, dxca, _ = _contactor(prm, t)
    vr0 = du + V - dxca
    mu, dmu = stribeck_mu(abs(vr0), W, mus, muk, prm.stribeck_a, prm.stribeck_b, prm.stribeck_p, prm.stribeck_d, 1)
    while t < tend:
        F0 = -_sgn(vr0) * mu * W
        ceff = c + dmu * W
        hs = min(prm.substep, tend - t)
        if ceff < 0.0:
            hs = min(hs, 0.5 * m / (-ceff))
        if hs < 1e-12 * max(1.0, abs(t)):
            hs = tend - t
        # F(vr) ~ F0 - dmu W (vr - vr0) with vr = u' + V - xc'(mid): a linear
        # oscillator m u'' + (c + dmu W) u' + k u = F0 - dmu W (V - xc'(mid) - vr0)
        _, dxcm, _ = _contactor(prm, t + 0.5 * hs)
        ueq = (F0 - dmu * W * (V - dxcm - vr0)) / k
        y1, v1 = osc(m, ceff, k, u - ueq, du, hs)
        u = y1 + ueq
        du = v1
        t += hs
        _, dxcb, _ = _contactor(prm, t)
        vr1 = du + V - dxcb
        mu, dmu = stribeck_mu(abs(vr1), W, mus, muk, prm.stribeck_a, prm.stribeck_b, prm.stribeck_p, prm.stribeck_d, 1)
        if vr1 != 0.0:
            F = -_sgn(vr1) * mu * W
            s = -_sgn(vr1)
        else:
            F = F0
        vr0 = vr1
    return u, du, s, F


@njit(cache=True, fastmath=_STRIBECK_FASTMATH)
def stribeck_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    """Imaizumi pad on a laterally vibrating contactor, finger bone at speed ``V``.

    ``st.x`` is the spring stretch u = x_p - x_f, ``st.v`` its rate; ``W = N``.
    The friction force ``F`` on the pad is reported in ``st.f``.

    Plain Stribeck curve (``prm.stribeck_variant == 0``): stick in closed
    form (the pad moves with the contactor, u' = x_c' - V; breakaway when the
    needed friction ``m x_c'' + c u' + k u`` exceeds ``mu_s W``, located to
    ~1e-16 s). Slip by steps whose local error stays below
    ``prm.stribeck_tol`` of the pad's scales, at most ``prm.substep`` long:
    from :data:`STRIBECK_EXP_MIN_TOL` up exponential Rosenbrock steps
    (:func:`_stribeck_exp_slip`; the re-stick is a step landed on the zero of
    the relative velocity), below it Taylor series steps of adaptive order and
    length (:func:`_stribeck_series`; the re-stick is the zero on the step's
    polynomial). Either way the re-stick is taken when the needed friction is
    within ``mu_s W``; a step cut at the end of a tick restarts from there,
    so event times depend on the tick rate only within the tolerance.

    Pre-maximum variant (1): friction is continuous through zero, no
    set-valued stick: exponential Rosenbrock substeps of at most
    ``prm.substep`` (:func:`_stribeck_slip`). The pre-maximum region counts
    as "stick" (state 0): entered when |vr| <= d W, left (the stick-to-slip
    event, located to one substep) when |vr| >= 2 d W, clear of the jump of
    mu at d W (the hysteresis keeps round-off from chattering there).
    """
    B = prm.burst_gain * gain
    nev0 = n_ev
    if prm.stribeck_variant != 1:
        n_ev = _stribeck_plain_tick(st, prm, t0, h, V, N, mus, muk, B, ev_t, ev_a, n_ev)
        st.n_events = n_ev - nev0
        return n_ev
    k = prm.stiffness
    W = N
    u = st.x
    du = st.v
    phase = st.phase
    s = st.s
    F = st.f
    nsub = int(math.ceil(h / prm.substep - 1e-9))
    if nsub < 1:
        nsub = 1
    hs = h / nsub
    for i in range(nsub):
        ta = t0 + i * hs
        u, du, s, F = _stribeck_slip(prm, u, du, s, V, W, mus, muk, ta, hs)
        _, dxc, _ = _contactor(prm, ta + hs)
        avr = abs(du + V - dxc)
        if phase == 0.0 and avr >= 2.0 * prm.stribeck_d * W:
            n_ev = _record(ev_t, ev_a, n_ev, ta + hs, B * abs(k * u))
            phase = 1.0
        elif phase == 1.0 and avr <= prm.stribeck_d * W:
            phase = 0.0
    st.x = u
    st.v = du
    st.phase = phase
    st.s = s
    st.f = F
    st.n_events = n_ev - nev0
    return n_ev


# ================================================================ tanh-regularised Coulomb
_SQRT2 = math.sqrt(2.0)
_SQRT2E = math.sqrt(2.0 * math.e)


@njit(cache=True)
def tanh_friction(w, N, mus, muk, eps):
    """Regularised friction on the pad at slip speed ``w = V - v`` (m/s); returns ``(f, df/dw)`` (N, N s/m).

    ``f = N [(mu_s - mu_k) sqrt(2e) u exp(-u^2) + mu_k tanh(w / v_C)]`` with
    ``u = w / v_St``, ``v_St = sqrt(2) eps``, ``v_C = eps / 10``: smooth and
    odd, peaking at ``mu_s N`` (to 1e-6) at ``|w| = eps`` and falling to
    ``mu_k N`` for ``|w| >> eps``; tends to Coulomb friction with a static
    limit as ``eps -> 0``.
    """
    vst = _SQRT2 * eps
    vc = 0.1 * eps
    u = w / vst
    e = math.exp(-u * u)
    th = math.tanh(w / vc)
    dmu = mus - muk
    f = N * (dmu * _SQRT2E * u * e + muk * th)
    df = N * (dmu * _SQRT2E * (1.0 - 2.0 * u * u) * e / vst + muk * (1.0 - th * th) / vc)
    return f, df


@njit(cache=True)
def tanh_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    """Konyo pad with tanh-regularised friction: no stick state, only creep inside ``|w| < eps``.

    Linearly implicit exponential substeps: the friction is linearised about
    the current slip speed and the resulting linear oscillator
    ``m x'' + (c + f') x' + k x = f0 + f' v0`` solved in closed form in
    increment form (stable and free of cancellation for the very stiff
    ``f' ~ mu_k N / v_C``). A substep that would carry the
    slip speed through zero from outside the band is cut at the crossing, so
    the saturated friction cannot overshoot. ``st.phase`` reports slip while
    ``|w| >= 2 eps`` (entered: the burst event, interpolated inside the
    substep) and stick again once ``|w| <= eps``.
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    B = prm.burst_gain * gain
    eps = prm.tanh_eps
    hmax = prm.substep
    x = st.x
    v = st.v
    phase = st.phase
    nev0 = n_ev
    vc = 0.1 * eps
    if phase == 0.0 and abs(V - v) > 2.0 * eps:
        v = V        # a new surface speed while stuck: the pad takes it at once, as in ``exact``
    t = 0.0
    it = 0
    while t < h:
        it += 1
        if it > MAX_EVENTS_PER_TICK:
            st.truncated += 1
            break
        w0 = V - v
        f0, df = tanh_friction(w0, N, mus, muk, eps)
        ceff = c + df
        hs = min(hmax, h - t)
        if ceff < 0.0:
            hs = min(hs, 0.5 * m / (-ceff))
        # exponential Euler in increment form, Y1 = Y0 + A^-1 (e^{hA} - I) Y0' with Y = (x, v):
        # (e^{hA} - I) Y0' is the free oscillator started at (v0, a0), and
        # A^-1 = [[-ceff/k, -m/k], [1, 0]]; no large equilibrium offset cancels
        a0 = (f0 - c * v - k * x) / m
        for _ in range(60):
            yh, vh = osc(m, ceff, k, v, a0, hs)
            dx = yh - v
            v1 = v + dx
            w1 = V - v1
            if not (w0 * w1 < 0.0 and abs(w1) > vc and abs(w0) > vc) or hs <= 1e-15:
                break
            hs *= max(min(w0 / (w0 - w1), 0.5), 1e-3)
        x1 = x - (ceff * dx + m * (vh - a0)) / k
        if phase == 0.0 and abs(w1) >= 2.0 * eps:
            a0 = abs(w0)
            fr = (2.0 * eps - a0) / (abs(w1) - a0) if abs(w1) > a0 else 1.0
            fr = min(max(fr, 0.0), 1.0)
            n_ev = _record(ev_t, ev_a, n_ev, t0 + t + fr * hs, B * abs(k * (x + fr * (x1 - x))))
            phase = 1.0
        elif phase == 1.0 and abs(w1) <= eps:
            phase = 0.0
        x = x1
        v = v1
        t = t + hs if t + hs < h else h
    f, _ = tanh_friction(V - v, N, mus, muk, eps)
    st.x = x
    st.v = v
    st.phase = phase
    st.f = f
    st.work_friction = 0.0
    st.work_damping = 0.0
    st.n_events = n_ev - nev0
    return n_ev


# ================================================================ naive baselines
@njit(cache=True)
def _explicit_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev, rk4):
    """One fixed explicit step per tick (forward Euler or RK4) with stick/slip switching.

    Kept only to show where naive integration fails on this stiff pad: on the
    Konyo pad forward Euler needs h < 2 zeta / omega_n ~ 5 us and RK4
    h < 2.8 / omega_n ~ 63 us. Blow-up (|x| beyond a physical bound, or a
    non-finite state) sets ``st.diverged`` and freezes the state at zero.
    """
    m = prm.mass
    k = prm.stiffness
    c = prm.damping
    B = prm.burst_gain * gain
    x = st.x
    v = st.v
    phase = st.phase
    s = st.s
    nev0 = n_ev
    thr = mus * N
    if st.diverged != 0:
        st.f = 0.0
        st.n_events = 0
        return n_ev
    if phase == 0.0:
        x += V * h
        v = V
        f = k * x + c * V
        if abs(f) > thr or (thr == 0.0 and f != 0.0):
            s = _sgn(f)
            n_ev = _record(ev_t, ev_a, n_ev, t0 + h, B * abs(k * x))
            phase = 1.0
    else:
        F = s * muk * N
        if rk4:
            a1 = (F - c * v - k * x) / m
            x2 = x + 0.5 * h * v
            v2 = v + 0.5 * h * a1
            a2 = (F - c * v2 - k * x2) / m
            x3 = x + 0.5 * h * v2
            v3 = v + 0.5 * h * a2
            a3 = (F - c * v3 - k * x3) / m
            x4 = x + h * v3
            v4 = v + h * a3
            a4 = (F - c * v4 - k * x4) / m
            x = x + h / 6.0 * (v + 2 * v2 + 2 * v3 + v4)
            v = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        else:
            a1 = (F - c * v - k * x) / m
            x, v = x + h * v, v + h * a1
        if -s * (v - V) <= 0.0:
            if abs(k * x + c * V) <= thr:
                phase = 0.0
                v = V
            else:
                s = -s
    limit = 10.0 * (max(mus, muk) * N / k + abs(V) * (h + math.sqrt(m / k))) + 1e-6
    if not (math.isfinite(x) and math.isfinite(v)) or abs(x) > limit:
        st.diverged = 1
        st.diverged_at = t0 + h
        x = 0.0
        v = 0.0
        phase = 0.0
    st.x = x
    st.v = v
    st.phase = phase
    st.s = s
    st.f = (k * x + c * V) if phase == 0.0 else s * muk * N
    if st.diverged != 0:
        st.f = 0.0
    st.n_events = n_ev - nev0
    return n_ev


@njit(cache=True)
def euler_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    """Forward Euler, one step per tick (see :func:`_explicit_tick`)."""
    return _explicit_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev, False)


@njit(cache=True)
def rk4_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    """Classical RK4, one step per tick (see :func:`_explicit_tick`)."""
    return _explicit_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev, True)
