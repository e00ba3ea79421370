"""The exact model's cost per slip: the re-stick fast paths against the bracket walk, in the same run.

Run: ``.venv/bin/python benchmarks/bench_exact_slip.py``.

The slips are those of a stroke like ``bench_runtime.py``'s full render: the
default pad (m 1e-6 kg, k 2000 N/m, c 0.01 N s/m, slip ~71 us) at 10 kHz,
50 mm/s either way, N from 0.5 to 2.5 N (a different N at every slip, so the
model's slip memo never applies). Each slip starts fresh at a breakaway a
random fraction into its tick; if it has not re-stuck by the tick's end it
goes on in the next tick from that state, under the next tick's N (0.2 %
higher: the ramp), as a slip under way. Per slip: the fresh search, the
continued search where the slip crosses a tick boundary, and the damping
work of each segment (``osc_damping_work``), as ``exact_tick`` does.

Baseline: the same slips through ``slip_search`` (the bracket walk, which
every slip took before the fast paths, and the fallback of both). Printed:
ns per slip, min / median / max over rounds (best of 7 passes each), and the
ratio fast / walk of each round's pair (alternating, so load drifts cancel).
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from shapedisplay.runtime import pads

M, K, C = 1.0e-6, 2000.0, 0.01
MUS, MUK = 0.5, 0.3
H = 1e-4


def slips(n, seed=1):
    """(n, 5) rows: y0 of the fresh slip (from its equilibrium), surface speed V, slip direction s, time left
    in the breakaway's tick, normal force N."""
    rng = np.random.default_rng(seed)
    N = rng.uniform(0.5, 2.5, n)
    V = np.where(rng.random(n) < 0.5, -0.05, 0.05)
    s = np.sign(V)
    y0 = (s * MUS * N - C * V) / K - s * MUK * N / K
    rem = rng.uniform(0.0, H, n)
    return np.column_stack([y0, V, s, rem, N])


@njit(cache=False)
def run(rows, fast):
    """Every slip of ``rows`` (fresh, then under way if it crosses its tick's end); returns the summed
    re-stick times and works (kept so nothing is optimised away)."""
    acc = 0.0
    for i in range(rows.shape[0]):
        y0, V, s, rem, N = rows[i]
        if fast:
            kind, t, y, v = pads.fresh_slip_search(M, C, K, y0, V, s, rem)
        else:
            kind, t, y, v = pads.slip_search(M, C, K, y0, V, V, s, rem, 0.0)
        acc += t + pads.osc_damping_work(M, C, K, y0, V, t)
        if kind == 0:
            # next tick: N 0.2 % higher moves the slip's equilibrium by s muk dN / k
            y1 = y - s * MUK * (0.002 * N) / K
            if fast:
                kind, t, y, v = pads.continued_slip_search(M, C, K, y1, v, V, s, H)
            else:
                kind, t, y, v = pads.slip_search(M, C, K, y1, v, V, s, H, 0.0)
            acc += t + pads.osc_damping_work(M, C, K, y1, v, t)
    return acc


def best(fn, reps=7):
    b = math.inf
    for _ in range(reps):
        t0 = time.thread_time()
        fn()
        b = min(b, time.thread_time() - t0)
    return b


def spread(v, fmt="{:.0f}"):
    v = sorted(v)
    return " / ".join(fmt.format(x) for x in (v[0], v[len(v) // 2], v[-1]))


def main() -> int:
    rows = slips(20_000)
    run(rows[:10], True)
    run(rows[:10], False)
    n = rows.shape[0]
    fast, walk, ratio = [], [], []
    for _ in range(5):
        tw = best(lambda: run(rows, False)) / n * 1e9
        tf = best(lambda: run(rows, True)) / n * 1e9
        walk.append(tw)
        fast.append(tf)
        ratio.append(tf / tw)
    print(f"exact slips of the default pad, 10 kHz ticks, N 0.5-2.5 N, 50 mm/s ({n} slips, min / median / max "
          f"of 5 rounds, CPU time):")
    print(f"  bracket walk (slip_search):     {spread(walk)} ns per slip (search + damping work)")
    print(f"  fast paths (fresh / continued): {spread(fast)} ns per slip")
    print(f"  fast / walk:                    {spread(ratio, '{:.2f}')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
