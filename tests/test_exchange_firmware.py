"""The C header export is enough on its own: toggles, widget map, every runtime constant.

The phone scene's header compiles strictly (C99, -Wall -Wextra -pedantic
-Werror); the C runtime, bound from the header alone (no -D flags), plays
both states of the Wi-Fi toggle bit for bit as the host's Renderer plays
the table switched with ``select_state`` (the header and its toggle switch
carry everything the image does); the JSON export carries the same
states and widget map.
"""
import json
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.table.widgets import toggle_states, widget_map
from shapedisplay.exchange.export import c_header, export_c, export_json
from shapedisplay.render.renderer import Renderer
from shapedisplay.author.scene import compile_scene
from shapedisplay.author.scene.compiler import select_state

ROOT = Path(__file__).resolve().parent.parent
CDIR = ROOT / "shapedisplay" / "engine"
STRICT = ["-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-ffp-contract=off"]


def _cc():
    import os
    import shutil
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    pytest.fail("no C compiler (cc/gcc/clang) found")


@pytest.fixture(scope="module")
def phone():
    return compile_scene(ROOT / "assets" / "scenes" / "phone.toml").table


@pytest.fixture(scope="module")
def phone_player(phone, tmp_path_factory):
    d = tmp_path_factory.mktemp("phone-header")
    header = export_c(phone, d / "phone.h", name="sd_table")
    exe = d / "sd_play_header"
    cmd = [_cc(), *STRICT, f'-DSD_TABLE_HEADER="{header}"', "-I", str(CDIR), str(CDIR / "tool_play_header.c"),
           *(str(p) for p in sorted(CDIR.glob("sd_*.c")) if p.name != "sd_wasm.c"), "-lm", "-o", str(exe)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr
    return exe, header


def test_phone_header_alone_compiles_strictly(phone, tmp_path):
    """Header alone and header after sd_runtime.h (the binding): no warning under -pedantic -Werror."""
    h = tmp_path / "phone.h"
    export_c(phone, h, name="phone")
    for pre in ("", '#include "sd_runtime.h"\n'):
        src = tmp_path / "use.c"
        src.write_text(pre + '#include "phone.h"\nint main(void) { return phone_widget_at(0.06, 0.036) == '
                             'PHONE_WIDGET_WIFI ? 0 : 1; }\n')
        exe = tmp_path / "use"
        res = subprocess.run([_cc(), *STRICT, "-I", str(CDIR), "-I", str(tmp_path), str(src), "-o", str(exe)],
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        assert subprocess.run([str(exe)]).returncode == 0   # hit-test finds the toggle's knob


def _play(exe, x, y, tmp_path, *toggle):
    fin, fout = tmp_path / "in", tmp_path / "out"
    fin.write_bytes(struct.pack("<q", x.size) + np.asarray(x, "<f8").tobytes() + np.asarray(y, "<f8").tobytes())
    res = subprocess.run([str(exe), "48000", str(fin), str(fout), *map(str, toggle)],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    raw = fout.read_bytes()
    drive = np.frombuffer(raw[:8 * x.size], "<f8")
    (na,) = struct.unpack_from("<q", raw, 8 * x.size)
    return drive, np.frombuffer(raw[8 * x.size + 8:], "<f8")


@pytest.mark.parametrize("state", ["off", "on"])
def test_c_runtime_plays_both_toggle_states_from_the_header_alone(phone, phone_player, tmp_path, state):
    exe, header = phone_player
    text = header.read_text()
    idx = {"off": int(text.split("#define SD_TABLE_TOGGLE_WIFI_OFF ")[1].split()[0]),
           "on": int(text.split("#define SD_TABLE_TOGGLE_WIFI_ON ")[1].split()[0])}
    toggle = int(text.split("#define SD_TABLE_TOGGLE_WIFI ")[1].split()[0])
    # a stroke across the toggle (x 54..78 mm, y 30..42 mm) at 40 mm/s, 10 kHz ticks
    n = 6000
    x = np.linspace(0.050, 0.080, n)
    y = np.full(n, 0.036)
    table = select_state(phone, "wifi", state)
    r = Renderer(table, model="jump", audio_rate=48_000.0)
    assert r.tick_rate == 10_000.0
    drive_py = np.array([r.step(float(a), float(b)) for a, b in zip(x, y)])
    r.reset()
    audio_py = []
    for a, b in zip(x, y):
        r.step(float(a), float(b))
        audio_py.append(r.audio_block[:int(r.last["audio_samples"])].copy())
    drive_c, audio_c = _play(exe, x, y, tmp_path, toggle, idx[state])
    assert r.event_count > 20
    np.testing.assert_array_equal(drive_c, drive_py)
    np.testing.assert_array_equal(audio_c, np.concatenate(audio_py))


def test_toggle_states_differ_and_switching_changes_only_the_block_offset(phone):
    ts = toggle_states(phone)
    assert [t["id"] for t in ts] == ["wifi"]
    t = ts[0]
    assert t["state"] == "off" and [s["name"] for s in t["states"]] == ["off", "on"]
    offsets = phone.patch_offsets()
    for s in t["states"]:
        assert s["offset"] == offsets[s["patch"]]
    on, off = select_state(phone, "wifi", "on"), select_state(phone, "wifi", "off")
    assert not np.array_equal(on.dense("normal_force"), off.dense("normal_force"))
    assert [b for i, b in enumerate(on.blocks) if i != t["block"]] == \
           [b for i, b in enumerate(off.blocks) if i != t["block"]]


def test_header_carries_every_runtime_constant(phone):
    h = c_header(phone, "t")
    for name in ("pad_mass_kg", "pad_stiffness_n_per_m", "pad_damping_ns_per_m", "mu_s", "mu_k", "burst_gain",
                 "max_stick_period_s", "tick_rate_hz", "audio_rate_hz", "burst_carrier_hz", "burst_rise_s",
                 "burst_decay_s", "skin_target_m"):
        assert f"static const double t_{name} = " in h
    assert "static const double t_slope_friction_gain = 0.2;" in h     # the phone's K_mu, no -D needed
    assert "#define T_NORMAL_FORCE_DTYPE SD_U" in h


def test_widget_map_matches_the_scene_and_json_carries_it(phone, tmp_path):
    wm = widget_map(phone)
    ids = [w["id"] for w in wm]
    assert ids[:2] == ["frame", "app-1"] and "wifi" in ids and len(ids) == 11
    wifi = wm[ids.index("wifi")]
    assert wifi["type"] == "toggle" and wifi["toggle"] == 0
    assert wifi["bbox_m"] == pytest.approx([0.054, 0.030, 0.078, 0.042])
    # the block of every widget covers its bounding box centre on the canvas
    g = phone.grid
    for w in wm:
        (b,) = w["blocks"]
        r0, c0, p = phone.blocks[b]
        rows, cols = phone.patch_shapes[p]
        cx, cy = (w["bbox_m"][0] + w["bbox_m"][2]) / 2, (w["bbox_m"][1] + w["bbox_m"][3]) / 2
        c, r = round((cx - g.x0) / g.dx), round((cy - g.y0) / g.dy)
        assert r0 <= r < r0 + rows and c0 <= c < c0 + cols, w["id"]
    doc = json.loads(export_json(phone, tmp_path / "p.json").read_text())
    assert [w["id"] for w in doc["widgets"]] == ids
    (tj,) = doc["toggles"]
    on = select_state(phone, "wifi", "on")
    r0, c0, p = on.blocks[tj["block"]]
    rows, cols = on.patch_shapes[p]
    got = np.array(tj["states"][1]["channels"]["normal_force"])
    np.testing.assert_array_equal(got, on.dense("normal_force")[r0:r0 + rows, c0:c0 + cols])


REACT_PLAYER_C = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "sd_runtime.h"
#include "react.h"
static sd_renderer_t R;
static int32_t blocks[SD_TABLE_N_BLOCKS][5];
int main(int argc, char **argv)
{
    sd_table_t T;
    sd_config_t C;
    sd_react_event_t e;
    FILE *in = fopen(argv[1], "rb"), *out = fopen(argv[2], "wb");
    long long n, i;
    double xyp[3];
    (void)argc;
    sd_table_bind(&T, &C, blocks);
    C.audio_rate = 48000.0;
    if (sd_renderer_init(&R, &T, &C) != SD_OK || !in || !out || fread(&n, 8, 1, in) != 1) return 2;
    for (i = 0; i < n; i++) {
        double d;
        if (fread(xyp, 8, 3, in) != 3) return 2;
        d = sd_renderer_step_press(&R, xyp[0], xyp[1], xyp[2]);
        fwrite(&d, 8, 1, out);
        while (sd_react_pop(&R, &e)) fprintf(stderr, "%lld %lld %lld %.17g\n", (long long)e.kind, (long long)e.widget,
                                             (long long)e.tick, (double)e.value);
    }
    /* the states the header names */
    fprintf(stderr, "toggle %g thumb %.17g\n", (double)R.react.state[SD_TABLE_REACT_TOGGLE].state,
            (double)R.react.state[SD_TABLE_REACT_SLIDER].thumb);
    return fclose(out) == 0 ? 0 : 2;
}
"""


def test_reactive_header_plays_reactions_as_the_package(tmp_path):
    """The bundled reactive scene's header: the engine bound from it alone (sd_table_bind: the reactive widgets'
    records, NAME_REACT_<ID> to read their states by) presses, flips, drags as ``Renderer`` does: the same
    events, drive bit for bit, the toggle's and thumb's final states."""
    from shapedisplay.render.cursor import parse_stroke
    from shapedisplay.render.layouts import EVENT_KINDS
    table = compile_scene(ROOT / "assets" / "scenes" / "reactive.toml").table
    export_c(table, tmp_path / "react.h", name="sd_table")
    (tmp_path / "play.c").write_text(REACT_PLAYER_C)
    exe = tmp_path / "play"
    cmd = [_cc(), *STRICT, "-I", str(CDIR), "-I", str(tmp_path), str(tmp_path / "play.c"),
           *(str(p) for p in sorted(CDIR.glob("sd_*.c")) if p.name != "sd_wasm.c"), "-lm", "-o", str(exe)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr
    r = Renderer(table, model="jump", tick_rate=table.meta.get("tick_rate_hz", 10_000.0), audio_rate=48_000.0)
    cp = parse_stroke("20,20 -> 20,20.5 @ 50mm/s; press 3N 20ms; -> 60,20 @ 300mm/s; press 3N 20ms; "
                      "-> 14,45 @ 300mm/s; press 3N 10ms; -> 40,45 @ 170mm/s press 3N; press 0N 10ms", r.tick_rate)
    data = struct.pack("<q", cp.t.size) + np.stack([cp.x, cp.y, cp.press], 1).astype("<f8").tobytes()
    (tmp_path / "in").write_bytes(data)
    res = subprocess.run([str(exe), str(tmp_path / "in"), str(tmp_path / "out")], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr
    lines = res.stderr.strip().splitlines()
    r.reset()
    drive = np.array([r.step(x, y, p) for x, y, p in zip(cp.x, cp.y, cp.press)])
    np.testing.assert_array_equal(np.frombuffer((tmp_path / "out").read_bytes(), "<f8"), drive)
    want = r.render(cp)
    ids = [w["id"] for w in table.meta["scene"]["widgets"]]
    got = [ln.split() for ln in lines[:-1]]
    assert [EVENT_KINDS[int(g[0]) - 1] for g in got] == list(want.event_kind)
    assert [ids[int(g[1])] for g in got] == list(want.event_widget)
    np.testing.assert_array_equal([int(g[2]) / r.tick_rate for g in got], want.event_t)
    states = r.widget_states()
    assert lines[-1] == f"toggle {states['toggle']['state']:g} thumb {states['slider']['thumb']:.17g}"
    assert states["toggle"]["state"] == 1.0
