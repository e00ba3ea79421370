"""C99 runtime speed on the host: jump-model ticks per second, against the Python renderer.

Builds runtime-c/ with the system C compiler (-O2, C99, no fast-math, no FMA
contraction: the flags that keep it bit-identical to the Python renderer) and
runs ``sd_bench`` (see runtime-c/tool_bench.c for the workload: the published
tent, handheld-stick pad, a 100 mm/s back-and-forth stroke at 10 kHz):

* pad      - the jump model kernel alone (sd_jump_tick), target >= 50 M ticks/s;
* exact    - the exact model kernel alone (sd_exact_tick), for comparison;
* drive    - the full renderer tick without audio (lookup, model, burst drive);
* audio48k - the full renderer tick with 48 kHz burst synthesis.

The baseline is the Python ``Renderer.step`` (numba) on the same stroke in
this run; ratios are printed. All rates are ticks per second of CPU time of
the process (time spent descheduled on a shared machine is not counted);
the machine load is printed too.

Run: .venv/bin/python benchmarks/bench_c_runtime.py
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CDIR = ROOT / "shapedisplay" / "runtime_c"
TARGET = 50e6


def build(out: Path) -> Path:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise SystemExit("no C compiler found")
    exe = out / "sd_bench"
    srcs = [str(CDIR / n) for n in ("sd_pad.c", "sd_exact.c", "sd_render.c", "tool_bench.c")]
    subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-I", str(CDIR), *srcs, "-lm", "-o", str(exe)],
                   check=True)
    return exe


def python_rates() -> dict:
    from shapedisplay.devices import load_device
    from shapedisplay.runtime import Renderer
    from shapedisplay.runtime.cursor import CursorPath
    from shapedisplay.table import FrictionTable, Grid, choose_quantization
    dev = load_device("handheld-stick")
    xg = np.arange(241) * 0.25e-3
    nf = np.interp(xg, [0, 0.015, 0.030, 0.045, 0.060], [0.5, 0.5, 2.5, 0.5, 0.5])
    table = FrictionTable.from_dense(Grid(1, 241, 0.25e-3, 0.25e-3), {"normal_force": nf[None, :]},
                                     {"normal_force": choose_quantization(nf, "uint16")}, {"device": dev.to_json()})
    r = Renderer(table, model="jump", tick_rate=10_000.0, audio_rate=48_000.0)
    n = 200_000
    i = np.arange(n)
    p = i % 10000
    x = 0.005 + 0.050 * np.where(p < 5000, p / 5000.0, (10000 - p) / 5000.0)
    r.reset()
    step = r.step
    t0 = time.process_time()
    for v in x:
        step(v, 0.0)
    online = n / (time.process_time() - t0)
    cp = CursorPath(i / 10_000.0, x, np.zeros(n), 10_000.0, "bench")
    r.render(cp)
    t0 = time.process_time()
    r.render(cp)
    offline = n / (time.process_time() - t0)
    return {"online": online, "offline": offline}


def main() -> int:
    with tempfile.TemporaryDirectory() as d:
        exe = build(Path(d))
        out = subprocess.run([str(exe), "20000000"], capture_output=True, text=True, check=True).stdout
    rates = {m.group(1): float(m.group(2)) * 1e6 for m in re.finditer(r"^(\w+)\s+([0-9.]+) Mticks/s", out, re.M)}
    py = python_rates()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine: {os.cpu_count()} cores, load average {load:.2f} during the run")
    print("rates are ticks per CPU-second")
    print(f"Python Renderer.step (online, numba): {py['online'] / 1e6:8.3f} Mticks/s   (baseline)")
    print(f"Python Renderer.render (offline):     {py['offline'] / 1e6:8.3f} Mticks/s")
    for key, what in (("pad", "C jump model kernel (sd_jump_tick)"),
                      ("exact", "C exact model kernel (sd_exact_tick)"),
                      ("drive", "C renderer tick, drive only"),
                      ("audio48k", "C renderer tick + 48 kHz audio")):
        v = rates.get(key, float("nan"))
        line = f"{what:<36}: {v / 1e6:8.2f} Mticks/s = {v / py['online']:7.1f} x Python step"
        if key == "pad":
            line += f", {v / TARGET:.2f} x the 50 M ticks/s target ({'OK' if v >= TARGET else 'MISSED'})"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
