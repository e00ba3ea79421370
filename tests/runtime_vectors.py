"""Shared test vectors of the C runtime's three targets (host, WebAssembly, Cortex-M4F).

Every target plays the same binary table image with the same settings and
stroke; the outputs are compared with the Python renderer. Input of
``sd_vectors image`` (and of the wasm and M4 harnesses): i64 image size, the
image, zero padding to 8 bytes, i64 policy, i64 model, f64 tick rate, f64
audio rate, i64 n, f64 x[n], f64 y[n]. Output: sd_outputs_t out[n]
(layouts.OUTPUTS records), i64 n_audio, f64 audio[n_audio], i64 clipped, events,
events dropped, cursor samples held as faults.
"""
import struct

import numpy as np

from shapedisplay.runtime.image import to_image
from shapedisplay.runtime.layouts import OUTPUTS

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


def case_setup(dtype, kind, policy, tick, audio, model, seconds=0.25):
    """Table, Python renderer, stroke and image of one case."""
    from test_c_runtime import stroke, widget_table
    from shapedisplay.runtime import Renderer
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


def derived_bounds(r, outs, unit_roundoff: float, libm_ulps: float = 1.0):
    """Bounds on the differences between two builds of the runtime that do the same operations but
    differ in libm (each result within ``libm_ulps`` ulp) and/or precision (``unit_roundoff`` u):
    ``(dt_event, d_drive, d_force)`` -- event-time, drive/audio-sample and friction-force bounds.
    The derivation is in runtime_c/README.md ("Tolerance"); ``outs`` are the reference per-tick
    outputs (layouts.OUTPUTS records)."""
    u = unit_roundoff
    F = np.abs(outs["friction_force"])
    V = np.abs(outs["pad_speed"])
    ev = outs["events"] > 0
    k = r.device.pad.stiffness
    x_max = F.max() / k                           # largest spring stretch seen, m
    v_min = V[ev].min() if ev.any() else 1.0      # slowest surface speed at an event, m/s
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



#: Outputs that a build with another libm must reproduce exactly (times, positions, states, counts).
EXACT_FIELDS = ("t", "x", "y", "vx", "vy", "normal_force", "events", "state", "audio_samples", "pad_speed")


def assert_within_derived_bounds(r, po, pa, co, ca) -> float:
    """A double build with another libm against the Python reference: :data:`EXACT_FIELDS` equal,
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


def build_m4(out_dir, defs=()):
    """`make -C runtime-c m4` into ``out_dir`` (a copy of the build directory); returns the ELF and
    the size line (text, data, bss)."""
    import shutil
    import subprocess
    from pathlib import Path
    cdir = Path(__file__).resolve().parent.parent / "shapedisplay" / "runtime_c"
    src = Path(out_dir) / "src"
    shutil.copytree(cdir, src, ignore=shutil.ignore_patterns("build", "wasm", "sd_vectors", "sd_bench"))
    res = subprocess.run(["make", "-s", "-C", str(src), "m4", f"M4_DEFS={' '.join(defs)}"],
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
