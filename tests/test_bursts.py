"""Bursts on one phase-continuous carrier: published envelope, amplitude convention, no steps, 300 Hz."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shapedisplay.table.devices import load_device
from shapedisplay.render.bursts import BURST_POLICIES, burst_envelope, render_bursts
from shapedisplay.render.models import simulate_pad

RISE, DECAY, FC, RATE = 0.005, 0.030, 300.0, 48_000.0
CARRIER_STEP = 2.0 * math.sin(math.pi * FC / RATE)      # largest sample step of a unit carrier


def published(tau):
    tau = np.asarray(tau, dtype=np.float64)
    return np.where(tau < 0, 0.0, np.where(tau < RISE, tau / RISE,
                                           np.where(tau < RISE + DECAY, (1 - (tau - RISE) / DECAY) ** 2, 0.0)))


def segment(tau, e0, A):
    """A burst's envelope ``tau`` s after its event, rising linearly from ``e0`` to ``A`` then decaying as published."""
    tau = np.asarray(tau, dtype=np.float64)
    decay = A * np.clip(1 - (tau - RISE) / DECAY, 0.0, None) ** 2
    return np.where(tau < 0, 0.0, np.where(tau < RISE, e0 + (A - e0) * tau / RISE,
                                           np.where(tau < RISE + DECAY, decay, 0.0)))


def reference_envelope(et, ea, t0, n, policy, rate=RATE):
    """The overlap rules written out sample by sample (the answer the engine must give, not its algorithm).

    ``add``: the sum of every burst's published envelope. ``retrigger``: each event restarts the envelope from
    its value at the event time, rising to the new peak. ``max``: only an event whose peak exceeds the
    envelope's value at its time does so; a weaker one is absorbed. An event sounds from the first sample after it.
    """
    tt = t0 + np.arange(n) / rate
    if policy == "add":
        return sum((segment(tt - t, 0.0, a) for t, a in zip(et, ea)), np.zeros(n))
    out, cur, k = np.zeros(n), None, 0
    for j, tj in enumerate(tt):
        while k < len(et) and et[k] < tj:
            now = 0.0 if cur is None else float(segment(et[k] - cur[0], cur[1], cur[2]))
            if policy == "retrigger" or ea[k] > now:
                cur = (et[k], now, ea[k])
            k += 1
        out[j] = 0.0 if cur is None else float(segment(tj - cur[0], cur[1], cur[2]))
    return out


def test_envelope_closed_form_at_its_landmarks():
    """Linear rise (half way: 0.5), peak 1 at ``rise``, quadratic decay (half way: 0.25), silence after."""
    env = burst_envelope(np.array([0.0]), np.array([1.0]), 0.0, 0.05, RATE)
    at = lambda t: env[int(round(t * RATE))]                                     # noqa: E731
    assert env[0] == 0.0
    assert math.isclose(at(RISE / 2), 0.5, abs_tol=1e-12)
    assert math.isclose(at(RISE), 1.0, abs_tol=1e-12)
    assert math.isclose(at(RISE + DECAY / 2), 0.25, abs_tol=1e-12)
    assert not env[int(round((RISE + DECAY) * RATE)) + 1:].any()
    tt = np.arange(env.size) / RATE
    assert np.max(np.abs(env - published(tt))) <= 1e-12


@pytest.mark.parametrize("policy", list(BURST_POLICIES))
def test_isolated_burst_plays_the_published_envelope_on_the_running_carrier(policy):
    te, A, t0 = 0.0123456, 0.7, 0.25
    audio, clipped = render_bursts(np.array([te + t0]), np.array([A]), t0, 0.1, RATE, policy=policy)
    env = burst_envelope(np.array([te + t0]), np.array([A]), t0, 0.1, RATE, policy=policy)
    tt = np.arange(audio.size) / RATE
    assert np.max(np.abs(env - A * published(tt - te))) <= 1e-9 * A
    # the carrier runs from the first sample and is not restarted by the burst
    assert np.max(np.abs(audio - A * published(tt - te) * np.sin(2 * np.pi * FC * tt))) <= 1e-9 * A
    assert clipped == 0 and audio.size == int(0.1 * RATE) + 1


@settings(max_examples=40, deadline=None)
@given(te=st.floats(0.001, 0.02), A=st.floats(0.01, 1.0))
def test_amplitude_convention_envelope_peak_is_A(te, A):
    """A is the peak of the envelope on the unit carrier; the largest sample is within [0.92 A, A] whatever the phase.

    0.9199 A is the continuous-time minimum over the carrier phase at the envelope peak of
    max_t E(t) |sin(phase(t))|; sampling at 48 kHz lowers it by at most cos(pi f_c / rate).
    """
    audio, _ = render_bursts(np.array([te]), np.array([A]), 0.0, 0.06, RATE)
    env = burst_envelope(np.array([te]), np.array([A]), 0.0, 0.06, RATE)
    peak_sample_env = A * (1 - 1 / (RISE * RATE))              # the envelope one sample away from its peak
    assert peak_sample_env <= env.max() <= A * (1 + 1e-12)
    assert 0.9199 * math.cos(math.pi * FC / RATE) * A <= np.abs(audio).max() <= A * (1 + 1e-12)
    tt = np.arange(audio.size) / RATE
    assert np.max(np.abs(audio - env * np.sin(2 * np.pi * FC * tt))) <= 1e-9 * A


