"""Compiler: published tent N(x) within the stated error, pruning, quantization, reports, exports."""
import json
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

from shapedisplay.author import sources
from shapedisplay.author.compile import CompileOptions, compile_heightfield, quantization_for
from shapedisplay.table.devices import load_device
from shapedisplay.errors import InputError
from shapedisplay.exchange.export import c_header, export_c, export_json
from shapedisplay.author.forces import MappingOptions
from shapedisplay.table.model import CHANNELS, FrictionTable

ASSETS = Path(__file__).resolve().parent.parent / "assets" / "maps"
RIG = load_device("desktop-rig")


def test_tent_height_map_reproduces_published_tent():
    # published tent: N1 = 0.5 N, L1 = 10 mm, L2 = 25 mm, k = 0.15 N/mm (N2 = 2.75 N), L4 = 50 mm
    hf = sources.tent_profile("10mm", "25mm", "50mm", n1="0.5N", k="0.15 N/mm", n_gain="2 N/mm", dx="0.1mm")
    res = compile_heightfield(hf, "linear-slider", MappingOptions(n_base=0.5, n_gain=2000.0))
    t = res.table
    assert t.is_1d and t.grid.cols == hf.cols
    n = t.dense("normal_force")[0]
    published = sources.tent_force(hf.x, 0.010, 0.025, n1=0.5, k=150.0)
    err = np.abs(n - published).max()
    stated = res.report["quantization"]["normal_force"]["max_error"]
    assert err <= stated
    assert stated <= 0.1 / 2 * 0.5                     # within half a JND of the smallest force
    # and the table's own bilinear lookup between samples follows the piecewise-linear profile
    xs = np.linspace(0.011, 0.024, 57)
    assert np.abs(t.sample("normal_force", xs) - sources.tent_force(xs, 0.010, 0.025, n1=0.5, k=150.0)).max() <= stated


def test_bundled_tent_png_reproduces_published_tent():
    from shapedisplay.author.sources import load_image
    hf = load_image(ASSETS / "tent_profile.png", "60x4mm", "0:2mm")
    res = compile_heightfield(hf, None, MappingOptions.parse("height", n_base="0.5N", n_gain="2N/mm"))
    n = res.table.dense("normal_force")
    published = sources.tent_force(hf.x, 0.010, 0.030, n1=0.5, n2=4.5)
    gray_step = 2e-3 / 65535 / 2 * 2000.0              # rounding of the 16-bit gray values, in N
    assert np.abs(n - published[None, :]).max() <= res.report["quantization"]["normal_force"]["max_error"] + gray_step


def _rand_field(seed, shape=(20, 30)):
    rng = np.random.default_rng(seed)
    return sources.from_array(rng.uniform(0, 1e-3, shape), 0.2e-3)


def test_pruning_removes_unused_channels_and_never_changes_kept_values():
    hf = sources.gaussian_bump("1mm", "3mm", "20x16mm", "0.2mm")
    m = MappingOptions.parse("height+lateral+slope")
    full = compile_heightfield(hf, RIG, m).table
    burst_only = compile_heightfield(hf, RIG.with_(outputs=("burst",)), m).table
    assert set(full.channels) == {"normal_force", "grad_x", "grad_y", "lateral_x", "lateral_y"}
    assert burst_only.channels == ["grad_x", "grad_y", "normal_force"]
    for name in burst_only.channels:
        assert burst_only.quant[name] == full.quant[name]
        assert np.array_equal(burst_only.codes[name], full.codes[name])
    kept_more = compile_heightfield(hf, RIG.with_(outputs=("burst",)), m,
                                    CompileOptions(keep=("lateral_x",))).table
    assert "lateral_x" in kept_more.channels
    for name in burst_only.channels:
        assert np.array_equal(kept_more.codes[name], burst_only.codes[name])


@settings(max_examples=25, deadline=None)
@given(heights=hnp.arrays(np.float64, st.tuples(st.integers(1, 8), st.integers(2, 12)),
                          elements=st.floats(-3e-3, 3e-3)),
       spec=st.sampled_from(["height", "height+lateral", "height+slope+lateral-normal", "slope"]),
       quantize=st.sampled_from(["auto", "uint8", "uint16", "float32"]))
