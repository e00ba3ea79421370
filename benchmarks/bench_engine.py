"""The playing engine against the last release, measured in one run: whole-process plays, offline renders, reports.

Compares this tree ("new": ``.venv/bin/python``, ``.venv/bin/shapedisplay``)
with a checkout of the last released state ("old": commit 59ad372 with its own
``.venv``), one command of each per round (old, new, old, new, ...), so a
change of machine load hits both sides alike:

a. first play, whole process: ``shapedisplay play phone.npz --stroke
   "62,2 -> 62,156 @ 30mm/s" --model exact --tick-rate 10kHz -o OUT.wav``
   with cold caches: every run gets fresh, empty ``NUMBA_CACHE_DIR`` (numba's
   compiled kernels) and ``XDG_CACHE_HOME`` (where the old release built its
   C runtime library, ``$XDG_CACHE_HOME/shapedisplay``);
b. warm play: the same command with the ordinary caches (numba's
   ``__pycache__`` beside each tree's sources, ``~/.cache``), filled by one
   untimed run;
c. offline render in the process: ``Renderer(table, model=m).render(cursor)``
   (``shapedisplay.render.renderer``: numba in the old release, the C runtime
   now) and the renderer ``play`` uses (the old release's ``PathRenderer``,
   engine "auto", whose engine is printed; the new ``Renderer``) for the models
   exact, jump, karnopp and stribeck, a 5 s stroke (``parse_stroke("62,2 ->
   62,152 @ 30mm/s", 10 kHz)``, 50 001 ticks); one warm-up render, then only
   ``render`` is timed (the renderer is built once; the ordinary caches);
d. ``shapedisplay report accuracy --quick`` and ``report stability --quick``
   (``--no-plots``): whole-process wall time, and from ``accuracy.json`` the
   renderer's CPU time per simulated second (``Renderer.render``, and ``run_kernel``: the model alone)
   summed per model over the settings both sides ran;
e. WebAssembly against native, per tick: each side's C sources (``engine/``, the library its
   ``Makefile`` lists as ``LIB``) built natively (``cc -O2``, a loop over ``sd_renderer_step`` timed inside
   the process) and as its WebAssembly module (``make -C engine wasm`` in a copy of its tree; the
   shipped ``engine/wasm/sd_runtime.wasm`` if clang/wasm-ld are missing), run in wasmtime through
   ``sd_wasm_run`` (one call for all ticks, as ``benchmarks/bench_wasm.py``), both modules in the same
   wasmtime (this tree's venv, where the old venv has none). The input: ``case_setup`` of each side's
   ``tests/runtime_vectors.py`` (2-D widget table, six channels, retrigger, 10 kHz ticks, 48 kHz audio,
   the diagonal stroke back and forth), 200 000 ticks, models jump and exact (the old C has only those).
   CPU time of the tick loop alone; ``--wasm-rounds`` processes per side and target, 3 loops each;
f. Cortex-M4F instructions per ``sd_renderer_step`` under QEMU (mps2-an386, ``-icount``): each side's
   harness (``build_m4`` of its ``tests/runtime_vectors.py``, its own ``engine/`` sources, single
   precision, the M4F's FPU) plays the same shared vector (the widget table, diagonal stroke,
   retrigger, 10 kHz ticks, 48 kHz audio, 0.25 s: 2 500 ticks) for exact and jump. Instruction counts
   are deterministic, so one run per side suffices; min / median / max are over the ticks, and the
   note gives the mean and the worst tick against the 16 800 cycles of a 10 kHz tick at 168 MHz.

Each table comes from ``assets/scenes/phone.toml`` compiled by its own side's
``shapedisplay compile`` (if one side cannot compile, both play the other's).
Every figure is min / median / max over the runs, wall time (e: CPU time per tick; f: instructions
per tick, over the ticks); the ratio is
old median / new median, so **a ratio above 1 means the new code is faster**.
Whole-process rows also give the ratio of the median CPU time (user + system
of the child), which a loaded machine inflates less than wall time.

The tree under test may change while this runs: every run is a new process,
and a run that fails prints its last error line and the benchmark goes on
(its row then shows ``failed``).

Set up the baseline once::

    git clone /work/main /tmp/sd-base && git -C /tmp/sd-base checkout 59ad372
    cd /tmp/sd-base && python3 -m venv .venv && .venv/bin/pip install -q -e '.[all]' pytest
    # pytest: the old tests/runtime_vectors.py (e, f) imports test_c_runtime, which imports it

Run (standard library only, any Python 3.9+)::

    python benchmarks/bench_engine.py --baseline /tmp/sd-base
    python benchmarks/bench_engine.py --baseline /tmp/sd-base --skip-reports   # about a minute

e needs this tree's venv to have wasmtime (``pip install -e '.[test]'``) and a C compiler; f needs
arm-none-eabi-gcc, newlib and qemu-system-arm (``scripts/install-system-deps.sh --with-toolchains``);
a side that cannot build prints its failure and the row shows ``failed``.

The quick reports take under a minute each on a 2-core machine; ``--report-rounds`` defaults to 1.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from native_loop import LOOP_C  # noqa: E402  (the loop bench_wasm.py times)

ROOT = Path(__file__).resolve().parent.parent
PLAY_STROKE = "62,2 -> 62,156 @ 30mm/s"
RENDER_STROKE = "62,2 -> 62,152 @ 30mm/s"        # 150 mm at 30 mm/s: 5 s, 50 001 ticks at 10 kHz
RENDER_MODELS = ("exact", "jump", "karnopp", "stribeck")
TIMEOUT_S = 1800                                   # one process; a report on a loaded machine takes minutes

# Run by each side's python: one JSON line per (class, model), the render times in seconds or the error.
RENDER_SCRIPT = r"""
import json, sys, time
import shapedisplay.render.renderer as renderer
from shapedisplay.render.cursor import parse_stroke
from shapedisplay.table.model import FrictionTable

