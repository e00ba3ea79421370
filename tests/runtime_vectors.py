"""Shared test vectors of the C runtime's three targets (host, WebAssembly, Cortex-M4F).

Every target plays the same binary table image with the same settings and
stroke; the outputs are compared with the package's renderer (``Renderer``, the engine built in double
precision for the host) within bounds derived for each target's arithmetic. Input of
``sd_vectors image`` (and of the wasm and M4 harnesses): i64 image size, the
image, zero padding to 8 bytes, i64 policy, i64 model, f64 tick rate, f64
audio rate, i64 n, f64 x[n], f64 y[n]. Output: sd_outputs_t out[n]
(layouts.OUTPUTS records), i64 n_audio, f64 audio[n_audio], i64 clipped, events,
events dropped, cursor samples held as faults.
"""
import functools
import struct

import numpy as np

from shapedisplay.render.image import to_image
from shapedisplay.render.layouts import OUTPUTS

# (table dtype, stroke, policy, tick rate, audio rate, model): the cases every target runs
CASES = [
    ("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump"),
    ("uint16", "diagonal", "retrigger", 10_000.0, None, "exact"),
    ("float32", "teleports", "max", 4_000.0, 48_000.0, "exact"),
    ("uint8", "circles", "add", 4_000.0, 44_100.0, "jump"),
]


def image_payload(image: bytes, r, x, y) -> bytes:
    x = np.asarray(x, "<f8")
    y = np.asarray(y, "<f8")
    pad = b"\0" * (-len(image) % 8)
    return (struct.pack("<q", len(image)) + image + pad
            + struct.pack("<qq", r.config["policy"], r.config["model"]) + struct.pack("<dd", r.tick_rate, r.audio_rate)
            + struct.pack("<q", x.size) + x.tobytes() + y.tobytes())


def parse_outputs(raw: bytes, n: int):
    pos = OUTPUTS.itemsize * n
    outs = np.frombuffer(raw[:pos], OUTPUTS)
    (na,) = struct.unpack_from("<q", raw, pos)
    audio = np.frombuffer(raw[pos + 8:pos + 8 + 8 * na], "<f8")
    counters = struct.unpack_from("<qqqq", raw, pos + 8 + 8 * na)
    return outs, audio, counters


def parse_events(raw: bytes, n: int):
    """The event log that follows the counters (host tool and M4 harness): (times s, amplitudes)."""
    pos = OUTPUTS.itemsize * n
    (na,) = struct.unpack_from("<q", raw, pos)
    pos += 8 + 8 * na + 32
    (ne,) = struct.unpack_from("<q", raw, pos)
    return (np.frombuffer(raw, "<f8", ne, pos + 8), np.frombuffer(raw, "<f8", ne, pos + 8 + 8 * ne))


def py_render_events(r, x, y, press=None):
    """The package renderer's outputs and audio (as test_c_runtime.py_render) with every event's time and
    amplitude, read from the event ring after each tick; with ``press`` (N per tick) also the reaction
    events of each tick, as a list."""
    from shapedisplay.render.layouts import OUTPUTS as _O
    r.reset()
    outs, audio, et, ea, rev = [], [], [], [], []
    for i, (xi, yi) in enumerate(zip(x, y)):
        if press is None:
            r.step(float(xi), float(yi))
        else:
            r.step(float(xi), float(yi), float(press[i]))
        o = r.last.copy()
        outs.append(o)
        audio.append(r.audio_block[:int(o["audio_samples"])].copy())
        k = int(o["events"])
        if k:
            t, a = r.recent_events()
            et.append(t[-k:])
            ea.append(a[-k:])
        if press is not None:
            rev += list(r.reactions())
    cat = (lambda v: np.concatenate(v) if v else np.zeros(0))
    res = (np.array(outs, dtype=_O), np.concatenate(audio), cat(et), cat(ea))
    return res if press is None else res + (rev,)


