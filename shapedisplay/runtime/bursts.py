"""Vibrotactile bursts at stick-to-slip events (Konyo et al.'s Vib-Touch bursts) on one phase-continuous carrier.

The drive of an output is ``E(t) * sin(2 pi f_c (t - t_0))``: **one** carrier
(300 Hz by default) running from the stream's first sample ``t_0`` and never
restarted, times an envelope ``E(t) >= 0`` that the bursts shape. A burst at
event time ``t_e`` (sub-sample) with peak ``A`` has the published envelope
``A env(t - t_e)``: a linear rise over ``rise`` (5 ms), then the quadratic
decay ``(1 - (tau - rise) / decay)^2`` over ``decay`` (30 ms).

What "amplitude A" means at the actuator
----------------------------------------
``A`` is the peak of the envelope ``E(t)`` that multiplies the unit
carrier (the drive's amplitude, reached ``rise`` after the event). The
carrier keeps its own phase, so where its crest falls relative to the
envelope peak varies from burst to burst: the largest sample of an isolated
burst lies between ``0.92 A`` and ``A`` (the worst case is a crest about a
quarter period off the peak, where the envelope is lower). Breakaway forces
therefore map linearly to drive amplitude whatever the event's phase;
``A = B (mu_s N - c xdot)`` full scale.

Overlap policies (:data:`BURST_POLICIES`), none of which ever steps the drive
(the envelope is continuous and the carrier never restarts), each O(1) per
audio sample however many bursts are live:

* ``retrigger`` (default) — a new burst restarts the envelope **from its
  current value**, rising linearly over ``rise`` to the new peak ``A`` (down
  to it if ``A`` is lower), then decaying as published;
* ``add`` — envelopes add up (``sum_i A_i env(t - t_i)``, kept as two running
  polynomials: the linear rises and the quadratic decays; each event enters,
  turns and leaves them once);
* ``max`` — a burst whose peak exceeds the envelope as it stands at its event
  retriggers it (rising from its current value to the new peak); a weaker
  one is absorbed by the louder burst playing.

An isolated burst (envelope at 0 at its event) plays the published envelope
under every policy. Output samples are limited to [-1, 1] (full scale);
every limited sample is counted and reported as ``clipped``, never silent.

Carrier arithmetic
------------------
Sample ``j`` (time ``t_0 + j / rate``) takes its carrier from a rotation by
``2 pi f_c / rate`` per sample, re-anchored with ``sin``/``cos`` of the
exact phase at every multiple of :data:`CARRIER_BLOCK` samples; the
rotation carries over from call to call (a call that does not continue the
previous one starts from the anchor of its block). The anchors depend only
on ``j``, so a stream synthesised in one call (offline) or tick by tick
(online) is the same, bit for bit, the phase error stays below
``CARRIER_BLOCK`` rotations' round-off (~1e-14 rad), and a tick costs one
``sin``/``cos`` pair per ``CARRIER_BLOCK`` samples.

The offline stream (:func:`synth_stream`) computes the same samples group
by group of :data:`CARRIER_GROUP` carrier blocks (1024 samples, which stay
in the first-level cache): the group's carrier first, sixteen blocks side by
side, four to a vector register, into a scratch row; then the envelope piece
by piece (between two transitions the envelope is one expression of the
sample time, for every policy), each sample written already multiplied by
its carrier sample; last, only in a group whose envelope may reach full
scale, the limiting. All are loops without branches that the compiler
vectorises. They are compiled with numpy's error model: their
divisors (the sample rate, ``rise``, ``decay``) are positive by the
settings' rules, so only numba's ZeroDivisionError checks go; the
arithmetic and every sample are unchanged.

Burst state
-----------
A :data:`~.layouts.BURST_STATE` record (C: ``sd_burst_state_t``): the
events entered, turned and finished (indices into the event arrays), the
playing segment of ``retrigger``/``max`` (``te``, ``e0``, ``a``), the
running sums of ``add`` about ``tref``, and the carrier's rotation.
"""
from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from .borrow import borrowed
from .exactdiv import div_fixed, div_nonzero, divisor_ok, span_nonzero
from .layouts import BURST_POLICIES, BURST_STATE, Policy, record
from .settings import MAX_AUDIO_SAMPLES, audio_length, policy_id  # noqa: F401 (their home is .settings)

#: See shapedisplay.runtime.codegen: numba's cache does not notice changes to layouts.py (Policy).
KERNEL_SOURCES_SHA256 = "62934621b389021f0c114ced24c5114cf27cc74b13d5062c86c5af9c3ba35661"
#: Carrier re-anchored with sin/cos every this many samples (rotation in between).
CARRIER_BLOCK = 64



