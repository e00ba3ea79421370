"""The WebAssembly build (runtime_c/wasm/sd_runtime.wasm) in wasmtime on the shared vectors.

The module links wasi-libc's libm (musl), not glibc's: exp/sin/cos may differ by an ulp, so
the comparison is by the derived bounds of runtime_vectors.derived_bounds (event counts and
stick/slip states must match exactly).
"""
import shutil
import subprocess

import numpy as np
import pytest

from shapedisplay.runtime import wasm
from shapedisplay.runtime.models import MODEL_IDS

from runtime_vectors import (CASES, WasmRunner, assert_within_derived_bounds, assert_within_float_bounds, case_setup,
                             derived_bounds, py_render_events, wasm_play_events)
from test_c_runtime import CDIR, py_render

pytest.importorskip("wasmtime", reason="wasmtime (pip install 'shapedisplay[test]') runs the WebAssembly tests")


def test_shipped_module_is_built_from_the_shipped_sources():
    assert wasm.MODULE.is_file() and wasm.WRAPPER.is_file() and wasm.WORKLET.is_file()
    assert wasm.is_current(), ("runtime_c/wasm/sd_runtime.wasm is older than the C sources: "
                               "run make -C runtime-c wasm-package")


def _toolchain():
    return shutil.which("clang") and shutil.which("wasm-ld") and (CDIR.parent.parent / "runtime-c").exists()


@pytest.fixture(scope="module")
def module_path(tmp_path_factory):
    """The module built now by `make -C runtime-c wasm` when the toolchain is installed (CI installs it),
    else the shipped one."""
    if not _toolchain():
        return wasm.MODULE
    res = subprocess.run(["make", "-s", "-C", str(CDIR), "wasm"], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    built = CDIR / "build" / "sd_runtime.wasm"
    assert built.is_file()
    assert built.read_bytes() == wasm.MODULE.read_bytes(), "the shipped module differs from a fresh build"
    return built


@pytest.mark.parametrize("dtype, kind, policy, tick, audio, model", CASES)
def test_wasm_plays_the_shared_vectors(module_path, dtype, kind, policy, tick, audio, model):
    table, r, x, y, img = case_setup(dtype, kind, policy, tick, audio, model)
    po, pa, (pclip, pev) = py_render(r, x, y)
    co, ca, (cclip, cev, cdrop, cfault) = WasmRunner(module_path).play(img, r, x, y)
    assert pev > 20 and cev == pev and cdrop == 0 and ca.size == pa.size
    d_drive = assert_within_derived_bounds(r, po, pa, co, ca)
    assert abs(cclip - pclip) <= np.count_nonzero(np.abs(np.abs(pa) - 1.0) <= d_drive)


def test_wasm_refuses_damaged_images_and_swaps_tables():
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.02)
    w = WasmRunner(wasm.MODULE)
    assert w.load(img[:-4]) == -10
    assert w.load(img[:900] + bytes([img[900] ^ 4]) + img[901:]) == -13
    assert w.call("sd_wasm_step", 0.01, 0.0) == 0.0            # nothing loaded: silent, no trap
    assert w.load(img) == 0
    jump = MODEL_IDS["jump"]
    assert w.call("sd_wasm_configure", jump, 0, 10_000.0, 48_000.0) == 0
    assert w.call("sd_wasm_configure", jump, 0, 50.0, 48_000.0) == -3       # tick rate out of range
    assert w.call("sd_wasm_configure", jump, 0, 10_000.0, 44_100.0) == 0
    assert w.load(img) == 0                                     # a swap keeps the configured rates
    assert w.load(b"SDTI" + img[4:-4] + b"\0\0\0\0") == -13     # a bad swap keeps the table playing
    drive = [w.call("sd_wasm_step", xi, 0.004) for xi in np.linspace(0.0, 0.05, 400)]
    assert w.call("sd_wasm_audio_count") in (4, 5, 6)          # 44.1 kHz at 10 kHz ticks
    assert w.call("sd_wasm_counter", 1) > 5 and np.count_nonzero(drive) > 50
    assert w.call("sd_wasm_param", 5) == r.device.friction.mu_s


@pytest.mark.skipif(shutil.which("node") is None, reason="node is optional: runs sd_wasm.js outside a browser")
def test_js_wrapper_in_node(tmp_path):
    """sd_wasm.js (the wrapper the AudioWorklet uses) plays a table like the wasmtime runner."""
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump", seconds=0.05)
    po, pa, _ = py_render(r, x, y)
    (tmp_path / "t.bin").write_bytes(img)
    xy = np.empty(2 * len(x))
    xy[0::2], xy[1::2] = x, y
    (tmp_path / "xy.bin").write_bytes(xy.astype("<f8").tobytes())
    script = tmp_path / "run.mjs"
    script.write_text(f"""
import {{readFileSync, writeFileSync}} from "fs";
import {{SdRuntime}} from "{wasm.WRAPPER.as_uri()}";
const rt = await SdRuntime.create(readFileSync("{wasm.MODULE}"));
rt.loadTable(readFileSync("{tmp_path / 't.bin'}"));
rt.configure({{model: "jump", policy: "retrigger", tickRate: 10000, audioRate: 48000}});
const b = readFileSync("{tmp_path / 'xy.bin'}");
const xy = new Float64Array(b.buffer, b.byteOffset, b.length / 8);
const out = new Float64Array((xy.length / 2) * rt.audioCap());
const n = rt.run(xy, out);
writeFileSync("{tmp_path / 'audio.bin'}", Buffer.from(out.buffer, 0, 8 * n));
let bad = 0; try {{ rt.loadTable(new Uint8Array(600)); }} catch (e) {{ bad = e.code; }}
console.log(JSON.stringify({{n, bad, mu_s: rt.param("mu_s")}}));
""")
    res = subprocess.run(["node", str(script)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    import json
    info = json.loads(res.stdout)
    audio = np.frombuffer((tmp_path / "audio.bin").read_bytes(), "<f8")
    assert info["n"] == pa.size and info["bad"] == -11 and info["mu_s"] == r.device.friction.mu_s
    _, d_drive, _ = derived_bounds(r, po, 2.0 ** -53)
    assert np.abs(audio - pa).max() <= d_drive and np.count_nonzero(pa) > 0.2 * pa.size


@pytest.fixture(scope="module")
def single_module():
    """The single-precision module (`make -C runtime-c wasm-single`): the M4F's arithmetic in a second
    engine, with musl's float libm."""
    if not _toolchain():
        assert shutil.which("apt-get") is None, "clang/wasm-ld missing: scripts/install-system-deps.sh --with-toolchains"
        pytest.skip("no clang/wasm-ld and no apt-get to install them")
    res = subprocess.run(["make", "-s", "-C", str(CDIR), "wasm-single"], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    return CDIR / "build" / "sd_runtime_single.wasm"


@pytest.mark.parametrize("dtype, kind, policy, tick, audio, model", CASES)
def test_wasm_single_precision_within_derived_bounds(single_module, dtype, kind, policy, tick, audio, model):
    table, r, x, y, img = case_setup(dtype, kind, policy, tick, audio, model, seconds=0.12)
    po, pa, pt, pA = py_render_events(r, x, y)
    co, ca, (cclip, cev, cdrop, cfault), ct, cA = wasm_play_events(WasmRunner(single_module), img, r, x, y)
    assert len(pt) > 10 and cev == len(pt) and cdrop == 0 and ca.size == pa.size
    assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA)