def _stroke_events(V, N=1.0, duration=1.5):
    dev = load_device("handheld-stick")            # the published Konyo pad, B = 0.25 / N
    r = simulate_pad("exact", V=V, N=N, pad=dev.pad, friction=dev.friction, tick_rate=10_000, duration=duration)
    return r.event_time, dev.burst.gain * r.event_amplitude


def step_ratio(audio, env):
    """Largest drive step over the carrier's largest step at the envelope of the current carrier cycle."""
    w = int(round(RATE / FC))
    pad = np.pad(env, w, mode="edge")
    cyc = np.lib.stride_tricks.sliding_window_view(pad, 2 * w + 1).max(axis=1)
    cur = np.maximum(cyc[:-1], cyc[1:])
    steps = np.abs(np.diff(audio))
    ok = cur > 0.02 * env.max()
    assert steps[~ok].max(initial=0.0) <= CARRIER_STEP * 0.02 * env.max() * 1.05
    return float(np.max(steps[ok] / (CARRIER_STEP * cur[ok])))


def spectral_peak(audio):
    spec = np.abs(np.fft.rfft(audio * np.hanning(audio.size)))
    f = np.fft.rfftfreq(audio.size, 1 / RATE)
    return float(f[np.argmax(spec)])


@pytest.mark.parametrize("V", [0.020, 0.030])
@pytest.mark.parametrize("policy", list(BURST_POLICIES))
def test_overlapping_bursts_never_step_and_stay_at_300_hz(V, policy):
    """N = 1 N on the published pad: events every 5.7-8.5 ms, far closer than one 35 ms burst."""
    et, ea = _stroke_events(V)
    assert np.median(np.diff(et)) < 0.010 and et.size > 100
    dur = 1.5
    audio, clipped = render_bursts(et, ea, 0.0, dur, RATE, policy=policy)
    env = burst_envelope(et, ea, 0.0, dur, RATE, policy=policy)
    assert clipped == 0
    assert step_ratio(audio, env) <= 1.05
    assert abs(spectral_peak(audio) - FC) <= 3.0
    # relative to the burst amplitude itself: the envelope never exceeds the sum of the live bursts
    assert np.abs(np.diff(audio)).max() <= 1.05 * CARRIER_STEP * env.max()


def test_add_is_the_sum_and_max_absorbs_weaker_bursts():
    et = np.array([0.010, 0.016, 0.020, 0.060])
    ea = np.array([0.3, 0.2, 0.25, 0.1])
    dur = 0.12
    tt = np.arange(int(dur * RATE) + 1) / RATE
    total = sum(a * published(tt - t) for t, a in zip(et, ea))
    add = burst_envelope(et, ea, 0.0, dur, RATE, policy="add")
    assert np.max(np.abs(add - total)) <= 1e-12
    mx = burst_envelope(et, ea, 0.0, dur, RATE, policy="max")
    re = burst_envelope(et, ea, 0.0, dur, RATE, policy="retrigger")
    j = int(0.016 * RATE) + 1
    # max: the 0.2 burst at 16 ms is weaker than the envelope playing (0.28): absorbed, the first goes on;
    # the 0.25 burst at 20 ms beats the envelope then (0.21) and takes over from its value
    k = int(0.020 * RATE) + 1
    assert np.allclose(mx[:k], 0.3 * published(tt[:k] - 0.010), atol=1e-12)
    e20 = 0.3 * published(0.020 - 0.010)
    assert mx[k] == pytest.approx(e20 + (0.25 - e20) * (tt[k] - 0.020) / RISE, abs=1e-12)
    # retrigger: the envelope turns at 16 ms from its value towards 0.2 (no step)
    e16 = 0.3 * published(0.016 - 0.010)
    assert re[j] == pytest.approx(e16 + (0.2 - e16) * (tt[j] - 0.016) / RISE, abs=1e-12)
    for e in (add, mx, re):
        assert np.max(np.abs(np.diff(e))) <= 1.001 * ea.sum() / (RISE * RATE)      # continuous envelopes
    # the 60 ms burst starts from silence under every policy
    i = int(0.06 * RATE) + 1
    for e in (mx, re):
        assert np.allclose(e[i:], 0.1 * published(tt[i:] - 0.06), atol=1e-12)


