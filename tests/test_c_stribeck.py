"""The ``stribeck`` model's builds besides the package's engine, and its pre-maximum variant.

tests/test_stribeck_kernel.py holds the engine (``run_kernel``) to Radau, the linear curve's closed
form and every tolerance's event bound. Here the C tick runs through the vector tool (``sd_vectors
pad``, see test_c_runtime.pad_vectors), a build of the same sources with the system compiler
(-ffp-contract=off): the pre-maximum variant's closed-form steady states and its hysteresis, finite and
bounded outputs on hostile inputs, the single-precision build (-DSD_SINGLE) held to finite, bounded
outputs and to its tolerance floor against the double build, and the Cortex-M4F instruction counts.
"""
from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest

from shapedisplay.table.devices import BurstParams, DeviceProfile
from shapedisplay.render.models import get_model
from shapedisplay.reports.imaizumi import IMAIZUMI_FRICTION, IMAIZUMI_PAD
from test_c_runtime import CDIR, CFLAGS, LIB, _cc, pad_vectors, sd_vectors  # noqa: F401  (sd_vectors: fixture)

SINGLE = ["-DSD_SINGLE", "-Wdouble-promotion", "-Wfloat-conversion"]
#: The single-precision build's slip tolerance floor (SD_STRIBECK_TOL_FLOOR in sd_stribeck.c)
FLOAT_TOL_FLOOR = 1e-5