def new_burst_state(carrier: float, rate: float) -> np.ndarray:
    """A fresh burst state (a one-element :data:`~.layouts.BURST_STATE` array) for a ``carrier`` Hz
    carrier sampled at ``rate`` Hz: no event entered, envelope 0, no carrier sample yet."""
    key = (float(carrier), float(rate))
    fresh = _FRESH_STATES.get(key)
    if fresh is None:
        w = 2.0 * math.pi * key[0]
        fresh = record(BURST_STATE, cj=-1, rc=math.cos(w / key[1]), rs=math.sin(w / key[1])).tobytes()
        if len(_FRESH_STATES) < 64:
            _FRESH_STATES[key] = fresh
    return np.frombuffer(bytearray(fresh), BURST_STATE)


#: The bytes of fresh burst states by (carrier, rate), for :func:`new_burst_state` (a record built field by
#: field, or a copy of one, costs several microseconds; an array over a copy of its bytes about one, and
#: every offline render starts one).
_FRESH_STATES: dict = {}


@njit(cache=True)
def envelope(tau, rise, decay):
    """Published burst envelope at time ``tau`` (s) after the event, in [0, 1]."""
    if tau < 0.0:
        return 0.0
    if tau < rise:
        return tau / rise
    u = tau - rise
    if u < decay:
        r = 1.0 - u / decay
        return r * r
    return 0.0


@njit(cache=True)
def _segment(BS, t, rise, decay):
    """Envelope of the retrigger/max segment at time t (>= its start)."""
    tau = t - BS.te
    if tau < rise:
        return BS.e0 + (BS.a - BS.e0) * (tau / rise)
    u = tau - rise
    if u < decay:
        r = 1.0 - u / decay
        return BS.a * r * r
    return 0.0


@njit(cache=True)
def _sums(BS, t, rise, decay):
    """Envelope of ``add`` at time t from its running sums."""
    dt = t - BS.tref
    e = (BS.ra * dt - BS.rat) / rise
    x = dt / decay
    e += BS.q0 - 2.0 * BS.q1 * x + BS.q2 * x * x
    return e if e > 0.0 else 0.0


@njit(cache=True)
def _shift_ref(BS, tnew, decay):
    """Move ``add``'s reference time to ``tnew`` (exact re-expansion of the two polynomials)."""
    dlt = tnew - BS.tref
    if dlt == 0.0:
        return
    d = dlt / decay
    BS.rat -= dlt * BS.ra
    BS.q0 += d * (d * BS.q2 - 2.0 * BS.q1)
    BS.q1 -= d * BS.q2
    BS.tref = tnew


@njit(cache=True, inline="always")
def _add_advance(BS, ev_t, ev_a, n_ev, t, rise, decay):
    """``add``: apply every transition before ``t`` to the running sums, in time order.

    Returns the time of the earliest transition still pending (``inf`` if none): until a sample time
    passes it, the sums stay as they are.
    """
    i_in = BS.i_in
    i_mid = BS.i_mid
    i_out = BS.i_out
    dur = rise + decay
    while True:
        # the earliest pending transition before t
        t_in = ev_t[i_in] if i_in < n_ev else np.inf
        t_mid = ev_t[i_mid] + rise if i_mid < i_in else np.inf
        t_out = ev_t[i_out] + dur if i_out < i_mid else np.inf
        if t_out <= t_mid and t_out <= t_in:
            if not t_out < t:
                nxt = t_out
                break
            a = ev_a[i_out]
            u = 1.0 + (ev_t[i_out] + rise - BS.tref) / decay
            BS.q0 -= a * u * u
            BS.q1 -= a * u
            BS.q2 -= a
            i_out += 1
            if i_out == i_mid:           # no decaying burst left: clear the round-off
                BS.q0 = 0.0
                BS.q1 = 0.0
                BS.q2 = 0.0
        elif t_mid <= t_in:
            if not t_mid < t:
                nxt = t_mid
                break
            a = ev_a[i_mid]
            BS.ra -= a
            BS.rat -= a * (ev_t[i_mid] - BS.tref)
            u = 1.0 + (ev_t[i_mid] + rise - BS.tref) / decay
            BS.q0 += a * u * u
            BS.q1 += a * u
            BS.q2 += a
            i_mid += 1
            if i_mid == i_in:            # no rising burst left
                BS.ra = 0.0
                BS.rat = 0.0
        else:
            if not t_in < t:
                nxt = t_in
                break
            _shift_ref(BS, ev_t[i_in], decay)
            BS.ra += ev_a[i_in]
            i_in += 1
    BS.i_in = i_in
    BS.i_mid = i_mid
    BS.i_out = i_out
    return nxt


@njit(cache=True)
def envelope_at(BS, ev_t, ev_a, n_ev, t, rise, decay, policy):
    """Advance the burst state over every event transition before ``t`` and return ``E(t)``.

    Transitions (an event entering, a burst turning from rise to decay,
    a burst ending) are applied in time order, so the state and the values
    do not depend on where the envelope is evaluated in between. ``t`` must
    not decrease from call to call.
    """
    i_in = BS.i_in
    if policy != Policy.ADD:
        while i_in < n_ev and ev_t[i_in] < t:
            te = ev_t[i_in]
            a = ev_a[i_in]
            e_now = _segment(BS, te, rise, decay)
            if policy == Policy.RETRIGGER or a > e_now:
                BS.te = te
                BS.e0 = e_now
                BS.a = a
            i_in += 1
        BS.i_in = i_in
        return _segment(BS, t, rise, decay)
    _add_advance(BS, ev_t, ev_a, n_ev, t, rise, decay)
    if BS.i_out == BS.i_in:
        return 0.0
    return _sums(BS, t, rise, decay)