try:                                     # the old release plays through PathRenderer (engine "auto")
    from shapedisplay.render.play import PathRenderer
except ImportError:                      # the C runtime's Renderer is what play calls
    PathRenderer = None

table_path, repeats, stroke, models = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4].split(",")
table = FrictionTable.load(table_path)
cursor = parse_stroke(stroke, 10_000.0)


def timed(make):
    try:
        r = make()
        r.render(cursor)                                   # warm-up: compiles, fills caches
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            r.render(cursor)
            times.append(time.perf_counter() - t0)
        engine = getattr(r, "engine", None)
        return {"times": times, "engine": f"{type(r).__name__}, engine {engine}" if engine else type(r).__name__}
    except Exception as exc:                               # a model the tree cannot play: report it, go on
        text = f"{type(exc).__name__}: {exc}"
        return {"error": text.splitlines()[0] if text.strip() else type(exc).__name__}


play_class = PathRenderer or renderer.Renderer
for m in models:
    for name, make in (("Renderer", lambda: renderer.Renderer(table, model=m, tick_rate=10_000.0)),
                       ("play", lambda: play_class(table, model=m, tick_rate=10_000.0))):
        print(json.dumps({"cls": name, "model": m, **timed(make)}), flush=True)
"""


# Run by each side's python (e, f): argv tests dir, output dir, models, ticks. The shared vector of that side's
# tests/runtime_vectors.py (its own table image), the diagonal stroke back and forth to `ticks` ticks.
PAYLOAD_SCRIPT = r"""
import sys
from pathlib import Path
import numpy as np
sys.path.insert(0, sys.argv[1])
from runtime_vectors import case_setup, image_payload
out, models, n = Path(sys.argv[2]), sys.argv[3].split(","), int(sys.argv[4])
for m in models:
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, m, seconds=0.25)
    reps = n // len(x) + 1
    x = np.tile(np.concatenate([x, x[::-1]]), reps)[:n]
    y = np.tile(np.concatenate([y, y[::-1]]), reps)[:n]
    (out / f"{m}.in").write_bytes(image_payload(img, r, x, y))
"""

# Run by each side's python (f): argv tests dir, models. Builds that side's M4F harness from its own sources,
# one JSON line per model with the instructions of every sd_renderer_step.
M4_SCRIPT = r"""
import json, sys, tempfile
from pathlib import Path
sys.path.insert(0, sys.argv[1])
from runtime_vectors import build_m4, case_setup, image_payload, m4_instructions, run_m4
with tempfile.TemporaryDirectory() as d:
    d = Path(d)
    elf = build_m4(d / "build", (), "single")[0]
    for m in sys.argv[2].split(","):
        table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, m, seconds=0.25)
        ins = m4_instructions(run_m4(elf, "bench", image_payload(img, r, x, y), d, icount=True))
        print(json.dumps({"model": m, "instructions": ins.tolist()}), flush=True)
