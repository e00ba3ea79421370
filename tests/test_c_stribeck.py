"""The C runtime's ``stribeck`` model (runtime_c/sd_stribeck.c) against independent answers.

The C tick runs through the vector tool (``sd_vectors pad``, see test_c_runtime.pad_vectors), a build
of the engine's sources with the system compiler (-ffp-contract=off), and is checked as
tests/test_stribeck_kernel.py checks the shipped engine: a tight ``solve_ivp`` Radau run with event
functions (``reports.peers.stribeck_ivp``), the closed form of the linear curve (``a = 0``), the event
bound of every tolerance the accuracy report tries, the pre-maximum variant's closed-form steady states
and its hysteresis, finite and bounded outputs on hostile inputs, and events that do not depend on how
the ticks cut the stroke. The single-precision build (-DSD_SINGLE) is held to finite, bounded outputs
and to its tolerance floor against the double build.
"""
from __future__ import annotations

import math
import shutil
import subprocess

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shapedisplay.devices import BurstParams, DeviceProfile, FrictionParams, PadParams
from shapedisplay.reports.peers import stribeck_ivp
from shapedisplay.runtime.models import get_model
from shapedisplay.runtime.studies import IMAIZUMI_FRICTION, IMAIZUMI_PAD
from test_c_runtime import CDIR, CFLAGS, LIB, _cc, pad_vectors, sd_vectors  # noqa: F401  (sd_vectors: fixture)
from test_stribeck_kernel import _viscous_belt_events

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


def _radau(m=1e-4, k=1e3, c=1.0, b=1.9, V=0.1, hz=9.0, amp=1.25e-3, t_end=0.15, rtol=1e-11):
    ref = stribeck_ivp("Radau", rtol, m=m, k=k, c=c, mu_s=2.1, mu_k=1.4, a=55.0, b=b, W=1.0, V=V, amp=amp,
                       omega=2 * math.pi * hz, t_end=t_end)
    assert ref.status == "ok" and ref.event_time.size >= 2
    return ref


# ------------------------------------------------------------------ plain curve against Radau
@pytest.mark.parametrize("hz,amp,v,duration", [(9.0, 1.25e-3, 0.1, 0.15), (0.0, 0.0, 0.04, 0.12)])
def test_plain_curve_matches_tight_radau(sd_vectors, tmp_path, hz, amp, v, duration):
    """Default tolerance (Taylor slip steps): every event within 1e-9 s of Radau at rtol 1e-11, amplitudes
    within 1e-8 (relative), at 1 and 10 kHz ticks."""
    ref = _radau(V=v, hz=hz, amp=amp, t_end=duration)
    model = _model(contactor_hz=hz, contactor_amplitude_m=amp)
    for rate in (1000, 10_000):
        f, phase, x, et, ea = _c_run(sd_vectors, tmp_path, model, _ticks(rate, duration), v, 1.0)
        assert et.size == ref.event_time.size, rate
        assert np.max(np.abs(et - ref.event_time)) < 1e-9, rate
        np.testing.assert_allclose(ea, ref.event_amplitude, rtol=1e-8, atol=0)


def test_default_steps_hold_on_a_pad_with_almost_no_sliding_damping(sd_vectors, tmp_path):
    """c = 0, b = 0.05 N s/m (35 breakaways in 0.5 s) at 100 Hz ticks: the Taylor steps' defect check keeps
    every event within 1e-9 s of Radau."""
    pad = PadParams(1.0e-4, 1.0e3, 0.0)
    ref = _radau(c=0.0, b=0.05, t_end=0.5)
    assert ref.event_time.size >= 30
    model = _model(pad=pad, extra={"stribeck": {"a": 55.0, "b": 0.05}}, contactor_hz=9.0,
                   contactor_amplitude_m=1.25e-3)
    _, _, _, et, _ = _c_run(sd_vectors, tmp_path, model, _ticks(100, 0.5), 0.1, 1.0)
    assert et.size == ref.event_time.size
    assert np.max(np.abs(et - ref.event_time)) < 1e-9


@pytest.mark.parametrize("hz,amp,v,duration", [(9.0, 1.25e-3, 0.1, 0.25), (0.0, 0.0, 0.04, 0.12)])
def test_exponential_steps_match_tight_radau_within_their_tolerance(sd_vectors, tmp_path, hz, amp, v, duration):
    """Looser tolerances (exponential Rosenbrock slip steps): event errors within 10 tolerances of the mean
    event interval, amplitudes within 100 tolerances, at 100 Hz, 1 and 10 kHz."""
    ref = _radau(V=v, hz=hz, amp=amp, t_end=duration)
    scale = float(np.mean(np.diff(ref.event_time)))
    worst = {}
    for tol in (1e-8, 1e-7, 1e-5, 1e-4):
        model = _model(contactor_hz=hz, contactor_amplitude_m=amp, tolerance=tol)
        for rate in (100, 1000, 10_000):
            _, _, _, et, ea = _c_run(sd_vectors, tmp_path, model, _ticks(rate, duration), v, 1.0)
            assert et.size == ref.event_time.size, (tol, rate)
            err = float(np.max(np.abs(et - ref.event_time)))
            assert err <= 10 * tol * scale, (tol, rate, err)
            np.testing.assert_allclose(ea, ref.event_amplitude, rtol=100 * tol, atol=0)
            worst[tol] = max(worst.get(tol, 0.0), err)
    if hz:
        assert worst[1e-8] < worst[1e-7] < worst[1e-5] < worst[1e-4]


