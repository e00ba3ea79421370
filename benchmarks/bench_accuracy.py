"""Speed against scipy at equal error, and the ``stribeck`` model against real time.

Run: ``.venv/bin/python benchmarks/bench_accuracy.py [--runs 3] [--batches 3] [--quick] [--cases a,b] [--models exact]``.

Targets:

* every case of the accuracy report (``shapedisplay report accuracy``) at
  least 1000x faster than the best scipy ``solve_ivp`` method at equal
  error, or the bound that makes it impossible;
* the ``stribeck`` model at least real time on the Konyo pad.

Part 1 runs every setting of every case of the report (renderer models, tick
rates, tables, substeps; scipy Radau/BDF/LSODA at rtol 1e-3...1e-9) with the
report's own functions, ``--runs`` times, each setting's cost in a run the
least of ``--batches`` timed batches (3, as the report times them) on both
sides. Each run gives, per case, the
speed-up at equal error at the least favourable error level (see
``shapedisplay.reports.accuracy.equal_error``) for the model alone and for
the full render, and the bound: scipy's cost over the least work a tick
renderer must do (per tick and per 48 kHz audio sample; for the model alone,
at least the least work of ``run_kernel``'s six input and six output rows at
the path's length, or of ``run_kernel`` with the cheapest model over as many
ticks with the pad stuck on every one, whichever costs more), timed in the
same run. Printed: min/median/max over the runs.

Part 2 plays a flat table with the ``stribeck`` model on the Konyo pad (the
bundled ``handheld-stick`` profile: m = 1e-6 kg, k = 2 N/mm) over a grid of
normal forces, speeds and tick rates (full render: lookup, model, 48 kHz
audio) and prints the CPU seconds per simulated second of the slowest grid
point (below 1 = faster than real time), with the ``exact`` model on the same
grid in the same run as the baseline.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from shapedisplay.reports import accuracy as A
from shapedisplay.reports import common


def mmm(values, spec=".3g"):
    v = [x for x in values if x is not None]
    if not v:
        return "—"
    return "/".join(format(x, spec) for x in (min(v), statistics.median(v), max(v)))


def part_scipy(runs, quick, only, models=(), levels=False, batches=3):
    cases = [c for c in A.build_cases(quick) if not only or c.name in only]
    per_case = {}
    floors = []
    refs = {}
    for r in range(runs):
        ft, fa = common.floor_costs()
        floors.append((ft, fa))
        for case in cases:
            t0 = time.perf_counter()
            device = A._device(case)
            if case.name not in refs:
                refs[case.name] = A.reference(case, quick)     # untimed; the same every run
            ref = refs[case.name]
            results = [A.run_setting(case, s, device, ref, runs_renderer=batches, runs_peer=batches)
                       for s in A.settings(case, quick)
                       if not models or s["family"] == "scipy" or s["model"] in models]
            eq = {"model": A.equal_error(results, A.COSTS["model"], ft, interface=A.interface_floor(case.duration)),
                  "render": A.equal_error(results, A.COSTS["render"], ft, fa)}
            per_case.setdefault(case.name, []).append(eq)
            print(f"run {r + 1}/{runs} {case.name}: {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    print(f"floors (min/median/max over {runs} runs): per tick {mmm([f[0] for f in floors])} s, "
          f"per audio sample {mmm([f[1] for f in floors])} s")
    print()
    hdr = ["case", "cost", "error level", "best scipy there", "renderer there", "speed-up x", "bound x", "target"]
    rows = []
    for name, eqs in per_case.items():
        for kind in A.COSTS:
            qs = [e[kind] for e in eqs]
            if any(q is None for q in qs):
                rows.append([name, kind, "—", "—", "—", "—", "—", "no level both reach"])
                continue
            med = sorted(qs, key=lambda q: q["worst"]["speedup"])[len(qs) // 2]["worst"]
            sp = [q["worst"]["speedup"] for q in qs]
            bd = [q["worst"]["bound"] for q in qs]
            if min(sp) >= A.SPEEDUP_TARGET:
                verdict = "met"
            elif max(bd) < A.SPEEDUP_TARGET:
                verdict = "impossible: bound < 1000"
            else:
                verdict = "NOT met"
            rows.append([name, kind, format(med["period_rel_max"], ".2g"), med["scipy"], med["renderer"],
                         mmm(sp, ".3g"), mmm(bd, ".3g"), verdict])
    print("Speed-up over the best scipy method at equal error (least favourable error level), min/median/max "
          f"over {runs} runs; 'model' = run_kernel on the renderer's per-tick inputs, 'render' = full "
          "Renderer.render with 48 kHz audio")
    print(common.text_table(hdr, rows))
    if levels:
        print_levels(per_case, runs)


def print_levels(per_case, runs):
    """Every error level of the model-alone comparison: scipy's and the renderer's cheapest settings there."""
    rows = []
    for name, eqs in per_case.items():
        by = {}
        for e in eqs:
            for lv in (e["model"] or {}).get("levels", ()):
                by.setdefault(lv["period_rel_max"], []).append(lv)
        for err, lvs in sorted(by.items()):
            ren = sorted({v["renderer"] for v in lvs})
            rows.append([name, format(err, ".2g"), lvs[0]["scipy"], ", ".join(ren),
                         mmm([v["scipy_cpu_s_per_sim_s"] * 1e3 for v in lvs]),
                         mmm([v["renderer_cpu_s_per_sim_s"] * 1e6 for v in lvs]),
                         mmm([v["speedup"] for v in lvs]), len(lvs)])
    print()
    print(f"Every error level, model alone (min/median/max over the runs that reached it, of {runs})")
    print(common.text_table(["case", "error level", "best scipy there", "renderer there", "scipy ms / sim s",
                             "renderer us / sim s", "speed-up x", "runs"], rows))


def part_stribeck(runs):
    from shapedisplay.author.compile import CompileOptions, compile_heightfield
    from shapedisplay.table.devices import load_device
    from shapedisplay.author.forces import MappingOptions
    from shapedisplay.render.cursor import CursorPath
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.author.sources import from_array
    dev = load_device("handheld-stick")
    grid = [(N, V, rate) for N in (0.5, 2.0, 6.0) for V in (0.001, 0.02, 0.1, 0.3) for rate in (1000.0, 10000.0, 96000.0)]
    dur = 0.2
    tables = {N: compile_heightfield(from_array(np.zeros((1, 4)), 1e-3), dev,
                                     MappingOptions(n_base=N, n_gain=1.0), CompileOptions(quantize="float64")).table
              for N in (0.5, 2.0, 6.0)}
    worst = {"stribeck": [], "exact": []}
    where = {}
    for _ in range(runs):
        for model in worst:
            w = 0.0
            for N, V, rate in grid:
                rend = Renderer(tables[N], device=dev, model=model, tick_rate=rate)
                n = int(round(dur * rate)) + 1
                t = np.arange(n) / rate
                cur = CursorPath(t, V * t, np.zeros(n), rate, "bench")
                (cpu,), _ = common.cpu_per_call(lambda: rend.render(cur), runs=1, min_batch_s=0.02)
                if cpu / dur > w:
                    w = cpu / dur
                    where[model] = (N, V, rate)
            worst[model].append(w)
    print()
    print(f"stribeck on the Konyo pad (handheld-stick), full render of {dur:g} s strokes over N 0.5-6 N, "
          f"V 1-300 mm/s, 1/10/96 kHz: CPU s per simulated s at the slowest grid point, min/median/max over {runs} runs")
    rows = []
    for model, ws in worst.items():
        N, V, rate = where[model]
        rows.append([model, mmm(ws), mmm([1.0 / x for x in ws], ".1f"),
                     f"N {N:g} N, V {V * 1e3:g} mm/s, {rate / 1e3:g} kHz"])
    rows.append(["stribeck / exact", mmm([a / b for a, b in zip(worst["stribeck"], worst["exact"])], ".2f"), "", ""])
    print(common.text_table(["model", "CPU s / simulated s", "x real time", "slowest point (last run)"], rows))
    print("target: stribeck CPU s / simulated s <= 1 (real time): "
          + ("met" if max(worst["stribeck"]) <= 1.0 else "NOT met"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="the quick report's cases (a smoke run)")
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--models", default="", help="comma-separated renderer models to compare (default: all of a case's)")
    ap.add_argument("--skip-scipy", action="store_true")
    ap.add_argument("--skip-stribeck", action="store_true")
    ap.add_argument("--levels", action="store_true", help="also print every error level of the model-alone comparison")
    ap.add_argument("--batches", type=int, default=3,
                    help="timed batches per setting and run, the least taken, on both sides (the report's own: 3)")
    a = ap.parse_args()
    only = {x for x in a.cases.split(",") if x}
    if not a.skip_scipy:
        part_scipy(a.runs, a.quick, only, {x for x in a.models.split(",") if x}, a.levels, a.batches)
    if not a.skip_stribeck:
        part_stribeck(a.runs)


if __name__ == "__main__":
    main()
