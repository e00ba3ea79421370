"""Studio latencies in a real headless Chromium: edit -> feel, AudioWorklet CPU, audio latency.

1. Edit saved -> view updated and new table playing (phone scene): the scene
   file is rewritten (alternating two button levels) and the page reports when
   the new top view is shown and when the AudioWorklet plays the new table.
   Baseline measured in the same run: the compile alone (Python, in-process).
2. AudioWorklet CPU per 128-sample render quantum at a 10 kHz tick (48 kHz
   audio): a 3 s stroke across the phone scene rendered through an
   OfflineAudioContext (the same worklet and WebAssembly C runtime as live),
   wall time / quanta, as a fraction of the quantum's duration (2.67 ms).
   Baseline in the same run: the package's Renderer.render (the same C engine, native) on the same stroke.
3. Cursor-to-sound latency as the browser reports it: baseLatency +
   outputLatency of the live AudioContext, plus the studio's input delay
   (the cursor is rendered 1.5 pointer intervals behind the pointer, at
   least 20 ms, so that every tick lies between two pointer events).

Run: .venv/bin/python benchmarks/bench_studio.py  (needs chromium and playwright)
"""
from __future__ import annotations

import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from studio_helpers import PHONE, StudioProcess  # noqa: E402

REPEATS = 12


def stats(values):
    return f"min {min(values):7.1f}  median {statistics.median(values):7.1f}  max {max(values):7.1f}"


def main() -> int:
    from playwright.sync_api import sync_playwright

    from shapedisplay.render import Renderer
    from shapedisplay.render.cursor import parse_stroke
    from shapedisplay.author.scene import compile_scene

    folder = Path(tempfile.mkdtemp(prefix="sd-bench-studio-"))
    scene = folder / "phone.toml"
    shutil.copy(PHONE, scene)
    good = scene.read_text()
    studio = StudioProcess(scene)
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=shutil.which("chromium") or "/usr/bin/chromium",
                                        args=["--autoplay-policy=no-user-gesture-required"])
            page = browser.new_page(viewport={"width": 1400, "height": 950}, bypass_csp=True)
            page.goto(studio.url)
            page.wait_for_function("window.studio && studio.swaps.length && studio.swaps[0].t_view", timeout=30000)
            page.click("#feel")
            page.wait_for_function("studio.node && studio.ctx.state === 'running'", timeout=20000)

            # 1. edit -> view and playing
            view, playing, compile_ms, message = [], [], [], []
            for i in range(REPEATS):
                gen = page.evaluate("studio.tableGeneration")
                text = good.replace("level = 3 ", f"level = {4 + i % 2} ")
                tmp = folder / ".phone.toml.tmp"
                tmp.write_text(text)
                t_write = time.time() * 1e3
                os.replace(tmp, scene)                  # saved as editors save: one rename
                page.wait_for_function(f"studio.tableGeneration > {gen} && studio.swaps.some(s => "
                                       "s.generation === studio.tableGeneration && s.t_view && s.t_playing)",
                                       timeout=20000)
                sw = page.evaluate("studio.swaps.find(s => s.generation === studio.tableGeneration)")
                view.append(sw["t_view"] - t_write)
                message.append(sw["t_message"] - t_write)
                playing.append(sw["t_playing"] - t_write)
                t0 = time.perf_counter()
                compile_scene(scene)
                compile_ms.append((time.perf_counter() - t0) * 1e3)
            print("edit saved -> new table, phone scene, ms over", REPEATS, "edits")
            print(f"  page told (watch, compile, prepare) {stats(message)}")
            print(f"  view updated        {stats(view)}")
            print(f"  new table playing   {stats(playing)}   (target <= 250 ms)")
            print(f"  baseline: compile   {stats(compile_ms)}   "
                  f"(edit->playing / compile: {statistics.median(playing) / statistics.median(compile_ms):.1f}x)")

            # 2. AudioWorklet CPU per quantum
            stroke = parse_stroke("62,2 -> 62,80 -> 40,125 @ 60mm/s", 10000.0)
            xs, ys = stroke.x.tolist(), stroke.y.tolist()
            walls = []
            for _ in range(5):
                r = page.evaluate(f"studio.renderOffline({xs}, {ys}).then(s => ({{wall: s.wall_ms, quanta: s.quanta, "
                                  "events: s.event_time.length, ticks: s.ticks}))")
                walls.append(r["wall"] / r["quanta"] * 1e3)             # us per quantum
            quantum_us = 128 / 48000 * 1e6
            table = compile_scene(scene).table
            py = Renderer(table, model="exact")
            py.render(stroke)
            t0 = time.perf_counter()
            res = py.render(stroke)
            py_us = (time.perf_counter() - t0) * 1e6 / r["quanta"]
            print(f"AudioWorklet (C runtime in WebAssembly), {r['ticks']} ticks at 10 kHz, {r['events']} events "
                  f"(native: {res.event_time.size}), us per 128-sample quantum")
            print(f"  worklet             {stats(walls)}   = {100 * statistics.median(walls) / quantum_us:.2f} % "
                  f"of the {quantum_us:.0f} us quantum (target <= 10 %)")
            print(f"  baseline: Renderer.render (native C, offline) {py_us:7.1f} us per quantum's worth "
                  f"(worklet / native: {statistics.median(walls) / py_us:.2f}x)")

            # 3. latency
            lat = page.evaluate("({base: studio.ctx.baseLatency, output: studio.ctx.outputLatency, "
                                "rate: studio.ctx.sampleRate})")
            total = (lat["base"] + lat["output"]) * 1e3
            print(f"audio latency as the browser reports it: baseLatency {lat['base'] * 1e3:.1f} ms + outputLatency "
                  f"{lat['output'] * 1e3:.1f} ms = {total:.1f} ms at {lat['rate']:.0f} Hz; "
                  f"plus the studio's input delay (1.5 pointer intervals, at least 20 ms) and < 1 tick: "
                  f"cursor to sound {total + 20.1:.1f} ms with a mouse reporting at 60 Hz or faster")
            browser.close()
    finally:
        scene.write_text(good)
        studio.stop()
        shutil.rmtree(folder, ignore_errors=True)
    return 0


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    sys.exit(main())
