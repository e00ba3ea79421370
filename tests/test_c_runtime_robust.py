"""The C runtime under abuse: non-finite and absurd cursor positions, and counters near 2^32 and 2^63.

Built with the undefined-behaviour and address sanitizers (gcc), so an integer overflow, a
NaN converted to an integer or an out-of-bounds access fails the test, not just a wrong value.
"""
import os
import struct
import subprocess

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from runtime_vectors import case_setup, image_payload, parse_outputs
from test_c_runtime import CDIR, CFLAGS, LIB, assert_outputs_equal, py_render

BAD = [float("nan"), float("inf"), -float("inf"), 1e300, -1e300, 1000.5, -2e3]
LIMIT = 1000.0               # SD_POSITION_LIMIT_M


@pytest.fixture(scope="module")
def sd_vectors_san(tmp_path_factory):
    out = tmp_path_factory.mktemp("c-san") / "sd_vectors"
    srcs = [str(CDIR / n) for n in (*LIB, "tool_vectors.c")]
    cmd = ["gcc", *CFLAGS, "-g", "-fsanitize=undefined,address", "-fno-sanitize-recover=all",
           "-I", str(CDIR), *srcs, "-lm", "-o", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr
    return out


def _run(exe, mode, payload, tmp_path):
    fin, fout = tmp_path / f"{mode}.in", tmp_path / f"{mode}.out"
    fin.write_bytes(payload)
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=0"}     # the host tool frees nothing at exit, by design
    res = subprocess.run([str(exe), mode, str(fin), str(fout)], capture_output=True, text=True, timeout=300, env=env)
    assert res.returncode == 0 and "runtime error" not in res.stderr, res.stderr[-3000:]
    return fout.read_bytes()


def _held(table, x, y):
    """The stroke the renderer must play: every bad sample replaced by the last valid one
    (the table origin before any valid one)."""
    hx, hy = np.array(x, float), np.array(y, float)
    px, py = table.grid.x0, table.grid.y0
    faults = 0
    for i in range(len(hx)):
        if not (abs(hx[i]) <= LIMIT and abs(hy[i]) <= LIMIT):
            hx[i], hy[i] = px, py
            faults += 1
        px, py = hx[i], hy[i]
    return hx, hy, faults


def _check_holds(exe, tmp_path, x_bad, y_bad, case=("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump")):
    table, r, x, y, img = case_setup(*case, seconds=0.08)
    hx, hy, faults = _held(table, x_bad, y_bad)
    po, pa, (pclip, pev) = py_render(r, hx, hy)
    co, ca, (cclip, cev, cdrop, cfault) = parse_outputs(_run(exe, "image", image_payload(img, r, x_bad, y_bad),
                                                             tmp_path), len(x_bad))
    assert cfault == faults and cev == pev and cclip == pclip
    assert all(np.isfinite(co[n]).all() for n in co.dtype.names) and np.isfinite(ca).all()
    assert np.abs(ca).max() <= 1.0
    assert_outputs_equal(co, po)                  # exactly the held stroke, bit for bit
    np.testing.assert_array_equal(ca, pa)
    return pev


def test_nan_inf_and_huge_positions_hold_the_last_valid_one(sd_vectors_san, tmp_path):
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.08)
    rng = np.random.default_rng(7)
    xb, yb = np.array(x), np.array(y)
    xb[0] = float("nan")                                     # before any valid sample
    idx = rng.choice(np.arange(1, len(x)), size=len(x) // 8, replace=False)
    for n, i in enumerate(idx):
        v = BAD[n % len(BAD)]
        if n % 3 == 0:
            xb[i] = v
        elif n % 3 == 1:
            yb[i] = v
        else:
            xb[i] = yb[i] = v
    xb[300:340] = float("nan")                               # a run of bad samples (a dropped sensor)
    assert _check_holds(sd_vectors_san, tmp_path, xb, yb) > 20


@given(st.lists(st.tuples(st.integers(0, 799), st.sampled_from(BAD), st.booleans()), min_size=1, max_size=30))
@settings(max_examples=12, deadline=None)
def test_fuzz_bad_positions_exact_model_and_max_policy(sd_vectors_san, tmp_path_factory, bad):
    table, r, x, y, img = case_setup("float32", "teleports", "max", 10_000.0, 48_000.0, "exact", seconds=0.08)
    xb, yb = np.array(x), np.array(y)
    for i, v, on_x in bad:
        (xb if on_x else yb)[i] = v
    _check_holds(sd_vectors_san, tmp_path_factory.mktemp("fz"), xb, yb,
                 case=("float32", "teleports", "max", 10_000.0, 48_000.0, "exact"))


def _seek_payload(img, r, k0, x, y):
    """image_payload with the seek fields (start tick, resting cursor) after the rates."""
    base = image_payload(img, r, x, y)
    head = len(base) - 8 - 16 * len(x)                     # up to the stroke's i64 n
    return base[:head] + struct.pack("<qdd", k0, float(x[0]), float(y[0])) + base[head:]


@pytest.mark.parametrize("samples", [2 ** 31, 2 ** 32, 2 ** 40])
def test_sample_counter_passes_2_to_the_31_and_32(sd_vectors_san, tmp_path, samples):
    """Audio keeps coming, one sample per 1/48 kHz, past 2^31 and 2^32 samples (12.4 h, 24.9 h)."""
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.25)
    x, y = x[1000:1600], y[1000:1600]                      # across the first widget
    k0 = int((samples - 2000) * r.tick_rate / r.audio_rate)
    co, ca, (_, cev, _, cfault) = parse_outputs(_run(sd_vectors_san, "seek", _seek_payload(img, r, k0, x, y),
                                                     tmp_path), len(x))
    n_audio = co["audio_samples"]

    def j_end(k):          # renderer.online_step's sample index, in the same double arithmetic
        return np.floor(((0.0 + k / r.tick_rate) - 0.0) * r.audio_rate + 1e-9) + 1

    ks = k0 + np.arange(len(x))
    expected = j_end(ks) - j_end(ks - 1)
    np.testing.assert_array_equal(n_audio, expected)
    assert j_end(ks[-1]) > samples and ca.size == expected.sum()      # crossed the boundary
    assert set(np.unique(n_audio)) <= {4.0, 5.0}
    assert cev > 5 and np.count_nonzero(ca) > 0.2 * ca.size and cfault == 0
    np.testing.assert_array_equal(co["t"], ks / r.tick_rate)