@njit(cache=True)
def forget_events(BS, ev_t, ev_a, k, rise, decay, policy):
    """The first ``k`` events leave the event arrays: shift the state's indices.

    Bursts still sounding among them (only when a caller must drop events
    early, at absurd event rates) are removed from ``add``'s sums.
    """
    if policy == Policy.ADD:
        i_mid = int(BS.i_mid)
        i_in = BS.i_in
        for i in range(int(BS.i_out), min(k, i_in)):
            a = ev_a[i]
            if i < i_mid:
                u = 1.0 + (ev_t[i] + rise - BS.tref) / decay
                BS.q0 -= a * u * u
                BS.q1 -= a * u
                BS.q2 -= a
            else:
                BS.ra -= a
                BS.rat -= a * (ev_t[i] - BS.tref)
    BS.i_in = max(BS.i_in - k, 0)
    BS.i_mid = max(BS.i_mid - k, 0)
    BS.i_out = max(BS.i_out - k, 0)


@njit(cache=True)
def finished_events(BS, policy):
    """How many leading events the burst state no longer needs."""
    return BS.i_out if policy == Policy.ADD else BS.i_in


@njit(cache=True)
def carrier_at(t, t_origin, carrier):
    """The carrier ``sin(2 pi f_c (t - t_origin))`` at any time (one ``sin``; used once per tick)."""
    return math.sin(2.0 * math.pi * carrier * (t - t_origin))


@njit(cache=True)
def synth(BS, ev_t, ev_a, n_ev, t_origin, rate, j0, j1, carrier, rise, decay, policy, out):
    """Audio samples ``j0 .. j1-1`` (time ``t_origin + j / rate``) into ``out[0 : j1-j0]``.

    Events ``ev_t[:n_ev]`` must be sorted; an event sounds from the first
    sample strictly after it. ``BS`` (from :func:`new_burst_state` for this
    carrier and rate, a record) carries the envelope and the carrier from call to call.
    Returns the number of samples limited to [-1, 1].
    """
    clipped = 0
    w = 2.0 * math.pi * carrier
    cd = BS.rc
    sd = BS.rs
    blk = CARRIER_BLOCK
    cr = BS.cc
    sr = BS.cs
    for j in range(j0, j1):
        if j % blk == 0:
            th = w * (j / rate)
            cr = math.cos(th)
            sr = math.sin(th)
        elif j == j0 and BS.cj != j:
            # not the continuation of the last call: rotate from the anchor of this block
            ja = j - j % blk
            th = w * (ja / rate)
            cr = math.cos(th)
            sr = math.sin(th)
            for _ in range(j - ja):
                cr, sr = cr * cd - sr * sd, sr * cd + cr * sd
        else:
            cr, sr = cr * cd - sr * sd, sr * cd + cr * sd
        t = t_origin + j / rate
        val = envelope_at(BS, ev_t, ev_a, n_ev, t, rise, decay, policy) * sr
        if val > 1.0:
            val = 1.0
            clipped += 1
        elif val < -1.0:
            val = -1.0
            clipped += 1
        out[j - j0] = val
    if j1 > j0:
        BS.cc = cr
        BS.cs = sr
        BS.cj = j1
    return clipped


@njit(cache=True, error_model="numpy")
def _seg(te, e0, a, t, rise, decay):
    """:func:`_segment` on explicit values (the same arithmetic, kept in registers by the offline loop)."""
    tau = t - te
    if tau < rise:
        return e0 + (a - e0) * (tau / rise)
    u = tau - rise
    if u < decay:
        r = 1.0 - u / decay
        return a * r * r
    return 0.0


@njit(cache=True, inline="always")
def _first_not_below(out, j, k, guess, base, limit):
    """First ``m`` in ``[j, k]`` with ``not (out[m] - base < limit)`` (``k`` if none), searched from ``guess``.

    ``out[j:k]`` is non-decreasing, so the predicate is false then true along it, and the search only
    steps from a guess near the answer: the test is the same comparison a sample-by-sample loop makes.
    """
    m = min(max(guess, j), k)
    while m > j and not (out[m - 1] - base < limit):
        m -= 1
    while m < k and out[m] - base < limit:
        m += 1
    return m


@njit(cache=True, inline="always")
def _first_not_below2(out, j, k, guess, te, rise, decay):
    """First ``m`` in ``[j, k]`` with ``not ((out[m] - te) - rise < decay)`` (``k`` if none), from ``guess``."""
    m = min(max(guess, j), k)
    while m > j and not ((out[m - 1] - te) - rise < decay):
        m -= 1
    while m < k and (out[m] - te) - rise < decay:
        m += 1
    return m


