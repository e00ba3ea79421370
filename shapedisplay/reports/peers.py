"""Peer solvers: ``scipy.integrate.solve_ivp`` with event functions.

The peers integrate the same pad models as the renderer kernels, the way a
careful scipy user would: one ``solve_ivp`` call per phase, the stick/slip
switch located by a terminal event function, the integration restarted at
every event and at every discontinuity of the inputs (``breaks``). They are
used as the independent cross-check of the ``exact`` reference and as the
speed baseline of the accuracy report.

Two systems
-----------
:func:`konyo_ivp`
    The Konyo pad: stick ``x' = V(t)``; breakaway when
    ``|k x + c V| = mu_s N(t)``; slip ``m x'' + c x' + k x = s mu_k N(t)``;
    re-stick when the relative velocity ``-s (x' - V)`` falls through zero
    and ``|k x + c V| <= mu_s N``, otherwise the slip continues with the
    friction sign flipped.
:func:`stribeck_ivp`
    The Imaizumi pad with Stribeck friction on a vibrating contactor
    (Imaizumi et al.), same conventions as the ``stribeck`` kernel
    (:func:`shapedisplay.render.pads.stribeck_tick`): ``u`` is the spring
    stretch, ``vr = u' + V - x_c'`` the relative velocity, stick while the
    needed friction ``m x_c'' + c u' + k u`` stays within ``mu_s W``.

Both return a :class:`PeerResult` with the stick-to-slip event times and
amplitudes ``|k x|`` at breakaway (burst gain 1), the number of
``solve_ivp`` calls and right-hand-side evaluations, and a ``status``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: Methods of ``solve_ivp`` used as peers (all accept event functions).
PEER_METHODS = ("Radau", "BDF", "LSODA")


@dataclass
class PeerResult:
    """Output of a peer run.

    Attributes
    ----------
    event_time, event_amplitude : ndarray (n_events,), float64
        Stick-to-slip times (s) and ``|k x|`` at breakaway (N).
    calls : int
        Number of ``solve_ivp`` calls (one per phase or input segment).
    nfev : int
        Right-hand-side evaluations summed over the calls.
    status : str
        ``"ok"``, ``"failed"`` (solve_ivp reported a failure; ``message``
        says why) or ``"truncated"`` (the phase budget ran out).
    message : str
    """

    event_time: np.ndarray
    event_amplitude: np.ndarray
    calls: int = 0
    nfev: int = 0
    status: str = "ok"
    message: str = ""
    extra: dict = field(default_factory=dict)


def _tolerances(rtol, scales):
    return float(rtol), np.asarray([float(rtol) * s for s in scales], dtype=np.float64)


class _Failed:
    """Stands in for a solve_ivp result when the solver raised (e.g. a non-finite Jacobian)."""

    def __init__(self, exc):
        self.status = -1
        self.message = f"solver raised {type(exc).__name__}: {exc}"
        self.nfev = 0


def _solve(solve_ivp, *args, **kw):
    """``solve_ivp`` that reports numerical breakdowns as a failed result instead of raising."""
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return solve_ivp(*args, **kw)
    except (ValueError, FloatingPointError, OverflowError, ZeroDivisionError, np.linalg.LinAlgError) as exc:
        return _Failed(exc)


class _Phases:
    """One ``solve_ivp`` call per phase: counts calls and evaluations, keeps the events and the status."""

    def __init__(self, method, rtol, max_phases):
        from scipy.integrate import solve_ivp
        self._solve_ivp = solve_ivp
        self.method, self.rtol, self.max_phases = method, rtol, max_phases
        self.calls = self.nfev = 0
        self.status, self.message = "ok", ""
        self.ev_t, self.ev_a = [], []

    def budget_left(self) -> bool:
        """False (status "truncated") once ``max_phases`` calls have been made."""
        if self.calls >= self.max_phases:
            self.status, self.message = "truncated", f"more than {self.max_phases} phases"
            return False
        return True

    def run(self, rhs, t, tb, y0, atol, event):
        """Integrate from ``t`` to ``tb`` or to the first zero of the terminal ``event``.

        Returns ``(hit, t_stop, y_stop)`` (``hit`` True at an event), or None
        if the solver failed (status "failed").
        """
        sol = _solve(self._solve_ivp, rhs, (t, tb), y0, method=self.method, rtol=self.rtol, atol=atol,
                     events=event)
        self.calls += 1
        self.nfev += sol.nfev
        if sol.status < 0:
            self.status, self.message = "failed", f"{self.method}: {sol.message}"
            return None
        if sol.status == 1 and len(sol.t_events[0]):
            return True, float(sol.t_events[0][0]), [float(q) for q in sol.y_events[0][0]]
        return False, tb, [float(q) for q in sol.y[:, -1]]

    def record(self, t, amplitude):
        self.ev_t.append(t)
        self.ev_a.append(amplitude)

    def result(self) -> PeerResult:
        return PeerResult(np.asarray(self.ev_t, dtype=np.float64), np.asarray(self.ev_a, dtype=np.float64),
                          self.calls, self.nfev, self.status, self.message)


def _next_break(breaks, t, t_end):
    for b in breaks:
        if b > t * (1 + 1e-15) + 1e-15:
            return min(b, t_end)
    return t_end


def konyo_ivp(method, rtol, *, m, k, c, mu_s, mu_k, V, N, t_end, breaks=(), x_scale=None, v_scale=None,
              max_phases=200_000):
    """Konyo pad by ``solve_ivp`` with stick/slip events, restarted at each event.

    Parameters
    ----------
    method : {"Radau", "BDF", "LSODA"}
    rtol : float
        Relative tolerance; the absolute tolerances are ``rtol`` times the
        natural scales ``x_scale`` (m, default ``mu_s N / k``) and
        ``v_scale`` (m/s, default surface speed plus slip-velocity amplitude).
    m, k, c : float
        Pad mass (kg), stiffness (N/m), damping (N s/m).
    mu_s, mu_k : float
    V, N : callable t -> float
        Surface velocity (m/s) and normal force (N); smooth between ``breaks``.
    t_end : float
        s.
    breaks : sequence of float
        Times where V or N jump (the integration is restarted there).

    Returns
    -------
    PeerResult
    """
    breaks = sorted(float(b) for b in breaks if 0.0 < b < t_end)
    n0 = abs(N(0.0)) or 1.0
    xs = x_scale or mu_s * n0 / k
    vs = v_scale or (abs(V(0.0)) + (mu_s - mu_k) * n0 / math.sqrt(k * m) + 1e-6)
    rt, at2 = _tolerances(rtol, (xs, vs))
    at1 = at2[:1]
    ph = _Phases(method, rt, max_phases)
    t, x, v = 0.0, 0.0, V(0.0)
    phase, s = 0, 1.0

    def stick_rhs(tt, y):
        return [V(tt)]

    def brk(tt, y):
        return abs(k * y[0] + c * V(tt)) - mu_s * N(tt)
    brk.terminal = True
    brk.direction = 1

    while t < t_end and ph.budget_left():
        tb = _next_break(breaks, t, t_end)
        if phase == 0:
            f = k * x + c * V(t)
            thr = mu_s * N(t)
            if abs(f) > thr * (1 + 1e-12) or (abs(f) >= thr > 0 and f * V(t) > 0) or (thr == 0 and f != 0):
                phase, s = 1, (1.0 if f > 0 else -1.0)
                ph.record(t, abs(k * x))
                v = V(t)
                continue
            out = ph.run(stick_rhs, t, tb, [x], at1, brk)
            if out is None:
                break
            hit, t, (x,) = out
            if hit:
                s = 1.0 if k * x + c * V(t) > 0 else -1.0
                ph.record(t, abs(k * x))
                phase = 1
            v = V(t)
            continue
        # ---- slip
        ss = s

        def slip_rhs(tt, y, ss=ss):
            return [y[1], (ss * mu_k * N(tt) - c * y[1] - k * y[0]) / m]

        def restick(tt, y, ss=ss):
            return -ss * (y[1] - V(tt))
        restick.terminal = True
        restick.direction = -1
        out = ph.run(slip_rhs, t, tb, [x, v], at2, restick)
        if out is None:
            break
        hit, t, (x, v) = out
        if hit:
            if abs(k * x + c * V(t)) <= mu_s * N(t):
                phase, v = 0, V(t)
            else:
                s = -s
    return ph.result()


def stribeck_mu(vr_abs, W, mu_s, mu_k, a, b):
    """Stribeck coefficient ``mu_k + (mu_s - mu_k) exp(-a |vr|/W) + b |vr|/W`` (Imaizumi et al.)."""
    u = vr_abs / W
    return mu_k + (mu_s - mu_k) * math.exp(-a * u) + b * u


def stribeck_ivp(method, rtol, *, m, k, c, mu_s, mu_k, a, b, W, V, amp, omega, t_end, max_phases=200_000):
    """Imaizumi pad (Stribeck friction, contactor ``x_c = amp sin(omega t)``) by ``solve_ivp`` with events.

    Parameters
    ----------
    method, rtol : as :func:`konyo_ivp`
    m, k, c : float
        kg, N/m, N s/m.
    mu_s, mu_k, a, b : float
        Stribeck curve (plain variant).
    W : float
        Normal load, N (> 0).
    V : float
        Finger-bone speed, m/s.
    amp, omega : float
        Contactor amplitude (m) and angular frequency (rad/s).
    t_end : float
        s.

    Returns
    -------
    PeerResult
        Events are breakaways (stick to slip), amplitude ``|k u|``.
    """
    def xc(tt):
        return amp * math.sin(omega * tt)

    def dxc(tt):
        return amp * omega * math.cos(omega * tt)

    def ddxc(tt):
        return -amp * omega * omega * math.sin(omega * tt)

    us = mu_s * W / k
    vs = abs(V) + amp * omega + mu_s * W / math.sqrt(k * m)
    rt, at2 = _tolerances(rtol, (us, vs))
    ph = _Phases(method, rt, max_phases)
    t, u, du = 0.0, 0.0, dxc(0.0) - V
    phase, sr = 0, 1.0

    def need(tt, uu, duu):
        return m * ddxc(tt) + c * duu + k * uu

    def stick_rhs(tt, y):
        return [dxc(tt) - V]

    def brk(tt, y):
        return abs(need(tt, y[0], dxc(tt) - V)) - mu_s * W
    brk.terminal = True
    brk.direction = 1

    while t < t_end and ph.budget_left():
        if phase == 0:
            F = need(t, u, dxc(t) - V)
            if abs(F) > mu_s * W:
                ph.record(t, abs(k * u))
                phase, sr, du = 1, (-1.0 if F > 0 else 1.0), dxc(t) - V
                continue
            out = ph.run(stick_rhs, t, t_end, [u], at2[:1], brk)
            if out is None:
                break
            hit, t, (u,) = out
            if hit:
                du = dxc(t) - V
                F = need(t, u, du)
                ph.record(t, abs(k * u))
                # the pad falls behind the needed force: vr takes the sign opposite to F
                phase, sr = 1, (-1.0 if F > 0 else 1.0)
            continue
        s_ = sr

        def slip_rhs(tt, y, s_=s_):
            vr = y[1] + V - dxc(tt)
            mu = stribeck_mu(abs(vr), W, mu_s, mu_k, a, b)
            return [y[1], (-c * y[1] - k * y[0] - s_ * mu * W) / m]

        def restick(tt, y, s_=s_):
            return s_ * (y[1] + V - dxc(tt))
        restick.terminal = True
        restick.direction = -1
        out = ph.run(slip_rhs, t, t_end, [u, du], at2, restick)
        if out is None:
            break
        hit, t, (u, du) = out
        if hit:
            if abs(need(t, u, dxc(t) - V)) <= mu_s * W:
                phase, du = 0, dxc(t) - V
            else:
                sr = -sr
    return ph.result()
