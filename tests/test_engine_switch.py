"""The switch to one engine, checked once: the C engine plays what the numba kernels of the last release played.

``tests/data/engine_switch/old_main.npz`` holds what release 59ad372 (the
numba kernels) played on the cases of ``record.py``, from the tables that
release compiled. The C engine performs the same double-precision operations
in the same order for exact, jump and karnopp, and the same burst and
carrier arithmetic, so events, friction force, state and audio are the same
bit for bit. Stribeck is the exception: the numba kernel was compiled with fused
multiply-add contraction and the C engine is compiled without
(``-ffp-contract=off``), so each slip step differs by rounding (relative
1e-16 per operation). On a regular stick-slip (the tent stroke) the outcomes
stay within 1e-8 s in event time and 1e-6 N in force throughout. On the phone
stroke the Stribeck pad's stick-slip is sensitive to rounding: the first 278
of its 334 events agree to 1e-16 s, then the two trajectories part (by up to
0.3 ms in event time, the same as the studio's WebAssembly build against the
native one, whose libm differs in the last bit). There the check is the
one a listener hears: the same number of events, the first 80 % of them
within 1e-8 s, and the mean friction force, mean burst amplitude, slip share
and audio RMS within 0.2 %.
"""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent / "data" / "engine_switch"
_spec = importlib.util.spec_from_file_location("engine_switch_record", HERE / "record.py")
record = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(record)
OLD = np.load(HERE / "old_main.npz")


@pytest.mark.parametrize("i", range(len(record.CASES)), ids=[f"{c[0]}-{c[2]}-{c[3]}" for c in record.CASES])
def test_engine_plays_what_the_numba_kernels_played(i):
    case = record.CASES[i]
    res = record.play(case)
    old = {k[len(f"{i}_"):]: OLD[k] for k in OLD.files if k.startswith(f"{i}_")}
    assert old["event_time"].size > 0, "a case without events checks nothing"
    if case[2] != "stribeck":
        np.testing.assert_array_equal(res.event_time, old["event_time"])
        np.testing.assert_array_equal(res.event_amplitude, old["event_amplitude"])
        # the friction force, state per tick and audio, bit for bit (their SHA-256)
        np.testing.assert_array_equal(record.digests(res.friction_force, res.state, res.audio), old["digests"])
        return
    assert res.event_time.size == old["event_time"].size
    k = int(0.8 * old["event_time"].size)
    np.testing.assert_allclose(res.event_time[:k], old["event_time"][:k], rtol=0, atol=1e-8)
    if case[0] == "tent.npz":
        np.testing.assert_allclose(res.event_time, old["event_time"], rtol=0, atol=1e-8)
        np.testing.assert_allclose(res.friction_force, old["friction_force"], rtol=0, atol=1e-6)
    rms = float(np.sqrt(np.mean(res.audio * res.audio)))
    for new, was in ((np.mean(res.friction_force), np.mean(old["friction_force"])),
                     (np.mean(res.event_amplitude), np.mean(old["event_amplitude"])),
                     (np.mean(res.state), np.mean(old["state"])), (rms, float(old["audio_rms"]))):
        assert abs(new - was) <= 2e-3 * abs(was), (new, was)