@njit(cache=True, inline="always")
def _first_after(out, j, k, guess, tn):
    """First ``m`` in ``[j, k]`` with ``tn < out[m]`` (``k`` if none), searched from ``guess`` (``out`` non-decreasing)."""
    m = min(max(guess, j), k)
    while m > j and tn < out[m - 1]:
        m -= 1
    while m < k and not tn < out[m]:
        m += 1
    return m


@njit(cache=True, inline="always")
def _index_near(t, t_origin, rate):
    """The sample index near time ``t`` (a starting guess for the searches above; any value is safe)."""
    g = (t - t_origin) * rate
    if not g > 0.0:
        return 0
    if g > 9.0e18:
        return 9 * 10 ** 18
    return int(g)


@njit(cache=True, error_model="numpy")
def sample_times(t_origin, rate, out):
    """``out[j] = t_origin + j / rate``, the sample times of a stream (bit for bit: the division by the rate
    is a multiply-add with the same bits, :mod:`.exactdiv`, where its conditions hold; a loop the compiler
    vectorises). A :class:`~.renderer.Renderer` keeps those of ``t_origin = 0`` from render to render."""
    _times_from(t_origin, rate, 0, out)


@intrinsic
def _bits_as_double(typingctx, i):
    """The float64 whose bits are those of the int64 ``i``."""
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return sig, codegen


#: 2**52: ``_bits_as_double(_TWO52_BITS | j) - _TWO52`` is ``float(j)`` for ``0 <= j < 2**52``.
_TWO52 = 4503599627370496.0
_TWO52_BITS = 0x4330000000000000


@njit(cache=True, inline="always", error_model="numpy")
def _times_from(t_origin, rate, j0, out):
    """``out[m] = t_origin + (j0 + m) / rate``: :func:`sample_times` of samples ``j0 ..``. The index is
    made a float by its bits (2**52 + j as a double, less 2**52: exact below 2**52), two instructions the
    compiler vectorises where ``float(j)`` of an int64 takes a scalar conversion per sample on CPUs without
    AVX-512."""
    if divisor_ok(rate) and j0 >= 0 and j0 + out.shape[0] < 2 ** 52:
        yr = 1.0 / rate
        for m in range(out.shape[0]):
            jf = _bits_as_double(_TWO52_BITS | (j0 + m)) - _TWO52
            out[m] = t_origin + div_fixed(jf, rate, yr)
    else:
        for m in range(out.shape[0]):
            out[m] = t_origin + (j0 + m) / rate


@njit(cache=True, inline="always", error_model="numpy")
def _fill_rise(ts, out, car, te, e0, a, rise, yrise, fast):
    """The rise of a segment at the sample times ``ts``, times the carrier samples ``car``, into ``out`` (one
    shape; ``ts`` may be ``out`` itself, then a loop in place)."""
    if out.shape[0] > 0 and fast and span_nonzero(ts[0] - te, ts[ts.shape[0] - 1] - te):
        for m in range(out.shape[0]):
            out[m] = (e0 + (a - e0) * div_nonzero(ts[m] - te, rise, yrise)) * car[m]
    else:
        for m in range(out.shape[0]):
            out[m] = (e0 + (a - e0) * ((ts[m] - te) / rise)) * car[m]


@njit(cache=True, inline="always", error_model="numpy")
def _fill_decay(ts, out, car, te, a, rise, decay, ydecay, fast):
    """The decay of a segment, as :func:`_fill_rise`."""
    if out.shape[0] > 0 and fast and span_nonzero((ts[0] - te) - rise, (ts[ts.shape[0] - 1] - te) - rise):
        for m in range(out.shape[0]):
            r = 1.0 - div_nonzero((ts[m] - te) - rise, decay, ydecay)
            out[m] = (a * r * r) * car[m]
    else:
        for m in range(out.shape[0]):
            r = 1.0 - ((ts[m] - te) - rise) / decay
            out[m] = (a * r * r) * car[m]


@njit(cache=True, inline="always", error_model="numpy")
def _fill_silence(out, car):
    """No burst playing: ``0 * car`` into ``out`` (the zero takes the carrier sample's sign, as the product does)."""
    for m in range(out.shape[0]):
        out[m] = 0.0 * car[m]


@njit(cache=True, inline="always", error_model="numpy")
def _fill_sums(ts, out, car, tref, ra, rat, q0, q1, q2, rise, decay, yrise, ydecay, fast):
    """The running sums of ``add`` between two transitions, as :func:`_fill_rise`."""
    d0 = ts[0] - tref
    d1 = ts[ts.shape[0] - 1] - tref
    if fast and span_nonzero(d0, d1) and span_nonzero(ra * d0 - rat, ra * d1 - rat):
        for m in range(out.shape[0]):
            dt = ts[m] - tref
            e = div_nonzero(ra * dt - rat, rise, yrise)
            x = div_nonzero(dt, decay, ydecay)
            e += q0 - 2.0 * q1 * x + q2 * x * x
            out[m] = (e if e > 0.0 else 0.0) * car[m]
    elif fast and span_nonzero(d0, d1) and ra * d0 - rat == 0.0 and ra * d1 - rat == 0.0:
        # no burst rising: the rise term is a zero on every sample (its sign cannot change the sum's
        # sample: a nonzero sum is the sum, a zero one gives 0 either way)
        for m in range(out.shape[0]):
            x = div_nonzero(ts[m] - tref, decay, ydecay)
            e = q0 - 2.0 * q1 * x + q2 * x * x
            out[m] = (e if e > 0.0 else 0.0) * car[m]
    else:
        for m in range(out.shape[0]):
            dt = ts[m] - tref
            e = (ra * dt - rat) / rise
            x = dt / decay
            e += q0 - 2.0 * q1 * x + q2 * x * x
            out[m] = (e if e > 0.0 else 0.0) * car[m]


