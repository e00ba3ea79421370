"""What playing a table costs in the process: offline renders, the model alone, ``step()`` from Python.

Run: ``.venv/bin/python benchmarks/bench_runtime.py [--quick]``.

The table is the bundled phone scene (``assets/scenes/phone.toml``, compiled
in the process), the stroke the one ``play`` is timed with elsewhere: 150 mm
at 30 mm/s (5 s, 50 001 ticks at 10 kHz, 48 kHz audio). For each model:

* ``render``: ``Renderer(table, model=m).render(cursor)`` (table lookups, the
  model, every output row, the burst audio: what ``play`` waits for once the
  table is loaded), against the floor of any tick renderer measured in the
  same run (``reports.common.floor_costs``: one read and one write per tick,
  one sample written per audio sample, as C loops);
* ``model``: ``run_kernel`` on the per-tick inputs the renderer gives the
  model (``Renderer.model_inputs``), against the least work of the model's
  interface over as many ticks (``reports.common.interface_floor``).

Then ``Renderer.step`` called from Python once per tick (the online path of
a host loop), against an empty Python loop iteration in the same run.

Every figure is CPU time of this process (a loaded machine preempts a long
render more than a short floor, which wall time would count against the
render), min / median / max over the rounds, each round the least of a few
calls (``reports.common.cpu_per_call``). No figure is a pass or a fail: the
ratios are what to compare between two runs or two machines.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from shapedisplay.reports.common import cpu_per_call, floor_costs, interface_floor
from shapedisplay.render.cursor import parse_stroke
from shapedisplay.render.models import run_kernel
from shapedisplay.render.renderer import Renderer
from shapedisplay.author.scene import compile_scene

ROOT = Path(__file__).resolve().parent.parent
STROKE = "62,2 -> 62,152 @ 30mm/s"           # 5 s, the stroke of bench_startup.py and bench_engine.py
MODELS = ("exact", "jump", "karnopp", "stribeck")
RATE = 10_000.0


def spread(values, fmt="{:.2f}") -> str:
    v = sorted(values)
    return " / ".join(fmt.format(a) for a in (v[0], statistics.median(v), v[-1]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 rounds instead of 7, shorter step() timing")
    ap.add_argument("--models", default=",".join(MODELS), help="comma-separated models (default: %(default)s)")
    a = ap.parse_args()
    rounds = 3 if a.quick else 7
    table = compile_scene(ROOT / "assets" / "scenes" / "phone.toml").table
    cursor = parse_stroke(STROKE, RATE)
    n = cursor.t.size
    load = os.getloadavg()[0]
    print(f"phone scene, stroke '{STROKE}' ({cursor.duration:g} s, {n} ticks at {RATE / 1e3:g} kHz); CPU time, "
          f"min / median / max of {rounds} rounds; load average {load:.1f} on {os.cpu_count()} CPUs")
    for model in a.models.split(","):
        r = Renderer(table, model=model, tick_rate=RATE)
        n_audio = int(cursor.duration * r.audio_rate) + 1
        inputs = r.model_inputs(cursor)
        render, kernel, rfloor, kfloor = [], [], [], []
        for _ in range(rounds):
            per_tick, per_sample = floor_costs(runs=3)
            rfloor.append(n * per_tick + n_audio * per_sample)
            kfloor.append(interface_floor(n, runs=3))
            render.append(min(cpu_per_call(lambda: r.render(cursor), runs=1, min_batch_s=0.05)[0]))
            kernel.append(min(cpu_per_call(lambda: run_kernel(r.model, *inputs), runs=1, min_batch_s=0.05)[0]))
        rr = [x / f for x, f in zip(render, rfloor)]
        kr = [x / f for x, f in zip(kernel, kfloor)]
        print(f"{model:8s} render {spread([x * 1e3 for x in render])} ms "
              f"({cursor.duration / statistics.median(render):,.0f}x real time), "
              f"{spread(rr, '{:.0f}')} x the floor ({statistics.median(rfloor) * 1e3:.2f} ms)")
        print(f"{'':8s} model  {spread([x * 1e3 for x in kernel])} ms, "
              f"{spread(kr, '{:.0f}')} x the interface floor ({statistics.median(kfloor) * 1e3:.2f} ms)")
    # step() from Python, the online path (one ctypes call per tick)
    r = Renderer(table, model="exact", tick_rate=RATE)
    xs, ys = cursor.x.tolist(), cursor.y.tolist()
    m = 10_000 if a.quick else n - 1
    step, per, empty = r.step, [], []
    for _ in range(rounds):
        r.reset()
        t0 = time.thread_time()
        for j in range(m):
            step(xs[j], ys[j])
        per.append((time.thread_time() - t0) / m)
        t0 = time.thread_time()
        for j in range(m):
            pass
        empty.append((time.thread_time() - t0) / m)
    print(f"step() from Python (exact, {m} ticks a round): {spread([p * 1e6 for p in per])} us per tick, "
          f"{spread([p / e for p, e in zip(per, empty)], '{:.0f}')} x an empty loop iteration")
    return 0


if __name__ == "__main__":
    sys.exit(main())