def test_stated_errors_hold_and_output_is_finite(heights, spec, quantize):
    hf = sources.from_array(heights, 0.1e-3)
    m = MappingOptions.parse(spec)
    dev = RIG
    res = compile_heightfield(hf, dev, m, CompileOptions(quantize=quantize, limit_walls=False, max_slope=float("inf")))
    from shapedisplay.author.forces import force_channels
    from shapedisplay.author.gradients import gradient
    exact = force_channels(hf, dev, m, grad=gradient(hf))
    assert sorted(exact) == res.table.channels
    for name, q in res.report["quantization"].items():
        dense = res.table.dense(name)
        assert np.all(np.isfinite(dense))
        assert np.abs(dense - exact[name]).max() <= q["max_error"]
        if quantize == "auto":
            assert q["meets_bound"]
        else:
            assert q["dtype"] == quantize


def test_report_accounts_for_everything():
    hf = _rand_field(1)
    res = compile_heightfield(hf, RIG, MappingOptions.parse("height+lateral"))
    r = res.report
    assert set(r["kept"]) | set(r["left_out"]) == set(CHANNELS)
    assert not set(r["kept"]) & set(r["left_out"])
    assert r["stored_bytes"] == res.table.stored_bytes == sum(c.nbytes for c in res.table.codes.values())
    assert r["dense_bytes"] == res.table.dense_bytes and r["bytes_saved"] == r["dense_bytes"] - r["stored_bytes"]
    meta = res.table.meta
    assert meta["device"] == RIG.to_json()
    assert meta["mapping"]["slope_friction_gain"] == 0.0 and meta["mapping"]["spec"] == "height+lateral"
    assert meta["source"]["sha256"] == hf.sha256()
    assert meta["tick_rate_hz"] == RIG.tick_rate_hz
    assert meta["velocity_range_m_s"] == list(RIG.velocity_range)
    assert meta["report"] == r
    json.dumps(meta, allow_nan=False)


def test_auto_quantization_follows_the_perceptual_rule():
    hf = sources.from_array(np.linspace(0, 2e-3, 200)[None, :], 0.1e-3)
    m = MappingOptions(n_base=0.5, n_gain=2000.0)
    # N spans 0.5..4.5 N: uint8 error 4/255/2 = 7.8 mN <= w/2 * 0.5 N = 25 mN
    q = quantization_for("normal_force", 0.5 + 2000.0 * hf.heights, RIG, CompileOptions(), m)
    assert q.dtype == "uint8"
    # a stricter Weber fraction needs 16 bits: bound 0.005/2*0.5 = 1.25 mN < 7.8 mN
    q = quantization_for("normal_force", 0.5 + 2000.0 * hf.heights, RIG, CompileOptions(weber_fraction=0.005), m)
    assert q.dtype == "uint16"


def test_walls_reported_and_limited():
    hf = sources.rounded_button("10mm", "8mm", "1mm", "20x20mm", "0.1mm", edge="step")
    m = MappingOptions.parse("height+lateral", lateral_gain="1 N")
    res = compile_heightfield(hf, RIG, m, CompileOptions(max_slope=0.5))
    w = res.report["walls"]
    assert w["count"] > 0 and w["steepest"] == pytest.approx(1e-3 / 0.2e-3 * np.sqrt(2), rel=0.01)
    assert "clipped to 0.5" in w["limited"]
    b = w["boxes_mm"][0]
    assert b[0] == pytest.approx(4.95, abs=0.11) and b[1] == pytest.approx(15.05, abs=0.11)
    lat = np.hypot(res.table.dense("lateral_x"), res.table.dense("lateral_y"))
    assert lat.max() <= 0.5 * 1.0 + res.report["quantization"]["lateral_x"]["max_error"] * 2
    unlimited = compile_heightfield(hf, RIG, m, CompileOptions(max_slope=0.5, limit_walls=False))
    assert np.hypot(unlimited.table.dense("lateral_x"), unlimited.table.dense("lateral_y")).max() > 1.0
    only_height = compile_heightfield(hf, RIG, MappingOptions())
    assert "not needed" in only_height.report["walls"]["limited"]


