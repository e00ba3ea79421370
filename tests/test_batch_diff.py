"""Batch compile (compile A B C -o DIR/) and diff A.npz B.npz."""
import json
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.table.diff import diff_tables
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
from shapedisplay.cli.main import main

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "assets" / "scenes"


def test_batch_compiles_each_source_into_the_folder_with_one_summary(tmp_path, capsys):
    out = tmp_path / "tables"
    code = main(["compile", str(SCENES / "phone.toml"), str(SCENES / "keypad.toml"), "-o", f"{out}/"])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    assert sorted(p.name for p in out.iterdir()) == ["keypad.npz", "phone.npz"]
    assert "compiled 2 of 2 sources" in cap.out and cap.out.count("ok") >= 2
    # each table is what a single compile writes (same checksum)
    assert main(["compile", str(SCENES / "phone.toml"), "-o", str(tmp_path / "single.npz"), "-q"]) == 0
    assert FrictionTable.load(out / "phone.npz").checksum == FrictionTable.load(tmp_path / "single.npz").checksum


def test_batch_keeps_going_past_a_bad_source_and_fails_at_the_end(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[scene]\nname = 'x'\n")
    code = main(["compile", str(bad), str(SCENES / "keypad.toml"), "-o", str(tmp_path / "o") + "/", "--json"])
    cap = capsys.readouterr()
    assert code == 2
    rows = json.loads(cap.out)
    assert "error" in rows[0] and rows[1]["output"].endswith("keypad.npz")
    assert (tmp_path / "o" / "keypad.npz").exists() and not (tmp_path / "o" / "bad.npz").exists()
    assert "shapedisplay compile: error:" in cap.err and "Traceback" not in cap.err


def test_batch_refuses_before_compiling_anything(tmp_path, capsys):
    a = tmp_path / "a" / "phone.toml"
    a.parent.mkdir()
    a.write_text((SCENES / "phone.toml").read_text())
    out = tmp_path / "o"
    code = main(["compile", str(a), str(SCENES / "phone.toml"), "-o", f"{out}/"])
    assert code == 2 and "would both be written" in capsys.readouterr().err
    assert not out.exists()
    code = main(["compile", str(SCENES / "phone.toml"), str(tmp_path / "missing.toml"), "-o", f"{out}/"])
    assert code == 2 and "missing.toml" in capsys.readouterr().err and not out.exists()
    f = tmp_path / "file.npz"
    f.write_bytes(b"x")
    code = main(["compile", str(SCENES / "phone.toml"), str(SCENES / "keypad.toml"), "-o", str(f)])
    assert code == 2 and "must be a folder" in capsys.readouterr().err and f.read_bytes() == b"x"


def _t(nf, meta=None, dtype="float64"):
    g = Grid(nf.shape[0], nf.shape[1], 0.5e-3, 0.5e-3)
    return FrictionTable.from_dense(g, {"normal_force": nf}, {"normal_force": choose_quantization(nf, dtype)},
                                    meta or {"mapping": {"n_base": 0.5}})


def test_diff_names_the_largest_difference_and_where(tmp_path, capsys):
    a = np.full((10, 20), 0.5)
    b = a.copy()
    b[3, 7] += 0.25
    b[6, 2] += 0.1
    d = diff_tables(_t(a), _t(b, {"mapping": {"n_base": 0.6}}))
    c = d["channels"]["normal_force"]
    assert not d["identical"] and c["max_abs_diff"] == pytest.approx(0.25) and c["at_row_col"] == [3, 7]
    assert c["at_mm"] == pytest.approx([3.5, 1.5]) and c["differing_samples"] == 2
    assert d["meta"] == [{"key": "mapping.n_base", "a": 0.5, "b": 0.6}]
    pa, pb = _t(a).save(tmp_path / "a.npz"), _t(b).save(tmp_path / "b.npz")
    assert main(["diff", str(pa), str(pb)]) == 1
    out = capsys.readouterr().out
    assert "max |diff| 0.25 at row 3, col 7 (x 3.5 mm, y 1.5 mm)" in out
    assert main(["diff", str(pa), str(pa)]) == 0 and "identical" in capsys.readouterr().out


def test_diff_reports_channels_in_one_table_only_and_grid_changes():
    a = _t(np.full((4, 5), 0.5))
    g = Grid(4, 6, 0.5e-3, 0.5e-3)
    nf = np.full((4, 6), 0.5)
    b = FrictionTable.from_dense(g, {"normal_force": nf, "burst_gain": nf},
                                 {n: choose_quantization(nf, "float64") for n in ("normal_force", "burst_gain")},
                                 {"mapping": {"n_base": 0.5}})
    d = diff_tables(a, b)
    assert d["grid"]["same"] is False and d["channels"]["burst_gain"] == {"only_in": "b"}
    assert "not_compared" in d["channels"]["normal_force"]
