"""The single-precision build of the C runtime (-DSD_SINGLE: sd_real = float) on the host.

The build the Cortex-M4F runs (tests/test_m4_runtime.py runs the same vectors under QEMU), compiled
here with the system compiler, the undefined-behaviour and address sanitizers, and
-Wdouble-promotion -Wfloat-conversion -Werror (no implicit double anywhere). Its arithmetic is not
the reference's, so it is held to the bounds derived in engine/README.md ("Tolerance of the
single-precision build", runtime_vectors.float_bounds) against the double-precision engine the package
ships (``Renderer``): the same events, event times, drive and friction force within the bounds.
"""
import os
import struct
import subprocess

import numpy as np
import pytest

from runtime_vectors import (CASES, assert_within_float_bounds, case_setup, float_bounds, image_payload,
                             parse_events, parse_outputs, py_render_events)
from test_c_runtime import CDIR, CFLAGS, LIB, _cc
from test_c_runtime_robust import _run, _seek_payload

SINGLE = ["-DSD_SINGLE", "-Wdouble-promotion", "-Wfloat-conversion"]


def _build(out, extra):
    srcs = [str(CDIR / n) for n in (*LIB, "tool_vectors.c")]
    cmd = [_cc(), *CFLAGS, *extra, "-I", str(CDIR), *srcs, "-lm", "-o", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, f"{' '.join(cmd)}\n{res.stderr}"
    return out


@pytest.fixture(scope="module")
def sd_single(tmp_path_factory):
    return _build(tmp_path_factory.mktemp("c-single") / "sd_vectors_single",
                  [*SINGLE, "-g", "-fsanitize=undefined,address", "-fno-sanitize-recover=all"])


@pytest.fixture(scope="module")
def sd_double(tmp_path_factory):
    return _build(tmp_path_factory.mktemp("c-double") / "sd_vectors", [])


@pytest.mark.parametrize("dtype, kind, policy, tick, audio, model", CASES)
def test_single_precision_build_within_derived_bounds(sd_single, tmp_path, dtype, kind, policy, tick, audio, model):
    table, r, x, y, img = case_setup(dtype, kind, policy, tick, audio, model, seconds=0.12)
    po, pa, pt, pA = py_render_events(r, x, y)
    raw = _run(sd_single, "image", image_payload(img, r, x, y), tmp_path)
    co, ca, (cclip, cev, cdrop, cfault) = parse_outputs(raw, len(x))
    ct, cA = parse_events(raw, len(x))
    assert len(pt) > 10 and cev == len(pt) and cdrop == 0 and cfault == 0 and ca.size == pa.size
    dt, d_drive, d_force = assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA)
    # the bounds are worst cases; the single build is far inside them, and not bit-exact
    assert 0 < np.abs(ct - pt).max() < dt and np.abs(co["drive"] - po["drive"]).max() < d_drive


def test_single_precision_epochs_over_a_long_stroke(sd_single, tmp_path):
    """A 1 s stroke crosses 16 epochs of the float time base (live event times shifted each time): the
    outputs stay within the derived bounds, which grow with the stroke's length and event count."""
    table, r, x, y, img = case_setup("uint16", "circles", "add", 4_000.0, 48_000.0, "jump", seconds=1.0)
    po, pa, pt, pA = py_render_events(r, x, y)
    raw = _run(sd_single, "image", image_payload(img, r, x, y), tmp_path)
    co, ca, (_, cev, cdrop, _) = parse_outputs(raw, len(x))
    ct, cA = parse_events(raw, len(x))
    assert cev == len(pt) > 100 and cdrop == 0
    assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA)


@pytest.mark.parametrize("samples", [2 ** 31, 2 ** 32, 2 ** 40])
def test_single_precision_sample_counter_passes_2_to_the_31_and_32(sd_single, tmp_path, samples):
    """Integer tick and sample counts: audio keeps coming, exactly as many samples per tick as the
    reference computes, past 2^31, 2^32 and 2^40 samples; the event times, counted from the epoch, keep
    their precision (the drive is as dense as at the start)."""
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.25)
    x, y = x[1000:1600], y[1000:1600]
    k0 = int((samples - 2000) * r.tick_rate / r.audio_rate)
    raw = _run(sd_single, "seek", _seek_payload(img, r, k0, x, y), tmp_path)
    co, ca, (_, cev, _, cfault) = parse_outputs(raw, len(x))
    ct, _ = parse_events(raw, len(x))
    ks = k0 + np.arange(len(x))
    j_end = (ks * 48_000) // 10_000 + 1                     # exact integer sample index
    np.testing.assert_array_equal(co["audio_samples"], j_end - (ks - 1) * 48_000 // 10_000 - 1)
    assert cev > 5 and np.count_nonzero(ca) > 0.2 * ca.size and cfault == 0
    assert np.isfinite(ca).all() and np.abs(ca).max() <= 1.0
    np.testing.assert_allclose(ct, ct[0] + np.cumsum(np.r_[0, np.diff(ct)]), rtol=0)   # finite, ordered
    assert (np.diff(ct) > 0).all() and (ct >= k0 / r.tick_rate - 1e-3).all()


def test_single_precision_build_refuses_fractional_rates(sd_single, tmp_path):
    """The float time base counts ticks and samples in integers: a rate that is not a whole number of
    hertz is refused at init (sd_renderer_init returns SD_ERR_PARAM; the tool exits 3)."""
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.01)
    payload = bytearray(image_payload(img, r, x, y))
    head = len(payload) - 8 - 16 * len(x) - 16                 # the two f64 rates before the stroke
    payload[head:head + 16] = struct.pack("<dd", 10_000.5, 48_000.0)
    fin, fout = tmp_path / "in", tmp_path / "out"
    fin.write_bytes(bytes(payload))
    res = subprocess.run([str(sd_single), "image", str(fin), str(fout)], capture_output=True, text=True,
                         env={**os.environ, "ASAN_OPTIONS": "detect_leaks=0"})
    assert res.returncode == 3 and "sd_renderer_init failed (-3)" in res.stderr