"""

# Run by a python with wasmtime (e): argv module, payload, loops. The payload as image_payload writes it; the
# ticks through sd_wasm_run as benchmarks/bench_wasm.py; prints the CPU seconds of each loop (JSON list).
WASM_SCRIPT = r"""
import json, math, struct, sys, time
import wasmtime
module_path, payload, loops = sys.argv[1], open(sys.argv[2], "rb").read(), int(sys.argv[3])
(size,) = struct.unpack_from("<q", payload, 0)
image = payload[8:8 + size]
pos = 8 + size + (-size % 8)
policy, model = struct.unpack_from("<qq", payload, pos)
tick, audio = struct.unpack_from("<dd", payload, pos + 16)
(n,) = struct.unpack_from("<q", payload, pos + 32)
x = payload[pos + 40:pos + 40 + 8 * n]
y = payload[pos + 40 + 8 * n:pos + 40 + 16 * n]
xy = bytearray(16 * n)                                   # interleaved x0 y0 x1 y1 ...
for i in range(8):
    xy[i::16] = x[i::8]
    xy[8 + i::16] = y[i::8]
engine = wasmtime.Engine()
store = wasmtime.Store(engine)
inst = wasmtime.Instance(store, wasmtime.Module.from_file(engine, module_path), [])
ex = inst.exports(store)
ex["_initialize"](store)
mem = ex["memory"]
base = ex["sd_wasm_stage"](store, len(image))
mem.write(store, image, base)
assert ex["sd_wasm_load"](store, base, len(image)) == 0, "sd_wasm_load"
assert ex["sd_wasm_configure"](store, model, policy, tick, audio) == 0, "sd_wasm_configure"
per_tick = math.ceil(audio / tick) + 2
p = ex["sd_wasm_scratch"](store, 16 * n + 8 * per_tick * n)
mem.write(store, bytes(xy), p)
times = []
for _ in range(loops):
    ex["sd_wasm_reset"](store, 0.0)
    t0 = time.process_time()
    na = ex["sd_wasm_run"](store, p, n, 0, p + 16 * n, per_tick * n)
    times.append(time.process_time() - t0)
    assert na > 0, "sd_wasm_run wrote no audio"
