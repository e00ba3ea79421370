"""Bursts on one phase-continuous carrier: published envelope, amplitude convention, no steps, 300 Hz."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shapedisplay.devices import load_device
from shapedisplay.runtime.bursts import (BURST_POLICIES, burst_envelope, envelope, new_burst_state,
                                         render_bursts, synth)
from shapedisplay.runtime.models import simulate_pad

RISE, DECAY, FC, RATE = 0.005, 0.030, 300.0, 48_000.0
CARRIER_STEP = 2.0 * math.sin(math.pi * FC / RATE)      # largest sample step of a unit carrier


def published(tau):
    tau = np.asarray(tau, dtype=np.float64)
    return np.where(tau < 0, 0.0, np.where(tau < RISE, tau / RISE,
                                           np.where(tau < RISE + DECAY, (1 - (tau - RISE) / DECAY) ** 2, 0.0)))


def test_envelope_function():
    assert envelope(-1e-9, RISE, DECAY) == 0.0
    assert math.isclose(envelope(0.0025, RISE, DECAY), 0.5)
    assert math.isclose(envelope(RISE, RISE, DECAY), 1.0)
    assert math.isclose(envelope(RISE + DECAY / 2, RISE, DECAY), 0.25)
    assert envelope(RISE + DECAY + 1e-9, RISE, DECAY) == 0.0


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


@pytest.mark.parametrize("policy", list(BURST_POLICIES))
def test_tick_by_tick_synthesis_equals_one_call(policy):
    """The state carries the envelope between calls, the carrier anchors depend only on the sample index."""
    et, ea = _stroke_events(0.03, duration=0.3)
    n = int(0.3 * RATE) + 1
    whole, c1 = render_bursts(et, ea, 0.0, 0.3, RATE, policy=policy)
    BS = new_burst_state(FC, RATE)[0]
    out = np.zeros(n)
    buf = np.zeros(64)
    rng = np.random.default_rng(3)
    j = 0
    clipped = 0
    pid = BURST_POLICIES[policy]
    while j < n:
        j1 = min(n, j + int(rng.integers(1, 60)))
        clipped += synth(BS, et, ea, et.size, 0.0, RATE, j, j1, FC, RISE, DECAY, pid, buf)
        out[j:j1] = buf[:j1 - j]
        j = j1
    np.testing.assert_array_equal(out, whole)
    assert clipped == c1


def test_clipping_is_counted():
    big, clipped = render_bursts(np.array([0.01]), np.array([3.0]), 0.0, 0.05, RATE)
    assert clipped > 0 and np.abs(big).max() == 1.0
    ad, clipped_add = render_bursts(np.array([0.010, 0.0101, 0.0102]), np.array([0.5, 0.5, 0.5]), 0.0, 0.06, RATE,
                                    policy="add")
    assert clipped_add > 0 and np.abs(ad).max() <= 1.0


@pytest.mark.parametrize("V", [0.020, 0.030])
def test_renderer_drive_on_the_published_pad_every_policy(V):
    """End to end: a constant N = 1 N table played by the renderer, every policy: no step, 300 Hz."""
    from shapedisplay.runtime import Renderer
    from shapedisplay.studies import constant_table
    from shapedisplay.studies.presets import line_stroke

    dev = load_device("handheld-stick")
    table = constant_table(1.0, dev)
    for policy in BURST_POLICIES:
        r = Renderer(table, device=dev, burst_policy=policy, audio_rate=RATE)
        res = r.render(line_stroke(0.0, V * 1.2, V, r.tick_rate))
        env = burst_envelope(res.event_time, res.event_amplitude, res.t[0], res.duration, RATE, policy=policy)
        assert res.event_time.size > 100 and res.clipped == 0
        assert step_ratio(res.audio, env) <= 1.05
        assert abs(spectral_peak(res.audio) - FC) <= 3.0


@settings(max_examples=60, deadline=None)
@given(n=st.sampled_from([1, 2, 63, 64, 65, 255, 256, 257, 320, 321, 511, 512, 513, 577, 1000, 1024, 1025,
                          1088, 1089, 1090, 2113, 4099]),
       rate=st.sampled_from([8000.0, 44100.0, 48000.0, 96000.0]), policy=st.sampled_from(sorted(BURST_POLICIES)),
       seed=st.integers(0, 2 ** 32 - 1), gain=st.sampled_from([0.3, 2.5]))
def test_whole_stream_synthesis_is_the_sample_by_sample_one_bit_for_bit(n, rate, policy, seed, gain):
    """render_bursts' two-pass synthesis (the envelope piece by piece, then sixteen carrier blocks side by side)
    writes exactly what synth writes sample by sample, for every policy: audio, clipped count and the final
    burst state."""
    from shapedisplay.runtime.bursts import policy_id, synth, synth_stream
    rng = np.random.default_rng(seed)
    ne = int(rng.integers(0, 40))
    et = np.sort(rng.uniform(-0.01, n / rate + 0.01, ne))
    ea = rng.uniform(0.0, gain, ne)
    t0 = float(rng.uniform(-0.1, 0.1))
    pid = policy_id(policy)
    a, b = np.zeros(n), np.empty(n)
    sa, sb = new_burst_state(300.0, rate)[0], new_burst_state(300.0, rate)[0]
    ca = synth(sa, et, ea, ne, t0, rate, 0, n, 300.0, 0.005, 0.03, pid, a)
    cb = synth_stream(sb, et, ea, ne, t0, rate, n, 300.0, 0.005, 0.03, pid, b)
    assert ca == cb and a.tobytes() == b.tobytes() and sa.tobytes() == sb.tobytes()


@pytest.mark.parametrize("carrier, rate", [(300.0, 48000.0), (250.0, 44100.0), (1000.5, 96000.0), (37.0, 8000.0)])
def test_whole_stream_carrier_groups_equal_the_sample_by_sample_rotation(carrier, rate):
    """The carrier of the whole-stream synthesis (blocks rotated two to a vector, sixteen side by side, then
    the last blocks one by one) is the sample-by-sample rotation bit for bit over a long stream, at other
    carrier frequencies and rates too; an envelope above 1 makes it limit samples."""
    from shapedisplay.runtime.bursts import policy_id, synth, synth_stream
    n = 70_001
    et = np.array([0.001, 0.4, 0.41, 0.9, 2.0])
    ea = np.array([0.7, 1.6, 0.2, 1.1, 5.0])
    pid = policy_id("retrigger")
    a, b = np.zeros(n), np.empty(n)
    sa, sb = new_burst_state(carrier, rate)[0], new_burst_state(carrier, rate)[0]
    ca = synth(sa, et, ea, et.size, 0.0, rate, 0, n, carrier, 0.005, 0.03, pid, a)
    cb = synth_stream(sb, et, ea, et.size, 0.0, rate, n, carrier, 0.005, 0.03, pid, b)
    assert ca == cb and ca > 0 and a.tobytes() == b.tobytes() and sa.tobytes() == sb.tobytes()


@pytest.mark.parametrize("carrier, rate", [(300.0, 48000.0), (1000.5, 96000.0)])
def test_kept_carrier_anchors_give_the_same_stream(carrier, rate):
    """A stream synthesised with the carrier's anchors handed in (fewer blocks than the stream, exactly its
    blocks, more; as a renderer keeps them) is the stream that computes them, bit for bit."""
    from shapedisplay.runtime.bursts import CARRIER_BLOCK, carrier_anchors
    dur = 0.9
    et = np.array([0.001, 0.2, 0.5, 0.52, 0.8])
    ea = np.array([0.7, 1.6, 0.2, 1.1, 0.9])
    ref, c0 = render_bursts(et, ea, 0.0, dur, rate, carrier)
    blocks = -(-ref.size // CARRIER_BLOCK)
    for nb in (0, 1, 15, 16, 17, 40, blocks - 1, blocks, blocks + 9):
        got, c1 = render_bursts(et, ea, 0.0, dur, rate, carrier, anchors=carrier_anchors(carrier, rate, nb))
        assert c1 == c0 > 0 and got.tobytes() == ref.tobytes(), nb


@pytest.mark.parametrize("policy", sorted(BURST_POLICIES))
def test_whole_stream_synthesis_with_events_on_sample_times_and_repeated(policy):
    """Events exactly at sample times (an event sounds from the next sample) and several at one time: the
    whole-stream synthesis still writes what synth writes sample by sample."""
    from shapedisplay.runtime.bursts import policy_id, synth, synth_stream
    rate, t0, n = 48000.0, 0.0125, 3000
    js = np.array([0, 5, 5, 6, 700, 701, 1500, 1500, 1500, 2999])
    et = t0 + js / rate
    ea = np.linspace(0.2, 1.4, js.size)
    pid = policy_id(policy)
    a, b = np.zeros(n), np.empty(n)
    sa, sb = new_burst_state(300.0, rate)[0], new_burst_state(300.0, rate)[0]
    ca = synth(sa, et, ea, et.size, t0, rate, 0, n, 300.0, 0.005, 0.03, pid, a)
    cb = synth_stream(sb, et, ea, et.size, t0, rate, n, 300.0, 0.005, 0.03, pid, b)
    assert ca == cb and a.tobytes() == b.tobytes() and sa.tobytes() == sb.tobytes()
    assert np.abs(b).max() > 0.1


@pytest.mark.parametrize("policy", sorted(BURST_POLICIES))
@pytest.mark.parametrize("rate", [48000.0, 44100.0, 7919.0])
def test_kept_sample_times_give_the_same_stream(policy, rate):
    """A stream from t = 0 (+0 or -0) that reads kept sample times (sample_times of a stream from 0, as long as
    the stream or longer, as a renderer keeps them) is the stream that computes them, bit for bit, and equals
    synth sample by sample; times too short for the stream, or a stream that does not start at 0, compute
    their own."""
    from shapedisplay.runtime.bursts import policy_id, sample_times, synth
    dur = 0.4
    et = np.array([0.0, 0.001, 0.05, 0.0502, 0.0502, 0.2, 0.39, 0.4])
    ea = np.array([0.7, 1.6, 0.2, 1.1, 0.4, 0.9, 1.3, 0.5])
    ref, c0 = render_bursts(et, ea, 0.0, dur, rate, policy=policy)
    n = ref.size
    a = np.zeros(n)
    ca = synth(new_burst_state(300.0, rate)[0], et, ea, et.size, 0.0, rate, 0, n, 300.0, 0.005, 0.03,
               policy_id(policy), a)
    assert ca == c0 and a.tobytes() == ref.tobytes()
    for m in (n, n + 1, 3 * n, n - 1, 10):
        times = np.empty(m)
        sample_times(0.0, rate, times)
        assert times.tobytes() == (0.0 + np.arange(m) / rate).tobytes()
        for t0 in (0.0, -0.0):
            got, c1 = render_bursts(et, ea, t0, dur, rate, policy=policy, times=times)
            assert c1 == c0 and got.tobytes() == ref.tobytes(), (m, t0)
        shifted, _ = render_bursts(et + 0.01, ea, 0.01, dur, rate, policy=policy)
        got, _ = render_bursts(et + 0.01, ea, 0.01, dur, rate, policy=policy, times=times)
        assert got.tobytes() == shifted.tobytes()


@pytest.mark.parametrize("policy", ["retrigger", "max"])
def test_groups_below_full_scale_skip_the_limiting_and_lose_nothing(policy):
    """A group whose envelope bound is below full scale by the margin is not limited: with peaks just inside
    the margin (1 - 2e-9), and just outside it (1 - 5e-10, 1 and above), the stream is still what synth
    writes sample by sample, clipped count included, over many groups and carrier phases."""
    from shapedisplay.runtime.bursts import policy_id, synth, synth_stream
    rate, n = 48000.0, 200_000
    rng = np.random.default_rng(7)
    et = np.sort(rng.uniform(0.0, n / rate, 400))
    for peak in (1.0 - 2e-9, 1.0 - 5e-10, 1.0, 1.0 + 1e-12, 1.3):
        ea = np.full(et.size, peak)
        a, b = np.zeros(n), np.empty(n)
        sa, sb = new_burst_state(300.0, rate)[0], new_burst_state(300.0, rate)[0]
        ca = synth(sa, et, ea, et.size, 0.0, rate, 0, n, 300.0, 0.005, 0.03, policy_id(policy), a)
        cb = synth_stream(sb, et, ea, et.size, 0.0, rate, n, 300.0, 0.005, 0.03, policy_id(policy), b)
        assert ca == cb and a.tobytes() == b.tobytes(), peak
        assert ca == 0 if peak <= 1.0 else True, (peak, ca)
        assert ca > 0 if peak > 1.2 else True, (peak, ca)


def test_rotated_carrier_stays_within_the_limiting_margin():
    """The margin that lets a group skip the limiting: every carrier sample of the offline rotation is within
    1e-12 of [-1, 1] (anchors exact to rounding, at most CARRIER_BLOCK - 1 rotations from one)."""
    from numba import njit

    from shapedisplay.runtime.bursts import CARRIER_BLOCK, CARRIER_GROUP, _rotate_blocks, carrier_anchors

    @njit
    def rotate(anchors, cd, sd, car, blk):
        _rotate_blocks(anchors, cd, sd, car, blk)
    for carrier, rate in ((300.0, 48000.0), (250.0, 44100.0), (1000.5, 96000.0), (37.0, 8000.0), (3000.0, 8000.0)):
        st = new_burst_state(carrier, rate)[0]
        groups = 400
        anchors = carrier_anchors(carrier, rate, groups * CARRIER_GROUP)
        car = np.empty(CARRIER_GROUP * CARRIER_BLOCK)
        worst = 0.0
        for g in range(groups):
            rotate(anchors[2 * CARRIER_GROUP * g:2 * CARRIER_GROUP * (g + 1)], st["rc"], st["rs"], car,
                   CARRIER_BLOCK)
            worst = max(worst, float(np.abs(car).max()))
        assert 0.99 < worst <= 1.0 + 1e-12, (carrier, rate, worst)