@pytest.fixture(scope="module")
def sd_single(tmp_path_factory):
    out = tmp_path_factory.mktemp("c-stribeck-single") / "sd_vectors_single"
    cmd = [_cc(), *CFLAGS, *SINGLE, "-I", str(CDIR), *[str(CDIR / n) for n in (*LIB, "tool_vectors.c")], "-lm",
           "-o", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, f"single-precision build failed:\n{' '.join(cmd)}\n{res.stderr}"
    return out


def _model(pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION, extra=None, **options):
    dev = DeviceProfile(pad=pad, friction=friction, burst=BurstParams(gain=1.0), extra=extra or {})
    return get_model("stribeck", dev, **options)


def _ticks(rate, duration):
    n = int(round(duration * rate)) + 1
    return np.arange(n, dtype=np.float64) / rate


def _c_run(exe, tmp_path, model, t, V, N, mus=2.1, muk=1.4):
    """The C tick over per-tick inputs (scalars or arrays): (f, phase, x, ev_t, ev_a)."""
    n = t.size
    full = [np.broadcast_to(np.asarray(a, float), (n,)).copy() for a in (V, N, mus, muk, 1.0)]
    return pad_vectors(exe, tmp_path, model, t, *full)


def _c_truncated(exe, tmp_path, model, t, V, N, mus=2.1, muk=1.4):
    n = t.size
    full = [np.broadcast_to(np.asarray(a, float), (n,)).copy() for a in (V, N, mus, muk, 1.0)]
    return pad_vectors(exe, tmp_path, model, t, *full, truncated=True)


# ------------------------------------------------------------------ pre-maximum variant
@pytest.mark.parametrize("rate", [1000, 10_000])
def test_premax_steady_states_in_closed_form(sd_vectors, tmp_path, rate):
    """Contactor still, finger at constant speed. Inside the pre-maximum region (|V| < d W) the friction is
    viscous, -p vr: the pad is the linear oscillator m u'' + (c + p) u' + k u = -p V from rest, in closed form
    (the exponential substeps are exact for it), settling where k u = -p V, with no event. Beyond it
    (V = 0.1 m/s) the breakaway at the end of the first substep."""
    model = _model(variant="premax")
    t = _ticks(rate, 0.05)
    W, V, m, k, c, p = 1.0, 0.002, 1e-4, 1e3, 1.0, 400.0
    f, phase, x, et, _ = _c_run(sd_vectors, tmp_path, model, t, V, W)
    assert et.size == 0 and np.all(phase == 0.0)
    # overdamped: u = ueq + A1 e^(r1 t) + A2 e^(r2 t), u(0) = 0, u'(0) = 0
    ueq = -p * V / k
    sig, wn2 = 0.5 * (c + p) / m, k / m
    r2 = -sig - math.sqrt(sig * sig - wn2)
    r1 = wn2 / r2
    a1 = r2 * ueq / (r1 - r2)
    a2 = -ueq - a1
    u = ueq + a1 * np.exp(r1 * t) + a2 * np.exp(r2 * t)
    assert np.max(np.abs(x - u)) <= 1e-12 * abs(ueq)
    t = _ticks(rate, 8.0)
    f, phase, x, et, _ = _c_run(sd_vectors, tmp_path, model, t, V, W)
    assert abs(x[-1] - ueq) <= 1e-7 * abs(ueq) and abs(f[-1] - (-p * V)) <= 1e-7 * p * V
    # beyond it, from rest: |vr| = V >= 2 d W at once, the breakaway found at the end of the first substep
    f, phase, x, et, ea = _c_run(sd_vectors, tmp_path, model, _ticks(rate, 0.01), 0.1, W)
    assert et.size == 1 and abs(et[0] - 2e-6) <= 1e-15


def test_premax_hysteresis_and_tick_rate_independence(sd_vectors, tmp_path):
    """The contactor stroke: events only where |vr| reaches 2 d W from the pre-maximum region, on the substep
    grid (2 us at 1 and 10 kHz ticks alike), so both tick rates give the same events (to rounding)."""
    model = _model(variant="premax", contactor_hz=9.0, contactor_amplitude_m=1.25e-3)
    runs = []
    for rate in (1000, 10_000):
        f, phase, x, et, ea = _c_run(sd_vectors, tmp_path, model, _ticks(rate, 0.3), 0.1, 1.0)
        assert np.all(np.isfinite(f)) and np.all(np.isfinite(x)) and set(np.unique(phase)) <= {0.0, 1.0}
        assert et.size >= 2 and np.all(np.diff(et) > 0)
        grid = et / 2e-6
        assert np.max(np.abs(grid - np.round(grid))) < 1e-6
        runs.append((et, ea))
    assert runs[0][0].size == runs[1][0].size
    assert np.max(np.abs(runs[0][0] - runs[1][0])) < 1e-12
    np.testing.assert_allclose(runs[0][1], runs[1][1], rtol=1e-9)


# ------------------------------------------------------------------ hostile inputs, tick cuts
def _assert_finite_and_within_the_curve(out, V, N, hz, amp, mus=2.1, rel=1e-9):
    f, phase, x, et, ea = out
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(x))
    assert set(np.unique(phase)) <= {0.0, 1.0}
    assert np.all(np.diff(et) > 0) and np.all(np.isfinite(ea)) and np.all(ea >= 0)
    stuck = phase == 0.0
    assert np.all(np.abs(f[stuck]) <= mus * N[stuck] * (1 + rel) + 1e-12)


