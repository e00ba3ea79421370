"""Karnopp virtual spring with every event inside the tick: event times independent of the tick rate."""
import math

import numpy as np
import pytest

from shapedisplay.table.devices import load_device
from shapedisplay.render.models import simulate_pad

KK, VT = 1500.0, 0.0125                     # N/m, m/s: the model's defaults ([karnopp] of the tactor profile)
FR = load_device("skin-stretch-tactor").friction    # mu_s 0.6, mu_k 0.54 = 0.9 mu_s

#: (end time s, finger speed m/s): slow stick-slip, fast sliding, a reversal slow then fast, slow again
SEGMENTS = [(0.300, 0.005), (0.500, 0.030), (0.650, -0.008), (0.800, -0.020), (1.000, 0.004)]


def speed(t):
    """Piecewise-constant finger speed; every change on a 1 ms boundary (on the tick grid of both rates)."""
    out = np.zeros_like(t)
    start = 0.0
    for end, v in SEGMENTS:
        out[(t >= start - 1e-12) & (t < end - 1e-12)] = v
        start = end
    return out


def continuous_reference(N, mus, muk):
    """Event times of the modified Karnopp model in continuous time, segment by segment.

    Written from the model's rules, not from the kernel: stuck, the stretch z grows at the finger
    speed and breaks away where k_K |z| = mu_s N; sliding holds z = s mu_k N / k_K while the
    finger moves in the slip direction at >= v_T; it sticks again (force kept) below v_T or on
    a reversal.
    """
    z, sliding, s = 0.0, False, 1.0
    thr, zk = mus * N, muk * N / KK
    events = []
    start = 0.0
    for end, v in SEGMENTS:
        if sliding and (abs(v) < VT or v * s <= 0):
            sliding = False
        t = start
        while not sliding and v != 0:
            hit = t + (math.copysign(thr / KK, v) - z) / v
            if hit >= end:
                z += v * (end - t)
                break
            events.append(hit)
            t, s = hit, math.copysign(1.0, v)
            z = s * zk
            sliding = abs(v) >= VT
        if sliding:
            z = s * zk
        start = end
    return np.array(events)


def run(rate, N=1.3):
    n = int(round(SEGMENTS[-1][0] * rate)) + 1
    t = np.arange(n) / rate
    V = np.r_[0.0, speed(t[:-1])]          # tick i runs from t[i-1] at the speed of its start
    return simulate_pad("karnopp", V=V, N=N, tick_rate=rate, friction=FR)


def test_karnopp_event_times_do_not_depend_on_the_tick_rate_and_match_continuous_time():
    slow, fast = run(1000.0), run(10_000.0)
    ref = continuous_reference(1.3, FR.mu_s, FR.mu_k)
    assert ref.size > 20
    assert slow.event_time.size == fast.event_time.size == ref.size
    assert np.max(np.abs(slow.event_time - fast.event_time)) <= 1e-9
    assert np.max(np.abs(fast.event_time - ref)) <= 1e-9
    assert np.max(np.abs(slow.event_time - ref)) <= 1e-9
    # closed forms of the first segment: breakaway after mu_s N / k_K of travel, then a sawtooth with
    # period (mu_s - mu_k) N / (k_K V) (below v_T the pad sticks again after each slip)
    v = SEGMENTS[0][1]
    first = FR.mu_s * 1.3 / KK / v
    period = (FR.mu_s - FR.mu_k) * 1.3 / (KK * v)
    k = np.arange(int((SEGMENTS[0][0] - first) / period) + 1)
    assert np.allclose(ref[:k.size], first + k * period, rtol=0, atol=1e-12)
    assert np.allclose(slow.event_time[:k.size], first + k * period, rtol=0, atol=1e-9)
    # every burst at B mu_s N; friction bounded by the static limit
    assert np.allclose(slow.event_amplitude, FR.mu_s * 1.3)
    assert np.all(np.abs(slow.friction_force) <= FR.mu_s * 1.3 * (1 + 1e-12))


def test_karnopp_low_speed_period_on_the_tactor_at_1_khz():
    """The skin-stretch tactor ticks at 1 kHz: the sawtooth period is exact, not rounded to ticks."""
    dev = load_device("skin-stretch-tactor")
    assert dev.tick_rate_hz == 1000.0
    V, N = 0.004, 1.31
    r = simulate_pad("karnopp", V=V, N=N, tick_rate=dev.tick_rate_hz, duration=2.0, friction=dev.friction)
    d = np.diff(r.event_time)
    assert d.size > 10
    assert np.allclose(d, (dev.friction.mu_s - dev.friction.mu_k) * N / (KK * V), rtol=1e-9)


@pytest.mark.parametrize("rate", [100.0, 1000.0, 192_000.0])
def test_karnopp_degenerate_inputs_stay_finite(rate):
    n = int(0.2 * rate) + 1
    rng = np.random.default_rng(int(rate))
    V = rng.choice([0.0, 1e-6, -0.02, 0.05, 5.0, -5.0], n)
    N = rng.choice([0.0, 1e-9, 1.0, 50.0], n)
    r = simulate_pad("karnopp", V=V, N=N, tick_rate=rate)
    assert np.all(np.isfinite(r.friction_force)) and np.all(np.isfinite(r.event_time))
    assert np.all(np.abs(r.friction_force) <= 0.5 * N * (1 + 1e-9) + 1e-12)
    same = simulate_pad("karnopp", V=0.003, N=1.0, tick_rate=rate, duration=0.2,
                        friction=type(FR)(0.5, 0.5))              # delta_mu = 0 at a slow finger: one event
    assert same.event_time.size == 1