def test_bad_compile_requests():
    hf = _rand_field(2)
    with pytest.raises(InputError, match="nothing to store"):
        compile_heightfield(hf, load_device("handheld-stick"), MappingOptions(height=False, lateral="gradient",
                                                                                lateral_gain=1.0))
    with pytest.raises(InputError, match="cannot keep channel 'skin_stretch'"):
        compile_heightfield(hf, RIG, MappingOptions(), CompileOptions(keep=("skin_stretch",)))
    with pytest.raises(InputError, match=r"unknown channel 'normal_forse' \(did you mean 'normal_force'\?\)"):
        CompileOptions(keep=("normal_forse",))
    with pytest.raises(InputError, match=r"unknown quantization 'uint12'"):
        CompileOptions(quantize="uint12")
    with pytest.raises(InputError, match="weber_fraction"):
        CompileOptions(weber_fraction=0.0)
    with pytest.raises(InputError, match=r"unknown device 'desktop-rug' \(did you mean 'desktop-rig'\?\)"):
        compile_heightfield(hf, "desktop-rug")


def test_compiled_table_round_trips_bit_exact(tmp_path):
    res = compile_heightfield(_rand_field(3), RIG, MappingOptions.parse("height+lateral+slope"))
    p = res.table.save(tmp_path / "t.npz")
    u = FrictionTable.load(p)
    assert u.checksum == res.table.checksum and u.meta == res.table.meta
    for n in u.channels:
        assert u.codes[n].tobytes() == res.table.codes[n].tobytes()


def test_json_export_schema(tmp_path):
    hf = sources.tent_profile("10mm", "20mm", "40mm", n2="1.5N", dx="0.5mm")
    t = compile_heightfield(hf, RIG, MappingOptions.parse("height+lateral")).table
    export_json(t, tmp_path / "t.json")
    doc = json.loads((tmp_path / "t.json").read_text())
    assert doc["format_version"] == 1
    assert set(doc["grid"]) == {"rows", "cols", "dx_m", "dy_m", "x0_m", "y0_m"}
    assert doc["grid"]["rows"] == 1 and doc["grid"]["x0_m"] == pytest.approx(0.25e-3)
    assert doc["channels"]["normal_force"]["unit"] == "N"
    assert doc["channels"]["lateral_x"]["unit"] == "N"
    assert np.array_equal(np.array(doc["channels"]["normal_force"]["values"]), t.dense("normal_force"))
    assert "lateral_y" not in doc["channels"]      # 1-D: no y force


