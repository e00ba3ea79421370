"""Compile a 4096x4096 16-bit PNG height map: time and peak memory, in process and whole process.

Whole process (``shapedisplay compile`` run as a user runs it, height+lateral
mapping, table written): budget 1.5 s on a smooth map and on a noisy one
(2.2 M separate wall regions). Each is run 5 times; the script prints
min/median/max of wall and CPU time (user+system of the child) and the ratio
against a baseline process run in the same loop: a plain Python script that
imports numpy and Pillow, reads the same PNG, takes the same gradients,
quantizes the same three channels and writes them uncompressed with
``numpy.savez`` (no walls, no checks, no report). The budget is judged on
CPU time: on a shared 2-core machine wall time also counts waiting for a
core.

In process (issue 2): PNG read + gradient analysis (slopes, walls, wall
limiting) + height+lateral mapping + quantization in <= 2 s on one core
(judged on CPU time of this single-threaded process, which waiting for a
busy machine does not inflate; wall time is printed too), peak memory <= 8x
the float64 height array (tracemalloc, which sees numpy's buffers). Timings are noisy on a shared machine, so the script also times a
plain-numpy pipeline doing the same arithmetic in the same run and prints
the ratio. Usage: ``.venv/bin/python benchmarks/bench_compile.py [size]``.
"""
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from shapedisplay.author.compile import CompileOptions, compile_heightfield  # noqa: E402
from shapedisplay.table.devices import load_device  # noqa: E402
from shapedisplay.author.imageio import read_picture, write_png  # noqa: E402
from shapedisplay.author.forces import MappingOptions  # noqa: E402
from shapedisplay.author.sources import load_image  # noqa: E402

BUDGET_S = 2.0
BUDGET_MEM = 8.0


def make_map(n: int, noise: float = 0.01) -> np.ndarray:
    """A smooth relief plus Gaussian noise of ``noise`` (fraction of full scale): 0.01 gives a noisy map
    whose slopes exceed 1 on 23 % of the samples in 2.2 M separate wall regions; 0 a smooth map."""
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:n, 0:n] / n
    h = 0.5 + 0.25 * np.sin(7 * x) * np.cos(5 * y) + 0.2 * np.exp(-((x - 0.4) ** 2 + (y - 0.6) ** 2) / 0.01)
    if noise:
        h += noise * rng.standard_normal((n, n))
    return np.rint(np.clip(h, 0, 1) * 65535).astype(np.uint16)


BUDGET_PROCESS_S = 1.5
PROCESS_RUNS = 5
CLI_ARGS = ["--size", "100x100mm", "--height", "0:2mm", "--mapping", "height+lateral", "--device", "desktop-rig",
            "--n-gain", "1N/mm", "--lateral-gain", "1N", "-q"]
BASELINE_SCRIPT = """
import sys
import numpy as np
from PIL import Image
g = np.asarray(Image.open(sys.argv[1]), dtype=np.float64)
h = g * (2e-3 / 65535)
del g
gy, gx = np.gradient(h, 100e-3 / h.shape[0], 100e-3 / h.shape[1])
n = 0.5 + 1000.0 * h
out = {}
for name, v in (("normal_force", n), ("lateral_x", -gx), ("lateral_y", -gy)):
    lo, hi = v.min(), v.max()
    out[name] = np.rint((v - lo) / ((hi - lo) / 255)).astype(np.uint8)
np.savez(sys.argv[2], **out)
"""


def run_process(cmd):
    """(wall s, CPU s = user + system of the child) of one process."""
    import resource
    import subprocess
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def spread(values) -> str:
    v = sorted(values)
    return f"{v[0]:5.2f} / {v[len(v) // 2]:5.2f} / {v[-1]:5.2f}"