def test_float_bounds_are_derived_not_picked():
    """The event-time bound grows with the stroke's duration and event count (rounding accumulates
    from event to event), and shrinks when the surface moves faster at the events."""
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.06)
    po, pa, pt, pA = py_render_events(r, x, y)
    dt1, _, _ = float_bounds(r, table, x, y, po, pt)
    po2 = po.copy()
    po2["pad_speed"] *= 2.0
    dt2, _, _ = float_bounds(r, table, x, y, po2, pt)
    dt3, _, _ = float_bounds(r, table, np.r_[x, x], np.r_[y, y], np.r_[po, po], np.r_[pt, pt])
    assert dt2 < dt1 < dt3


@pytest.mark.parametrize("dtype", ["uint16", "float64"])
def test_single_precision_plays_a_header_compiled_table(tmp_path, dtype):
    """A table compiled in from `export --format c` (tile index, float64 codes converted by integer
    operations) in the single-precision build: drive within the derived bound of every tick whose
    events lie farther than the event-time bound from its edges, the same number of audio samples."""
    from shapedisplay.exchange.export import export_c
    from shapedisplay.render import Renderer
    from test_c_runtime import stroke, widget_table
    table = widget_table(dtype)
    table.meta["tick_rate_hz"] = 10_000.0
    header = export_c(table, tmp_path / "table.h", name="sd_table")
    exe = tmp_path / "sd_play_header"
    cmd = [_cc(), *CFLAGS, *SINGLE, f'-DSD_TABLE_HEADER="{header}"', "-I", str(CDIR), str(CDIR / "tool_play_header.c"),
           *(str(CDIR / n) for n in LIB), "-lm", "-o", str(exe)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    r = Renderer(table, model="jump", tick_rate=10_000.0, audio_rate=48_000.0)
    x, y = stroke(1200, "diagonal")
    po, pa, pt, pA = py_render_events(r, x, y)
    fin, fout = tmp_path / "in", tmp_path / "out"
    fin.write_bytes(struct.pack("<q", x.size) + np.asarray(x, "<f8").tobytes() + np.asarray(y, "<f8").tobytes())
    res = subprocess.run([str(exe), "48000", str(fin), str(fout)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    raw = fout.read_bytes()
    drive = np.frombuffer(raw, "<f8", x.size)
    (na,) = struct.unpack_from("<q", raw, 8 * x.size)
    assert len(pt) > 20 and na == pa.size
    dt, d_drive, _ = float_bounds(r, table, x, y, po, pt)
    t = po["t"]
    edge = np.zeros(len(t) + 1, bool)
    j = np.clip(np.rint((pt - t[0]) * r.tick_rate).astype(int), 0, len(t) - 1)   # the tick time nearest each event
    near = np.abs(t[j] - pt) <= dt      # an event that can move across that tick time changes ticks j and j + 1
    edge[j[near]] = edge[j[near] + 1] = True
    edge = edge[:-1]
    assert edge.mean() < 0.2
    assert np.abs(drive - po["drive"])[~edge].max() <= d_drive
    assert np.abs(drive - po["drive"]).max() > 0          # float arithmetic: not the reference's bits


def test_single_precision_loader_refuses_reals_beyond_float_range(sd_single, sd_double, tmp_path):
    """A stored scale of 1e300 is finite (the double build loads it) but no float holds it: the
    single-precision build refuses the image with SD_ERR_IMAGE_VALUE (-16) instead of playing inf."""
    import zlib
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, None, "jump", seconds=0.01)
    bad = bytearray(img)
    struct.pack_into("<d", bad, 224 + 8, 1e300)                     # slot 0's scale
    struct.pack_into("<I", bad, len(bad) - 4, zlib.crc32(bytes(bad[:-4])) & 0xFFFFFFFF)
    fin, fout = tmp_path / "in", tmp_path / "out"
    fin.write_bytes(image_payload(bytes(bad), r, x, y))
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=0"}
    single = subprocess.run([str(sd_single), "image", str(fin), str(fout)], capture_output=True, text=True, env=env)
    double = subprocess.run([str(sd_double), "image", str(fin), str(fout)], capture_output=True, text=True)
    assert single.returncode == 4 and "(-16)" in single.stderr
    assert double.returncode == 0