C_MAIN = r"""
#include <stdio.h>
#include <stddef.h>
#include "t.h"
static uint32_t crc32(const uint8_t *p, size_t n) {
    uint32_t c = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) { c ^= p[i]; for (int k = 0; k < 8; k++) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u))); }
    return ~c;
}
int main(void) {
    int ok = crc32((const uint8_t *)t_normal_force_codes, sizeof t_normal_force_codes) == t_normal_force_crc32
          && crc32((const uint8_t *)t_lateral_x_codes, sizeof t_lateral_x_codes) == t_lateral_x_crc32;
    printf("%d %d %d %d\n", ok, T_ROWS, T_COLS, T_N_BLOCKS);
    for (int i = 0; i < T_N_VALUES; i += 37) printf("%d %.17g %.17g\n", i, T_DECODE(normal_force, i), T_DECODE(lateral_x, i));
    printf("%.17g %.17g %.17g\n", t_pad_stiffness_n_per_m, t_mu_s, t_dx_m);
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler on this machine")
def test_c_header_compiles_and_decodes_the_same_values(tmp_path):
    hf = sources.gaussian_bump("1mm", "2mm", "10x6mm", "0.25mm")
    t = compile_heightfield(hf, RIG, MappingOptions.parse("height+lateral")).table
    export_c(t, tmp_path / "t.h")
    (tmp_path / "main.c").write_text(C_MAIN)
    subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-o", str(tmp_path / "m"), str(tmp_path / "main.c")],
                   check=True, cwd=tmp_path)
    out = subprocess.run([str(tmp_path / "m")], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0].split() == ["1", str(t.grid.rows), str(t.grid.cols), "1"]
    nf, lx = t.dense("normal_force").ravel(), t.dense("lateral_x").ravel()
    lines = [ln.split() for ln in out[1:] if ln.strip()]
    for i, a, b in lines[:-1]:
        assert float(a) == nf[int(i)] and float(b) == lx[int(i)]
    assert [float(v) for v in lines[-1]] == [2000.0, 0.5, t.grid.dx]


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler on this machine")
def test_c_header_alone_compiles_warning_free(tmp_path):
    """The header as its own translation unit (nothing used) passes -Wall -Wextra -Werror."""
    hf = sources.gaussian_bump("1mm", "2mm", "10x6mm", "0.25mm")
    t = compile_heightfield(hf, RIG, MappingOptions.parse("height+slope+lateral")).table
    export_c(t, tmp_path / "t.h")
    r = subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-x", "c", "-c",
                        str(tmp_path / "t.h"), "-o", str(tmp_path / "t.o")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_c_header_rejects_bad_names():
    t = compile_heightfield(_rand_field(4), RIG, MappingOptions()).table
    with pytest.raises(InputError, match="must be a C identifier"):
        c_header(t, "1bad-name")
    assert "#define SD_TABLE_HAS_NORMAL_FORCE 1" in c_header(t)


def test_fast_kernels_match_numpy_bit_for_bit():
    from shapedisplay.author.compile import _encode, _minmax
    from shapedisplay.author.gradients import limit_walls
    from shapedisplay.table.model import Quantization
    rng = np.random.default_rng(5)
    v = rng.uniform(0.5, 4.5, 70000)          # above KERNEL_MIN_SIZE: the chunked path (not a multiple of CHUNK)
    v[:100] = 0.5 + (np.arange(100) + 0.5) * (4.0 / 255)       # exact ties between codes
    for dt, top in (("uint8", 255), ("uint16", 65535)):
        q = Quantization(dt, 4.0 / top, 0.5, 0.0)
        assert np.array_equal(_encode(q, v), q.encode(v))
    assert _minmax(v) == (v.min(), v.max())
    gx, gy = rng.normal(0, 2, (300, 300)), rng.normal(0, 2, (300, 300))
    fast = limit_walls(gx, gy, 1.5)
    slow = limit_walls(gx[:, ::1].T.copy().T, gy.T.copy().T, 1.5)   # Fortran order: numpy path
    assert np.allclose(fast[0], slow[0], rtol=1e-14) and np.allclose(fast[1], slow[1], rtol=1e-14)
    from shapedisplay.author.gradients import detect_walls
    hf = sources.from_array(np.zeros((300, 300)), 1e-4)
    a, b = detect_walls(hf, gx, gy, 1.5), detect_walls(hf, gx.T.copy().T, gy.T.copy().T, 1.5)
    assert (a.count, a.steepest, a.regions, a.boxes_mm) == (b.count, b.steepest, b.regions, b.boxes_mm)
    assert np.array_equal(a.mask, b.mask)
    inside = np.hypot(gx, gy) <= 1.5
    assert np.array_equal(fast[0][inside], gx[inside]) and np.array_equal(slow[0][inside], gx[inside])


def test_extruded_profile_stores_one_row():
    hf = sources.tent_profile("10mm", "20mm", "40mm", n2="1.5N", dx="0.2mm", rows=25)
    res = compile_heightfield(hf, RIG, MappingOptions.parse("height+lateral"))
    t = res.table
    assert len(t.patch_shapes) == 1 and t.patch_shapes[0] == (1, hf.cols) and len(t.blocks) == 25
    assert res.report["stored_bytes"] == t.stored_bytes == 3 * hf.cols      # N, F_x, F_y rows, uint8
    one = compile_heightfield(sources.tent_profile("10mm", "20mm", "40mm", n2="1.5N", dx="0.2mm"), RIG,
                              MappingOptions.parse("height+lateral")).table
    assert np.array_equal(t.dense("normal_force"), np.repeat(one.dense("normal_force"), 25, axis=0))
    bumped = hf.heights.copy()
    bumped[3, 7] += 1e-4
    dense = compile_heightfield(hf.with_heights(bumped), RIG, MappingOptions.parse("height+lateral"))
    assert len(dense.table.blocks) == 1 and dense.report["layout"].startswith("dense")


@settings(max_examples=25, deadline=None)
@given(heights=hnp.arrays(np.float64, st.tuples(st.integers(1, 6), st.integers(2, 9)),
                          elements=st.floats(-2e-3, 2e-3)),
       keep=st.sets(st.sampled_from(["grad_x", "lateral_x", "normal_force"])))
def test_pruning_property(heights, keep):
    hf = sources.from_array(heights, 0.2e-3)
    m = MappingOptions.parse("height+slope+lateral")
    full = compile_heightfield(hf, RIG, m).table
    pruned = compile_heightfield(hf, RIG.with_(outputs=("burst",)), m, CompileOptions(keep=tuple(keep))).table
    assert set(pruned.channels) <= set(full.channels)
    assert not {"lateral_x", "lateral_y"} - set(keep) & set(pruned.channels)
    for name in pruned.channels:
        assert pruned.quant[name] == full.quant[name]
        assert np.array_equal(pruned.dense(name), full.dense(name))


def test_chunked_kernels_equal_whole_array_arithmetic():
    """Chunk boundaries change nothing: the chunked passes give the whole-array numpy results bit for bit."""
    from shapedisplay.author import kernels as _kernels
    rng = np.random.default_rng(11)
    n = 3 * _kernels.CHUNK + 1234
    gx, gy = rng.normal(0, 2, n), rng.normal(0, 2, n)
    m2 = gx * gx + gy * gy
    count, peak, mask = _kernels.wall_scan(gx, gy, 2.25)
    assert (count, peak) == (int((m2 > 2.25).sum()), m2.max())
    assert np.array_equal(mask, m2 > 2.25)
    fx, fy = gx.copy(), gy.copy()
    count, peak = _kernels.clip_magnitude(fx, fy, 1.5)
    f = np.where(m2 > 2.25, 1.5 / np.sqrt(m2), 1.0)
    assert count == int((m2 > 2.25).sum()) and peak == np.sqrt(m2.max())
    assert np.array_equal(fx, np.where(m2 > 2.25, gx * f, gx)) and np.array_equal(fy, np.where(m2 > 2.25, gy * f, gy))
    wx, wy = gx.copy(), gy.copy()           # only the masked samples visited: the same values bit for bit
    assert _kernels.clip_where(wx, wy, 1.5, mask) == count
    assert np.array_equal(wx, fx) and np.array_equal(wy, fy)
    # walls only in the last chunk: the mask is all False before it; no wall at all: no mask
    quiet = np.zeros(n)
    quiet[n - 3] = 2.0
    count, peak, mask = _kernels.wall_scan(quiet, np.zeros(n), 2.25)
    assert (count, peak, int(mask.sum()), bool(mask[n - 3])) == (1, 4.0, 1, True)
    assert _kernels.wall_scan(quiet, np.zeros(n), 4.0) == (0, 4.0, None)
    gx[n - 5] = np.nan
    lo, hi = _kernels.minmax(gx)
    assert np.isnan(lo) and np.isnan(hi)


def test_limit_walls_given_the_wall_report_visits_only_walls_with_the_same_result():
    from shapedisplay.author.gradients import detect_walls, limit_walls
    rng = np.random.default_rng(8)
    gx, gy = rng.normal(0, 2, (300, 300)), rng.normal(0, 2, (300, 300))
    hf = sources.from_array(np.zeros((300, 300)), 1e-4)
    walls = detect_walls(hf, gx, gy, 1.5)
    plain = limit_walls(gx, gy, 1.5)
    masked = limit_walls(gx, gy, 1.5, walls=walls)
    assert np.array_equal(plain[0], masked[0]) and np.array_equal(plain[1], masked[1])
    other = detect_walls(hf, gx, gy, 2.0)        # a report for another limit is not used
    again = limit_walls(gx, gy, 1.5, walls=other)
    assert np.array_equal(plain[0], again[0]) and np.array_equal(plain[1], again[1])


def test_compile_of_a_walled_map_is_unchanged_by_the_shared_scratch_and_the_masked_clipping(monkeypatch):
    """The scratch array shared by the wall labels and N, and wall clipping that visits only the walls, give
    the table that fresh arrays and a clipping pass over every sample give (codes channel for channel)."""
    from shapedisplay.author import compile as compile_mod
    rng = np.random.default_rng(3)
    h = np.cumsum(rng.normal(0, 2e-5, (300, 320)), axis=1) + rng.normal(0, 3e-5, (300, 320))
    hf = sources.from_array(h, 0.1e-3)
    m = MappingOptions.parse("height+lateral")
    fast = compile_heightfield(hf, RIG, m)
    assert fast.report["walls"]["count"] > 1000 and fast.report["walls"]["regions"] > 100
    detect, limit = compile_mod.detect_walls, compile_mod.limit_walls
    monkeypatch.setattr(compile_mod, "detect_walls", lambda *a: detect(*a))
    monkeypatch.setattr(compile_mod, "limit_walls", lambda *a, walls=None, **kw: limit(*a, **kw))
    plain = compile_heightfield(hf, RIG, m)
    assert fast.report == plain.report and fast.table.quant == plain.table.quant
    for name in fast.table.channels:
        assert np.array_equal(fast.table.codes[name], plain.table.codes[name]), name
    assert fast.table.to_bytes() == plain.table.to_bytes()


def test_normal_force_written_into_a_given_array():
    from shapedisplay.author.forces import normal_force
    h = np.random.default_rng(1).uniform(-1e-3, 3e-3, (40, 50))
    hf = sources.from_array(h, 0.1e-3)
    for m in (MappingOptions.parse("height"), MappingOptions.parse("height+perceptual", perceptual_exponent=0.6)):
        n, note = normal_force(hf, RIG, m)
        out = np.full(h.shape, np.nan)
        n2, note2 = normal_force(hf, RIG, m, out=out)
        assert n2 is out and np.array_equal(n, n2) and note == note2
    with pytest.raises(InputError, match="`out` must be a float64 array of shape"):
        normal_force(hf, RIG, MappingOptions.parse("height"), out=np.empty((40, 50), np.float32))


def test_wall_regions_load_no_scipy_ndimage(tmp_path):
    """Counting wall regions runs the package's C kernel: scipy.ndimage (about 0.25 s of start-up) is not
    imported, and the count is scipy's."""
    code = (
        "import sys, numpy as np\n"
        "from shapedisplay.author.gradients import wall_regions\n"
        "mask = np.random.default_rng(4).random((300, 300)) < 0.4\n"
        "n, top, spans = wall_regions(mask, 5)\n"
        "print('scipy.ndimage' in sys.modules)\n"
        "from scipy import ndimage\n"
        "labels, m = ndimage.label(mask)\n"
        "print(n == m, ndimage.find_objects(labels)[top[0] - 1] == "
        "(slice(spans[0][0], spans[0][1] + 1), slice(spans[0][2], spans[0][3] + 1)))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["False", "True", "True"]


def test_heights_whose_sum_overflows_are_still_finite():
    h = np.full((4, 5), 1.5e308)
    assert sources.from_array(h, 1e-3).heights.max() == 1.5e308
    h = h.copy()
    h[2, 3] = np.inf
    with pytest.raises(InputError, match="1 NaN/inf samples, first at row 2, col 3"):
        sources.from_array(h, 1e-3)


def _compile_both_ways(monkeypatch, hf, device, mapping, options=CompileOptions(), chunk=1024, band_samples=4096):
    """(banded, whole-array) compiles of ``hf`` (None if it is not compiled band by band): small chunks and
    bands so that a small map has many of both."""
    from shapedisplay.author import compile as compile_mod
    from shapedisplay.author import kernels as _kernels, gradients
    monkeypatch.setattr(_kernels, "CHUNK", chunk)
    monkeypatch.setattr(gradients, "KERNEL_MIN_SIZE", 1)      # both ways through the chunked passes
    monkeypatch.setattr(compile_mod, "KERNEL_MIN_SIZE", 1)
    monkeypatch.setattr(compile_mod, "BANDS_MIN_SIZE", 1)
    monkeypatch.setattr(compile_mod, "BAND_SAMPLES", band_samples)
    kept = compile_mod.needed_channels(device, mapping, hf.is_1d)[0]
    if not compile_mod._band_rows(hf, [n for n in CHANNELS if n in kept], mapping, options):
        return None
    banded = compile_heightfield(hf, device, mapping, options)
    monkeypatch.setattr(compile_mod, "BANDS_MIN_SIZE", 1 << 60)
    whole = compile_heightfield(hf, device, mapping, options)
    return banded, whole


def _assert_same_table(a, b):
    assert a.report == b.report
    assert a.table.quant == b.table.quant and a.table.meta == b.table.meta
    for name in b.table.channels:
        assert a.table.codes[name].dtype == b.table.codes[name].dtype
        assert np.array_equal(a.table.codes[name], b.table.codes[name]), name
    assert a.table.to_bytes() == b.table.to_bytes()


def _noisy_map(rows, cols, seed, noise=3e-5):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(0, 2e-5, (rows, cols)), axis=1) + rng.normal(0, noise, (rows, cols))