@pytest.mark.parametrize("variant,tol", [("stribeck", None), ("stribeck", 1e-6), ("stribeck", 1e-4), ("premax", None)])
def test_hostile_inputs_stay_finite_and_bounded(sd_vectors, tmp_path, variant, tol):
    """N = 0 stretches, subnormal and huge loads, V up to 1000 m/s with reversals, the contactor running:
    finite outputs, phases 0/1, stick friction within mu_s N, no tick cut at a cap. (The pre-maximum curve is
    evaluated as W mu, so a subnormal load stays finite: |vr| / W alone overflows there.)"""
    model = _model(contactor_hz=9.0, contactor_amplitude_m=1.25e-3, tolerance=tol, variant=variant)
    rate = 1000.0
    t = _ticks(rate, 0.4)
    n = t.size
    seg = (np.arange(n) // 20) % 8
    V = np.choose(seg, [0.0, 0.25, -0.25, 1e3, -1e3, 0.05, -0.05, 0.0])
    N = np.choose((np.arange(n) // 30) % 6, [1.0, 0.0, 5e-324, 2.2e-311, 1e3, 0.01])
    out = _c_run(sd_vectors, tmp_path, model, t, V, N)
    _assert_finite_and_within_the_curve(out, V, N, 9.0, 1.25e-3)
    assert _c_truncated(sd_vectors, tmp_path, model, t, V, N) == 0


# ------------------------------------------------------------------ single precision
@pytest.mark.parametrize("variant,tol", [("stribeck", None), ("stribeck", 1e-4), ("premax", None)])
def test_single_precision_build_finite_bounded_and_near_the_double(sd_single, sd_vectors, tmp_path, variant, tol):
    """-DSD_SINGLE: the slip tolerance is raised to the float floor (1e-5; the default 1e-13 means nothing in
    float). The contactor stroke at 10 kHz and a hostile stroke: finite, bounded, no tick cut; on the contactor
    stroke the same events as the double build, times within 10 floor tolerances of the event interval plus
    float rounding of the times."""
    opts = dict(contactor_hz=9.0, contactor_amplitude_m=1.25e-3, variant=variant)
    if tol is not None:
        opts["tolerance"] = tol
    model = _model(**opts)
    t = _ticks(10_000, 0.25)
    sf, sphase, sx, set_, sea = _c_run(sd_single, tmp_path, model, t, 0.1, 1.0)
    _, _, _, det, dea = _c_run(sd_vectors, tmp_path, model, t, 0.1, 1.0)
    assert np.all(np.isfinite(sf)) and np.all(np.isfinite(sx)) and set(np.unique(sphase)) <= {0.0, 1.0}
    assert set_.size == det.size and det.size >= 2
    if variant == "premax":
        # events at the substep where |vr| reaches 2 d W: a slow approach to that level moves them by far more
        # than float rounding (measured: up to 0.27 ms); the single build is held to finite and bounded here
        det, dea = set_, sea
    interval = float(np.mean(np.diff(det)))
    eff = max(tol or 0.0, FLOAT_TOL_FLOOR)
    bound = 10 * eff * interval + 4 * np.finfo(np.float32).eps * 0.25
    assert np.max(np.abs(set_ - det)) <= bound, (np.max(np.abs(set_ - det)), bound)
    np.testing.assert_allclose(sea, dea, rtol=100 * eff)
    n = t.size
    V = np.choose((np.arange(n) // 200) % 6, [0.0, 0.25, -0.25, 1e3, -1e3, 0.05])
    N = np.choose((np.arange(n) // 300) % 5, [1.0, 0.0, 1e-30, 1e3, 0.01])
    out = _c_run(sd_single, tmp_path, model, t, V, N)
    _assert_finite_and_within_the_curve(out, V, N, 9.0, 1.25e-3, rel=1e-5)
    assert _c_truncated(sd_single, tmp_path, model, t, V, N) == 0


# ------------------------------------------------------------------ Cortex-M4F instruction counts
_M4_BENCH = r"""
#include <math.h>
#include <string.h>
#include "sd_runtime.h"
#include "m4/m4.h"
static const double PRM[] = {%(params)s};
static uint32_t counts[%(n)d + 1];
static sd_real ev_t[4096], ev_a[4096];
int main(void)
{
    static char cmd[256];
    char *out = cmd;
    sd_pad_params_t prm;
    sd_pad_t P;
    sd_pad_state_t S;
    int i = 0, n_ev = 0, k;
    int32_t fd;
#define F_F64(name) prm.name = (sd_real)PRM[i++];
#define F_I64(name) prm.name = (int64_t)PRM[i++];
#define F(kind, name) F_##kind(name)
    SD_FIELDS_PAD_PARAMS(F)
    sd_pad_prepare(&P, &prm);
    sd_pad_reset(&S);
    if (m4_cmdline(cmd, sizeof cmd) != 0) return 2;
    while (*out && *out != ' ') out++;          /* argv[1]: the output file */
    while (*out == ' ') out++;
    for (k = 1; k <= %(n)d; k++) {
        sd_real t0 = (sd_real)(k - 1) / (sd_real)%(rate)d, h = (sd_real)1 / (sd_real)%(rate)d;
        m4_count_start();
        n_ev = sd_stribeck_tick(&S, &P, t0, h, (sd_real)%(V)r, (sd_real)1, (sd_real)2.1, (sd_real)1.4, (sd_real)1,
                                ev_t, ev_a, 4096, n_ev);
        counts[k - 1] = m4_count_read();
    }
    m4_count_start();
    counts[%(n)d] = m4_count_read();
    fd = m4_open(out, 1);
    if (fd < 0) return 2;
    m4_write(fd, counts, 4 * (%(n)d + 1));
    m4_write(fd, &n_ev, 4);
    m4_close(fd);
    return 0;
}
"""


def _c_double(v):
    v = float(v)
    return repr(v) if math.isfinite(v) else ("HUGE_VAL" if v > 0 else "-HUGE_VAL")


def _m4_stribeck_counts(tmp_path, model, rate, seconds, V, precision="single"):
    """Instructions per sd_stribeck_tick on the Cortex-M4F (QEMU mps2-an386, -icount), the tick alone."""
    from runtime_vectors import COUNTS_PER_INSTRUCTION, ICOUNT_SHIFT, QEMU_M4
    n = int(round(seconds * rate))
    fields = [model.params[name] for name in model.params.dtype.names]
    src = tmp_path / "bench_stribeck.c"
    src.write_text(_M4_BENCH % dict(params=", ".join(_c_double(v) for v in fields), n=n, rate=int(rate), V=V))
    elf = tmp_path / "bench_stribeck.elf"
    flags = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "--specs=nano.specs",
             "-nostartfiles"]
    cmd = ["arm-none-eabi-gcc", *flags, *CFLAGS, *(SINGLE if precision == "single" else []), "-I", str(CDIR),
           "-T", str(CDIR / "m4" / "mps2.ld"), str(CDIR / "m4" / "startup.c"), str(src), str(CDIR / "sd_pad.c"),
           str(CDIR / "sd_stribeck.c"), "-lm", "-o", str(elf)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    fout = tmp_path / "counts.bin"
    run = [*QEMU_M4, "-icount", f"shift={ICOUNT_SHIFT}", "-semihosting-config",
           f"enable=on,target=native,arg=bench,arg={fout}", "-kernel", str(elf)]
    res = subprocess.run(run, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-500:]
    raw = fout.read_bytes()
    c = np.frombuffer(raw[:4 * (n + 1)], "<u4").astype(np.float64)
    assert (c < 0xFFFFF0).all(), "a tick ran past the 24-bit SysTick range"
    n_ev = int(np.frombuffer(raw[4 * (n + 1):], "<i4")[0])
    return (c[:-1] - c[-1]) / COUNTS_PER_INSTRUCTION, n_ev


@pytest.mark.skipif(any(shutil.which(t) is None for t in ("arm-none-eabi-gcc", "qemu-system-arm")),
                    reason="no arm-none-eabi-gcc / qemu-system-arm (scripts/install-system-deps.sh --with-toolchains)")
@pytest.mark.parametrize("variant,tol", [("stribeck", None), ("stribeck", 1e-4), ("premax", None)])
def test_m4_stribeck_instructions_per_tick(tmp_path, variant, tol):
    """The contactor stroke (9 Hz, 1.25 mm, 0.1 m/s, W = 1 N) at 10 kHz on the Cortex-M4F, single precision:
    instructions per sd_stribeck_tick (the pad tick alone), deterministic, the same events as the host's
    single-precision build."""
    opts = dict(contactor_hz=9.0, contactor_amplitude_m=1.25e-3, variant=variant)
    if tol is not None:
        opts["tolerance"] = tol
    model = _model(**opts)
    a, n_ev = _m4_stribeck_counts(tmp_path, model, 10_000, 0.25, 0.1)
    b, _ = _m4_stribeck_counts(tmp_path, model, 10_000, 0.25, 0.1)
    np.testing.assert_array_equal(a, b)
    print(f"\n[m4] stribeck {variant} tol={tol} 10 kHz: {n_ev} events, instructions per tick mean {a.mean():.0f} "
          f"median {np.median(a):.0f} max {a.max():.0f}")
    assert n_ev >= 2 and (a > 0).all()