print(json.dumps(times))
"""

WASM_TICKS = 200_000
WASM_LOOPS = 3                                     # timed loops per process
M4_MODELS = ("exact", "jump")                      # the old C runtime has only these two
M4_BUDGET = 16_800                                 # cycles of a 10 kHz tick at 168 MHz

@dataclass
class Side:
    """One tree under test: its root and virtual environment."""
    name: str                   # "old" or "new"
    root: Path

    @property
    def python(self) -> str:
        return str(self.root / ".venv" / "bin" / "python")

    @property
    def cli(self) -> str:
        return str(self.root / ".venv" / "bin" / "shapedisplay")


@dataclass
class Row:
    """Samples of one measurement, per side."""
    label: str
    wall: dict = field(default_factory=lambda: {"old": [], "new": []})
    cpu: dict = field(default_factory=lambda: {"old": [], "new": []})
    failures: dict = field(default_factory=lambda: {"old": [], "new": []})
    note: str = ""
    unit: str = "s"             # "s": a duration; "tick": seconds per tick; "instr": instructions per tick


def last_error_line(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[-1] if lines else "(no output)"


def run(side: Side, argv: list, env: dict, cwd: Path):
    """Run one process; return (wall s, cpu s, stdout) or raise RuntimeError with the failure line."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    try:
        p = subprocess.run(argv, env={**os.environ, **env}, cwd=cwd, capture_output=True, text=True,
                           timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise RuntimeError(f"timed out after {TIMEOUT_S} s") from None
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        raise RuntimeError(f"exit {p.returncode}: {last_error_line(p.stderr or p.stdout)}")
    return wall, cpu, p.stdout


def fresh_caches(work: Path) -> dict:
    d = Path(tempfile.mkdtemp(prefix="cache-", dir=work))
    return {"NUMBA_CACHE_DIR": str(d / "numba"), "XDG_CACHE_HOME": str(d / "xdg")}


def record(row: Row, side: Side, fn):
    """Add one timed sample of ``fn()`` -> (wall, cpu, stdout) to ``row``; print a failure and go on."""
    try:
        wall, cpu, out = fn()
    except RuntimeError as exc:
        row.failures[side.name].append(str(exc))
        print(f"  {side.name:3} {row.label}: FAILED {exc}", flush=True)
        return None
    row.wall[side.name].append(wall)
    row.cpu[side.name].append(cpu)
    return out


def play_argv(side: Side, table: Path, out: Path) -> list:
    return [side.cli, "play", str(table), "--stroke", PLAY_STROKE, "--model", "exact", "--tick-rate", "10kHz",
            "-o", str(out)]


def compile_tables(sides, work: Path) -> dict:
    """phone.npz per side, compiled by that side; a side that cannot compile borrows the other's."""
    tables, errors = {}, {}
    for s in sides:
        out = work / f"phone-{s.name}.npz"
        try:
            run(s, [s.cli, "compile", str(s.root / "assets" / "scenes" / "phone.toml"), "-o", str(out)],
                fresh_caches(work), work)
            tables[s.name] = out
        except RuntimeError as exc:
            errors[s.name] = str(exc)
            print(f"  {s.name:3} compile phone.toml: FAILED {exc}", flush=True)
    for s in sides:
        if s.name not in tables and tables:
            other = next(iter(tables.values()))
            print(f"  {s.name:3} plays {other.name} (compiled by the other side)")
            tables[s.name] = other
    return tables


def measure_plays(sides, tables, work: Path, cold_runs: int, warm_runs: int) -> tuple:
    cold = Row(f"a. first play, cold caches (n={cold_runs})")
    warm = Row(f"b. warm play (n={warm_runs})")
    print("a. first play, cold caches", flush=True)
    for _ in range(cold_runs):
        for s in sides:
            env = fresh_caches(work)
            record(cold, s, lambda: run(s, play_argv(s, tables[s.name], work / f"{s.name}.wav"), env, work))
    print("b. warm play", flush=True)
    warm_env = {s.name: {} for s in sides}                # the ordinary caches (numba's __pycache__, ~/.cache)
    for s in sides:                                        # fill them (untimed)
        try:
            run(s, play_argv(s, tables[s.name], work / f"{s.name}.wav"), warm_env[s.name], work)
        except RuntimeError as exc:
            print(f"  {s.name:3} warm-up play: FAILED {exc}", flush=True)
    for _ in range(warm_runs):
        for s in sides:
            record(warm, s, lambda: run(s, play_argv(s, tables[s.name], work / f"{s.name}.wav"),
                                        warm_env[s.name], work))
    return [cold, warm], warm_env


def measure_renders(sides, tables, work: Path, warm_env: dict, rounds: int, repeats: int) -> list:
    print(f"c. offline render, {rounds} processes x {repeats} renders per side", flush=True)
    what = {"Renderer": "Renderer", "play": "play's renderer"}
    rows = {(cls, m): Row(f"c. {m} 5 s at 10 kHz, {what[cls]}") for m in RENDER_MODELS for cls in what}
    engines: dict = {}
    for _ in range(rounds):
        for s in sides:
            argv = [s.python, "-c", RENDER_SCRIPT, str(tables[s.name]), str(repeats), RENDER_STROKE,
                    ",".join(RENDER_MODELS)]
            try:
                out = run(s, argv, warm_env[s.name], work)[2]
            except RuntimeError as exc:
                print(f"  {s.name:3} c. render process: FAILED {exc}", flush=True)
                for row in rows.values():
                    row.failures[s.name].append(f"render process: {exc}")
                continue
            for line in out.splitlines():
                try:
                    r = json.loads(line)
                except ValueError:                         # not ours (a library printing to stdout)
                    continue
                key = (r["cls"], r["model"])
                row = rows[key]
                if "error" in r:
                    row.failures[s.name].append(r["error"])
                    print(f"  {s.name:3} {row.label}: FAILED {r['error']}", flush=True)
                else:
                    row.wall[s.name].extend(r["times"])
                    if r["cls"] == "play":
                        engines.setdefault((key, s.name), set()).add(r["engine"])
    for key, row in rows.items():
        row.note = "; ".join(f"{n}: {'/'.join(sorted(engines[key, n]))}" for n in ("old", "new")
                             if (key, n) in engines)
    return [rows[k] for k in sorted(rows, key=lambda k: (RENDER_MODELS.index(k[1]), k[0] != "Renderer"))]


def accuracy_timings(path: Path) -> dict:
    """{(case, setting label): (model, render CPU s per simulated s, model-alone CPU s per simulated s)} of the
    renderer settings that ran."""
    data = json.loads(path.read_text())
    return {(c["name"], st["label"]): (st["model"], st["cpu_s_per_sim_s"], st.get("model_cpu_s_per_sim_s"))
            for c in data["cases"] for st in c["settings"]
            if st.get("family") == "renderer" and st.get("status") == "ok" and st.get("cpu_s_per_sim_s") is not None}


def measure_reports(sides, work: Path, warm_env: dict, rounds: int) -> list:
    rows = []
    timings = {"old": [], "new": []}
    for kind in ("accuracy", "stability"):
        row = Row(f"d. report {kind} --quick, whole process (n={rounds})")
        print(f"d. report {kind} --quick", flush=True)
        for _ in range(rounds):
            for s in sides:
                out_dir = Path(tempfile.mkdtemp(prefix=f"{kind}-{s.name}-", dir=work))
                argv = [s.cli, "report", kind, "--quick", "--no-plots", "--no-progress", "-o", str(out_dir)]
                if record(row, s, lambda: run(s, argv, warm_env[s.name], work)) is not None and kind == "accuracy":
                    try:
                        timings[s.name].append(accuracy_timings(out_dir / "accuracy.json"))
                    except (OSError, ValueError, KeyError) as exc:
                        print(f"  {s.name:3} accuracy.json unreadable: {exc}", flush=True)
        rows.append(row)
    runs = timings["old"] + timings["new"]
    if timings["old"] and timings["new"]:
        common = set.intersection(*(set(t) for t in runs))
        models = sorted({runs[0][k][0] for k in common})
        for m in models:
            keys = [k for k in common if runs[0][k][0] == m]
            for i, what in ((1, "render"), (2, "model alone")):
                if any(t[k][i] is None for t in runs for k in keys):
                    continue
                row = Row(f"d. accuracy {m}, {what}: CPU per sim s, {len(keys)} settings")
                for name in ("old", "new"):
                    row.wall[name] = [sum(t[k][i] for k in keys) for t in timings[name]]
                rows.insert(-1, row)
    return rows


def library_sources(cdir: Path) -> list:
    """A side's engine library: the C sources its ``engine/Makefile`` lists as ``LIB :=``."""
    for line in (cdir / "Makefile").read_text().splitlines():
        if line.startswith("LIB") and ":=" in line:
            return [str(cdir / n) for n in line.split(":=", 1)[1].split()]
    raise RuntimeError(f"no LIB := line in {cdir / 'Makefile'}")


def wasm_python(sides) -> str:
    """A python with wasmtime: this tree's (both modules then run in the same wasmtime)."""
    for s in reversed(sides):
        if subprocess.run([s.python, "-c", "import wasmtime"], capture_output=True).returncode == 0:
            return s.python
    raise RuntimeError("no venv has wasmtime (pip install -e '.[test]' in this tree)")


def build_wasm_targets(side: Side, work: Path) -> tuple:
    """(native loop executable, WebAssembly module, how the module was got) built from the side's sources."""
    cdir = side.root / "shapedisplay" / "engine"
    out = work / f"e-{side.name}"
    out.mkdir()
    (out / "loop.c").write_text(LOOP_C)
    exe = out / "sd_loop"
    cc = os.environ.get("CC", "cc")
    p = subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-I", str(cdir), *library_sources(cdir),
                        str(out / "loop.c"), "-lm", "-o", str(exe)], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"native build: {last_error_line(p.stderr)}")
    copy = out / "engine"
    shutil.copytree(cdir, copy, ignore=shutil.ignore_patterns("build", "sd_vectors*", "sd_bench", "*.o"))
    p = subprocess.run(["make", "-s", "-C", str(copy), "wasm"], capture_output=True, text=True, timeout=300)
    if p.returncode == 0 and (copy / "build" / "sd_runtime.wasm").is_file():
        return exe, copy / "build" / "sd_runtime.wasm", "built now by make wasm"
    print(f"  {side.name:3} make wasm: FAILED {last_error_line(p.stderr)}; the shipped module plays", flush=True)
    return exe, cdir / "wasm" / "sd_runtime.wasm", "the shipped module"