def case_setup(dtype, kind, policy, tick, audio, model, seconds=0.25):
    """Table, renderer, stroke and image of one case."""
    from test_c_runtime import stroke, widget_table
    from shapedisplay.render import Renderer
    table = widget_table(dtype)
    r = Renderer(table, model=model, tick_rate=tick, audio_rate=audio, burst_policy=policy)
    x, y = stroke(int(seconds * tick), kind)
    return table, r, x, y, to_image(table)


class WasmRunner:
    """sd_runtime.wasm in wasmtime, driven through its exports as sd_wasm.js drives it."""

    def __init__(self, path):
        import wasmtime
        self.engine = wasmtime.Engine()
        self.store = wasmtime.Store(self.engine)
        module = wasmtime.Module.from_file(self.engine, str(path))
        assert not module.imports, "the module must import nothing (an AudioWorklet gives it no WASI)"
        self.ex = wasmtime.Instance(self.store, module, []).exports(self.store)
        self.ex["_initialize"](self.store)
        self.mem = self.ex["memory"]

    def call(self, name, *args):
        return self.ex[name](self.store, *args)

    def write(self, ptr, data: bytes):
        self.mem.write(self.store, data, ptr)

    def read(self, ptr, n):
        return bytes(self.mem.read(self.store, ptr, ptr + n))

    def load(self, image: bytes) -> int:
        """Stage the image and load it; the return code of sd_wasm_load."""
        base = self.call("sd_wasm_stage", len(image))
        assert base and base % 8 == 0
        self.write(base, image)
        return self.call("sd_wasm_load", base, len(image))

    def play(self, image: bytes, r, x, y):
        """Outputs, audio and counters as parse_outputs gives them for the host tool."""
        n = len(x)
        per_tick = int(np.ceil(r.audio_rate / r.tick_rate)) + 2
        xy = np.empty(2 * n, "<f8")
        xy[0::2], xy[1::2] = x, y
        sizes = (16 * n, OUTPUTS.itemsize * n, 8 * per_tick * n)
        rc = self.load(image)
        assert rc == 0, rc
        rc = self.call("sd_wasm_configure", int(r.config["model"]), int(r.config["policy"]), r.tick_rate,
                       r.audio_rate)
        assert rc == 0, rc
        assert self.call("sd_wasm_audio_cap") == per_tick
        p = self.call("sd_wasm_scratch", sum(sizes))
        xy_p, out_p, audio_p = p, p + sizes[0], p + sizes[0] + sizes[1]
        self.write(xy_p, xy.tobytes())
        na = self.call("sd_wasm_run", xy_p, n, out_p, audio_p, per_tick * n)
        assert na >= 0
        outs = np.frombuffer(self.read(out_p, sizes[1]), OUTPUTS)
        audio = np.frombuffer(self.read(audio_p, 8 * na), "<f8")
        return outs, audio, tuple(int(self.call("sd_wasm_counter", i)) for i in range(4))


