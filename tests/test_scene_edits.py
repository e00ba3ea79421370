"""The studio's scene edits without a browser: format-preserving operations, the undo history, merges,
and the per-widget lines of ``shapedisplay diff``."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("tomlkit")

from shapedisplay.errors import InputError, ShapeDisplayError  # noqa: E402
from shapedisplay.studio.edits import apply_ops, merge3, version_of  # noqa: E402
from shapedisplay.studio.scenefile import Conflict, SceneFile  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PHONE = ROOT / "assets" / "scenes" / "phone.toml"


@pytest.fixture
def scene(tmp_path):
    p = tmp_path / "phone.toml"
    p.write_bytes(PHONE.read_bytes())
    return p


def diff_lines(a: str, b: str) -> list:
    import difflib
    return [ln for ln in difflib.unified_diff(a.splitlines(), b.splitlines(), n=0, lineterm="")
            if ln[:1] in "+-" and not ln.startswith(("+++", "---"))]


@pytest.mark.parametrize("ops, expected", [
    ([{"op": "box", "widget": "app-1", "d": [3.2, -2.1, 3.2, -2.1]}],
     ['-position = "5,118 mm"', '+position = "8,116 mm"']),
    ([{"op": "box", "widget": "app-1", "d": [0, 0, 4, 0]}], ['-size = "20x20 mm"', '+size = "24x20 mm"']),
    ([{"op": "box", "widget": "frame", "d": [2, -1, 2, -1]}],
     ['-from = "4,152 mm"', '-to = "76,152 mm"', '+from = "6,151 mm"', '+to = "78,151 mm"']),
    ([{"op": "box", "widget": "frame", "d": [0, -1, 0, 1]}], ['-width = "2 mm"', '+width = "4 mm"']),
    ([{"op": "set", "widget": "volume", "key": "value", "value": 0.7}],
     ['-value = 0.4                 # thumb at 40 %', '+value = 0.7                 # thumb at 40 %']),
    ([{"op": "set", "widget": "call", "key": "height", "value": "1 mm"}],
     ['-force = "3.5 N"             # plateau force (flat ground is 1 N)', '+height = "1 mm"']),
])
def test_operations_change_only_their_values(scene, ops, expected):
    text = scene.read_text()
    out, _ = apply_ops(text, ops, scene)
    assert diff_lines(text, out) == expected


def test_add_duplicate_delete_are_whole_entries(scene):
    text = scene.read_text()
    out, sel = apply_ops(text, [{"op": "add", "type": "slider"}], scene)
    assert sel == "slider-1" and out.startswith(text) and out.endswith('size = "60x12 mm"\n')
    out, sel = apply_ops(text, [{"op": "duplicate", "widget": "app-3"}], scene)
    import tomllib
    ids = [w["id"] for w in tomllib.loads(out)["widget"]]
    assert sel == "app-7" and ids[3:5] == ["app-3", "app-7"]
    assert tomllib.loads(out)["widget"][4]["position"] == "60,113 mm"
    out, _ = apply_ops(text, [{"op": "delete", "widget": "home"}], scene)
    assert out == text.split("# ---- home")[0]


def test_entries_are_found_past_values_over_several_lines(tmp_path):
    import shutil
    import tomllib
    for f in (ROOT / "assets" / "scenes").iterdir():
        if f.is_file():
            shutil.copy(f, tmp_path / f.name)
    scene = tmp_path / "map.toml"                 # the rainfall layer's `values` spans three lines
    text = scene.read_text()
    before = tomllib.loads(text)["widget"]
    out, _ = apply_ops(text, [{"op": "delete", "widget": "rainfall"}], scene)
    assert tomllib.loads(out)["widget"] == [w for w in before if w["id"] != "rainfall"]
    out, sel = apply_ops(text, [{"op": "duplicate", "widget": "rainfall"}], scene)
    after = tomllib.loads(out)["widget"]
    assert sel == "rainfall-1" and after[-1]["values"] == before[-1]["values"] and len(after) == len(before) + 1


def test_a_change_that_breaks_a_rule_is_refused_with_the_loaders_message(scene):
    with pytest.raises(InputError, match=r"`widget\[9\]\.ramp` must be a length > 0"):
        apply_ops(scene.read_text(), [{"op": "set", "widget": "call", "key": "ramp", "value": "-1 mm"}], scene)
    with pytest.raises(InputError, match="no widget 'nope'"):
        apply_ops(scene.read_text(), [{"op": "delete", "widget": "nope"}], scene)


def test_undo_redo_restore_exact_bytes_and_the_history_outlives_the_object(scene, tmp_path):
    out = tmp_path / "out"
    original = scene.read_bytes()
    sf = SceneFile(scene, out)
    sf.sync()
    v1 = sf.edit(version_of(original), [{"op": "box", "widget": "app-1", "d": [5, 0, 5, 0]}], "move")["version"]
    moved = scene.read_bytes()
    v2 = sf.save_text(v1, scene.read_text().replace("level = 3 ", "level = 4 "))["version"]
    with pytest.raises(ShapeDisplayError, match="invalid TOML"):
        sf.save_text(v2, "[canvas\n")
    sf.flush()                                        # (the studio flushes after each change)
    sf2 = SceneFile(scene, out)                       # a restart: the history is read back
    assert [s["label"] for s in sf2.history.listing()["steps"]] == ["move", "text edit"]
    v = sf2.undo(v2)["version"]
    assert scene.read_bytes() == moved
    sf2.undo(v)
    assert scene.read_bytes() == original
    sf2.redo(version_of(original))
    assert scene.read_bytes() == moved


def test_a_stale_version_is_a_conflict_and_nothing_is_written(scene, tmp_path):
    sf = SceneFile(scene, tmp_path / "out")
    sf.sync()
    base = version_of(scene.read_bytes())
    external = scene.read_text().replace('force = "3.5 N"', 'force = "3 N"')
    scene.write_text(external)
    with pytest.raises(Conflict) as exc:
        sf.edit(base, [{"op": "set", "widget": "volume", "key": "value", "value": 0.6}], "value")
    assert scene.read_text() == external
    c = exc.value.payload()
    assert c["disk"] == external and "value = 0.6" in c["mine"]
    r = sf.resolve("merge", base, c["mine"], c["disk_version"])
    assert r["conflicts"] == [] and scene.read_text() == external.replace("value = 0.4 ", "value = 0.6 ")
    assert sf.history.listing()["steps"][0]["label"] == "changed outside the studio"


def test_merge3_keeps_the_disk_where_both_changed_a_line():
    base = "a = 1\nb = 2\nc = 3\n"
    merged, conflicts = merge3(base, "a = 10\nb = 2\nc = 30\n", "a = 1\nb = 2\nc = 31\n")
    assert merged == "a = 10\nb = 2\nc = 31\n" and conflicts[0]["line"] == 3


def test_diff_prints_per_widget_lines(tmp_path):
    b = tmp_path / "b.toml"
    b.write_text(PHONE.read_text().replace('force = "3.5 N"', 'force = "1.5 N"').replace('ramp = "5 mm"', 'ramp = "7 mm"')
                 .replace('position = "55,118 mm"', 'position = "59,118 mm"'))
    for src, name in ((PHONE, "a.npz"), (b, "b.npz")):
        r = subprocess.run([sys.executable, "-m", "shapedisplay", "compile", str(src), "-o", str(tmp_path / name)],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-m", "shapedisplay", "diff", str(tmp_path / "a.npz"), str(tmp_path / "b.npz")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1
    lines = r.stdout.splitlines()
    widgets = lines[lines.index("widgets:") + 1:lines.index("widgets:") + 3]
    assert widgets == ["  app-3: moved 4 mm right",
                       "  call: normal force 3.5 → 1.5 N (height 2.5 → 0.5 mm), ramp 5 → 7 mm"]


def _top_left_phone() -> str:
    """The phone scene written with y down from the top edge: the same table."""
    import re
    import tomllib
    text = PHONE.read_text().replace('[canvas]\n', '[canvas]\norigin = "top-left"\n', 1)
    for w in tomllib.loads(PHONE.read_text())["widget"]:
        if "position" in w:
            x, y = (float(v) for v in w["position"].split(" ")[0].split(","))
            h = float(w["size"].split(" ")[0].split("x")[1])
            text = text.replace(f'position = "{w["position"]}"', f'position = "{x:g},{160 - y - h:g} mm"')
        for k in ("from", "to"):
            if k in w:
                x, y = (float(v) for v in w[k].split(" ")[0].split(","))
                text = re.sub(rf'^{k} = "{re.escape(w[k])}"', f'{k} = "{x:g},{160 - y:g} mm"', text, flags=re.M)
    return text


def test_canvas_origin_top_left_reads_y_down_and_the_studio_writes_it_so(tmp_path):
    import numpy as np

    from shapedisplay.author.scene import compile_scene
    scene = tmp_path / "phone.toml"
    scene.write_text(_top_left_phone())
    a, b = compile_scene(PHONE).table, compile_scene(scene).table
    assert np.array_equal(a.dense("normal_force"), b.dense("normal_force"))
    text = scene.read_text()
    assert 'position = "5,22 mm"' in text                        # app-1: its top-left corner, 22 mm from the top
    out, _ = apply_ops(text, [{"op": "box", "widget": "app-1", "d": [1, 2, 1, 2]}], scene)   # right 1, up 2
    assert diff_lines(text, out) == ['-position = "5,22 mm"', '+position = "6,20 mm"']
    out, _ = apply_ops(text, [{"op": "box", "widget": "app-1", "d": [0, -3, 0, 0]}], scene)  # bottom edge down 3
    assert diff_lines(text, out) == ['-size = "20x20 mm"', '+size = "20x23 mm"']
    out, _ = apply_ops(text, [{"op": "box", "widget": "frame", "d": [0, 1, 0, 1]}], scene)   # the ridge up 1
    assert diff_lines(text, out) == ['-from = "4,8 mm"', '-to = "76,8 mm"', '+from = "4,7 mm"', '+to = "76,7 mm"']
    with pytest.raises(InputError, match="canvas.origin"):
        apply_ops(text.replace('"top-left"', '"top-right"'), [{"op": "delete", "widget": "home"}], scene)


def test_the_inspector_offers_the_reaction_keys_and_they_write_as_the_loader_reads_them(scene):
    """press, click, movable and motion (docs/reactive.md) are in the inspector of every type that takes them
    (a toggle or slider never moves), and a set writes them as values the scene loader accepts."""
    from shapedisplay.author.scene import load_scene
    from shapedisplay.studio.inspector import schema
    s = schema()
    keys = {t: {k["key"]: k for k in s[t]["keys"]} for t in s}
    for t in ("button", "dent", "image"):
        assert {"press", "click", "movable", "motion"} <= set(keys[t]), t
    for t in ("toggle", "slider"):
        assert {"press", "click"} <= set(keys[t]) and not {"movable", "motion"} & set(keys[t]), t
    assert keys["button"]["press"]["unit"] == "N" and keys["button"]["movable"]["choices"] == ("true", "false")
    text = scene.read_text()
    new, _ = apply_ops(text, [{"op": "set", "widget": "call", "key": "press", "value": "3 N release 1.5 N"},
                              {"op": "set", "widget": "call", "key": "movable", "value": True},
                              {"op": "set", "widget": "call", "key": "click", "value": "burst 0.4 8ms"}], scene)
    added = [ln for ln in diff_lines(text, new) if ln.startswith("+")]
    assert sorted(added) == ['+click = "burst 0.4 8ms"', '+movable = true', '+press = "3 N release 1.5 N"']
    scene.write_text(new)
    r = load_scene(scene).reactions["call"]
    assert (r["press_n"], r["release_n"]) == (3.0, 1.5) and r["kind"] == "object", r