def measure_wasm(sides, work: Path, rounds: int) -> list:
    print(f"e. WebAssembly vs native, {rounds} processes x {WASM_LOOPS} loops of {WASM_TICKS} ticks per side",
          flush=True)
    rows = {(m, t): Row(f"e. {m} per tick, {t}", unit="tick") for m in M4_MODELS
            for t in ("native C", "WebAssembly (wasmtime)")}
    targets, payloads = {}, {}
    try:
        wpy = wasm_python(sides)
    except RuntimeError as exc:
        print(f"  e: {exc}", flush=True)
        wpy = None
    for s in sides:
        out = work / f"e-in-{s.name}"
        out.mkdir()
        try:
            run(s, [s.python, "-c", PAYLOAD_SCRIPT, str(s.root / "tests"), str(out), ",".join(M4_MODELS),
                    str(WASM_TICKS)], {}, work)
            payloads[s.name] = out
            targets[s.name] = build_wasm_targets(s, work)
        except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
            print(f"  {s.name:3} e. set-up: FAILED {exc}", flush=True)
            for row in rows.values():
                row.failures[s.name].append(f"set-up: {exc}")
    for _ in range(rounds):
        for s in (s for s in sides if s.name in targets):
            exe, module, _ = targets[s.name]
            for m in M4_MODELS:
                payload = str(payloads[s.name] / f"{m}.in")
                for t, argv in (("native C", [str(exe), payload, str(WASM_LOOPS)]),
                                ("WebAssembly (wasmtime)",
                                 [wpy, "-c", WASM_SCRIPT, str(module), payload, str(WASM_LOOPS)] if wpy else None)):
                    row = rows[m, t]
                    if argv is None:
                        row.failures[s.name].append("no wasmtime")
                        continue
                    try:
                        out = run(s, argv, {}, work)[2]
                        row.wall[s.name].extend(v / WASM_TICKS for v in json.loads(out.strip().splitlines()[-1]))
                    except (RuntimeError, ValueError, IndexError) as exc:
                        row.failures[s.name].append(str(exc))
                        print(f"  {s.name:3} {row.label}: FAILED {exc}", flush=True)
    for m in M4_MODELS:
        nat, wa = rows[m, "native C"], rows[m, "WebAssembly (wasmtime)"]
        parts = [f"{n}: {statistics.median(wa.wall[n]) / statistics.median(nat.wall[n]):.2f}"
                 for n in ("old", "new") if wa.wall[n] and nat.wall[n]]
        how = "; ".join(f"{n} module {targets[n][2]}" for n in ("old", "new") if n in targets)
        wa.note = (f"WebAssembly / native per tick (medians): {', '.join(parts) or 'n/a'}; {how}; "
                   f"wasmtime of {wpy or '-'}")
    return [rows[k] for k in sorted(rows, key=lambda k: (M4_MODELS.index(k[0]), k[1] != "native C"))]


