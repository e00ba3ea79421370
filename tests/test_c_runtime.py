"""The portable C99 runtime (engine/) built with the system C compiler, and its host tools.

The C sources are compiled into a temporary directory (C99, -O2, -Werror, no fast-math, no FMA
contraction) with the vector tool (tool_vectors.c) and the header player (tool_play_header.c).
Checked here: the re-stick stretch of the jump tick against its closed form; a table compiled in from
`export --format c` plays as the same table loaded from its binary image (``Renderer``), bit for bit;
sd_renderer_init refuses bad parameters; the library never allocates (nm, valgrind). The shared
helpers (``pad_vectors``, ``widget_table``, ``stroke``, ``py_render``) serve the other C runtime tests.
"""
import math
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.render.layouts import GRID, OUTPUTS, RENDER_CONFIG, record
from shapedisplay.render.models import MODEL_IDS, get_model
from shapedisplay.table.devices import BurstParams, load_device

ROOT = Path(__file__).resolve().parent.parent
CDIR = ROOT / "shapedisplay" / "engine"
CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-ffp-contract=off"]
LIB = ("sd_pad.c", "sd_exact.c", "sd_render.c", "sd_image.c", "sd_stribeck.c", "sd_karnopp.c",
       "sd_baselines.c", "sd_react.c")      # the runtime library (no host tool)


def _cc():
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    pytest.fail("no C compiler (cc/gcc/clang) found; the C runtime tests need one")


