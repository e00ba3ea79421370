"""Division by a fixed divisor as multiply-adds (runtime.exactdiv): the bits of ``/`` wherever its checks allow it."""
from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from shapedisplay.runtime.exactdiv import HUGE, TINY, div_fixed, div_nonzero, divisor_ok, span_nonzero


@njit(cache=False)
def _mismatches(a, b):
    """How many ``div_fixed(a[i], b[i], 1 / b[i])`` differ from ``a[i] / b[i]`` in any bit (sign of zero included),
    and of the nonzero ``a[i]``, how many ``div_nonzero`` does."""
    bad = 0
    for i in range(a.shape[0]):
        q = a[i] / b[i]
        f = div_fixed(a[i], b[i], 1.0 / b[i])
        if f != q or np.signbit(f) != np.signbit(q):
            bad += 1
        if a[i] != 0.0:
            f = div_nonzero(a[i], b[i], 1.0 / b[i])
            if f != q or np.signbit(f) != np.signbit(q):
                bad += 1
    return bad


@pytest.mark.parametrize("rate", [1000.0, 8000.0, 22050.0, 44100.0, 48000.0, 96000.0, 192000.0, 384000.0])
def test_sample_times_are_the_divisions_bit_for_bit(rate):
    """Every sample index below 2**22 over every audio rate the renderer takes an example of."""
    j = np.arange(2 ** 22, dtype=np.float64)
    assert _mismatches(j, np.full(j.size, rate)) == 0


def test_random_quotients_over_sixty_decades_and_both_signs():
    rng = np.random.default_rng(2024)
    n = 2_000_000
    a = rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n)
    b = rng.uniform(-2.0, 2.0, n) * 10.0 ** rng.integers(-15, 15, n)
    assert _mismatches(a, b) == 0
    # envelope phases: time differences divided by a rise or decay of a few milliseconds
    tau = rng.uniform(0.0, 0.05, n) - rng.uniform(0.0, 1e-3, n)
    assert _mismatches(tau, np.full(n, 0.005)) == 0 and _mismatches(tau, np.full(n, 0.03)) == 0


def test_signed_zeros_and_the_checks():
    assert _mismatches(np.array([0.0, -0.0, 0.0, -0.0]), np.array([3.0, 3.0, -3.0, -3.0])) == 0
    assert divisor_ok(48000.0) and divisor_ok(-0.005) and not divisor_ok(0.0) and not divisor_ok(np.inf)
    assert not divisor_ok(np.nan) and not divisor_ok(2.0 ** 61) and not divisor_ok(2.0 ** -61)
    assert span_nonzero(1e-6, 2.0) and span_nonzero(-2.0, -1e-6) and span_nonzero(2.0, 1e-6)
    assert span_nonzero(TINY, HUGE) and span_nonzero(-HUGE, -TINY)
    assert not span_nonzero(0.0, 0.0) and not span_nonzero(-0.0, 1.0) and not span_nonzero(-1.0, 1.0)
    assert not span_nonzero(0.0, 1.0) and not span_nonzero(TINY / 2, 1.0)
    assert not span_nonzero(1.0, HUGE * 2) and not span_nonzero(np.nan, 1.0) and not span_nonzero(1.0, np.inf)