def measure_m4(sides, work: Path) -> list:
    print("f. Cortex-M4F instructions per sd_renderer_step (QEMU -icount), one run per side", flush=True)
    rows = {m: Row(f"f. {m} M4F instructions per tick (n=1 run)", unit="instr") for m in M4_MODELS}
    for s in sides:
        try:
            out = run(s, [s.python, "-c", M4_SCRIPT, str(s.root / "tests"), ",".join(M4_MODELS)], {}, work)[2]
        except RuntimeError as exc:
            print(f"  {s.name:3} f. M4F harness: FAILED {exc}", flush=True)
            for row in rows.values():
                row.failures[s.name].append(str(exc))
            continue
        for line in out.splitlines():
            try:
                r = json.loads(line)
            except ValueError:
                continue
            rows[r["model"]].wall[s.name] = r["instructions"]
    for row in rows.values():
        if row.wall["old"] and row.wall["new"]:
            mo, mn = (statistics.fmean(row.wall[n]) for n in ("old", "new"))
            row.note = (f"mean {mo:.0f} -> {mn:.0f} (old/new {mo / mn:.2f}); worst tick {max(row.wall['old']):.0f} "
                        f"-> {max(row.wall['new']):.0f} = {max(row.wall['new']) / M4_BUDGET:.2f} x the 16 800-cycle "
                        f"budget; {len(row.wall['new'])} ticks, single precision; deterministic counts")
    return list(rows.values())

def fmt(s: float, unit: str = "s") -> str:
    if unit == "instr":
        return f"{s:.0f}"
    if unit == "tick":
        return f"{s * 1e9:.0f} ns"
    return f"{s * 1e3:.1f} ms" if s < 1 else f"{s:.2f} s"


