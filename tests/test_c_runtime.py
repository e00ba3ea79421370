"""The portable C99 runtime (runtime-c/) against the Python renderer on shared test vectors.

The C sources are compiled with the system C compiler into a temporary
directory (C99, -O2, no fast-math, no FMA contraction). Tolerance: bit-exact.
The C jump kernel performs the same double-precision operations in the same
order as the numba kernel and calls the same libm, so every tick output and
every event time/amplitude must be identical (``assert_array_equal``).
"""
import math
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.runtime import pads
from shapedisplay.runtime.models import get_model, run_kernel
from shapedisplay.devices import BurstParams, FrictionParams, PadParams, load_device

ROOT = Path(__file__).resolve().parent.parent
CDIR = ROOT / "runtime-c"
CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-ffp-contract=off"]


def _cc():
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    pytest.fail("no C compiler (cc/gcc/clang) found; the C runtime tests need one")


@pytest.fixture(scope="module")
def sd_vectors(tmp_path_factory):
    out = tmp_path_factory.mktemp("c-runtime") / "sd_vectors"
    srcs = sorted(str(p) for p in CDIR.glob("sd_*.c"))
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
# Input:  f64 params[5] (m, k, c, B, max_stick_period), i64 n, f64 t[n], V[n], N[n], mus[n], muk[n], gain[n]
# Output: f64 f[n], phase[n], x[n], i64 n_ev, f64 ev_t[n_ev], ev_a[n_ev]
def pad_vectors(exe, tmp_path, model, t, V, N, mus, muk, gain):
    P = model.params
    payload = (np.array([P[pads.P_M], P[pads.P_K], P[pads.P_C], P[pads.P_B], P[pads.P_TMAX]], "<f8").tobytes()
               + struct.pack("<q", t.size)
               + b"".join(np.asarray(a, "<f8").tobytes() for a in (t, V, N, mus, muk, gain)))
    raw = _run(exe, "pad", payload, tmp_path)
    n = t.size
    arr = np.frombuffer(raw[:24 * n], "<f8").reshape(3, n)
    (n_ev,) = struct.unpack_from("<q", raw, 24 * n)
    ev = np.frombuffer(raw[24 * n + 8:], "<f8").reshape(2, n_ev)
    return arr[0], arr[1], arr[2], ev[0], ev[1]


def _jump(pad=None, friction=None, max_stick=0.0, gain=0.25):
    dev = load_device(None)
    dev = dev.with_(pad=pad or dev.pad, friction=friction or dev.friction,
                    burst=BurstParams(gain=gain, max_stick_period_s=max_stick))
    return get_model("jump", dev)


CASES = {
    "published pad, steady 50 mm/s, N = 2 N": dict(V=0.05, N=2.0),
    "slow stroke, high N": dict(V=0.004, N=6.0),
    "fast stroke, several events per tick": dict(V=0.45, N=0.5),
    "reversals and N ramps": dict(V="sine", N="ramp"),
    "delta_mu = 0: steady sliding": dict(V=0.05, N=2.0, friction=FrictionParams(0.5, 0.5)),
    "over-damped pad": dict(V=0.05, N=2.0, pad=PadParams(1e-6, 2000.0, 0.5)),
    "undamped pad": dict(V=0.05, N=2.0, pad=PadParams(1e-6, 2000.0, 0.0)),
    "max stick period 2 ms at high N": dict(V=0.002, N=8.0, max_stick=0.002),
    "N = 0 and V = 0 stretches": dict(V="stop-go", N="zero-blocks"),
}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("rate", [1000.0, 10000.0, 96000.0])
def test_jump_kernel_bit_exact(sd_vectors, tmp_path, case, rate):
    spec = dict(CASES[case])
    model = _jump(spec.pop("pad", None), spec.pop("friction", None), spec.pop("max_stick", 0.0))
    n = int(0.2 * rate) + 1
    t = np.arange(n) / rate
    rng = np.random.default_rng(abs(hash(case)) % 2**32)
    V, N = spec["V"], spec["N"]
    if V == "sine":
        V = 0.12 * np.sin(2 * np.pi * 7.0 * t) + 0.01 * rng.standard_normal(n)
    elif V == "stop-go":
        V = np.where((t * 20).astype(int) % 2 == 0, 0.06, 0.0)
    if N == "ramp":
        N = 0.5 + 4.0 * (t / t[-1])
    elif N == "zero-blocks":
        N = np.where((t * 13).astype(int) % 3 == 0, 0.0, 1.5)
    V = np.broadcast_to(np.asarray(V, float), (n,)).copy()
    N = np.broadcast_to(np.asarray(N, float), (n,)).copy()
    fr = model.device.friction
    mus, muk, gain = np.full(n, fr.mu_s), np.full(n, fr.mu_k), 1.0 + 0.5 * (rng.random(n) < 0.1)
    S, f, st, x, v, wf, wd, et, ea = run_kernel(model, t, V, N, mus, muk, gain)
    cf, cst, cx, cet, cea = pad_vectors(sd_vectors, tmp_path, model, t, V, N, mus, muk, gain)
    np.testing.assert_array_equal(cet, et)
    np.testing.assert_array_equal(cea, ea)
    np.testing.assert_array_equal(cst, st)
    np.testing.assert_array_equal(cx, x)
    np.testing.assert_array_equal(cf, f)
    if case.startswith("published"):
        assert et.size > 10          # the vector exercises stick-slip, not just sticking


def test_restick_closed_form_matches_python(sd_vectors, tmp_path):
    """The V -> 0 limit of the re-stick force, through the C kernel (exact answer, DESIGN 3.1)."""
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