def test_every_tolerance_the_report_tries_keeps_its_event_bound(sd_vectors, tmp_path):
    """The accuracy report's contactor stroke at each of its slip tolerances and tick rates: event times within
    10 tolerances of the mean event interval of a tight Radau run (1e-9 s for the default Taylor steps)."""
    from shapedisplay.reports.accuracy import STRIBECK_TOLERANCES, build_cases
    case = next(c for c in build_cases(False) if c.name == "stribeck_contactor")
    p = case.params
    hz, amp, v = case.contactor["hz"], case.contactor["amplitude_m"], float(case.V(0.0))
    ref = stribeck_ivp("Radau", 1e-11, m=p["m"], k=p["k"], c=p["c"], mu_s=p["mu_s"], mu_k=p["mu_k"], a=p["a"],
                       b=p["b"], W=1.0, V=v, amp=amp, omega=2 * math.pi * hz, t_end=case.duration)
    assert ref.status == "ok" and ref.event_time.size >= 8
    scale = float(np.mean(np.diff(ref.event_time)))
    for tol in STRIBECK_TOLERANCES:
        model = _model(contactor_hz=hz, contactor_amplitude_m=amp, tolerance=tol)
        for rate in case.rates:
            _, _, _, et, ea = _c_run(sd_vectors, tmp_path, model, _ticks(rate, case.duration), v, 1.0)
            assert et.size == ref.event_time.size, (tol, rate)
            err = float(np.max(np.abs(et - ref.event_time)))
            bound = 1e-9 if tol is None else 10 * tol * scale
            assert err <= bound, (tol, rate, err, bound)
            np.testing.assert_allclose(ea, ref.event_amplitude, rtol=100 * (tol or 1e-9), atol=0)


@pytest.mark.parametrize("tol", [None, 1e-6, 1e-3])
def test_linear_curve_matches_its_closed_form(sd_vectors, tmp_path, tol):
    """a = 0, b = -0.1 (a negative viscous slope self-excites the slip): exact for every tolerance."""
    dev_pad, dev_fr = PadParams(1.0, 1.0, 0.0), FrictionParams(1.0, 0.5)
    model = _model(pad=dev_pad, friction=dev_fr, extra={"stribeck": {"a": 0.0, "b": -0.1}}, tolerance=tol)
    expect = _viscous_belt_events(1.0, 1.0, -0.1, 1.0, 1.0, 0.2, 4)
    for rate in (100, 1000):
        _, _, _, et, ea = _c_run(sd_vectors, tmp_path, model, _ticks(rate, expect[-1] + 0.5), 0.2, 1.0,
                                 mus=1.0, muk=0.5)
        assert et.size == expect.size, rate
        assert np.max(np.abs(et - expect)) < 1e-9, rate
        np.testing.assert_allclose(ea, 1.0, rtol=1e-12)


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


_LOADS = st.one_of(st.just(0.0), st.floats(0.01, 3.0))
_CONTACTORS = st.sampled_from([(0.0, 0.0), (9.0, 1.25e-3), (3.0, 1.25e-3)])


@settings(max_examples=12, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.3, 0.3), _LOADS), min_size=3, max_size=8), _CONTACTORS,
       st.sampled_from([None, 3e-9, 1e-6, 1e-5]))
def test_events_independent_of_tick_cuts(sd_vectors, tmp_path_factory, segments, contactor, tol):
    """Inputs held for 20 ms each; ticks of 1 ms, cut in three, give the same events: within 1e-8 s for the
    default Taylor steps, 10 tolerances (in s) for the exponential ones."""
    tmp_path = tmp_path_factory.mktemp("cuts")
    hz, amp = contactor
    model = _model(contactor_hz=hz, contactor_amplitude_m=amp, tolerance=tol)
    V = np.repeat([s[0] for s in segments], 20)
    N = np.repeat([s[1] for s in segments], 20)
    events = []
    for split in (1, 3):
        n = V.size * split + 1
        t = np.arange(n) / (1000.0 * split)
        Vt = np.concatenate([[0.0], np.repeat(V, split)])
        Nt = np.concatenate([[N[0]], np.repeat(N, split)])
        out = _c_run(sd_vectors, tmp_path, model, t, Vt, Nt)
        _assert_finite_and_within_the_curve(out, Vt, Nt, hz, amp)
        events.append(out[3])
    assert events[0].size == events[1].size
    if events[0].size:
        assert np.max(np.abs(events[0] - events[1])) < (1e-8 if tol is None else 10 * tol)


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