def wasm_play_events(runner, image: bytes, r, x, y, press=None):
    """Tick by tick through the exports as sd_wasm.js steps it: outputs, audio, counters and every
    event (absolute time, amplitude) as the host tool logs them; with ``press`` (N per tick) the ticks are
    sd_wasm_step_press and the reaction events popped after each tick follow, as (kind, widget, tick, value)."""
    assert runner.load(image) == 0
    assert runner.call("sd_wasm_configure", int(r.config["model"]), int(r.config["policy"]), r.tick_rate,
                       r.audio_rate) == 0
    nout = runner.call("sd_wasm_n_outputs")
    assert nout == len(OUTPUTS.names)
    outs, audio, et, ea, rev = [], [], [], [], []
    for i, (xi, yi) in enumerate(zip(x, y)):
        if press is None:
            runner.call("sd_wasm_step", float(xi), float(yi))
        else:
            runner.call("sd_wasm_step_press", float(xi), float(yi), float(press[i]))
        outs.append(runner.read(runner.call("sd_wasm_outputs"), 8 * nout))
        na = runner.call("sd_wasm_audio_count")
        audio.append(np.frombuffer(runner.read(runner.call("sd_wasm_audio"), 8 * na), "<f8"))
        ne = runner.call("sd_wasm_tick_events")
        if ne:
            et.append(np.frombuffer(runner.read(runner.call("sd_wasm_event_times"), 8 * ne), "<f8"))
            ea.append(np.frombuffer(runner.read(runner.call("sd_wasm_event_amplitudes"), 8 * ne), "<f8"))
        while press is not None:
            p = runner.call("sd_wasm_react_pop")
            if not p:
                break
            k, w, t, v = np.frombuffer(runner.read(p, 32), "<f8")
            rev.append((int(k), int(w), int(round(t * r.tick_rate)), v))
    cat = (lambda v: np.concatenate(v) if v else np.zeros(0))
    counters = tuple(int(runner.call("sd_wasm_counter", i)) for i in range(4))
    res = (np.frombuffer(b"".join(outs), OUTPUTS), cat(audio), counters, cat(et), cat(ea))
    return res if press is None else res + (rev,)


def derived_bounds(r, outs, unit_roundoff: float, libm_ulps: float = 1.0):
    """Bounds on the differences between two builds of the runtime that do the same operations but
    differ in libm (each result within ``libm_ulps`` ulp) and/or precision (``unit_roundoff`` u):
    ``(dt_event, d_drive, d_force)`` -- event-time, drive/audio-sample and friction-force bounds.
    The derivation is in engine/README.md ("Tolerance"); ``outs`` are the reference per-tick
    outputs (layouts.OUTPUTS records)."""
    u = unit_roundoff
    F = np.abs(outs["friction_force"])
    V = np.abs(outs["pad_speed"])
    ev = outs["events"] > 0
    k = r.device.pad.stiffness
    x_max = F.max() / k                           # largest spring stretch seen, m
    moving = ev & (V > 0)                         # (a breakaway under a falling N -- a click's friction drop --
    v_min = V[moving].min() if moving.any() else 1.0   # fires with the surface still, at the tick's start)
    K = 16.0 * max(libm_ulps, 1.0)                # <= 8 libm results of 2u each along a re-stick
    dt = K * u * x_max / v_min                    # a re-stick stretch error, turned into time by V
    h = 1.0 / r.tick_rate
    if r.model.name == "exact":
        dt += 2.0 * (1e-16 + 1e-15 * h)           # Newton stopping rule of the re-stick polish
    b = r.device.burst
    w = 2.0 * np.pi * b.carrier_hz
    n_rot = (b.rise_s + b.decay_s) * r.audio_rate # carrier rotations per burst
    d_drive = (w + 1.0 / b.rise_s) * dt + (8.0 + 4.0 * n_rot) * u * max(libm_ulps, 1.0)
    d_force = K * u * F.max() + k * v_min * dt
    return dt, d_drive, d_force



# ------------------------------------------------------------------ the single-precision build
#: unit roundoff of IEEE single precision
U_FLOAT = 2.0 ** -24
#: ulps of a float libm result (newlib's and glibc's float functions: within 2)
FLOAT_LIBM_ULPS = 2.0


