"""Vibrotactile bursts at stick-to-slip events (Konyo et al.'s Vib-Touch bursts).

Each event at time ``t_e`` with amplitude ``A`` plays
``A * env(t - t_e) * sin(2 pi f_c (t - t_e))`` for ``t >= t_e``: the carrier
(300 Hz by default) starts at the sub-sample event time with zero phase; the
envelope rises linearly over ``rise`` (5 ms) and decays quadratically,
``(1 - (tau - rise) / decay)^2``, over ``decay`` (30 ms).

Overlap policies (:data:`BURST_POLICIES`):

* ``retrigger`` (default) — a new burst replaces the one playing;
* ``add`` — bursts add up; the sum is limited to [-1, 1];
* ``max`` — each sample plays the burst whose current envelope
  (``A * env``) is largest.

Output samples are limited to [-1, 1] (full scale); every limited sample is
counted and reported as ``clipped``, never silent.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..errors import InputError, unknown_key
from .layouts import BURST_POLICIES, Policy

#: See shapedisplay.runtime.codegen: numba's cache does not notice changes to layouts.py (Policy).
KERNEL_SOURCES_SHA256 = "207efa262d2aeea50e3df0e69cde3c9e8d64ae483ac3910b4acc98e3e2790f5b"
#: Most audio samples one offline render writes (1000 s at 48 kHz; 384 MB as float64).
MAX_AUDIO_SAMPLES = 48_000_001


def audio_length(duration: float, rate: float) -> int:
    """Samples ``floor(duration * rate + 1e-9) + 1`` of an offline stream; refused beyond :data:`MAX_AUDIO_SAMPLES`."""
    n = duration * rate
    if not (math.isfinite(n) and math.floor(n + 1e-9) + 1 <= MAX_AUDIO_SAMPLES):
        raise InputError(f"audio of {duration:.4g} s at {rate:g} Hz needs {n:.4g} samples, more than the "
                         f"{MAX_AUDIO_SAMPLES:,} of one offline render (shorten the path or lower the audio rate)")
    return int(math.floor(n + 1e-9)) + 1


def policy_id(name: str) -> int:
    """Number of burst policy ``name`` (:data:`~.layouts.BURST_POLICIES`, shared with C)."""
    if name not in BURST_POLICIES:
        raise unknown_key("burst policy", name, BURST_POLICIES)
    return BURST_POLICIES[name]


@njit(cache=True)
def envelope(tau, rise, decay):
    """Burst envelope at time ``tau`` (s) after the event, in [0, 1]."""
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
def burst_value(t, ev_t, ev_a, lo, hi, carrier, rise, decay, policy):
    """Unlimited drive value at time ``t`` from events ``lo..hi-1`` (sorted, all <= t)."""
    dur = rise + decay
    if hi <= lo:
        return 0.0
    w = 2.0 * math.pi * carrier
    if policy == Policy.RETRIGGER:
        tau = t - ev_t[hi - 1]
        if tau >= dur:
            return 0.0
        return ev_a[hi - 1] * envelope(tau, rise, decay) * math.sin(w * tau)
    acc = 0.0
    best = -1.0
    for i in range(lo, hi):
        tau = t - ev_t[i]
        if tau >= dur or tau < 0.0:
            continue
        e = ev_a[i] * envelope(tau, rise, decay)
        if policy == Policy.ADD:
            acc += e * math.sin(w * tau)
        elif e > best:
            best = e
            acc = e * math.sin(w * tau)
    return acc


@njit(cache=True)
def synth(ev_t, ev_a, n_ev, t_origin, rate, j0, j1, carrier, rise, decay, policy, out):
    """Audio samples ``j0 .. j1-1`` (time ``t_origin + j / rate``) into ``out[0 : j1-j0]``.

    Events ``ev_t[:n_ev]`` must be sorted; an event sounds from the first
    sample strictly after it (its value at its own time is 0 anyway), so
    an event landing exactly on a sample gives the same stream offline
    and tick by tick. Returns the number of samples
    limited to [-1, 1].
    """
    dur = rise + decay
    lo = 0
    hi = 0
    clipped = 0
    w = 2.0 * math.pi * carrier
    cd = math.cos(w / rate)
    sd = math.sin(w / rate)
    cur = -1
    cr = 0.0
    sr = 0.0
    for j in range(j0, j1):
        t = t_origin + j / rate
        while hi < n_ev and ev_t[hi] < t:
            hi += 1
        if policy == Policy.RETRIGGER:
            # one burst at a time: the carrier advances by a rotation per sample
            # (re-anchored with sin/cos at each new burst and at each call)
            val = 0.0
            if hi > 0:
                i = hi - 1
                tau = t - ev_t[i]
                if tau < dur:
                    if i != cur:
                        cur = i
                        cr = math.cos(w * tau)
                        sr = math.sin(w * tau)
                    else:
                        cr, sr = cr * cd - sr * sd, sr * cd + cr * sd
                    val = ev_a[i] * envelope(tau, rise, decay) * sr
        else:
            while lo < hi and ev_t[lo] + dur <= t:
                lo += 1
            val = burst_value(t, ev_t, ev_a, lo, hi, carrier, rise, decay, policy)
        if val > 1.0:
            val = 1.0
            clipped += 1
        elif val < -1.0:
            val = -1.0
            clipped += 1
        out[j - j0] = val
    return clipped


def render_bursts(event_time, event_amplitude, t_start, duration, rate, carrier_hz=300.0,
                  rise_s=0.005, decay_s=0.030, policy="retrigger"):
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

    Returns
    -------
    audio : ndarray (n,), float64 in [-1, 1]
    clipped : int
    """
    pid = policy_id(policy)
    n = audio_length(duration, rate)
    out = np.zeros(n)
    et = np.ascontiguousarray(event_time, dtype=np.float64)
    ea = np.ascontiguousarray(event_amplitude, dtype=np.float64)
    clipped = synth(et, ea, et.shape[0], float(t_start), float(rate), 0, n, float(carrier_hz),
                    float(rise_s), float(decay_s), pid, out)
    return out, int(clipped)
