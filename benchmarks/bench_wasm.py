"""Speed of the WebAssembly build in wasmtime against the native build of the same C sources.

The same table image, settings and stroke (2-D widget table, six channels, jump model,
retrigger, 10 kHz ticks, 48 kHz audio, 200 000 ticks) played by `sd_vectors image` compiled
natively (cc -O2, a loop over sd_renderer_step timed inside the process) and by sd_runtime.wasm
in wasmtime through `sd_wasm_run` (one call for all ticks, audio copied out); both are CPU time
of the tick loop alone, best of 5, measured in the same run. Prints ticks per second of both and
the ratio wasm / native.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_c_runtime import library_sources  # noqa: E402
from native_loop import LOOP_C  # noqa: E402
from runtime_vectors import WasmRunner, case_setup, image_payload  # noqa: E402
from shapedisplay.render import wasm  # noqa: E402

CDIR = Path(__file__).resolve().parent.parent / "shapedisplay" / "engine"
N = 200_000
REPEATS = 5          # best of 5 for both (a shared machine)


# The native loop: the same payload as `sd_vectors image`, the ticks timed inside the process
# (CPU time of the sd_renderer_step loop only; the audio block is summed so it is not optimised away).


def main() -> int:
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.25)
    reps = N // len(x) + 1
    x = np.tile(np.concatenate([x, x[::-1]]), reps)[:N]
    y = np.tile(np.concatenate([y, y[::-1]]), reps)[:N]
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        exe = d / "sd_loop"
        (d / "loop.c").write_text(LOOP_C)
        srcs = library_sources()
        cc = os.environ.get("CC", "cc")
        subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-I", str(CDIR), *srcs, str(d / "loop.c"),
                        "-lm", "-o", str(exe)], check=True)
        (d / "in").write_bytes(image_payload(img, r, x, y))
        native = min(json.loads(subprocess.run([str(exe), str(d / "in"), str(REPEATS)], capture_output=True,
                                               text=True, check=True).stdout))
    w = WasmRunner(wasm.MODULE)
    per_tick = int(np.ceil(r.audio_rate / r.tick_rate)) + 2
    assert w.load(img) == 0
    assert w.call("sd_wasm_configure", int(r.config["model"]), int(r.config["policy"]), r.tick_rate, r.audio_rate) == 0
    xy = np.empty(2 * N, "<f8")
    xy[0::2], xy[1::2] = x, y
    p = w.call("sd_wasm_scratch", 16 * N + 8 * per_tick * N)
    w.write(p, xy.tobytes())
    wasm_s = float("inf")
    for _ in range(REPEATS):
        w.call("sd_wasm_reset", 0.0)
        t0 = time.process_time()
        na = w.call("sd_wasm_run", p, N, 0, p + 16 * N, per_tick * N)
        wasm_s = min(wasm_s, time.process_time() - t0)
        assert na > 0
    print(f"native C   {N / native / 1e6:.2f} Mticks/s ({native:.3f} s CPU for {N} ticks)")
    print(f"wasmtime   {N / wasm_s / 1e6:.2f} Mticks/s ({wasm_s:.3f} s CPU)")
    print(f"wasm / native speed: {native / wasm_s:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