@njit(cache=True, error_model="numpy")
def _envelope_fill(BS, ev_t, ev_a, n_ev, t_origin, rate, j0, n, rise, decay, policy, out, times, car):
    """``out[j] = E(t_origin + j / rate) * car[j - j0]`` for ``j0 <= j < n``: the envelope :func:`envelope_at`
    gives sample by sample (continued from the state ``BS``, left at sample ``n``), times the carrier
    samples ``car``. Returns a bound on the envelope over these samples: no sample's envelope exceeds it
    by more than rounding (``inf`` for ``add``, whose sums are not bounded here).

    The sample times first (:func:`sample_times` into ``out``; for a stream that starts at ``t_origin = 0``
    they are read from ``times`` instead if it holds at least ``n``, the times of a stream from 0 kept from
    an earlier call: ``0 + s`` is ``s``); then, run by run, the transitions before a
    sample are applied and the samples up to the next transition take the values of one piece of the
    envelope: for ``retrigger``/``max`` the rise, the decay and the silence of one segment, for ``add``
    the two running polynomials. Each piece is a loop without branches, which the compiler vectorises
    (the two divisions per sample included); every value is computed by the same operations as
    :func:`_segment` and :func:`_sums`, so bit for bit the same. The pieces' bounds come from the same
    comparisons, searched from the index the event time gives. Each sample's envelope is rounded before
    it is multiplied by its carrier sample: the product of the two passes this once was, bit for bit.
    """
    # the divisions by the rise and decay are multiply-adds with the same bits (.exactdiv) where its
    # conditions hold: on the divisors here, on each piece's dividends (monotone along it) at its two ends
    # the rows without their reference count: the views of them taken piece by piece change none
    out = borrowed(out)
    times = borrowed(times)
    car = borrowed(car)
    yrise = 1.0 / rise
    ydecay = 1.0 / decay
    fast = divisor_ok(rate) and divisor_ok(rise) and divisor_ok(decay)
    kept = t_origin == 0.0 and times.shape[0] >= n
    if kept:
        ts = times
    else:
        _times_from(t_origin, rate, j0, out[j0:n])
        ts = out
    if policy == Policy.ADD:
        j = j0
        while j < n:
            nxt = _add_advance(BS, ev_t, ev_a, n_ev, ts[j], rise, decay)
            k = _first_after(ts, j + 1, n, _index_near(nxt, t_origin, rate), nxt)
            v = out[j:k]
            cv = car[j - j0:k - j0]
            if BS.i_out == BS.i_in:
                _fill_silence(v, cv)
            elif kept:
                _fill_sums(times[j:k], v, cv, BS.tref, BS.ra, BS.rat, BS.q0, BS.q1, BS.q2, rise, decay, yrise, ydecay,
                           fast)
            else:
                _fill_sums(v, v, cv, BS.tref, BS.ra, BS.rat, BS.q0, BS.q1, BS.q2, rise, decay, yrise, ydecay, fast)
            j = k
        return np.inf
    retrigger = policy == Policy.RETRIGGER
    i_in = BS.i_in
    te = BS.te
    e0 = BS.e0
    a = BS.a
    amax = 0.0
    j = j0
    while j < n:
        t = ts[j]
        while i_in < n_ev and ev_t[i_in] < t:
            tn = ev_t[i_in]
            an = ev_a[i_in]
            e_now = _seg(te, e0, a, tn, rise, decay)
            if retrigger or an > e_now:
                te = tn
                e0 = e_now
                a = an
            i_in += 1
        k = n
        if i_in < n_ev:
            tn = ev_t[i_in]
            k = _first_after(ts, j + 1, n, _index_near(tn, t_origin, rate), tn)
        amax = max(amax, max(e0, a))
        # samples j .. k-1 play segment (te, e0, a): rise until tau >= rise, decay until u >= decay, then 0
        m1 = _first_not_below(ts, j, k, _index_near(te + rise, t_origin, rate), te, rise)
        v = out[j:m1]                    # (loops over views: the compiler vectorises them, not range(j, m1))
        if kept:
            _fill_rise(times[j:m1], v, car[j - j0:m1 - j0], te, e0, a, rise, yrise, fast)
        else:
            _fill_rise(v, v, car[j - j0:m1 - j0], te, e0, a, rise, yrise, fast)
        m2 = m1
        if m1 < k:
            m2 = _first_not_below2(ts, m1, k, _index_near(te + rise + decay, t_origin, rate), te, rise, decay)
            v = out[m1:m2]
            if kept:
                _fill_decay(times[m1:m2], v, car[m1 - j0:m2 - j0], te, a, rise, decay, ydecay, fast)
            else:
                _fill_decay(v, v, car[m1 - j0:m2 - j0], te, a, rise, decay, ydecay, fast)
        _fill_silence(out[m2:k], car[m2 - j0:k - j0])
        j = k
    BS.i_in = i_in
    BS.te = te
    BS.e0 = e0
    BS.a = a
    return amax