def spread(values: list, failures: list, unit: str = "s") -> str:
    if not values:
        return "failed" if failures else "-"
    return f"{fmt(min(values), unit)} / {fmt(statistics.median(values), unit)} / {fmt(max(values), unit)}"


def ratio(old: list, new: list) -> str:
    if not old or not new:
        return "n/a"
    return f"{statistics.median(old) / statistics.median(new):.2f}"


def print_table(rows: list) -> None:
    print()
    print("ratio = old median / new median (wall time; e: CPU time per tick; f: instructions per tick): > 1 means "
          "the new code is faster; cpu = the same ratio of CPU time (user + system) for whole-process rows")
    w = max(len(r.label) for r in rows) if rows else 11
    head = f"{'measurement':{w}} {'old min / median / max':32} {'new min / median / max':32} {'old/new':>7} {'cpu':>6}"
    print(head)
    print("-" * len(head))
    for r in rows:
        cpu = ratio(r.cpu["old"], r.cpu["new"]) if r.cpu["old"] or r.cpu["new"] else ""
        print(f"{r.label:{w}} {spread(r.wall['old'], r.failures['old'], r.unit):32} "
              f"{spread(r.wall['new'], r.failures['new'], r.unit):32} {ratio(r.wall['old'], r.wall['new']):>7} "
              f"{cpu:>6}".rstrip())
        if r.note:
            print(f"{'':4}{r.note}")
    failed = [(r, n, f) for r in rows for n in ("old", "new") for f in dict.fromkeys(r.failures[n])]
    if failed:
        print("\nfailures (distinct):")
        for r, n, f in failed:
            print(f"  {n} {r.label}: {f}")


def describe(side: Side) -> str:
    def git(*args):
        p = subprocess.run(["git", "-C", str(side.root), *args], capture_output=True, text=True)
        return p.stdout.strip()
    dirty = " + uncommitted changes" if git("status", "--porcelain", "--untracked-files=no") else ""
    return f"{side.name}: {side.root} at {git('rev-parse', '--short', 'HEAD') or '?'}{dirty}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", required=True, type=Path, help="checkout of the old commit with its own .venv")
    ap.add_argument("--current", type=Path, default=ROOT, help="tree under test (default: this repository)")
    ap.add_argument("--cold-runs", type=int, default=3, help="cold first plays per side (default 3)")
    ap.add_argument("--warm-runs", type=int, default=5, help="warm plays per side (default 5)")
    ap.add_argument("--render-rounds", type=int, default=2, help="render processes per side (default 2)")
    ap.add_argument("--render-repeats", type=int, default=3, help="timed renders per process and model (default 3)")
    ap.add_argument("--report-rounds", type=int, default=1, help="runs of each report per side (default 1)")
    ap.add_argument("--skip-reports", action="store_true", help="skip d. (the quick reports)")
    ap.add_argument("--wasm-rounds", type=int, default=5,
                    help=f"processes per side, model and target in e. (default 5, {WASM_LOOPS} loops each)")
    ap.add_argument("--skip-wasm", action="store_true", help="skip e. (WebAssembly vs native)")
    ap.add_argument("--skip-m4", action="store_true", help="skip f. (Cortex-M4F instruction counts under QEMU)")
    args = ap.parse_args()

    sides = [Side("old", args.baseline.resolve()), Side("new", args.current.resolve())]
    for s in sides:
        if not Path(s.cli).exists():
            ap.error(f"{s.name}: {s.cli} does not exist (create {s.root / '.venv'} first)")
        print(describe(s))
    print(f"load average at start: {' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} cores")

    with tempfile.TemporaryDirectory(prefix="sd-bench-engine-") as d:
        work = Path(d)
        tables = compile_tables(sides, work)
        if len(tables) < 2:
            print("no side could compile phone.toml: nothing to play")
            return 1
        rows, warm_env = measure_plays(sides, tables, work, args.cold_runs, args.warm_runs)
        rows += measure_renders(sides, tables, work, warm_env, args.render_rounds, args.render_repeats)
        if not args.skip_reports:
            rows += measure_reports(sides, work, warm_env, args.report_rounds)
        if not args.skip_wasm:
            rows += measure_wasm(sides, work, args.wasm_rounds)
        if not args.skip_m4:
            rows += measure_m4(sides, work)
    print_table(rows)
    print(f"load average at end: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
