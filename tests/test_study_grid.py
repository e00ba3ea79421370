"""Your own study grid (``shapedisplay study grid``): trials, randomised order, stimuli and errors."""
import collections
import csv
import io
import json
import math

import numpy as np
import pytest

from shapedisplay.cli.main import main
from shapedisplay.errors import ShapeDisplayError
from shapedisplay.reports.grid import FACTORS, MAX_TRIALS, TRIAL_COLUMNS, plan_grid, run_grid
from shapedisplay.reports.presets import STUDIES

COMMAND = ["study", "grid", "--factor", "n_top=2N,3N,4N", "--factor", "ramp=5mm,15mm", "--repeat", "3"]
B = 0.25                     # 1/N, the handheld stick's burst gain


def read_csv(path):
    text = path.read_text()
    return text, list(csv.DictReader(io.StringIO(text)))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The documented command with seed 1 (twice) and seed 2, each into a new folder."""
    base = tmp_path_factory.mktemp("grid")
    out = {}
    for tag, seed in (("a", "1"), ("b", "1"), ("c", "2")):
        assert main([*COMMAND, "--seed", seed, "-o", str(base / tag)]) == 0
        out[tag] = base / tag
    return out


def test_the_command_writes_one_row_per_trial_and_one_stimulus_per_condition(runs):
    out = runs["a"]
    text, rows = read_csv(out / "trials.csv")
    lines = text.splitlines()
    assert len(lines) == 1 + 18
    assert lines[0].split(",")[:len(TRIAL_COLUMNS)] == list(TRIAL_COLUMNS)
    for col in ("n_top_N", "ramp_m", "speed_m_s", "events", "event_rate_hz", "burst_amplitude", "clipped"):
        assert col in rows[0]
    assert [int(r["trial"]) for r in rows] == list(range(1, 19))
    count = collections.Counter(r["condition"] for r in rows)
    assert sorted(count) == ["c01", "c02", "c03", "c04", "c05", "c06"] and set(count.values()) == {3}
    # repetitions are numbered in presentation order within each condition
    seen = collections.defaultdict(list)
    for r in rows:
        seen[r["condition"]].append(int(r["repetition"]))
    assert all(v == [1, 2, 3] for v in seen.values())
    # the full factorial, first factor slowest; values in SI units; defaults for the other factors
    combos = {r["condition"]: (float(r["n_top_N"]), float(r["ramp_m"])) for r in rows}
    assert [combos[c] for c in sorted(combos)] == [(n, L) for n in (2.0, 3.0, 4.0) for L in (0.005, 0.015)]
    for r in rows:
        assert (float(r["n_base_N"]), float(r["width_m"]), float(r["speed_m_s"])) == (0.5, 0.0, 0.02)
        assert (float(r["mu_s"]), float(r["delta_mu"]), r["model"]) == (0.5, 0.2, "exact")
        assert (r["wav"], r["trace"]) == (f"{r['condition']}.wav", f"{r['condition']}.npz")
        assert float(r["duration_s"]) == pytest.approx((0.020 + 2 * float(r["ramp_m"])) / 0.02)
        assert int(r["events"]) > 100 and int(r["clipped"]) == 0
    # one WAV and one trace per condition (not per trial), trials.csv and manifest.json: nothing else
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["trials.csv", "manifest.json", *(f"c0{i}.{e}" for i in range(1, 7) for e in ("wav", "npz"))])
    man = json.loads((out / "manifest.json").read_text())
    assert man["factors"] == ["n_top", "ramp"] and man["seed"] == 1 and man["repeat"] == 3
    assert man["levels"]["n_top"] == [2.0, 3.0, 4.0] and man["levels"]["ramp"] == [0.005, 0.015]
    assert man["levels"]["model"] == ["exact"] and set(man["levels"]) == set(FACTORS)
    assert man["shapedisplay_version"] and man["trial_count"] == 18 and len(man["conditions"]) == 6
    # the rows of one condition carry that condition's summary
    by = {c["id"]: c["summary"] for c in man["conditions"]}
    for r in rows:
        assert int(r["events"]) == by[r["condition"]]["events"]


def test_same_seed_same_files_other_seed_other_order(runs):
    a, b, c = runs["a"], runs["b"], runs["c"]
    assert {p.name: p.read_bytes() for p in a.iterdir()} == {p.name: p.read_bytes() for p in b.iterdir()}
    _, ra = read_csv(a / "trials.csv")
    _, rc = read_csv(c / "trials.csv")
    assert [r["condition"] for r in ra] != [r["condition"] for r in rc]

    def multiset(rows):
        return collections.Counter(tuple(v for k, v in r.items() if k not in ("trial", "repetition")) for r in rows)
    assert multiset(ra) == multiset(rc)
    # the stimuli do not depend on the order
    assert (a / "c04.wav").read_bytes() == (c / "c04.wav").read_bytes()
    # the order is numpy.random.default_rng(seed)'s permutation of condition x repeat
    order = np.random.default_rng(1).permutation(18)
    assert [r["condition"] for r in ra] == [f"c0{k // 3 + 1}" for k in order]


def test_the_wav_of_a_condition_is_what_the_renderer_plays_for_its_table_and_stroke(runs):
    from shapedisplay.author.compile import compile_heightfield
    from shapedisplay.author.forces import MappingOptions
    from shapedisplay.author.sources import tent_profile
    from shapedisplay.render.cursor import parse_stroke
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.render.sinks import read_trace, read_wav
    from shapedisplay.table.devices import load_device

    out = runs["a"]
    _, rows = read_csv(out / "trials.csv")
    row = next(r for r in rows if r["condition"] == "c04")          # n_top 3 N, ramp 15 mm
    assert (float(row["n_top_N"]), float(row["ramp_m"])) == (3.0, 0.015)
    dev = load_device("handheld-stick")
    hf = tent_profile("10mm", "25mm", "50mm", n1="0.5N", n2="3N", dx="0.1mm")
    table = compile_heightfield(hf, dev, MappingOptions(n_base=0.5, n_gain=hf.meta["n_gain"])).table
    r = Renderer(table, device=dev, model="exact")
    res = r.render(parse_stroke("0:50mm @ 20mm/s", r.tick_rate))
    audio, rate = read_wav(out / "c04.wav")
    assert rate == res.audio_rate and audio.size == res.audio.size
    assert np.array_equal(audio, res.audio.astype(np.float32).astype(np.float64))
    tr = read_trace(out / "c04.npz")
    assert np.array_equal(tr["normal_force"], res.normal_force) and np.array_equal(tr["x"], res.x)
    assert int(row["events"]) == res.event_time.size
    checksum = table.checksum() if callable(table.checksum) else table.checksum
    man = json.loads((out / "manifest.json").read_text())
    assert next(c for c in man["conditions"] if c["id"] == "c04")["table_checksum"] == checksum


def test_a_flat_top_with_its_own_friction_plays_the_closed_form(tmp_path):
    """width > 0 cuts the bump flat at n_top; the top's bursts break away at mu_s n_top: A = B (mu_s N - c V)."""
    from shapedisplay.render.sinks import read_trace
    from shapedisplay.table.devices import load_device

    res = run_grid({"width": ["10mm"], "ramp": "5mm", "n_top": ["3N"], "mu_s": [0.6], "delta_mu": ["0.3"],
                    "speed": "40mm/s", "model": "exact,jump"}, repeat=2, seed=5, out_dir=tmp_path / "g")
    assert len(res.rows) == 4 and len(res.conditions) == 2
    c = load_device("handheld-stick").pad.damping
    man = json.loads((tmp_path / "g" / "manifest.json").read_text())
    for cond, entry in zip(res.conditions, man["conditions"]):
        assert (entry["mu_s"], entry["mu_k"]) == (0.6, pytest.approx(0.3))
        assert cond["top_burst_amplitude"] == pytest.approx(B * (0.6 * 3.0 - c * 0.04), rel=2e-3)
        assert cond["top_normal_force_n"] == pytest.approx(3.0, abs=0.05)
        tr = read_trace(tmp_path / "g" / entry["trace"])
        # the trapezoid: 10 mm at 0.5 N, 5 mm up, 10 mm at 3 N, 5 mm down, 10 mm at 0.5 N
        x = tr["x"]
        n = np.interp(x, [0, 0.010, 0.015, 0.025, 0.030, 0.040], [0.5, 0.5, 3.0, 3.0, 0.5, 0.5])
        inside = (x > 0.001) & (x < 0.039)
        # within the tick's travel on the flanks (k V h), the cell (k dx / 2) and the quantization of N
        assert np.max(np.abs(tr["normal_force"][inside] - n[inside])) < 500 * (0.04 * 1e-4 + 0.5e-4) + 0.02
    assert res.conditions[0]["model"] == "exact" and res.conditions[1]["model"] == "jump"


