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
exact phase at every multiple of :data:`CARRIER_BLOCK` samples. The anchors
depend only on ``j``, so a stream synthesised in one call (offline) or tick
by tick (online) is the same, bit for bit, and the phase error stays below
``CARRIER_BLOCK`` rotations' round-off (~1e-14 rad).

One implementation
------------------
The bursts are the C engine's (``engine/sd_render.c``): the renderer
plays them tick by tick, and :func:`render_bursts` / :func:`burst_envelope`
play a list of events through the same code (``sd_render_events``), for
reports and tests that start from events rather than a table.
"""
from __future__ import annotations

import numpy as np

from shapedisplay.render.layouts import BURST_POLICIES  # noqa: F401 (the policies' home is .layouts)
from shapedisplay.render.settings import MAX_AUDIO_SAMPLES, audio_length, policy_id  # noqa: F401 (their home is .settings)

#: Carrier re-anchored with sin/cos every this many samples (rotation in between; C: SD_CARRIER_BLOCK).
CARRIER_BLOCK = 64


def _events(event_time, event_amplitude):
    et = np.ascontiguousarray(event_time, dtype=np.float64)
    ea = np.ascontiguousarray(event_amplitude, dtype=np.float64)
    if et.ndim != 1 or et.shape != ea.shape:
        raise ValueError(f"event times and amplitudes must be two 1-D arrays of one length (got {et.shape}, "
                         f"{ea.shape})")
    return et, ea


def _play(event_time, event_amplitude, t_start, duration, rate, carrier_hz, rise_s, decay_s, policy, envelope_only):
    from shapedisplay.render.native import library
    pid = policy_id(policy)
    n = audio_length(duration, rate)
    et, ea = _events(event_time, event_amplitude)
    out = np.empty(n)
    clipped = library().sd_render_events(et.ctypes.data, ea.ctypes.data, et.shape[0], float(t_start), float(rate),
                                         n, float(carrier_hz), float(rise_s), float(decay_s), pid,
                                         int(envelope_only), out.ctypes.data)
    return out, int(clipped)


def render_bursts(event_time, event_amplitude, t_start, duration, rate, carrier_hz=300.0,
                  rise_s=0.005, decay_s=0.030, policy="retrigger"):
    """Offline burst audio for sorted events, played by the C engine's bursts.

    Parameters
    ----------
    event_time, event_amplitude : ndarray (n_events,), float64
        Event times (s), sorted, and peak amplitudes (full scale 1.0).
    t_start, duration : float
        First sample time and length of the stream, s; the stream has
        ``floor(duration * rate + 1e-9) + 1`` samples.
    rate : float
        Audio sample rate, Hz.
    carrier_hz, rise_s, decay_s : float
        Carrier frequency (Hz), envelope rise and decay (s).
    policy : {"retrigger", "add", "max"}

    Returns
    -------
    audio : ndarray (n,), float64 in [-1, 1]
    clipped : int
        Samples limited to full scale.
    """
    return _play(event_time, event_amplitude, t_start, duration, rate, carrier_hz, rise_s, decay_s, policy, False)


def burst_envelope(event_time, event_amplitude, t_start, duration, rate, rise_s=0.005, decay_s=0.030,
                   policy="retrigger"):
    """The envelope ``E(t)`` that :func:`render_bursts` puts on the carrier (same samples), ndarray (n,)."""
    return _play(event_time, event_amplitude, t_start, duration, rate, 300.0, rise_s, decay_s, policy, True)[0]