def float_bounds(r, table, x, y, po, pt):
    """Bounds on the differences between the single-precision build and the double reference on one
    vector, derived in engine/README.md ("Tolerance of the single-precision build"):
    ``(dt_event, d_drive, d_force)``. ``po`` are the reference outputs, ``pt`` its event times."""
    u = U_FLOAT
    K = 16.0 * FLOAT_LIBM_ULPS                     # <= 8 libm results along a phase change, 2u per ulp
    k = r.device.pad.stiffness
    h = 1.0 / r.tick_rate
    F = np.abs(po["friction_force"])
    V = np.abs(po["pad_speed"])
    ev = po["events"] > 0
    x_max = F.max() / k                            # largest spring stretch
    moving = ev & (V > 0)                          # slowest surface speed at an event (one fired by a falling
    v_min = V[moving].min() if moving.any() else 1.0   # N -- a click's friction drop -- has the surface still)
    P = max(np.abs(x).max(), np.abs(y).max())      # largest coordinate: inputs rounded by u P
    d = np.stack([np.diff(x), np.diff(y)], 1)
    d = d[np.hypot(d[:, 0], d[:, 1]) > 0]
    ang = np.arctan2(d[:, 1], d[:, 0])
    theta = np.abs(np.angle(np.exp(1j * np.diff(ang)))).sum() if len(ang) > 1 else 0.0   # turning, rad
    G = 0.0                                        # largest relative slope of mu_s N on the table, 1/m
    for name in ("normal_force", "friction_scale"):
        if name in table.channels:
            a = table.dense(name)
            gy, gx = np.gradient(a, table.grid.dy, table.grid.dx) if a.shape[0] > 1 else \
                (0.0, np.gradient(a[0], table.grid.dx))
            G += (np.hypot(gx, gy) / np.maximum(np.abs(a), 1e-12)).max()
    t_run = len(x) * h
    n_ev = len(pt)
    dt = (K * u * t_run                            # relative rounding of every phase duration, summed
          + n_ev * (K * u + G * u * P) * x_max / v_min   # breakaway stretch of each event (threshold mu_s N)
          + np.sqrt(2.0) * u * P * (2.0 + theta) / v_min)  # rounded positions: arc length, not accumulated
    if r.model.name == "exact":
        dt += n_ev * 2.0 * (1e-12 + 4.0 * 2.0 ** -23 * h)   # Newton stopping rule (float build)
    b = r.device.burst
    w = 2.0 * np.pi * b.carrier_hz
    live = 1
    if n_ev:
        dur = b.rise_s + b.decay_s
        live = int((np.searchsorted(pt, pt + dur) - np.arange(n_ev)).max())   # bursts sounding at once
    amp = live if r.burst_policy == "add" else 1
    # envelope slope x time error + carrier (anchor 2 ulp + angle rounding pi u + 64 rotations of 4 roundings)
    # + amplitude and envelope rounding (K u per live burst)
    d_drive = (w + 1.0 / b.rise_s) * dt + (2 * FLOAT_LIBM_ULPS * 2 + np.pi + 4.0 * 64) * u + K * u * amp
    # per tick: the stretch moved at this tick's V -- on a tick where the finger rests, at the V it last moved
    # with (the stretch error it left stays until the next slip)
    last = np.maximum.accumulate(np.where(V > 0, np.arange(V.size), 0))
    V_carry = np.maximum(V, V[last])
    d_force = K * u * F.max() + k * (V_carry * dt + 2.0 * u * P)
    return dt, d_drive, d_force


def assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA):
    """The single-precision build against the double reference: the same events (count, times within
    the derived bound), drive, audio and friction force within the derived bounds; a pad phase may
    differ only on a tick whose end lies within the event-time bound of a phase change (the change
    moved across the tick boundary). Returns the bounds."""
    dt, d_drive, d_force = float_bounds(r, table, x, y, po, pt)
    h = 1.0 / r.tick_rate
    # below half a tick, an event can move across at most one tick boundary (the per-tick checks below)
    assert dt < 0.5 * h, f"event-time bound {dt:.3g} s is not below half a tick"
    assert ct.size == pt.size
    assert np.abs(ct - pt).max(initial=0.0) <= dt, (np.abs(ct - pt).max(), dt)
    # A = B k |x| at breakaway: relative rounding, and the stretch error of a breakaway moved by dt
    a_max = pA.max(initial=0.0)
    x_max = max(np.abs(po["friction_force"]).max() / r.device.pad.stiffness, 1e-30)
    d_amp = 32 * U_FLOAT * a_max + a_max / x_max * (np.abs(po["pad_speed"]).max() * dt + U_FLOAT * np.abs(x).max())
    assert np.abs(cA - pA).max(initial=0.0) <= d_amp
    for name in ("t", "x", "y"):
        np.testing.assert_allclose(co[name], po[name], rtol=2 * U_FLOAT, atol=0, err_msg=name)
    np.testing.assert_array_equal(co["audio_samples"], po["audio_samples"])
    same = co["state"] == po["state"]
    for i in np.flatnonzero(~same):
        # a phase change of the reference at this tick or the next, moved across the boundary
        assert (i > 0 and po["state"][i - 1] != po["state"][i]) or (i + 1 < len(po) and po["state"][i + 1] != po["state"][i]), i
    assert (~same).sum() <= max(2, len(pt) // 20)
    # per-tick event counts differ only where an event lies within dt of a tick boundary
    t_tick = po["t"]
    moved = np.flatnonzero(co["events"] != po["events"])
    for i in moved:
        near = np.abs(pt - t_tick[i]).min(initial=np.inf) <= dt or (i > 0 and np.abs(pt - t_tick[i - 1]).min(initial=np.inf) <= dt)
        assert near, i
    ok = same.copy()
    ok[moved] = False
    ok[np.minimum(moved + 1, len(ok) - 1)] = False
    assert np.abs(co["drive"] - po["drive"])[ok].max(initial=0.0) <= d_drive
    assert (np.abs(co["friction_force"] - po["friction_force"]) <= d_force)[same].all()
    assert np.abs(ca - pa).max(initial=0.0) <= d_drive or moved.size
    return dt, d_drive, d_force


#: Outputs that a build with another libm must reproduce exactly (times, positions, states, counts).
EXACT_FIELDS = ("t", "x", "y", "vx", "vy", "normal_force", "events", "state", "audio_samples", "pad_speed")


def assert_within_derived_bounds(r, po, pa, co, ca) -> float:
    """A double build with another libm against the host engine (``Renderer``): :data:`EXACT_FIELDS` equal,
    drive, audio and friction force within :func:`derived_bounds`. Returns the drive bound."""
    for name in EXACT_FIELDS:
        np.testing.assert_array_equal(co[name], po[name], err_msg=name)
    _, d_drive, d_force = derived_bounds(r, po, 2.0 ** -53)
    assert np.abs(co["drive"] - po["drive"]).max() <= d_drive
    assert np.abs(ca - pa).max() <= d_drive
    assert np.abs(co["friction_force"] - po["friction_force"]).max() <= d_force
    return d_drive

# ------------------------------------------------------------------ Cortex-M4F under QEMU
QEMU_M4 = ["qemu-system-arm", "-M", "mps2-an386", "-nographic", "-monitor", "none", "-serial", "none"]
#: -icount shift: every instruction advances virtual time by 2^ICOUNT_SHIFT ns, and SysTick (25 MHz
#: system clock of the MPS2 board) by 2^ICOUNT_SHIFT * 0.025 counts: 1.6 counts per instruction, so
#: one instruction is resolved and the 24-bit SysTick holds 10.4 million instructions per tick.
ICOUNT_SHIFT = 6
COUNTS_PER_INSTRUCTION = 2 ** ICOUNT_SHIFT * 25e6 / 1e9


def build_m4(out_dir, defs=(), precision="single"):
    """`make -C runtime-c m4` into ``out_dir`` (a copy of the build directory); returns the ELF and
    the size line (text, data, bss). ``precision``: "single" (the M4F build) or "double"."""
    import shutil
    import subprocess
    from pathlib import Path
    cdir = Path(__file__).resolve().parent.parent / "shapedisplay" / "engine"
    src = Path(out_dir) / "src"
    shutil.copytree(cdir, src, ignore=shutil.ignore_patterns("build", "wasm", "sd_vectors", "sd_bench"))
    res = subprocess.run(["make", "-s", "-C", str(src), "m4", f"M4_DEFS={' '.join(defs)}", f"M4_PRECISION={precision}"],
                         capture_output=True, text=True, timeout=300)
    if res.returncode != 0:
        raise RuntimeError(f"make m4 failed:\n{res.stderr}")
    text, data, bss = (int(v) for v in res.stdout.strip().splitlines()[-1].split()[:3])
    return src / "build" / "sd_m4.elf", (text, data, bss)


def run_m4(elf, mode: str, payload: bytes, tmp_path, icount: bool = False) -> bytes:
    """Run the harness in ``mode`` (vectors | bench) on ``payload``; returns its output file."""
    import subprocess
    fin, fout = tmp_path / f"m4-{mode}.in", tmp_path / f"m4-{mode}.out"
    fin.write_bytes(payload)
    cmd = [*QEMU_M4, *(["-icount", f"shift={ICOUNT_SHIFT}"] if icount else []), "-semihosting-config",
           f"enable=on,target=native,arg=sd_m4,arg={mode},arg={fin},arg={fout}", "-kernel", str(elf)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if res.returncode != 0:
        raise RuntimeError(f"the M4F harness exited with {res.returncode}: {res.stderr[-500:]}")
    return fout.read_bytes()


def m4_instructions(raw: bytes) -> np.ndarray:
    """Instructions per sd_renderer_step from the bench output (the measurement's own cost removed)."""
    c = np.frombuffer(raw, "<u4").astype(np.float64)
    if (c >= 0xFFFFF0).any():
        raise RuntimeError("a tick ran past the 24-bit SysTick range (10.4 million instructions)")
    return (c[:-1] - c[-1]) / COUNTS_PER_INSTRUCTION


def tick_path_functions(elf) -> dict:
    """Every function reachable from sd_renderer_step and the pad ticks (called through the model
    table) in the ELF's disassembly, with the functions each calls."""
    import re
    import subprocess
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", str(elf)], capture_output=True, text=True, check=True).stdout
    calls, cur = {}, None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <([^>]+)>:", line)
        if m:
            cur = m.group(1)
            calls[cur] = set()
            continue
        m = re.search(r"\b(?:bl|blx|b|b\.w|b\.n)(?:\.\w+)?\s+[0-9a-f]+ <([^>+]+)(?:\+0x[0-9a-f]+)?>", line)
        if m and cur:
            calls[cur].add(m.group(1))
    seen, todo = {}, ["sd_renderer_step", "sd_jump_tick", "sd_exact_tick"]
    while todo:
        f = todo.pop()
        if f not in seen:
            seen[f] = calls.get(f, set())
            todo += sorted(seen[f])
    return seen


# ------------------------------------------------------------------ reactions (docs/reactive.md)
#: (name, stroke over assets/scenes/reactive.toml, model, tick rate, audio rate): every target plays these with
#: the press force of each tick; the reaction events must be the same everywhere (kind, widget, tick).
REACT_CASES = [
    ("widgets", "20,20 -> 20,20.5 @ 50mm/s; press 3N 20ms; -> 60,20 @ 300mm/s; press 3N 20ms; "
                "-> 14,45 @ 300mm/s; press 3N 10ms; -> 40,45 @ 170mm/s press 3N; press 0N 10ms", "jump", 4_000.0,
     48_000.0),
    ("widgets-exact", "20,20 -> 20,20.5 @ 50mm/s; press 3N 20ms; -> 60,20 @ 300mm/s; press 3N 20ms; "
                      "-> 14,45 @ 300mm/s; press 3N 10ms; -> 40,45 @ 170mm/s press 3N; press 0N 10ms", "exact",
     4_000.0, 48_000.0),
    ("moving", "86,62 -> 86,62.5 @ 50mm/s; press 3N 10ms; -> 100,70 @ 200mm/s press 3N; press 0N 10ms; "
               "-> 100,30 @ 300mm/s; -> 100,22 @ 40mm/s", "jump", 4_000.0, 48_000.0),
]


#: The stroke of the M4F benchmark with reactions (10 kHz ticks): every kind of reactive widget pressed, dragged
#: or stroked in about a second.
REACT_BENCH = ("20,20 -> 20,20.5 @ 50mm/s; press 3N 30ms; -> 60,20 @ 200mm/s; press 3N 30ms; -> 14,45 @ 200mm/s; "
               "press 3N 20ms; -> 50,45 @ 150mm/s press 3N; press 0N 10ms; -> 86,62 @ 200mm/s; press 3N 20ms; "
               "-> 100,70 @ 100mm/s press 3N; press 0N 10ms; -> 100,30 @ 200mm/s; -> 100,20 @ 40mm/s")


@functools.cache
def reactive_table():
    """The bundled reactive scene, compiled (once per process)."""
    from pathlib import Path
    from shapedisplay.author.scene.compiler import compile_scene
    return compile_scene(Path(__file__).resolve().parent.parent / "assets" / "scenes" / "reactive.toml").table


def react_setup(name, stroke, model, tick, audio):
    """Table, renderer, cursor (x, y, press) and image of one reaction case."""
    from shapedisplay.render import Renderer
    from shapedisplay.render.cursor import parse_stroke
    table = reactive_table()
    r = Renderer(table, model=model, tick_rate=tick, audio_rate=audio)
    cp = parse_stroke(stroke, tick)
    return table, r, cp.x, cp.y, cp.press, to_image(table)


def react_payload(image: bytes, r, x, y, press) -> bytes:
    """Input of `sd_vectors react` and the M4 harness's react modes: the image payload, then f64 press[n]."""
    return image_payload(image, r, x, y) + np.asarray(press, "<f8").tobytes()


def parse_reactions(raw: bytes, n: int) -> np.ndarray:
    """The reaction events after the stick-slip event log: REACT_EVENT records."""
    from shapedisplay.render.layouts import REACT_EVENT
    pos = OUTPUTS.itemsize * n
    (na,) = struct.unpack_from("<q", raw, pos)
    pos += 8 + 8 * na + 32
    (ne,) = struct.unpack_from("<q", raw, pos)
    pos += 8 + 16 * ne
    (nr,) = struct.unpack_from("<q", raw, pos)
    return np.frombuffer(raw, REACT_EVENT.newbyteorder("<"), nr, pos + 8)


def py_render_reactions(r, x, y, press):
    """The package renderer tick by tick with the press: outputs, audio, event times and amplitudes, and the
    reaction events (REACT_EVENT records, ticks from 0)."""
    from shapedisplay.render.layouts import EVENT_KINDS, REACT_EVENT
    outs, audio, et, ea, rev = py_render_events(r, x, y, press)
    ids = r._widget_ids
    recs = np.zeros(len(rev), REACT_EVENT)
    for i, e in enumerate(rev):
        recs[i] = (EVENT_KINDS.index(e.kind) + 1, ids.index(e.widget), int(round(e.t * r.tick_rate)), e.value)
    return outs, audio, et, ea, recs


def assert_same_reactions(got, want, value_tol=0.0):
    """The same reaction events: kinds, widgets and ticks equal, values within ``value_tol``."""
    assert got.size == want.size, (got, want)
    for f in ("kind", "widget", "tick"):
        np.testing.assert_array_equal(got[f], want[f], err_msg=f)
    np.testing.assert_allclose(got["value"], want["value"], rtol=0, atol=value_tol)


def wasm_play_reactions(runner, image: bytes, r, x, y, press):
    """Tick by tick through the exports with the press (sd_wasm_step_press), popping the reaction events after
    every tick: outputs, audio, counters, stick-slip events and reaction events as REACT_EVENT records."""
    from shapedisplay.render.layouts import REACT_EVENT
    *res, rev = wasm_play_events(runner, image, r, x, y, press)
    return (*res, np.array(rev, REACT_EVENT) if rev else np.zeros(0, REACT_EVENT))