def whole_process(tmp: Path, n: int) -> bool:
    """Time ``shapedisplay compile`` on a smooth and a noisy map against the baseline process."""
    cli = Path(sys.executable).with_name("shapedisplay")
    cli_cmd = [str(cli)] if cli.exists() else [sys.executable, "-m", "shapedisplay.cli.main"]
    ok = True
    print(f"whole process, {PROCESS_RUNS} runs each: min / median / max seconds; ratio = median ours / median "
          f"baseline (same runs, interleaved)")
    for label, noise in (("smooth", 0.0), ("noisy", 0.01)):
        path = tmp / f"{label}.png"
        write_png(path, make_map(n, noise))
        ours_cmd = cli_cmd + ["compile", str(path), "-o", str(tmp / f"{label}.npz")] + CLI_ARGS
        base_cmd = [sys.executable, "-c", BASELINE_SCRIPT, str(path), str(tmp / f"{label}-base.npz")]
        run_process(ours_cmd)                       # warm the page cache (and any kernel cache)
        ours, base = [], []
        for _ in range(PROCESS_RUNS):
            ours.append(run_process(ours_cmd))
            base.append(run_process(base_cmd))
        ow, oc = zip(*ours)
        bw, bc = zip(*base)
        med = sorted(oc)[len(oc) // 2]
        within = med <= BUDGET_PROCESS_S
        ok &= within
        print(f"  {label:6s} shapedisplay compile   wall {spread(ow)}   CPU {spread(oc)}   "
              f"budget {BUDGET_PROCESS_S} s (CPU median): {'OK' if within else 'OVER'}")
        print(f"  {label:6s} baseline process       wall {spread(bw)}   CPU {spread(bc)}   "
              f"ratio ours/baseline: CPU {med / sorted(bc)[len(bc) // 2]:.2f}, "
              f"wall {sorted(ow)[len(ow) // 2] / sorted(bw)[len(bw) // 2]:.2f}")
        size = (tmp / f"{label}.npz").stat().st_size
        print(f"  {label:6s} table file {size / 2**20:.1f} MiB")
    return ok


def ours(path, device, mapping, options):
    hf = load_image(path, "100x100mm", "0:2mm")
    return compile_heightfield(hf, device, mapping, options)


def naive(path, lateral_gain=1.0):
    """Same arithmetic in plain numpy (no walls, no checks, no report)."""
    g = read_picture(path).values
    h = g * (2e-3 / 65535)
    del g
    gy, gx = np.gradient(h, 100e-3 / h.shape[0], 100e-3 / h.shape[1])
    n = 0.5 + 1000.0 * h
    out = []
    for v in (n, -lateral_gain * gx, -lateral_gain * gy):
        lo, hi = v.min(), v.max()
        out.append(np.rint((v - lo) / ((hi - lo) / 65535)).astype(np.uint16))
    return out


def best_of(fn, k=3):
    """Best wall time and best CPU time (process time, one thread) of k runs."""
    wall, cpu = [], []
    for _ in range(k):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu)


def main(n: int = 4096) -> int:
    device = load_device("desktop-rig")
    mapping = MappingOptions.parse("height+lateral", n_base="0.5N", n_gain="1N/mm", lateral_gain="1N")
    options = CompileOptions()
    with tempfile.TemporaryDirectory() as tmp:
        ok_process = whole_process(Path(tmp), n)
        path = Path(tmp) / "map.png"
        t0 = time.perf_counter()
        write_png(path, make_map(n))
        print(f"map {n}x{n} 16-bit PNG, {path.stat().st_size / 2**20:.1f} MiB, written in {time.perf_counter() - t0:.2f} s")
        ours(path, device, mapping, options)            # warm up (C kernels loaded, page cache)
        t_read, c_read = best_of(lambda: read_picture(path))
        t_ours, c_ours = best_of(lambda: ours(path, device, mapping, options))
        t_naive, c_naive = best_of(lambda: naive(path))
        res = ours(path, device, mapping, options)
        t0 = time.perf_counter()
        res.table.save(Path(tmp) / "t.npz")
        t_save = time.perf_counter() - t0

        tracemalloc.start()
        res = None
        ours(path, device, mapping, options)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        tracemalloc.start()
        naive(path)
        _, peak_naive = tracemalloc.get_traced_memory()
        tracemalloc.stop()

    base = n * n * 8
    print("                                     wall      CPU (one thread)")
    print(f"PNG read (16-bit grey)              {t_read:6.3f} s  {c_read:6.3f} s")
    print(f"load + compile (height+lateral)     {t_ours:6.3f} s  {c_ours:6.3f} s   budget {BUDGET_S} s "
          f"-> CPU {c_ours / BUDGET_S:.2f} of budget")
    print(f"plain-numpy pipeline, same math     {t_naive:6.3f} s  {c_naive:6.3f} s   "
          f"ratio ours/plain = {c_ours / c_naive:.2f} (CPU), {t_ours / t_naive:.2f} (wall)")
    print(f"table save (.npz, compressed)       {t_save:6.3f} s   (not part of the compile budget)")
    print(f"peak memory (tracemalloc)           {peak / 2**20:6.0f} MiB = {peak / base:.2f} x float64 heights "
          f"(budget {BUDGET_MEM:g} x); plain numpy {peak_naive / base:.2f} x")
    # CPU time is the one-core figure; wall time also counts waiting for a shared machine's cores
    ok = c_ours <= BUDGET_S and peak / base <= BUDGET_MEM and ok_process
    print("within budget" if ok else "OVER BUDGET")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 4096))