@njit(cache=True, inline="always", error_model="numpy")
def _limit(v, bound):
    """Limit the samples ``v`` to [-1, 1] in place and return how many were limited, unless the envelope
    ``bound`` of their group times ``1 + 1e-9`` is below 1: then none can be (see :func:`_synth_groups`)."""
    if bound * (1.0 + 1e-9) < 1.0:
        return 0
    clipped = 0
    for m in range(v.shape[0]):
        x = v[m]
        clipped += (x > 1.0) | (x < -1.0)
        x = 1.0 if x > 1.0 else x
        v[m] = -1.0 if x < -1.0 else x
    return clipped


#: Carrier blocks rotated side by side by :func:`_synth_groups` (four per 4-wide vector, a multiple of 4).
CARRIER_GROUP = 16


@intrinsic
def _rotate_blocks(typingctx, anchors, cd, sd, car, blk):
    """``car[b * blk + k]`` = the sine of carrier block ``b`` after ``k`` rotations, ``k < blk``, for the
    :data:`CARRIER_GROUP` blocks whose anchors are ``anchors = (cos_0, sin_0, cos_1, sin_1, ...)``; ``blk``
    a multiple of 4 (:data:`CARRIER_BLOCK`).

    The rotation of :func:`synth`, ``(c, s) -> (c cd - s sd, s cd + c sd)``, on four blocks at a time: their
    cosines in one 4-wide vector ``C`` and their sines in another ``S``, ``C' = C cd + S (-sd)``,
    ``S' = S cd + C sd``. Each lane is one IEEE product and one sum, the operations of the scalar recurrence
    (``x (-sd) = -(x sd)`` exactly, and adding it is subtracting ``x sd``), so every sample has the scalar
    loop's bits. Four steps' sine vectors (step by block) are transposed in registers into four samples of
    each block, stored as one vector each: no lane is taken out of a vector alone (storing lanes one by
    one took more shuffles than the rotation took arithmetic). numba has no vector type, so the loop is
    written here in LLVM IR, where the vectors stay in registers from step to step.
    """
    f64 = types.float64
    if not (isinstance(anchors, types.Array) and isinstance(car, types.Array) and anchors.dtype == f64
            and car.dtype == f64 and anchors.ndim == 1 and car.ndim == 1 and anchors.layout == "C"
            and car.layout == "C" and car.mutable and cd == f64 and sd == f64 and isinstance(blk, types.Integer)):
        return None
    sig = types.void(anchors, cd, sd, car, types.int64)

    def codegen(context, builder, signature, args):
        a_ty, _, _, c_ty, _ = signature.args
        ap = context.make_array(a_ty)(context, builder, args[0]).data
        cp = context.make_array(c_ty)(context, builder, args[3]).data
        cdv, sdv, nblk = args[1], args[2], args[4]
        dbl = ir.DoubleType()
        i32 = ir.IntType(32)
        i64 = ir.IntType(64)
        v4 = ir.VectorType(dbl, 4)
        undef = ir.Constant(v4, ir.Undefined)

        def splat(x):
            v = undef
            for i in range(4):
                v = builder.insert_element(v, x, ir.Constant(i32, i))
            return v

        def shuffle(a, b, lanes):
            return builder.shuffle_vector(a, b, ir.Constant(ir.VectorType(i32, 4), lanes))

        def vector_at(ptr, i):
            return builder.bitcast(builder.gep(ptr, [i]), v4.as_pointer())

        cds = splat(cdv)
        sds = splat(sdv)
        nsds = splat(builder.fsub(ir.Constant(dbl, -0.0), sdv))           # -sd exactly
        quads = CARRIER_GROUP // 4
        c_start, s_start = [], []
        for q in range(quads):
            # the anchors of blocks 4q .. 4q+3, (c, s) interleaved: two loads split into cosines and sines
            lo = builder.load(vector_at(ap, ir.Constant(i64, 8 * q)), align=8)
            hi = builder.load(vector_at(ap, ir.Constant(i64, 8 * q + 4)), align=8)
            c_start.append(shuffle(lo, hi, [0, 2, 4, 6]))
            s_start.append(shuffle(lo, hi, [1, 3, 5, 7]))
        pre = builder.block
        loop = builder.append_basic_block("rotate.loop")
        done = builder.append_basic_block("rotate.done")
        builder.cbranch(builder.icmp_signed(">", nblk, ir.Constant(i64, 0)), loop, done)
        builder.position_at_end(loop)
        k = builder.phi(i64)
        k.add_incoming(ir.Constant(i64, 0), pre)
        c_phi, s_phi, c_next, s_next = [], [], [], []
        for q in range(quads):
            c_phi.append(builder.phi(v4))
            c_phi[q].add_incoming(c_start[q], pre)
            s_phi.append(builder.phi(v4))
            s_phi[q].add_incoming(s_start[q], pre)
        for q in range(quads):
            c, s = c_phi[q], s_phi[q]
            steps = []                   # steps[j][b]: the sine of block 4q + b after k + j rotations
            for _ in range(4):
                steps.append(s)
                c, s = (builder.fadd(builder.fmul(c, cds), builder.fmul(s, nsds)),
                        builder.fadd(builder.fmul(s, cds), builder.fmul(c, sds)))
            c_next.append(c)
            s_next.append(s)
            even01 = shuffle(steps[0], steps[1], [0, 4, 2, 6])
            odd01 = shuffle(steps[0], steps[1], [1, 5, 3, 7])
            even23 = shuffle(steps[2], steps[3], [0, 4, 2, 6])
            odd23 = shuffle(steps[2], steps[3], [1, 5, 3, 7])
            blocks = (shuffle(even01, even23, [0, 1, 4, 5]), shuffle(odd01, odd23, [0, 1, 4, 5]),
                      shuffle(even01, even23, [2, 3, 6, 7]), shuffle(odd01, odd23, [2, 3, 6, 7]))
            for b in range(4):
                idx = builder.add(builder.mul(ir.Constant(i64, 4 * q + b), nblk), k)
                builder.store(blocks[b], vector_at(cp, idx), align=8)
        k4 = builder.add(k, ir.Constant(i64, 4))
        k.add_incoming(k4, builder.block)
        for q in range(quads):
            c_phi[q].add_incoming(c_next[q], builder.block)
            s_phi[q].add_incoming(s_next[q], builder.block)
        builder.cbranch(builder.icmp_signed("<", k4, nblk), loop, done)
        builder.position_at_end(done)
        return context.get_dummy_value()
    return sig, codegen