@pytest.mark.parametrize("rows, cols", [(300, 256), (257, 300), (301, 300), (40, 4096)])
@pytest.mark.parametrize("gain", ["1N", "3N"])
def test_banded_compile_gives_the_whole_array_table(monkeypatch, rows, cols, gain):
    """Band by band (slopes, walls, N and lateral forces a band of rows at a time, two passes) is the same
    table bit for bit as the whole-array compile: walls, clipping, ranges, codes, report."""
    hf = sources.from_array(_noisy_map(rows, cols, rows), 0.1e-3)
    banded, whole = _compile_both_ways(monkeypatch, hf, RIG, MappingOptions.parse("height+lateral", lateral_gain=gain))
    assert whole.report["walls"]["count"] > 1000 and whole.report["walls"]["regions"] > 100
    assert (whole.report["clamped"]["lateral"]["above"] > 0) == (gain == "3N")    # 1.5 N at most on this rig
    _assert_same_table(banded, whole)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), rows=st.integers(17, 90), cols=st.integers(3, 70),
       noise=st.sampled_from([0.0, 1e-6, 3e-5, 1e-3]), gain=st.sampled_from(["0.2N/mm", "1N/mm", "40N/mm"]),
       base=st.sampled_from(["0N", "0.5N", "3N"]), max_slope=st.sampled_from([0.3, 1.0, np.inf]),
       limit=st.booleans(), quantize=st.sampled_from(["auto", "uint8", "uint16", "float32"]),
       lateral=st.sampled_from(["height", "height+lateral", "lateral"]))