@pytest.mark.parametrize("policy", sorted(BURST_POLICIES))
def test_clipping_is_counted_sample_by_sample(policy):
    """Samples beyond full scale are limited to it and counted: the count is that of the unlimited stream's
    samples beyond 1 (none for peaks at or just below full scale)."""
    rng = np.random.default_rng(7)
    et = np.sort(rng.uniform(0.0, 0.5, 60))
    for peak in (1.0 - 2e-9, 1.0, 1.0 + 1e-6, 1.3, 3.0):
        ea = np.full(et.size, peak)
        audio, clipped = render_bursts(et, ea, 0.0, 0.55, RATE, policy=policy)
        tt = np.arange(audio.size) / RATE
        raw = reference_envelope(et, ea, 0.0, tt.size, policy) * np.sin(2 * np.pi * FC * tt)
        assert clipped == np.count_nonzero(np.abs(raw) > 1.0), peak
        assert np.max(np.abs(audio - np.clip(raw, -1.0, 1.0))) <= 1e-11, peak
        if peak <= 1.0 and policy != "add":
            assert clipped == 0, peak
        if peak >= 1.3:
            assert clipped > 0, peak
    ad, clipped_add = render_bursts(np.array([0.010, 0.0101, 0.0102]), np.array([0.5, 0.5, 0.5]), 0.0, 0.06, RATE,
                                    policy=policy)
    assert (clipped_add > 0) == (policy == "add") and np.abs(ad).max() <= 1.0


@pytest.mark.parametrize("V", [0.020, 0.030])
def test_renderer_drive_on_the_published_pad_every_policy(V):
    """End to end: a constant N = 1 N table played by the renderer, every policy: no step, 300 Hz."""
    from shapedisplay.render import Renderer
    from shapedisplay.reports.presets import constant_table
    from shapedisplay.reports.studies import line_stroke

    dev = load_device("handheld-stick")
    table = constant_table(1.0, dev)
    for policy in BURST_POLICIES:
        r = Renderer(table, device=dev, burst_policy=policy, audio_rate=RATE)
        res = r.render(line_stroke(0.0, V * 1.2, V, r.tick_rate))
        env = burst_envelope(res.event_time, res.event_amplitude, res.t[0], res.duration, RATE, policy=policy)
        assert res.event_time.size > 100 and res.clipped == 0
        assert step_ratio(res.audio, env) <= 1.05
        assert abs(spectral_peak(res.audio) - FC) <= 3.0


@pytest.mark.parametrize("policy", sorted(BURST_POLICIES))
def test_overlap_rules_against_their_sample_by_sample_reference(policy):
    """Random overlapping events (a start before the stream, several within one rise) and events exactly on
    sample times, several at one time: the envelope is the rule's reference to rounding."""
    rng = np.random.default_rng(11)
    for _ in range(4):
        ne = int(rng.integers(1, 60))
        et = np.sort(rng.uniform(-0.01, 0.3, ne))
        ea = rng.uniform(0.0, 0.8, ne)
        t0 = float(rng.uniform(-0.005, 0.005))
        env = burst_envelope(et, ea, t0, 0.32, RATE, policy=policy)
        assert np.max(np.abs(env - reference_envelope(et, ea, t0, env.size, policy))) <= 1e-12
    t0, n = 0.0125, 3000
    js = np.array([0, 5, 5, 6, 700, 701, 1500, 1500, 1500, 2999])
    et, ea = t0 + js / RATE, np.linspace(0.2, 1.4, js.size)
    env = burst_envelope(et, ea, t0, (n - 1) / RATE, RATE, policy=policy)
    assert env.size == n and env.max() > 0.1
    assert np.max(np.abs(env - reference_envelope(et, ea, t0, n, policy))) <= 1e-12


@pytest.mark.parametrize("carrier, rate", [(300.0, 48000.0), (250.0, 44100.0), (1000.5, 96000.0), (37.0, 8000.0),
                                           (3000.0, 8000.0)])
def test_carrier_keeps_its_phase_over_a_long_stream(carrier, rate):
    """Bursts seconds apart ride one carrier ``sin(2 pi f_c j / rate)`` started at the first sample, never
    restarted: over 2.6 s the drive is envelope times that carrier to the rounding of the phase itself
    (a few ulps of ``2 pi f_c t``), at other carrier frequencies and rates too."""
    et = np.array([0.001, 0.4, 0.41, 0.9, 2.0, 2.5])
    ea = np.array([0.7, 0.6, 0.2, 0.9, 0.5, 0.99])
    audio, clipped = render_bursts(et, ea, 0.0, 2.6, rate, carrier)
    env = burst_envelope(et, ea, 0.0, 2.6, rate)
    j = np.arange(audio.size, dtype=np.float64)
    cycles = np.fmod(j * carrier, rate) / rate              # j * f_c / rate mod 1, exact up to the division
    phase_ulps = 2 * np.pi * carrier * (j / rate) * np.finfo(np.float64).eps
    assert clipped == 0
    assert np.all(np.abs(audio - env * np.sin(2 * np.pi * cycles)) <= env * (1e-13 + 4 * phase_ulps))