@pytest.fixture(scope="module")
def sd_vectors(tmp_path_factory):
    out = tmp_path_factory.mktemp("c-runtime") / "sd_vectors"
    srcs = [str(CDIR / n) for n in (*LIB, "tool_vectors.c")]
    cmd = [_cc(), *CFLAGS, "-I", str(CDIR), *srcs, "-lm", "-o", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, f"C runtime failed to build:\n{' '.join(cmd)}\n{res.stderr}"
    return out


def _run(exe, mode, payload: bytes, tmp_path) -> bytes:
    fin, fout = tmp_path / f"{mode}.in", tmp_path / f"{mode}.out"
    fin.write_bytes(payload)
    res = subprocess.run([str(exe), mode, str(fin), str(fout)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return fout.read_bytes()


# ------------------------------------------------------------------ pad kernel vectors
# Input:  sd_pad_params_t (the bytes of the model's layouts.PAD_PARAMS record), i64 model id
#         (SD_MODEL_*, = model.model_id), i64 n, f64 t[n], V[n], N[n], mus[n], muk[n], gain[n]
# Output: f64 f[n], phase[n], x[n], i64 n_ev, f64 ev_t[n_ev], ev_a[n_ev], i64 ticks cut at the phase cap
def pad_vectors(exe, tmp_path, model, t, V, N, mus, muk, gain, truncated=False):
    payload = (model.params.tobytes()
               + struct.pack("<qq", model.model_id, t.size)
               + b"".join(np.asarray(a, "<f8").tobytes() for a in (t, V, N, mus, muk, gain)))
    raw = _run(exe, "pad", payload, tmp_path)
    n = t.size
    arr = np.frombuffer(raw[:24 * n], "<f8").reshape(3, n)
    (n_ev,) = struct.unpack_from("<q", raw, 24 * n)
    ev = np.frombuffer(raw, "<f8", 2 * n_ev, 24 * n + 8).reshape(2, n_ev)
    if truncated:
        return struct.unpack_from("<q", raw, 24 * n + 8 + 16 * n_ev)[0]
    return arr[0], arr[1], arr[2], ev[0], ev[1]


def _jump(pad=None, friction=None, max_stick=0.0, gain=0.25, name="jump"):
    dev = load_device(None)
    dev = dev.with_(pad=pad or dev.pad, friction=friction or dev.friction,
                    burst=BurstParams(gain=gain, max_stick_period_s=max_stick))
    return get_model(name, dev)


def test_jump_stick_period_from_the_closed_form_restick_force(sd_vectors, tmp_path):
    """The V -> 0 limit of the re-stick force gives the stick period of the jump tick in the vector tool
    (exact answer, the Konyo pad)."""
    model = _jump()
    p = model.device.pad
    fr = model.device.friction
    N = 2.0
    V = 1e-3          # r = V k / (delta_mu N omega_n) ~ 1e-4: the jump model's Newton step is exact here
    rate = 1000.0
    n = 3001
    t = np.arange(n) / rate
    ones = np.ones(n)
    cf, cst, cx, cet, cea = pad_vectors(sd_vectors, tmp_path, model, t, V * ones, N * ones,
                                        fr.mu_s * ones, fr.mu_k * ones, ones)
    assert cet.size >= 2
    zeta = p.zeta
    f_re = fr.mu_k * N - (fr.mu_s - fr.mu_k) * N * math.exp(-zeta * math.pi / math.sqrt(1 - zeta ** 2))
    # stick period at speed V: the spring force climbs from f_re to mu_s N at k V per second
    period = (fr.mu_s * N - f_re) / (p.stiffness * V)
    assert np.diff(cet)[0] == pytest.approx(period, rel=1e-3)


# ------------------------------------------------------------------ renderer vectors
# Input:  sd_config_t (the bytes of Renderer.config, a layouts.RENDER_CONFIG record); table:
#         sd_grid_t (a layouts.GRID record), i64 n_blocks,
#         i64 blocks[n_blocks][5], i64 n_values, per slot (renderer.SLOTS order): i64 dtype (-1 absent;
#         0 u8, 1 u16, 2 f32, 3 f64) then f64 scale, offset, background and the codes;
#         i64 n, f64 x[n], y[n].
# Output: sd_outputs_t out[n] (layouts.OUTPUTS records), i64 n_audio, f64 audio[n_audio], i64 clipped, events,
#         events dropped.
from shapedisplay.render import Renderer                      # noqa: E402
from shapedisplay.render import renderer as R_                # noqa: E402
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization   # noqa: E402

_DT = {"uint8": 0, "uint16": 1, "float32": 2, "float64": 3}


def render_payload(r: Renderer, x, y) -> bytes:
    head = r.config.tobytes()
    t = r.table
    g = t.grid
    off = t.patch_offsets()
    blocks = np.array([[r0, c0, *t.patch_shapes[p], off[p]] for r0, c0, p in t.blocks], "<i8").reshape(-1, 5)
    tab = record(GRID, rows=g.rows, cols=g.cols, dx=g.dx, dy=g.dy, x0=g.x0, y0=g.y0).tobytes()
    tab += struct.pack("<q", len(blocks)) + blocks.tobytes() + struct.pack("<q", int(off[-1]))
    for name in R_.SLOTS:
        if name not in t.channels:
            tab += struct.pack("<q", -1)
            continue
        q = t.quant[name]
        tab += struct.pack("<q", _DT[q.dtype]) + np.array([q.scale, q.offset, t.background[name]], "<f8").tobytes()
        codes = np.asarray(t.codes[name])
        tab += codes.astype(codes.dtype.newbyteorder("<"), copy=False).tobytes()
    x = np.asarray(x, "<f8")
    y = np.asarray(y, "<f8")
    return head + tab + struct.pack("<q", x.size) + x.tobytes() + y.tobytes()


def py_render(r, x, y):
    r.reset()
    outs, audio = [], []
    for xi, yi in zip(x, y):
        r.step(float(xi), float(yi))
        outs.append(r.last.copy())
        audio.append(r.audio_block[:int(r.last["audio_samples"])].copy())
    return np.array(outs, dtype=OUTPUTS), np.concatenate(audio), (r.clipped, r.event_count)


def assert_outputs_equal(c_outs, py_outs):
    """Every per-tick output (an OUTPUTS field), bit for bit."""
    assert c_outs.dtype == py_outs.dtype == OUTPUTS
    for name in OUTPUTS.names:
        np.testing.assert_array_equal(c_outs[name], py_outs[name], err_msg=name)


def widget_table(dtype="uint16", kmu=0.4, sparse=True):
    """A 2-D table with several channels, two identical widgets (one patch stored once), background."""
    rows, cols, dx = 40, 120, 0.5e-3
    yy, xx = np.mgrid[0:16, 0:24] * dx
    bump = np.exp(-(((xx - 6e-3) / 3e-3) ** 2 + ((yy - 4e-3) / 2e-3) ** 2))
    chans = {
        "normal_force": 0.5 + 2.5 * bump,
        "friction_scale": 1.0 + 0.3 * bump,
        "burst_gain": 0.5 + bump,
        "grad_x": np.gradient(bump * 1e-3, dx, axis=1),
        "grad_y": np.gradient(bump * 1e-3, dx, axis=0),
        "lateral_x": -0.2 * np.gradient(bump, axis=1),
    }
    quant = {n: choose_quantization(v, dtype) for n, v in chans.items()}
    bg = {"normal_force": 0.5, "friction_scale": 1.0, "burst_gain": 0.5, "grad_x": 0.0, "grad_y": 0.0,
          "lateral_x": 0.0}
    placed = [((4, 10), chans), ((20, 70), chans)] if sparse else [((0, 0), chans)]
    dev = load_device("desktop-rig")
    meta = {"device": dev.to_json(), "mapping": {"slope_friction_gain": kmu}}
    return FrictionTable.from_patches(Grid(rows, cols, dx, dx, 1e-3, -2e-3), placed, quant, bg, meta)


def stroke(n, kind):
    t = np.linspace(0.0, 1.0, n)
    if kind == "diagonal":
        return -0.005 + 0.07 * t, -0.004 + 0.025 * t
    if kind == "circles":
        return 0.03 + 0.02 * np.cos(9 * t), 0.008 + 0.008 * np.sin(9 * t)
    if kind == "teleports":               # jumps of many cells in one tick, and standing still
        x = np.repeat([0.0, 0.05, 0.012, 0.012, 0.061, -0.02], n // 6 + 1)[:n]
        return x + 0.01 * t, np.full(n, 0.005)
    raise ValueError(kind)


# ------------------------------------------------------------------ table compiled in from the C header export
def _header_play(tmp_path, table, model, n):
    """The table's C header export played by tool_play_header.c (``model`` by ``sd_table_use_model``, jump by
    default) and by ``Renderer.step`` over ``n`` ticks of the diagonal stroke: both drives and audios, and
    the events Renderer counted."""
    from shapedisplay.exchange.export import export_c
    header = export_c(table, tmp_path / "table.h", name="sd_table")
    exe = tmp_path / "sd_play_header"
    defs = [f'-DSD_TABLE_HEADER="{header}"']   # the header carries K_mu and every other constant
    if model != "jump":
        defs.append(f"-DSD_PLAY_MODEL=SD_MODEL_{model.upper()}")
    cmd = [_cc(), *CFLAGS, *defs, "-I", str(CDIR), str(CDIR / "tool_play_header.c"),
           *(str(CDIR / n) for n in LIB), "-lm", "-o", str(exe)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    r = Renderer(table, model=model, tick_rate=10_000.0, audio_rate=48_000.0)
    x, y = stroke(n, "diagonal")
    po, pa, (_, pev) = py_render(r, x, y)
    fin, fout = tmp_path / "in", tmp_path / "out"
    fin.write_bytes(struct.pack("<q", x.size) + np.asarray(x, "<f8").tobytes() + np.asarray(y, "<f8").tobytes())
    res = subprocess.run([str(exe), "48000", str(fin), str(fout)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    raw = fout.read_bytes()
    (na,) = struct.unpack_from("<q", raw, 8 * x.size)
    assert na == pa.size
    return np.frombuffer(raw[:8 * x.size], "<f8"), po["drive"], np.frombuffer(raw[8 * x.size + 8:], "<f8"), pa, pev


@pytest.mark.parametrize("model", ["exact", "karnopp", "stribeck"])
def test_header_plays_every_model_as_the_package(tmp_path, model):
    """Firmware plays every model from the header alone: ``sd_table_use_model`` sets the pad parameters the
    package derives for the model, and the header player's drive and audio equal ``Renderer.step``'s bit for
    bit (the same sources, the same double arithmetic) on a stroke with stick-slip events."""
    table = widget_table("uint16", kmu=0.4, sparse=True)
    table.meta["tick_rate_hz"] = 10_000.0
    drive, want_drive, audio, want_audio, events = _header_play(tmp_path, table, model, 1500)
    assert events > 0
    np.testing.assert_array_equal(drive, want_drive)
    np.testing.assert_array_equal(audio, want_audio)


@pytest.mark.parametrize("dtype, sparse, kmu", [("uint16", True, 0.4), ("uint16", False, 0.0), ("uint8", True, 0.4),
                                                ("float32", True, 0.4), ("float64", False, 0.4)])
def test_table_from_c_header_export(tmp_path, dtype, sparse, kmu):
    """`shapedisplay export --format c` + tool_play_header.c reproduce Renderer.step bit for bit.

    The header binds itself (``sd_table_bind``): any channel code type, K_mu without -D flags."""
    table = widget_table(dtype, kmu=kmu, sparse=sparse)
    table.meta["tick_rate_hz"] = 10_000.0
    drive, want_drive, audio, want_audio, events = _header_play(tmp_path, table, "jump", 2500)
    assert events > 20
    np.testing.assert_array_equal(drive, want_drive)
    np.testing.assert_array_equal(audio, want_audio)


def test_c_renderer_init_refuses_bad_parameters(sd_vectors, tmp_path):
    """sd_renderer_init validates before binding: mu_k > mu_s, a 50 Hz tick, no pad mass, a model id with no C tick,
    a pad whose h * omega_n exceeds devices.H_OMEGA_MAX (stiffness just past it at 10 kHz)."""
    from shapedisplay.table.devices import H_OMEGA_MAX
    table = widget_table("uint16", kmu=0.0)
    r = Renderer(table, model="jump", tick_rate=10_000.0)
    good = render_payload(r, [0.0, 1e-4], [0.0, 0.0])
    size = RENDER_CONFIG.itemsize
    cfg = np.frombuffer(good[:size], RENDER_CONFIG).copy()
    too_stiff = float(cfg["pad"]["mass"][0]) * (1.001 * H_OMEGA_MAX * 10_000.0) ** 2
    for field, value in (("mu_k", 0.9), ("tick_rate", 50.0), (("pad", "mass"), 0.0),
                         ("model", len(MODEL_IDS)),       # no such model: sd_model_tick gives NULL
                         (("pad", "stiffness"), too_stiff)):
        bad = cfg.copy()
        if isinstance(field, tuple):
            bad[field[0]][field[1]] = value
        else:
            bad[field] = value
        fin, fout = tmp_path / "bad.in", tmp_path / "bad.out"
        fin.write_bytes(bad.tobytes() + good[size:])
        res = subprocess.run([str(sd_vectors), "render", str(fin), str(fout)], capture_output=True, text=True,
                             timeout=60)
        assert res.returncode == 3 and "sd_renderer_init failed (-3)" in res.stderr


# ------------------------------------------------------------------ fixed memory
@pytest.mark.skipif(shutil.which("nm") is None, reason="needs nm (binutils) to list the objects' symbols")
def test_runtime_library_never_allocates(tmp_path):
    """The library (not the host tools) calls no allocator at all: memory is the caller's, fixed at init."""
    alloc = {"malloc", "calloc", "realloc", "free", "aligned_alloc", "posix_memalign", "alloca", "brk", "sbrk"}
    seen = set()
    for name in LIB:
        obj = tmp_path / (name[:-2] + ".o")
        res = subprocess.run([_cc(), *CFLAGS, "-I", str(CDIR), "-c", str(CDIR / name), "-o", str(obj)],
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        undefined = subprocess.run(["nm", "-u", str(obj)], capture_output=True, text=True, check=True).stdout
        called = {line.split()[-1].split("@")[0] for line in undefined.splitlines() if line.strip()}
        seen |= called
        assert not called & alloc, f"{name} calls {sorted(called & alloc)}"
    assert "exp" in seen                  # nm did list the objects' undefined symbols


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is optional (memory check of the C runtime)")
def test_runtime_under_valgrind_no_heap_and_no_memory_errors(tmp_path):
    """tool_bench.c keeps its renderer in a static object: running all models and the renderer the
    heap sees only stdio's one buffer, and valgrind finds no invalid access."""
    exe = tmp_path / "sd_bench"
    srcs = [str(CDIR / n) for n in (*LIB, "tool_bench.c")]
    res = subprocess.run([_cc(), *CFLAGS, "-g", "-I", str(CDIR), *srcs, "-lm", "-o", str(exe)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    res = subprocess.run(["valgrind", "--error-exitcode=9", str(exe), "2000"], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0 and "ERROR SUMMARY: 0 errors" in res.stderr, res.stderr[-2000:]
    allocs = int(res.stderr.split("total heap usage:")[1].split("allocs")[0].replace(",", ""))
    assert allocs <= 1, res.stderr[-1000:]      # stdout's buffer, allocated by printf
