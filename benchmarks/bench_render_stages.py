"""Where a full render's time goes: each stage of ``Renderer.render`` timed inside the render, against the floor loop.

Run: ``.venv/bin/python benchmarks/bench_render_stages.py [model ...]`` (default ``exact jump``).

The stroke, table and device are those of ``bench_runtime.py``'s "full render against the floor loop" (60 mm back
and forth four times at 50 mm/s, 10 kHz ticks, 48 kHz audio). Each round runs the render's stages one after the
other on fresh rows, as :meth:`Renderer.render` does, and times each on this thread's CPU clock:

* ``lookup``: the table lookup and the model inputs (``renderer.lookup_inputs``);
* ``model``: the model's tick loop (``dispatch.render_ticks`` through ``Renderer._run_model``);
* ``skin``: the skin-stretch row;
* ``audio``: the burst audio (``bursts.render_bursts`` with the renderer's kept carrier anchors and sample times);

then one whole ``Renderer.render``. The staged outputs are checked against that render's, byte for byte (a
stage list that no longer matches the render stops the benchmark). Printed per stage: ns per tick (min / median
over the rounds) and the share of the floor loop's time per tick, the floor (``bench_runtime.floor_loop``, one
lookup and one comparison per tick) measured in the same run. The full-render target (>= 25 % of the floor's ticks
per second) is a render of at most four floor loops' time per tick.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from bench_runtime import best_of, floor_loop
from shapedisplay.devices import BurstParams, load_device
from shapedisplay.runtime.bursts import render_bursts
from shapedisplay.runtime.cursor import parse_stroke
from shapedisplay.runtime.layouts import Slot
from shapedisplay.runtime.lookup import pack_channels
from shapedisplay.runtime.renderer import INPUT_ROWS, Renderer, lookup_inputs, skin_stretch_of, skin_stretch_uniform
from shapedisplay.runtime.settings import audio_length
from shapedisplay.table import FrictionTable, Grid, choose_quantization

STAGES = ("lookup", "model", "skin", "audio")


def bench_table() -> FrictionTable:
    """The one-row ``normal_force`` table of ``bench_runtime.py`` (0.5 N, a ramp to 2.5 N from 20 to 40 mm)."""
    g = Grid(1, 241, 0.25e-3, 0.25e-3)
    xs = np.arange(241) * 0.25e-3
    nx = (0.5 + np.clip(100 * (xs - 0.02), 0, 2.0))[None, :]
    return FrictionTable.from_dense(g, {"normal_force": nx}, {"normal_force": choose_quantization(nx, "uint8")}, {})


def staged_render(r: Renderer, cp, clock=time.thread_time):
    """The stages of ``r.render(cp)`` one after the other; returns ``(seconds per stage, outputs)``."""
    k = len(INPUT_ROWS)
    n = cp.t.size
    t0 = clock()
    block = np.empty((k + 6, n))
    ins = block[:k]
    ones = lookup_inputs(cp.t, cp.x, cp.y, r._blocks, r._data, r._bg, r._grid, r._config, r._slot_channel, ins,
                         block[k + 2:].view(np.int64), False)
    t1 = clock()
    f, ss = block[k], block[k + 1]
    rows = [ins[q, :1] if ones >> q & 1 and q > 0 and n > 0 else ins[q] for q in range(k)]
    V, vx, _, N, mus, muk, gain, _, _, target = rows
    if ones & 1:
        V = vx
    phase = np.empty(n, np.int8)
    et, ea = r._run_model(cp.t, V, N, mus, muk, gain, f, phase)
    t2 = clock()
    if r._slot_channel[Slot.SKIN_STRETCH] >= 0:
        skin_stretch_of(target, f, mus, N, ss)
    else:
        skin_stretch_uniform(float(r.config["skin_target"]), f, mus, N, ss)
    t3 = clock()
    na = audio_length(cp.duration, r.audio_rate)
    b = r.device.burst
    audio, clipped = render_bursts(et, ea, cp.t[0], cp.duration, r.audio_rate, b.carrier_hz, b.rise_s, b.decay_s,
                                   r.burst_policy, r._carrier_anchors(na),
                                   r._sample_times(na) if cp.t[0] == 0.0 else None)
    t4 = clock()
    out = {"friction_force": f, "skin_stretch": ss, "state": phase, "event_time": et, "event_amplitude": ea,
           "audio": audio, "clipped": clipped}
    return (t1 - t0, t2 - t1, t3 - t2, t4 - t3), out


def spread(values) -> str:
    v = sorted(values)
    return f"{v[0]:5.2f} / {v[len(v) // 2]:5.2f}"


def main(argv=None) -> int:
    models = (argv if argv is not None else sys.argv[1:]) or ["exact", "jump"]
    rate = 10_000.0
    table = bench_table()
    dev = load_device(None).with_(burst=BurstParams(gain=0.2))
    cp = parse_stroke("0,0 <-> 60,0 @ 50 mm/s x4", rate)
    n = cp.t.size
    blocks, data, _, grid = pack_channels(table, ["normal_force"])
    floor_loop(blocks, data, grid, cp.x, 1.0)
    floor = best_of(lambda: floor_loop(blocks, data, grid, cp.x, 1.0), 15, time.thread_time) / n * 1e9
    print(f"floor loop (one lookup + one comparison per tick): {floor:.2f} ns/tick; {n} ticks at {rate / 1000:g} kHz")
    print("stage inside the render, ns/tick min / median of 30 rounds, and the median as % of the floor's time per tick")
    for model in models:
        r = Renderer(table, device=dev, model=model, tick_rate=rate)
        whole = r.render(cp)
        _, out = staged_render(r, cp)
        for name, got in out.items():
            want = getattr(whole, name)
            if np.asarray(got).tobytes() != np.asarray(want).tobytes():
                raise SystemExit(f"the stages no longer give Renderer.render's {name}: update staged_render")
        # neither kept alive: as in bench_runtime, each render's rows are freed before the next one (the
        # allocator then hands the same memory out again instead of faulting fresh pages in)
        del whole, out, got, want
        times = {s: [] for s in STAGES + ("stages", "render")}
        for _ in range(30):
            per = staged_render(r, cp)[0]
            for s, dt in zip(STAGES, per):
                times[s].append(dt / n * 1e9)
            times["stages"].append(sum(per) / n * 1e9)
            t0 = time.thread_time()
            r.render(cp)
            times["render"].append((time.thread_time() - t0) / n * 1e9)
        for s, v in times.items():
            med = sorted(v)[len(v) // 2]
            print(f"{model:6s} {s:7s} {spread(v)} ns/tick  {med / floor * 100:5.0f} % of the floor's time")
    print(f"target: the whole render within {4 * floor:.2f} ns/tick (>= 25 % of the floor's ticks per second)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
