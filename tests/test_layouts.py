"""Engine layouts: one definition (numpy dtypes) for the binding's views, ctypes and the C structs; the header current."""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.render import codegen, layouts, renderer
from shapedisplay.render.layouts import BURST_POLICIES, LAYOUTS, SLOTS, ctypes_struct
from shapedisplay.render.models import MODEL_IDS, MODELS

CDIR = Path(layouts.__file__).resolve().parent.parent / "engine"


def _cc():
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


def _members(dt: np.dtype, prefix=""):
    """(member path, offset, size) of every field of ``dt``, nested structs included, in bytes."""
    out = []
    for name in dt.names:
        sub, off = dt.fields[name][:2]
        out.append((prefix + name, off, sub.itemsize))
        if sub.names:
            out += [(p, off + o, s) for p, o, s in _members(sub, prefix + name + ".")]
    return out


def test_generated_header_is_current():
    """engine/sd_layout.h is what `make generate` writes from the layouts and the model registry."""
    assert codegen.stale_files() == []


def test_layouts_are_packed_like_c_structs():
    for name, (dt, _) in LAYOUTS.items():
        assert dt.isalignedstruct, name
        for path, off, size in _members(dt):
            assert off % min(size, 8) == 0, (name, path)


@pytest.mark.parametrize("name", list(LAYOUTS))
def test_ctypes_view_matches_dtype(name):
    dt, cname = LAYOUTS[name]
    cls = ctypes_struct(dt)
    assert cls.__name__ == cname and ctypes.sizeof(cls) == dt.itemsize
    for path, off, size in _members(dt):
        obj, base = cls, 0
        for part in path.split("."):
            desc = getattr(obj, part)
            base += desc.offset
            obj = dict(obj._fields_)[part]
        assert (base, ctypes.sizeof(obj)) == (off, size), (name, path)
    rec = layouts.record(dt)
    assert len(bytes(cls.from_buffer_copy(rec.tobytes()))) == dt.itemsize


def test_c_structs_and_enums_match_python(tmp_path):
    """A C program prints sizeof/offsetof of every member and every shared enum; they equal the Python side."""
    cc = _cc()
    if cc is None:
        pytest.skip("no C compiler (cc/gcc/clang)")
    lines = ['#include <stddef.h>', '#include <stdio.h>', '#include "sd_runtime.h"', "int main(void)", "{"]
    for name, (dt, cname) in LAYOUTS.items():
        lines.append(f'    printf("{cname} . 0 %zu\\n", sizeof({cname}));')
        for path, _, _ in _members(dt):
            lines.append(f'    printf("{cname} {path} %zu %zu\\n", offsetof({cname}, {path}), '
                         f'sizeof((({cname} *)0)->{path}));')
    lines.append('    printf("sd_table_t grid %zu %zu\\n", offsetof(sd_table_t, grid), sizeof(sd_grid_t));')
    for model in MODELS:
        lines.append(f'    printf("enum model_{model} %d\\n", (int)SD_MODEL_{model.upper()});')
    lines.append('    printf("enum nmodel %d\\n", (int)SD_NMODEL);')
    for pol in BURST_POLICIES:
        lines.append(f'    printf("enum policy_{pol} %d\\n", (int)SD_{pol.upper()});')
    for slot in SLOTS:
        lines.append(f'    printf("enum slot_{slot} %d\\n", (int)SD_SLOT_{slot.upper()});')
    lines.append('    printf("enum nslot %d\\n", (int)SD_NSLOT);')
    for model in MODELS:           # every model of the registry has its C tick under its own id
        lines.append(f'    printf("tick {model} %d\\n", sd_model_tick(SD_MODEL_{model.upper()}) == sd_{model}_tick);')
    lines += ["    return 0;", "}"]
    src = tmp_path / "layout_probe.c"
    src.write_text("\n".join(lines) + "\n")
    exe = tmp_path / "layout_probe"
    cmd = [cc, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-I", str(CDIR), str(src),
           *(str(p) for p in sorted(CDIR.glob("sd_*.c")) if p.name != "sd_wasm.c"), "-lm", "-o", str(exe)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    got = {}
    enums = {}
    for line in subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.splitlines():
        kind, key, *vals = line.split()
        if kind == "enum" or kind == "tick":
            enums[(kind, key)] = int(vals[0])
        else:
            got[(kind, key)] = tuple(int(v) for v in vals)
    for name, (dt, cname) in LAYOUTS.items():
        assert got[(cname, ".")] == (0, dt.itemsize), f"sizeof({cname})"
        for path, off, size in _members(dt):
            assert got[(cname, path)] == (off, size), f"{cname}.{path}: C (offset, size) vs {name}"
    assert got[("sd_table_t", "grid")] == (0, layouts.GRID.itemsize)
    assert {m: enums[("enum", f"model_{m}")] for m in MODELS} == MODEL_IDS
    assert enums[("enum", "nmodel")] == len(MODELS)
    assert {p: enums[("enum", f"policy_{p}")] for p in BURST_POLICIES} == BURST_POLICIES
    assert [enums[("enum", f"slot_{s}")] for s in SLOTS] == list(range(len(SLOTS)))
    assert enums[("enum", "nslot")] == len(SLOTS)
    assert {m: enums[("tick", m)] for m in MODELS} == {m: 1 for m in MODELS}


def test_model_ids_are_registry_positions():
    assert list(MODEL_IDS.values()) == list(range(len(MODELS)))
    for name, cls in MODELS.items():
        assert cls().model_id == MODEL_IDS[name]


def test_policy_and_slot_numbers_shared_with_c():
    assert [int(layouts.Policy[p.upper()]) for p in BURST_POLICIES] == list(BURST_POLICIES.values())
    assert [int(layouts.Slot[s.upper()]) for s in SLOTS] == list(range(len(SLOTS)))
    assert renderer.OUT_NAMES == layouts.OUTPUTS.names


def test_javascript_wrapper_numbers_models_policies_and_outputs_as_c():
    """sd_wasm.js passes model and policy numbers to the WebAssembly build and names its outputs."""
    import json
    import re
    from shapedisplay.render.native import C_MODELS
    js = (CDIR / "wasm" / "sd_wasm.js").read_text()

    def const(name):
        body = re.search(rf"export const {name} = (\{{.*?\}}|\[.*?\]);", js, re.S).group(1)
        return json.loads(re.sub(r"(\w+):", r'"\1":', body) if body.startswith("{") else body)
    assert const("MODELS") == {m: MODEL_IDS[m] for m in C_MODELS}
    assert const("POLICIES") == BURST_POLICIES
    assert tuple(const("OUT_NAMES")) == layouts.OUTPUTS.names
    assert tuple(const("EVENT_KINDS")) == layouts.EVENT_KINDS
    assert tuple(const("REACT_STATE_FIELDS")) == layouts.REACT_STATE.names