@pytest.mark.parametrize("args, needle", [
    (["--factor", "n_tpo=2N,3N"], "`--factor n_tpo=2N,3N`: unknown grid factor 'n_tpo' (did you mean 'n_top'?)"),
    (["--factor", "ramp=5N,15mm"], "`--factor ramp=5N,15mm` must be a length in m (got '5N', a force)"),
    (["--factor", "n_top=2,3"], "`--factor n_top=2,3` needs a unit"),
    (["--factor", "n_top="], "`--factor n_top=`: no levels"),
    (["--factor", "n_top=2N,,3N"], "`--factor n_top=2N,,3N`: empty level"),
    (["--factor", "n_top=2N", "--repeat", "0"], "`--repeat` must be a whole number within 1..10000 (got 0)"),
    (["--factor", "n_top=2N", "--repeat", "-2"], "`--repeat` must be a whole number"),
    (["--factor", "model=exct"], "`--factor model=exct`: unknown model 'exct' (did you mean 'exact'?)"),
    (["--factor", "n_top=2N", "--factor", "n_top=3N"], "`--factor n_top=3N`: factor n_top is given twice"),
    ([], "needs at least one --factor"),
])
def test_bad_options_end_in_one_line_naming_the_option(tmp_path, capsys, args, needle):
    out = tmp_path / "g"
    assert main(["study", "grid", *args, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("factors, kw, needle", [
    ({"n_tpo": ["2N"]}, {}, "unknown grid factor 'n_tpo'"),
    ({"ramp": ["5N"]}, {}, "must be a length"),
    ({"n_top": []}, {}, "no levels"),
    ({"n_top": ["2N"]}, {"repeat": 0}, "`repeat` must be a whole number"),
    ({"n_top": ["2N"]}, {"seed": -1}, "`seed` must be a whole number"),
    ({"n_top": ["0.2N"]}, {}, "below factor n_base"),
    ({"mu_s": [0.1]}, {}, "mu_k = mu_s - delta_mu must be >= 0"),
    ({"speed": ["0.01mm/s"]}, {}, "outside the handheld-stick device's range"),
    ({"ramp": ["1m"], "speed": ["1mm/s"]}, {}, "at most 60 s"),
    ({"n_top": [f"{2 + i}N" for i in range(11)], "ramp": [f"{5 + i}mm" for i in range(10)]}, {"repeat": 100},
     f"at most 1000 conditions and {MAX_TRIALS} trials"),
])
def test_the_api_checks_the_design_before_anything_runs(tmp_path, factors, kw, needle):
    with pytest.raises(ShapeDisplayError) as e:
        run_grid(factors, out_dir=tmp_path / "g", **kw)
    assert needle in str(e.value)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_in_use_is_refused_and_a_failed_run_leaves_nothing(tmp_path, capsys):
    used = tmp_path / "used"
    used.mkdir()
    (used / "keep.txt").write_text("x")
    assert main(["study", "grid", "--factor", "ramp=5mm", "-o", str(used)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert [p.name for p in used.iterdir()] == ["keep.txt"]
    # the second condition diverges (forward Euler at the stick's tick): no folder, no temporary folder
    assert main(["study", "grid", "--factor", "model=exact,euler", "--factor", "ramp=2mm", "-o",
                 str(tmp_path / "g")]) == 2
    assert "diverged" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["used"]


def test_plan_without_running_and_the_presets_beside_grid(capsys):
    plan = plan_grid({"n_top": "2N,3N", "model": ["exact", "jump"]}, repeat=2, seed=0)
    assert [cid for cid, _ in plan.conditions] == ["c01", "c02", "c03", "c04"]
    assert [(p["n_top"], p["model"]) for _, p in plan.conditions] == [
        (2.0, "exact"), (2.0, "jump"), (3.0, "exact"), (3.0, "jump")]
    assert sorted(c for _, c, _ in plan.trials) == [0, 0, 1, 1, 2, 2, 3, 3]
    assert plan_grid({"n_top": "2N,3N", "model": ["exact", "jump"]}, repeat=2, seed=0) == plan
    assert main(["study", "grid", "--factor", "speed=20mm/s,40mm/s", "--list"]) == 0
    out = capsys.readouterr().out
    assert "speed_m_s" in out and "2 conditions x 1 = 2 trials" in out
    with pytest.raises(SystemExit) as e:
        main(["study", "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for name in (*STUDIES, "grid", *FACTORS):
        assert name in out
    # the grid's options are refused with a preset, and the presets' with grid
    assert main(["study", "bump", "--factor", "n_top=2N"]) == 2
    assert "applies to `study grid` only" in capsys.readouterr().err
    assert main(["study", "grid", "--factor", "n_top=2N", "--duration", "1s"]) == 2
    assert "applies to the presets" in capsys.readouterr().err
    assert main(["study", "friction", "--list", "--only", "slider-*-dmu0.3"]) == 0
    assert len(capsys.readouterr().out.split()) == 10


def test_without_a_folder_the_grid_runs_and_prints(capsys):
    res = run_grid({"ramp": "2mm", "speed": "100mm/s"}, repeat=2, seed=3)
    assert res.folder is None and res.manifest is None and len(res.rows) == 2
    assert res.rows[0]["events"] == res.rows[1]["events"] > 0 and res.rows[0]["wav"] == "c01.wav"
    assert main(["study", "grid", "--factor", "ramp=2mm", "--factor", "speed=100mm/s", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["events"] == res.rows[0]["events"] and math.isclose(rows[0]["speed_m_s"], 0.1)
