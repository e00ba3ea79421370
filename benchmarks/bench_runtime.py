"""Runtime renderer speed: ratios against real time and against a baseline run in the same process.

Run: ``.venv/bin/python benchmarks/bench_runtime.py``. Targets (issue 3):

* ``jump`` offline >= 2000x real time at 10 kHz (>= 20 M ticks/s);
* ``exact`` offline on the Konyo pad at 50 mm/s >= 300x real time;
* ``Renderer.step()`` from Python: median <= 5 us per tick;
* the full offline render (``Renderer.render``: table lookups, model, 48 kHz
  burst audio, every output array) >= 25 % of the ticks per second of the
  floor loop at 10 kHz, with ``jump`` and with ``exact`` (the ``play``
  default). A renderer keeps its carrier's anchors and the audio
  sample times from render to render; the ``jump/first`` line renders as a
  renderer's first render does (both computed), for comparison.

The floor loop (:func:`floor_loop`) is a compiled loop that does one
table lookup (the renderer's bilinear lookup on the packed table, written
out in the loop) and one comparison per tick, over the same cursor path and
table: the least any renderer must do per tick. A calibration line prints
the bare ``jump`` tick loop against it. Its ratio is measured in rounds of
floor and render calls in turn (floor, render, floor, ..., seven renders
per round). The target is judged on the render calls whose two
neighbouring floor calls agree within a tenth: such a call ran at the
machine speed those floor calls measured, and its ticks per second over
theirs is its ratio. Each round keeps its best such call (best of several
calls, as every other figure here: a slower call was slowed by something
other than the code), printed as min / median / max over the rounds, with
how many calls qualified. On a shared machine whose speed changes during a run
this is the figure of the code; the best render of each round against the
fastest floor round of the whole run is printed too (a floor slowed by a
busy neighbour cannot raise it, but a machine that slows during the run
lowers it whatever the code does). Everything is timed on this thread's
CPU clock: on a loaded machine a 10 ms render is preempted far more often
than a 2 ms floor loop, which wall time would count against the render.

The baseline is a plain numpy loop-free computation of a spring stretch
(one ``cumsum`` over the same number of ticks), so machine speed cancels
out of the ratio column.
"""
from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from numba import njit

from shapedisplay.devices import BurstParams, load_device
from shapedisplay.runtime.cursor import parse_stroke
from shapedisplay.runtime.lookup import _axis_cell, cell_index, pack_channels
from shapedisplay.runtime.models import get_model, run_kernel
from shapedisplay.runtime.renderer import Renderer
from shapedisplay.table import FrictionTable, Grid, choose_quantization


def best_of(fn, repeat=5, clock=time.perf_counter):
    best = float("inf")
    for _ in range(repeat):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


def kernel_rate(model_name, V, N, rate, seconds):
    n = int(seconds * rate) + 1
    t = np.arange(n) / rate
    Va = np.full(n, V)
    Na = np.full(n, N)
    dev = load_device(None)
    model = get_model(model_name, dev)
    mus = np.full(n, dev.friction.mu_s)
    muk = np.full(n, dev.friction.mu_k)
    gain = np.ones(n)
    run_kernel(model, t[:100], Va[:100], Na[:100], mus[:100], muk[:100], gain[:100])  # compile / warm
    dt = best_of(lambda: run_kernel(model, t, Va, Na, mus, muk, gain), 15)
    return n, dt


@njit(cache=False)         # compiled in every run: numba's cache would not see changes to the lookup helpers
def floor_loop(blocks, data, grid, x, threshold):
    """One table lookup and one comparison per tick; returns how many ticks were above ``threshold``.

    The lookup is the renderer's bilinear lookup on the packed one-row table (same cell search and
    arithmetic as :func:`sample_all`, channel 0), written out in the loop: the fastest form of it.
    """
    above = 0
    cols = grid.cols
    last = data.shape[1] - 1
    for i in range(x.shape[0]):
        c0, c1, tx = _axis_cell(x[i], grid.x0, grid.dx, cols)
        i0 = cell_index(blocks, 0, c0)
        i1 = cell_index(blocks, 0, c1)
        if i0 < 0:
            i0 = last
        if i1 < 0:
            i1 = last
        if data[0, i0] * (1 - tx) + data[0, i1] * tx > threshold:
            above += 1
    return above


# A render call counts towards the target's figure when the floor calls just before and after it agree
# within this factor (the machine ran at one speed through it); the figure needs MIN_STEADY rounds with such a call.
FLOOR_AGREE = 1.1
MIN_STEADY = 3


