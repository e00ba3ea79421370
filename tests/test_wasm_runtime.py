"""The WebAssembly build (engine/wasm/sd_runtime.wasm) in wasmtime on the shared vectors.

The module links wasi-libc's libm (musl), not glibc's: exp/sin/cos may differ by an ulp, so
the comparison is by the derived bounds of runtime_vectors.derived_bounds (event counts and
stick/slip states must match exactly).
"""
import shutil
import subprocess

import numpy as np
import pytest

from shapedisplay.render import Renderer, wasm
from shapedisplay.render.layouts import OUTPUTS
from shapedisplay.render.models import MODEL_IDS

from runtime_vectors import (CASES, REACT_CASES, WasmRunner, assert_same_reactions, assert_within_derived_bounds,
                             assert_within_float_bounds, case_setup, derived_bounds, py_render_events,
                             py_render_reactions, react_setup, wasm_play_events, wasm_play_reactions)
from test_c_runtime import CDIR, py_render

pytest.importorskip("wasmtime", reason="wasmtime (pip install 'shapedisplay[test]') runs the WebAssembly tests")


def test_shipped_module_is_built_from_the_shipped_sources():
    assert wasm.MODULE.is_file() and wasm.WRAPPER.is_file() and wasm.WORKLET.is_file()
    assert wasm.is_current(), ("engine/wasm/sd_runtime.wasm is older than the C sources: "
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


def _pad_block(runner, block) -> None:
    """Write a PAD_PARAMS block (doubles, field order) where sd_wasm_pad_block says."""
    ptr = runner.call("sd_wasm_pad_block", len(block))
    assert ptr and ptr % 8 == 0
    runner.write(ptr, np.asarray(block, "<f8").tobytes())


@pytest.mark.parametrize("model", ["karnopp", "stribeck"])
def test_wasm_plays_models_from_the_pad_block(model):
    """karnopp and stribeck read pad fields the image does not carry: configured with the block the studio
    sends (studio.wasm.model_blocks), the module plays as the host C runtime (Renderer) does; without one,
    or with a damaged one, configure refuses and the playing model stays."""
    from shapedisplay.render.cursor import CursorPath
    from shapedisplay.render.layouts import PAD_PARAMS
    from shapedisplay.studio.wasm import model_blocks
    import base64
    table, r, x, y, img = case_setup("uint16", "teleports", "retrigger", 10_000.0, 48_000.0, model, seconds=0.2)
    block = np.frombuffer(base64.b64decode(model_blocks(r.device)[model]["pad"]), "<f8").copy()
    assert block.size == len(PAD_PARAMS.names)
    w = WasmRunner(wasm.MODULE)
    assert w.load(img) == 0
    mid, jump = MODEL_IDS[model], MODEL_IDS["jump"]
    assert w.call("sd_wasm_configure", mid, 0, 10_000.0, 48_000.0) == -1        # the image has no such block
    assert w.call("sd_wasm_pad_block", block.size - 1) == 0                      # a block of another length
    for i, bad in ((0, np.nan), (PAD_PARAMS.names.index("stribeck_variant"), 0.5)):
        damaged = block.copy()
        damaged[i] = bad
        _pad_block(w, damaged)
        assert w.call("sd_wasm_configure", mid, 0, 10_000.0, 48_000.0) == -3
    _pad_block(w, block)
    assert w.call("sd_wasm_configure", mid, 0, 10_000.0, 48_000.0) == 0
    assert w.call("sd_wasm_configure", mid, 1, 10_000.0, 48_000.0) == 0          # the block stays for its model
    assert w.call("sd_wasm_configure", jump, 0, 10_000.0, 48_000.0) == 0         # exact, jump: no block needed
    assert w.call("sd_wasm_configure", mid, 0, 10_000.0, 48_000.0) == 0
    assert w.load(img) == 0                                                      # a swap keeps model and block
    w.call("sd_wasm_reset", 0.0)
    f, st, ev = [], [], 0
    for xi, yi in zip(x, y):
        w.call("sd_wasm_step", float(xi), float(yi))
        o = np.frombuffer(w.read(w.call("sd_wasm_outputs"), OUTPUTS.itemsize), OUTPUTS)[0]
        f.append(o["friction_force"])
        st.append(o["state"])
        ev += int(o["events"])
    ref = r.render(CursorPath(np.arange(len(x)) / 10_000.0, x, y, 10_000.0))
    exact = Renderer(table, model="exact").render(CursorPath(np.arange(len(x)) / 10_000.0, x, y, 10_000.0))
    assert ev == ref.event_time.size and ev >= 3 and np.array_equal(st, ref.state)
    assert np.max(np.abs(np.array(f) - ref.friction_force)) <= 1e-9          # musl's libm against glibc's
    assert np.max(np.abs(np.array(f) - exact.friction_force)) > 1e-2               # not exact's friction


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


@pytest.mark.parametrize("name, stroke, model, tick, audio", REACT_CASES)
def test_wasm_plays_the_reaction_vectors(name, stroke, model, tick, audio):
    """The shipped module with a press per tick (sd_wasm_step_press): the same reaction events as the host
    engine (kind, widget, tick, value), outputs within the derived bounds of another libm."""
    table, r, x, y, press, img = react_setup(name, stroke, model, tick, audio)
    po, pa, pt, pA, prev = py_render_reactions(r, x, y, press)
    co, ca, (cclip, cev, cdrop, cfault), ct, cA, crev = wasm_play_reactions(WasmRunner(wasm.MODULE), img, r, x, y,
                                                                          press)
    assert cev == len(pt) and cdrop == 0 and ca.size == pa.size
    assert_same_reactions(crev, prev)
    assert_within_derived_bounds(r, po, pa, co, ca)


@pytest.mark.parametrize("name, stroke, model, tick, audio", REACT_CASES)
def test_wasm_single_precision_plays_the_reaction_vectors(single_module, name, stroke, model, tick, audio):
    table, r, x, y, press, img = react_setup(name, stroke, model, tick, audio)
    po, pa, pt, pA, prev = py_render_reactions(r, x, y, press)
    co, ca, (cclip, cev, cdrop, cfault), ct, cA, crev = wasm_play_reactions(WasmRunner(single_module), img, r, x, y,
                                                                          press)
    assert cev == len(pt) and cdrop == 0 and ca.size == pa.size
    assert_same_reactions(crev, prev, value_tol=1e-5)
    assert_within_float_bounds(r, table, x, y, po, pa, pt, pA, co, ca, ct, cA)
