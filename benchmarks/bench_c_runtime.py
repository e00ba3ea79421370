"""The C engine's tick on the host, built outside Python, against the same engine called from Python.

Builds ``sd_bench`` from ``shapedisplay/engine/`` with the system C
compiler (the library sources of ``engine/Makefile``, C99, -O2, no FMA
contraction: the flags ``setup.py`` builds ``shapedisplay._engine`` with) and
runs it (``engine/tool_bench.c``: a 60 mm tent table, the Konyo pad, a
100 mm/s back-and-forth stroke at 10 kHz):

* pad      - the jump model's tick alone (``sd_jump_tick``);
* exact    - the exact model's tick alone (``sd_exact_tick``);
* drive    - the full renderer tick without audio (lookup, model, burst drive);
* audio48k - the full renderer tick with 48 kHz burst audio.

The baseline, measured in this run on the same table and stroke: the
package's ``Renderer.step`` called from Python once per tick (one ctypes
call into the same engine) and ``Renderer.render`` (one call for the whole
path). Rates are ticks per CPU-second of the process; the machine load is
printed too.

Run: ``.venv/bin/python benchmarks/bench_c_runtime.py [--quick]``
"""
from __future__ import annotations

import argparse
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
CDIR = ROOT / "shapedisplay" / "engine"


def library_sources() -> list:
    """The engine library's C sources, as ``engine/Makefile`` lists them (``LIB :=``)."""
    text = (CDIR / "Makefile").read_text()
    names = re.search(r"^LIB\s*:=\s*(.+)$", text, re.M).group(1).split()
    return [str(CDIR / n) for n in names]


def build(out: Path) -> Path:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise SystemExit("no C compiler found")
    exe = out / "sd_bench"
    srcs = [*library_sources(), str(CDIR / "tool_bench.c")]
    subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-I", str(CDIR), *srcs, "-lm", "-o", str(exe)],
                   check=True)
    return exe


def python_rates(n: int) -> dict:
    from shapedisplay.table.devices import load_device
    from shapedisplay.render import Renderer
    from shapedisplay.render.cursor import CursorPath
    from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
    dev = load_device("handheld-stick")
    xg = np.arange(241) * 0.25e-3
    nf = np.interp(xg, [0, 0.015, 0.030, 0.045, 0.060], [0.5, 0.5, 2.5, 0.5, 0.5])
    table = FrictionTable.from_dense(Grid(1, 241, 0.25e-3, 0.25e-3), {"normal_force": nf[None, :]},
                                     {"normal_force": choose_quantization(nf, "uint16")}, {"device": dev.to_json()})
    r = Renderer(table, model="jump", tick_rate=10_000.0, audio_rate=48_000.0)
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
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 M ticks in C (default 20 M), 50 000 from Python")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        exe = build(Path(d))
        out = subprocess.run([str(exe), "2000000" if a.quick else "20000000"], capture_output=True, text=True,
                             check=True).stdout
    rates = {m.group(1): float(m.group(2)) * 1e6 for m in re.finditer(r"^(\w+)\s+([0-9.]+) Mticks/s", out, re.M)}
    py = python_rates(50_000 if a.quick else 200_000)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine: {os.cpu_count()} cores, load average {load:.2f} during the run")
    print("rates are ticks per CPU-second")
    print(f"Renderer.step from Python (ctypes):   {py['online'] / 1e6:8.3f} Mticks/s   (baseline)")
    print(f"Renderer.render from Python (1 call): {py['offline'] / 1e6:8.3f} Mticks/s = "
          f"{py['offline'] / py['online']:7.1f} x Python step")
    for key, what in (("pad", "C jump model kernel (sd_jump_tick)"),
                      ("exact", "C exact model kernel (sd_exact_tick)"),
                      ("drive", "C renderer tick, drive only"),
                      ("audio48k", "C renderer tick + 48 kHz audio")):
        v = rates.get(key, float("nan"))
        print(f"{what:<36}: {v / 1e6:8.2f} Mticks/s = {v / py['online']:7.1f} x Python step")
    return 0


if __name__ == "__main__":
    sys.exit(main())