def test_banded_compile_property(seed, rows, cols, noise, gain, base, max_slope, limit, quantize, lateral):
    import contextlib

    from hypothesis import assume
    hf = sources.from_array(_noisy_map(rows, cols, seed, noise), 0.1e-3)
    m = MappingOptions.parse(lateral, n_gain=gain, n_base=base)
    opts = CompileOptions(quantize=quantize, max_slope=max_slope, limit_walls=limit)
    with pytest.MonkeyPatch.context() as mp:
        try:
            both = _compile_both_ways(mp, hf, RIG, m, opts, chunk=16, band_samples=64)
            assume(both is not None)
            banded, whole = both
        except InputError as exc:       # refused: the whole-array compile refuses with the same message
            mp.setattr("shapedisplay.author.compile.BANDS_MIN_SIZE", 1 << 60)
            with pytest.raises(InputError) as again:
                compile_heightfield(hf, RIG, m, opts)
            assert str(again.value) == str(exc)
            return
    _assert_same_table(banded, whole)
    with contextlib.suppress(KeyError):
        assert banded.report["clamped"]["normal_force"] == whole.report["clamped"]["normal_force"]


@pytest.mark.filterwarnings("ignore:overflow encountered")
def test_banded_compile_refuses_overflowing_slopes_as_the_whole_array_compile(monkeypatch):
    h = np.zeros((40, 50))
    h[20, 25] = 1e300
    hf = sources.from_array(h, 1e-9)
    for size in (1, 1 << 60):
        monkeypatch.setattr("shapedisplay.author.compile.BANDS_MIN_SIZE", size)
        monkeypatch.setattr("shapedisplay.author.compile.BAND_SAMPLES", 256)
        monkeypatch.setattr("shapedisplay.author.kernels.CHUNK", 64)
        with pytest.raises(InputError, match="slopes overflow float64"):
            compile_heightfield(hf, RIG, MappingOptions.parse("height+lateral"))