def spread(values, fmt="{:.1f}") -> str:
    v = sorted(values)
    return " / ".join(fmt.format(a) for a in (v[0], v[len(v) // 2], v[-1]))


def render_against_floor(table, dev, rate, spec, model="jump", rounds=5, policy="retrigger", first=False) -> float:
    """Print full-render and floor-loop ticks/s (min / median / max over rounds) and render / floor; return the
    median over rounds of each round's best render call between two agreeing floor calls (the fastest-floor
    ratio's median where fewer than ``MIN_STEADY`` rounds had such a call).

    ``first``: every render as a renderer's first one (the carrier anchors and audio sample times it keeps
    from render to render, which depend only on the carrier and the audio rate, dropped before each render
    and computed again).
    """
    stroke = parse_stroke(spec, rate)
    r = Renderer(table, device=dev, model=model, tick_rate=rate, burst_policy=policy)
    r.render(stroke)
    blocks, data, _, grid = pack_channels(table, ["normal_force"])
    floor_loop(blocks, data, grid, stroke.x, 1.0)
    n = stroke.t.size
    fl, rr, ratio = [], [], []

    def render():
        if first:
            r._anchors = np.empty(0)
            r._times = np.empty(0)
        r.render(stroke)

    def floor():
        floor_loop(blocks, data, grid, stroke.x, 1.0)

    def timed(fn):
        t0 = time.thread_time()
        fn()
        return time.thread_time() - t0

    steady, n_steady = [], 0
    for _ in range(rounds):
        # floor, render, floor, render, ..., floor: every render call sits between two floor calls
        tfs, trs = [timed(floor)], []
        for _ in range(7):
            trs.append(timed(render))
            tfs.append(timed(floor))
        fl.append(n / min(tfs) / 1e6)
        rr.append(n / min(trs) / 1e6)
        # a render call whose two neighbouring floor calls agree ran at the machine speed they measured; the
        # round keeps its best such call (best of several, as every other figure here)
        calls = [(f0 + f1) / 2 / tr * 100 for tr, f0, f1 in zip(trs, tfs, tfs[1:])
                 if max(f0, f1) <= FLOOR_AGREE * min(f0, f1)]
        n_steady += len(calls)
        steady += [max(calls)] if calls else []
    # Each round's best render against the fastest floor round of the run: a floor slowed by a busy neighbour
    # cannot raise the ratio, but a machine that slows during the run (its floor rounds spread) lowers it.
    ratio = [ticks_per_s / max(fl) * 100 for ticks_per_s in rr]
    label = (model if policy == "retrigger" else f"{model}/{policy}") + ("/first" if first else "")
    print(f"{label:8s} full render @{rate / 1000:g} kHz ({n} ticks, {int(stroke.duration * r.audio_rate) + 1} "
          f"audio samples at {r.audio_rate / 1000:g} kHz): {spread(rr)} M ticks/s; floor loop {spread(fl)} M ticks/s; "
          f"render / fastest floor {spread(ratio, '{:.0f}')} %")
    if len(steady) >= MIN_STEADY:
        print(f"         render / floor around it, best call of each round between two floor calls that agree "
              f"({n_steady} of {7 * rounds} calls were): {spread(steady, '{:.0f}')} %")
        return sorted(steady)[len(steady) // 2]
    print(f"         only {len(steady)} of {rounds} rounds had a render call between two floor calls that agree: the "
          f"machine's speed kept changing; the fastest-floor figure above stands (run again for a figure of the code)")
    return sorted(ratio)[len(ratio) // 2]


def main() -> int:
    rate = 10_000.0
    seconds = 20.0
    n = int(seconds * rate) + 1
    x = np.full(n, 0.05 / rate)
    base = best_of(lambda: np.cumsum(x) * 2000.0 + 0.01 * 0.05)
    print(f"baseline numpy cumsum over {n} ticks: {base * 1e3:.2f} ms ({n / base / 1e6:.0f} M ticks/s)")
    ok = True
    rows = []
    for name, V, target_rt in (("jump", 0.05, 2000.0), ("exact", 0.05, 300.0), ("karnopp", 0.05, None)):
        nn, dt = kernel_rate(name, V, 2.0, rate, seconds)
        rt = seconds / dt
        rows.append((name, nn / dt, rt, dt / base))
        flag = "" if target_rt is None else ("  OK" if rt >= target_rt else f"  BELOW TARGET {target_rt:g}x")
        ok &= target_rt is None or rt >= target_rt
        print(f"{name:8s} kernel @10 kHz, V=50 mm/s, N=2 N: {nn / dt / 1e6:7.1f} M ticks/s, "
              f"{rt:9.0f}x real time, {dt / base:6.1f}x baseline time{flag}")
    # the tick loop alone on preallocated buffers (what a host with its own buffers pays)
    from shapedisplay.runtime.dispatch import run_ticks
    dev = load_device(None)
    tt = np.arange(n) / rate
    ins = [np.full(n, v) for v in (0.05, 2.0, dev.friction.mu_s, dev.friction.mu_k, 1.0)]
    outs = [np.empty(n) for _ in range(6)]
    evs = [np.empty(n // 4 + 1024) for _ in range(2)]
    for name in ("jump", "exact"):
        m = get_model(name, dev)
        dt = best_of(lambda: run_ticks(m.model_id, m.new_state(), m.param_block, tt, *ins, *outs, *evs), 15)
        print(f"{name:8s} tick loop only (preallocated buffers): {n / dt / 1e6:7.1f} M ticks/s, "
              f"{seconds / dt:9.0f}x real time, {dt / base:6.1f}x baseline time")
    # full offline render over a table (lookups + kernel + burst audio)
    g = Grid(1, 241, 0.25e-3, 0.25e-3)
    xs = np.arange(241) * 0.25e-3
    Nx = (0.5 + np.clip(100 * (xs - 0.02), 0, 2.0))[None, :]
    table = FrictionTable.from_dense(g, {"normal_force": Nx}, {"normal_force": choose_quantization(Nx, "uint8")},
                                     {})
    dev = load_device(None).with_(burst=BurstParams(gain=0.2))
    stroke = parse_stroke("0,0 <-> 60,0 @ 50 mm/s x4", rate)
    for name in ("jump", "exact"):
        r = Renderer(table, device=dev, model=name, tick_rate=rate)
        r.render(stroke)
        dt = best_of(lambda: r.render(stroke), 3)
        print(f"{name:8s} full render (table lookup + kernel + 48 kHz audio), {stroke.duration:.1f} s stroke: "
              f"{stroke.duration / dt:7.0f}x real time")
    print("full render against the floor loop (one lookup + one comparison per tick), min / median / max of 5 rounds:")
    spec = "0,0 <-> 60,0 @ 50 mm/s x4"
    sp = parse_stroke(spec, rate)
    blocks, data, _, grid = pack_channels(table, ["normal_force"])
    floor_loop(blocks, data, grid, sp.x, 1.0)
    tf = best_of(lambda: floor_loop(blocks, data, grid, sp.x, 1.0), 15, time.thread_time)
    m = get_model("jump", dev)
    nn = sp.t.size
    ins = [np.full(nn, v) for v in (0.05, 2.0, dev.friction.mu_s, dev.friction.mu_k, 1.0)]
    outs = [np.empty(nn) for _ in range(6)]
    evs = [np.empty(nn // 4 + 1024) for _ in range(2)]
    tj = best_of(lambda: run_ticks(m.model_id, m.new_state(), m.param_block, sp.t, *ins, *outs, *evs), 15,
                 time.thread_time)
    print(f"         calibration: the bare jump tick loop runs at {tf / tj * 100:.0f} % of this floor's ticks per second "
          f"(floor {nn / tf / 1e6:.1f} M ticks/s)")
    pct = render_against_floor(table, dev, rate, spec, "jump")
    ok &= pct >= 25.0
    print(f"         target >= 25 % of the floor at 10 kHz (median): {'OK' if pct >= 25.0 else 'BELOW TARGET'}")
    render_against_floor(table, dev, rate, spec, "jump", first=True)
    pct = render_against_floor(table, dev, rate, spec, "exact")
    ok &= pct >= 25.0
    print(f"         target >= 25 % of the floor at 10 kHz for exact, the play default (median): "
          f"{'OK' if pct >= 25.0 else 'BELOW TARGET'}")
    render_against_floor(table, dev, 100_000.0, spec, "jump")
    render_against_floor(table, dev, rate, spec, "jump", policy="add")
    # online step from Python
    r = Renderer(table, device=dev, model="exact", tick_rate=rate)
    r.reset()
    cx = stroke.x
    step = r.step
    per = []
    for rep in range(5):
        r.reset()
        samples = []
        for i in range(0, 20_000, 1000):
            t0 = time.perf_counter()
            for j in range(i, i + 1000):
                step(cx[j], 0.0)
            samples.append((time.perf_counter() - t0) / 1000)
        per.extend(samples)
    med = statistics.median(per)
    t0 = time.perf_counter()
    for j in range(20_000):
        pass
    loop = (time.perf_counter() - t0) / 20_000
    ok &= med <= 5e-6
    print(f"step() from Python (exact, 1000-call batches): median {med * 1e6:.2f} us per tick "
          f"({med / loop:.0f}x an empty Python loop iteration){'  OK' if med <= 5e-6 else '  ABOVE 5 us'}")
    print("all targets met" if ok else "some targets missed")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
