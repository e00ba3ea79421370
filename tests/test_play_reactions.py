"""`shapedisplay play` with reactive widgets: the reaction events on stdout, in --json, in the trace beside the
stick-slip events, and marked on the plot (docs/reactive.md)."""
import json
from pathlib import Path

import pytest


def test_play_prints_the_reactions_and_writes_them_into_the_trace(tmp_path, capsys):
    """`shapedisplay play` with a pressing stroke over the bundled scene: the events on stdout, in --json, and
    as event_kind / event_widget / event_t beside the stick-slip event_time in the trace; the plot marks them."""
    from shapedisplay.cli.main import main
    from shapedisplay.render.sinks import read_trace
    table = tmp_path / "reactive.npz"
    scene = Path(__file__).resolve().parent.parent / "assets" / "scenes" / "reactive.toml"
    assert main(["compile", str(scene), "-o", str(table), "-q"]) == 0
    stroke = "20,15 -> 20,20 @ 20mm/s; press 3N 150ms; -> 60,20 @ 40mm/s; press 3N 100ms"
    trace = tmp_path / "t.npz"
    capsys.readouterr()
    assert main(["play", str(table), "--stroke", stroke, "--model", "jump", "-o", str(tmp_path / "a.wav"),
                 "--trace-out", str(trace)]) == 0
    out = capsys.readouterr().out
    assert "reactions: 6 events" in out and "toggle  toggle -> state 1" in out and "click   button" in out
    d = read_trace(trace)
    assert list(d["event_kind"]) == ["press", "click", "release", "press", "toggle", "click"]
    assert set(d["event_widget"]) == {"button", "toggle"}
    assert d["event_t"].size == d["event_kind"].size and d["event_time"].size > 10
    assert d["press"].max() == 3.0 and d["press"].size == d["t"].size
    assert main(["play", str(table), "--stroke", stroke, "--model", "jump", "-o", str(tmp_path / "b.wav"),
                 "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert [e["kind"] for e in js["reaction_events"]] == list(d["event_kind"]) and js["reactions"] == len(d["event_kind"])
    pytest.importorskip("matplotlib")
    png = tmp_path / "p.png"
    assert main(["play", str(table), "--stroke", stroke, "--model", "jump", "-o", str(tmp_path / "c.wav"),
                 "--plot", str(png)]) == 0
    assert png.stat().st_size > 10_000
