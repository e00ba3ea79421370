"""Studio design latency in a real headless Chromium: a canvas drag released -> the new table playing.

The phone scene; feel on (the AudioWorklet running the C runtime). Each edit
drags a widget on the top view with the mouse (app-1, back and forth by 20
pixels: a move of a few millimetres) and releases it. Measured per edit, from
the page's pointerup:

* answered: the server's answer to the edit (the file rewritten through the
  TOML editor, validated, written, recorded, compiled, prepared);
* playing: the worklet has loaded the new table (its table-ready message).

Baseline in the same run: the compile alone (Python, in-process, the scene
as the edit left it) and the server's own compile time for the edit.

Run: .venv/bin/python benchmarks/bench_studio_design.py [--edits N]  (needs chromium and playwright)
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

from studio_helpers import PHONE, StudioProcess  # noqa: E402


def stats(values):
    return f"min {min(values):7.1f}  median {statistics.median(values):7.1f}  max {max(values):7.1f}"


def main(argv=None) -> int:
    from playwright.sync_api import sync_playwright

    from shapedisplay.author.scene import compile_scene

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--edits", type=int, default=16, help="drags measured (default 16)")
    args = ap.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="sd-bench-design-"))
    scene = folder / "phone.toml"
    shutil.copy(PHONE, scene)
    studio = StudioProcess(scene)
    answered, playing, server_compile, compile_alone = [], [], [], []
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=shutil.which("chromium") or "/usr/bin/chromium",
                                        args=["--autoplay-policy=no-user-gesture-required"])
            page = browser.new_page(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
            page.goto(studio.url)
            page.wait_for_function("window.studio && studio.shownGeneration !== null && studio.design && "
                                   "studio.design.schema", timeout=30000)
            page.click("#feel")
            page.wait_for_function("studio.node && studio.ctx.state === 'running'", timeout=20000)
            for i in range(args.edits + 2):                       # the first two warm up
                gen = page.evaluate("studio.tableGeneration")
                box = page.locator('[data-widget="app-1"]').bounding_box()
                cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
                dx = 20 if i % 2 == 0 else -20
                page.keyboard.down("Alt")                         # the grid only: every drag moves the widget
                page.mouse.move(cx, cy)
                page.mouse.down()
                page.mouse.move(cx + dx, cy, steps=4)
                page.mouse.up()
                page.keyboard.up("Alt")
                page.wait_for_function(f"studio.tableGeneration > {gen} && studio.swaps.some(s => "
                                       "s.generation === studio.tableGeneration && s.t_playing)", timeout=20000)
                r = page.evaluate("""(() => { const s = studio.swaps.find(s => s.generation === studio.tableGeneration);
                    return {released: studio.design.released, message: s.t_message, playing: s.t_playing,
                            compile: studio.state.last_change.compile_ms}; })()""")
                t0 = time.perf_counter()
                compile_scene(scene)
                alone = (time.perf_counter() - t0) * 1e3
                if i < 2:
                    continue
                answered.append(r["message"] - r["released"])
                playing.append(r["playing"] - r["released"])
                server_compile.append(r["compile"])
                compile_alone.append(alone)
                time.sleep(0.15)
            browser.close()
    finally:
        studio.stop()
        shutil.rmtree(folder, ignore_errors=True)
    n = len(playing)
    print(f"canvas drag released -> new table, phone scene, ms over {n} drags")
    print(f"  state with the new table at the page {stats(answered)}")
    print(f"  new table playing in the worklet    {stats(playing)}   (target: median <= 100 ms)")
    print(f"  the server's compile + prepare      {stats(server_compile)}")
    print(f"  baseline: compile alone (in-process) {stats(compile_alone)}   "
          f"(playing / compile: {statistics.median(playing) / statistics.median(compile_alone):.1f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