def test_counters_near_2_to_the_63_stay_defined(sd_vectors_san, tmp_path):
    """At 2^63 - 5000 samples (beyond 2^53 the double times no longer resolve a tick) the renderer
    still runs without overflow or NaN: bounded audio per tick, finite outputs, counters monotonic."""
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.02)
    k0 = int((2 ** 63 - 5000) / (r.audio_rate / r.tick_rate))
    co, ca, (clip, cev, drop, cfault) = parse_outputs(
        _run(sd_vectors_san, "seek", _seek_payload(img, r, k0, x, y), tmp_path), len(x))
    n_audio = co["audio_samples"]
    assert all(np.isfinite(co[n]).all() for n in co.dtype.names) and np.isfinite(ca).all()
    assert np.abs(co["drive"]).max() <= 1.0
    assert (n_audio >= 0).all() and (n_audio <= np.ceil(r.audio_rate / r.tick_rate) + 2).all()
    assert min(clip, cev, drop, cfault) >= 0


@pytest.mark.parametrize("cc", ["gcc", "clang"])
def test_host_tools_build_werror_with_gcc_and_clang(tmp_path, cc):
    """`make -C runtime-c CC=...`: the library and host tools compile -Wall -Wextra -pedantic -Werror
    with both compilers (clang's -Wsometimes-uninitialized included)."""
    import shutil
    if shutil.which(cc) is None:
        assert shutil.which("apt-get") is None, f"{cc} missing: scripts/install-system-deps.sh --with-toolchains"
        pytest.skip(f"no {cc} and no apt-get to install it")
    src = tmp_path / "src"
    shutil.copytree(CDIR, src, ignore=shutil.ignore_patterns("build", "wasm", "m4"))
    res = subprocess.run(["make", "-s", "-C", str(src), f"CC={cc}", "sd_vectors", "sd_vectors_single", "sd_bench"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert (src / "sd_vectors").is_file() and (src / "sd_bench").is_file()


# ------------------------------------------------------------------ every loop bounded
def _sweep(model_name, pad, h, mu_s=0.6, dmus=(0.0, 1e-6, 0.1, 0.3, 0.55)):
    """Per-tick inputs covering the extremes: V 1 um/s to 1000 m/s with reversals, N 1 uN to 1 kN,
    delta mu 0 to 0.55; 20 ticks of each combination (a reversal among them), the pad carried through."""
    from test_c_runtime import _jump
    V, N, muk = [], [], []
    for v in (1e-6, 1e-3, 0.05, 0.5, 2.0, 10.0, 100.0, 1000.0):
        for n in (1e-6, 0.01, 0.5, 2.0, 10.0, 100.0, 1000.0):
            for d in dmus:
                V += [(-v if k % 7 == 3 else v) for k in range(20)]
                N += [n] * 20
                muk += [mu_s - d] * 20
    V, N, muk = np.array(V), np.array(N), np.array(muk)
    t = np.arange(V.size) * h
    return _jump(pad, name=model_name), t, V, N, np.full(V.size, mu_s), muk, np.ones(V.size)


@pytest.mark.parametrize("h", [1 / 192_000, 1e-4, 1e-3, 1e-2])
@pytest.mark.parametrize("name", ["jump", "exact"])
def test_phase_cap_not_reached_by_physical_inputs(plain_vectors, tmp_path, h, name):
    """The cap on phase changes per tick (SD_PHASES_BASE + 4 h omega / pi) holds every tick of the
    extreme sweep on the published pad, and on an over-damped one: no tick is cut."""
    from test_c_runtime import pad_vectors
    from shapedisplay.table.devices import PadParams
    exe = plain_vectors
    for pad in (None, PadParams(1e-6, 2000.0, 1.0)):
        args = _sweep(name, pad, h)
        assert pad_vectors(exe, tmp_path, *args, truncated=True) == 0


@pytest.mark.parametrize("h", [1 / 192_000, 1e-4, 1e-3])
def test_degenerate_pad_takes_no_zero_length_phases(plain_vectors, tmp_path, h):
    """The degenerate pad: the exact model with c = 0 and mu_k = mu_s under reversals. At a crossing with
    the stick force at the limit and moving inwards the pad re-sticks, and a slip starting with the
    relative velocity past zero crosses at once, so no tick cycles through zero-length phases: neither
    the vector tool nor the shipped engine reaches the phase cap, and the friction stays within mu_s N."""
    from test_c_runtime import pad_vectors
    from shapedisplay.table.devices import PadParams
    from shapedisplay.render.models import run_kernel
    exe = plain_vectors
    args = _sweep("exact", PadParams(1e-6, 2000.0, 0.0), h, dmus=(0.0,))
    assert pad_vectors(exe, tmp_path, *args, truncated=True) == 0
    S, f, phase, x, v, ev_t, ev_a = run_kernel(*args)      # raises ModelError if a tick is cut
    assert S["truncated"] == 0 and ev_t.size > 0
    N = args[3]
    assert np.all(np.isfinite(f)) and np.all(np.abs(f[1:]) <= 0.6 * N[1:] * (1 + 1e-12))


@pytest.fixture(scope="module")
def plain_vectors(tmp_path_factory):
    """The host tool without sanitizers (the sweeps run many ticks)."""
    out = tmp_path_factory.mktemp("c-plain") / "sd_vectors"
    srcs = [str(CDIR / n) for n in (*LIB, "tool_vectors.c")]
    res = subprocess.run(["gcc", *CFLAGS, "-I", str(CDIR), *srcs, "-lm", "-o", str(out)],
                         capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr
    return out


# ------------------------------------------------------------------ extreme tables through Renderer
_CODE_DTYPES = ("uint8", "uint16", "float32", "float64")
_EXTREME = st.one_of(st.floats(-1e308, 1e308), st.sampled_from([0.0, 1.0, -1.0, 1e300, -1e300, 1.7e308, -1.7e308,
                                                                3.4e38, -3.4e38, 1e-300, 5e-324]))


@st.composite
def _extreme_channel(draw, n):
    """(Quantization, codes of n values): any code type, scale and offset, codes over the type's range."""
    from shapedisplay.table.model import Quantization
    dtype = draw(st.sampled_from(_CODE_DTYPES))
    if dtype in ("float32", "float64"):
        vals = draw(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=32 if dtype == "float32" else 64),
                             min_size=n, max_size=n))
        return Quantization(dtype), np.array(vals, dtype)
    top = np.iinfo(dtype).max
    codes = draw(st.lists(st.sampled_from([0, 1, top // 2, top]) | st.integers(0, top), min_size=n, max_size=n))
    return Quantization(dtype, draw(_EXTREME), draw(_EXTREME)), np.array(codes, dtype)


@settings(max_examples=150, deadline=None)
@given(data=st.data(), model=st.sampled_from(["exact", "jump", "karnopp"]),
       names=st.sets(st.sampled_from(["friction_scale", "burst_gain", "grad_x", "grad_y", "lateral_x",
                                      "skin_stretch", "breakaway_force", "kinetic_force"]), max_size=4),
       kmu=st.sampled_from([0.0, 0.4, 1e300]), rows=st.integers(1, 2), cols=st.integers(1, 4))
def test_any_table_the_reader_accepts_plays_finite_outputs(data, model, names, kmu, rows, cols):
    """Small tables with extreme but finite scales, offsets, codes and backgrounds: whatever the reader
    (read_image: the table schema) accepts, the engine accepts too (the same range rule) and plays finite
    outputs for finite cursor samples, the drive and audio within [-1, 1]; a non-finite intermediate is a
    counted value fault, never an output."""
    from shapedisplay.errors import ShapeDisplayError
    from shapedisplay.render import Renderer
    from shapedisplay.render import image as I
    from shapedisplay.render.layouts import OUTPUTS
    from shapedisplay.table.model import FrictionTable, Grid
    from hypothesis import assume
    names = {"normal_force", *names}
    if kmu > 0:
        names.add("grad_x")
    quant, codes, bg = {}, {}, {}
    for n in sorted(names):
        q, c = data.draw(_extreme_channel(rows * cols), label=n)
        quant[n], codes[n] = q, c.reshape(rows, cols)
        bg[n] = data.draw(_EXTREME, label=f"{n} background")
    try:
        table = FrictionTable.from_codes(Grid(rows, cols, 1e-3, 1e-3), codes, quant, bg,
                                         meta={"mapping": {"slope_friction_gain": kmu}})
        table = I.read_image(I.to_image(table))          # what the reader accepts
    except ShapeDisplayError:
        assume(False)
    r = Renderer(table, model=model, tick_rate=10_000.0, audio_rate=48_000.0)   # the C loader must agree
    pos = st.floats(-1e6, 1e6) | st.floats(-2e-3, 6e-3) | st.sampled_from([0.0, 1e3, -1e3, 999.9])
    xs = data.draw(st.lists(pos, min_size=2, max_size=40), label="x")
    ys = data.draw(st.lists(pos, min_size=len(xs), max_size=len(xs)), label="y")
    r.reset()
    for x, y in zip(xs, ys):
        r.step(x, y)
        for name in OUTPUTS.names:
            assert np.isfinite(r.last[name]), (name, r.last[name])
        assert -1.0 <= r.last["drive"] <= 1.0
        a = r.audio_block[:int(r.last["audio_samples"])]
        assert np.all(np.abs(a) <= 1.0)


def test_overflowing_products_are_value_faults_not_outputs():
    """A table each of whose values is finite but whose forces overflow (N near the largest double times a
    friction scale of 1e10): every tick is counted in run.value_faults and plays without contact."""
    from shapedisplay.render import Renderer
    from shapedisplay.table.model import FrictionTable, Grid, Quantization
    codes = {"normal_force": np.full((1, 4), 255, np.uint8), "friction_scale": np.full((1, 4), 255, np.uint8)}
    quant = {"normal_force": Quantization("uint8", 1e305, 0.0), "friction_scale": Quantization("uint8", 1e10, 0.0)}
    r = Renderer(FrictionTable.from_codes(Grid(1, 4, 1e-3, 1e-3), codes, quant), model="jump",
                 tick_rate=10_000.0, audio_rate=48_000.0)
    r.reset()
    for k in range(50):
        r.step(1e-5 * k, 0.0)
        assert r.last["normal_force"] == 0.0 and r.last["friction_force"] == 0.0
    assert int(r._online.run["value_faults"]) == 50