def test_banded_compile_only_where_it_gives_the_same_table():
    from shapedisplay.author.compile import _band_rows
    hf = sources.from_array(np.zeros((2048, 2048)), 0.1e-3)
    kept = ["normal_force", "lateral_x", "lateral_y"]
    m = MappingOptions.parse("height+lateral")
    assert _band_rows(hf, kept, m, CompileOptions()) == 128
    assert not _band_rows(hf, kept, m, CompileOptions(gradient_method="gaussian"))
    assert not _band_rows(hf, kept + ["skin_stretch"], m, CompileOptions())
    assert not _band_rows(hf, kept, MappingOptions.parse("height+lateral-normal"), CompileOptions())
    assert not _band_rows(hf, kept, MappingOptions.parse("height+lateral+perceptual"), CompileOptions())
    assert not _band_rows(hf, kept, m.with_(n_base=-0.0), CompileOptions())
    assert not _band_rows(sources.from_array(np.zeros((100, 100)), 0.1e-3), kept, m, CompileOptions())


def test_banded_compile_where_the_bounds_need_the_smallest_nonzero_value(monkeypatch):
    """N reaching 0 and a frictionless pad: the perceptual bounds come from the smallest nonzero |value|
    of N and of the lateral forces, which the banded compile finds in extra passes: the same table."""
    from shapedisplay.table.devices import FrictionParams
    dev = RIG.with_(normal_force_range=(0.0, 8.0), friction=FrictionParams(mu_s=0.5, mu_k=0.0))
    h = _noisy_map(200, 256, 5)
    h[:, :40] = -1e-3                              # N = 0.5 N + 1 N/mm * h clamps at 0 here
    hf = sources.from_array(h, 0.1e-3)
    banded, whole = _compile_both_ways(monkeypatch, hf, dev, MappingOptions.parse("height+lateral"))
    assert whole.report["clamped"]["normal_force"]["below"] > 0
    assert "smallest nonzero" in whole.report["quantization"]["normal_force"]["rule"]
    assert "smallest nonzero" in whole.report["quantization"]["lateral_x"]["rule"]
    _assert_same_table(banded, whole)


@settings(max_examples=40, deadline=None)
@given(rows=st.integers(3, 30), cols=st.integers(3, 12), cuts=st.lists(st.integers(1, 29), max_size=5),
       seed=st.integers(0, 2 ** 32 - 1))
def test_central_slopes_of_bands_are_the_whole_map_slopes(rows, cols, cuts, seed):
    from shapedisplay.author.gradients import central, central_band
    h = np.random.default_rng(seed).normal(0, 1e-3, (rows, cols))
    gx, gy = central(sources.from_array(h, 0.1e-3))
    edges = sorted({0, rows, *(c for c in cuts if c < rows)})
    bx, by = np.full_like(h, np.nan), np.full_like(h, np.nan)
    for r0, r1 in zip(edges, edges[1:]):
        central_band(h, 0.1e-3, 0.1e-3, r0, r1, bx[r0:r1], by[r0:r1])
    assert np.array_equal(bx, gx) and np.array_equal(by, gy)