@njit(cache=True, error_model="numpy")
def carrier_anchors(carrier, rate, nblocks):
    """The carrier's anchors of the first ``nblocks`` blocks: ``(cos, sin)`` of its phase at samples
    ``0, CARRIER_BLOCK, 2 CARRIER_BLOCK, ...`` (the values :func:`synth` computes there), interleaved in one
    row of ``2 nblocks`` (the form :func:`_rotate_blocks` reads)."""
    w = 2.0 * math.pi * carrier
    out = np.empty(2 * nblocks)
    for b in range(nblocks):
        th = w * ((b * CARRIER_BLOCK) / rate)
        out[2 * b] = math.cos(th)
        out[2 * b + 1] = math.sin(th)
    return out


@njit(cache=True, error_model="numpy")
def _synth_groups(BS, ev_t, ev_a, n_ev, t_origin, rate, n, carrier, rise, decay, policy, out, known, times):
    """Samples ``0 .. n-1`` of a stream from a fresh ``BS`` into ``out[:n]``; returns the number limited.

    The carrier samples of :func:`synth` (anchors at multiples of :data:`CARRIER_BLOCK`, the same rotation
    in between), but :data:`CARRIER_GROUP` blocks are rotated side by side into a scratch row
    (:func:`_rotate_blocks`, four blocks per vector): the blocks are independent, so their recurrences
    fill the floating-point pipeline that one recurrence leaves mostly waiting. The group's envelope
    is then written multiplied by them (:func:`_envelope_fill`), and the group is limited to [-1, 1] only
    where its envelope bound times ``1 + 1e-9`` is not below 1: below, every product is below 1 in
    magnitude (a carrier sample is within 1e-12 of the unit circle after a block's rotations, an envelope
    sample within rounding of the bound), so the limiting would change and count nothing. The last
    blocks (fewer than a group) take the scalar rotation into the scratch row, then the same steps. ``known`` holds the anchors of the first blocks
    (:func:`carrier_anchors`, any number of them; the others are computed here): a renderer keeps them
    from stream to stream, since they depend only on the carrier and the rate.
    """
    out = borrowed(out)
    known = borrowed(known)
    times = borrowed(times)
    w = 2.0 * math.pi * carrier
    cd = BS.rc
    sd = BS.rs
    blk = CARRIER_BLOCK
    grp = CARRIER_GROUP
    clipped = 0
    nb = (n + blk - 1) // blk
    car = np.empty(grp * blk)
    anchors = np.empty(2 * grp)
    b = 0
    nknown = known.shape[0] // 2
    while b + grp < nb:
        j0 = b * blk
        if b + grp <= nknown:
            _rotate_blocks(known[2 * b:2 * (b + grp)], cd, sd, car, blk)
        else:
            for g in range(grp):
                th = w * ((j0 + g * blk) / rate)
                anchors[2 * g] = math.cos(th)
                anchors[2 * g + 1] = math.sin(th)
            _rotate_blocks(anchors, cd, sd, car, blk)
        amax = _envelope_fill(BS, ev_t, ev_a, n_ev, t_origin, rate, j0, j0 + grp * blk, rise, decay, policy, out,
                              times, car)
        clipped += _limit(out[j0:j0 + grp * blk], amax)
        b += grp
    # the last blocks (fewer than a group): the scalar rotation into the scratch row, then as a group
    j0 = b * blk
    cr = BS.cc
    sr = BS.cs
    for j in range(j0, n):
        if j % blk == 0:
            if j // blk < nknown:
                cr = known[2 * (j // blk)]
                sr = known[2 * (j // blk) + 1]
            else:
                th = w * (j / rate)
                cr = math.cos(th)
                sr = math.sin(th)
        else:
            cr, sr = cr * cd - sr * sd, sr * cd + cr * sd
        car[j - j0] = sr
    amax = _envelope_fill(BS, ev_t, ev_a, n_ev, t_origin, rate, j0, n, rise, decay, policy, out, times, car)
    clipped += _limit(out[j0:n], amax)
    if n > 0:
        BS.cc = cr
        BS.cs = sr
        BS.cj = n
    return clipped


@njit(cache=True)
def synth_stream(BS, ev_t, ev_a, n_ev, t_origin, rate, n, carrier, rise, decay, policy, out, anchors=None,
                 times=None):
    """A whole stream at once: samples ``0 .. n-1`` into ``out[:n]`` from a fresh ``BS``.

    Bit for bit what :func:`synth` writes for ``j0 = 0, j1 = n`` (the tests
    check it), group by group of carrier blocks
    (:func:`_synth_groups`; ``anchors``: the carrier's first anchors from
    :func:`carrier_anchors`, optional). ``times``: optional,
    :func:`sample_times` of a stream from 0 at this rate, read instead of
    computed when ``t_origin`` is 0 and it holds at least ``n``. Returns the
    number of samples limited to [-1, 1].
    """
    return _synth_groups(BS, ev_t, ev_a, n_ev, t_origin, rate, n, carrier, rise, decay, policy, out,
                         np.empty(0) if anchors is None else anchors, np.empty(0) if times is None else times)


def render_bursts(event_time, event_amplitude, t_start, duration, rate, carrier_hz=300.0,
                  rise_s=0.005, decay_s=0.030, policy="retrigger", anchors=None, times=None):
    """Offline burst audio for sorted events.

    Parameters
    ----------
    event_time, event_amplitude : ndarray (n_events,), float64
        Event times (s) and peak amplitudes (full scale 1.0).
    t_start, duration : float
        First sample time and length of the stream, s; the stream has
        ``floor(duration * rate + 1e-9) + 1`` samples.
    rate : float
        Audio sample rate, Hz.
    anchors : ndarray, optional
        :func:`carrier_anchors` of this carrier and rate for any number of
        first blocks (the samples do not change; those anchors are not
        computed again).
    times : ndarray, optional
        :func:`sample_times` ``(0.0, rate, m)`` for any ``m``: read instead
        of computed when ``t_start`` is 0 and ``m`` covers the stream (the
        samples do not change).

    Returns
    -------
    audio : ndarray (n,), float64 in [-1, 1]
    clipped : int
    """
    pid = policy_id(policy)
    n = audio_length(duration, rate)
    out = np.empty(n)
    et = np.ascontiguousarray(event_time, dtype=np.float64)
    ea = np.ascontiguousarray(event_amplitude, dtype=np.float64)
    clipped = synth_stream(new_burst_state(carrier_hz, rate)[0], et, ea, et.shape[0], float(t_start), float(rate), n,
                           float(carrier_hz), float(rise_s), float(decay_s), pid, out,
                           np.empty(0) if anchors is None else anchors, np.empty(0) if times is None else times)
    return out, int(clipped)


def burst_envelope(event_time, event_amplitude, t_start, duration, rate, rise_s=0.005, decay_s=0.030,
                   policy="retrigger"):
    """The envelope ``E(t)`` that :func:`render_bursts` puts on the carrier (same samples), ndarray (n,)."""
    pid = policy_id(policy)
    n = audio_length(duration, rate)
    et = np.ascontiguousarray(event_time, dtype=np.float64)
    ea = np.ascontiguousarray(event_amplitude, dtype=np.float64)
    return _envelope_samples(new_burst_state(300.0, rate)[0], et, ea, et.shape[0], float(t_start), float(rate), n,
                             float(rise_s), float(decay_s), pid)


@njit(cache=True)
def _envelope_samples(BS, ev_t, ev_a, n_ev, t_origin, rate, n, rise, decay, policy):
    out = np.empty(n)
    for j in range(n):
        out[j] = envelope_at(BS, ev_t, ev_a, n_ev, t_origin + j / rate, rise, decay, policy)
    return out
