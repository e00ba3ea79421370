"""Record what a shapedisplay checkout plays on the engine-switch cases (tests/test_engine_switch.py).

Run from the checkout to record, with its own environment:

    python tests/data/engine_switch/record.py OUT.npz

``old_main.npz`` beside this script was recorded by the last release that
played through the numba kernels (commit 59ad372) with this script; the tables
it played (``phone.npz``, ``tent.npz``) were compiled by that release too and
are kept here, so both sides play the same bytes. Per case it keeps the event
times and amplitudes; for the cases played bit for bit the SHA-256 of the
friction force, the state per tick and the audio (:func:`digests`); for
Stribeck the friction force and state per tick and the audio's RMS.
"""
import hashlib
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

#: (table file, stroke, model, burst policy, tick rate Hz): the cases both engines play.
CASES = [
    ("phone.npz", "62,2 -> 62,156 @ 30mm/s", "exact", "retrigger", 10_000.0),
    ("phone.npz", "62,2 -> 62,156 @ 30mm/s", "jump", "retrigger", 10_000.0),
    ("phone.npz", "10,20 -> 110,140 @ 60mm/s", "exact", "add", 4_000.0),
    ("phone.npz", "10,20 -> 110,140 @ 60mm/s", "jump", "max", 4_000.0),
    ("phone.npz", "62,2 -> 62,80 @ 30mm/s", "karnopp", "retrigger", 10_000.0),
    ("phone.npz", "62,2 -> 62,40 @ 30mm/s", "stribeck", "retrigger", 10_000.0),
    ("tent.npz", "0,2 -> 60,2 @ 20mm/s", "exact", "retrigger", 10_000.0),
    ("tent.npz", "0,2 -> 60,2 @ 20mm/s", "karnopp", "add", 2_000.0),
    ("tent.npz", "0,2 -> 30,2 @ 20mm/s", "stribeck", "max", 10_000.0),
]


def play(case):
    from shapedisplay.render import Renderer, parse_stroke
    from shapedisplay.table.model import FrictionTable
    name, stroke, model, policy, rate = case
    r = Renderer(FrictionTable.load(HERE / name), model=model, burst_policy=policy, tick_rate=rate)
    return r.render(parse_stroke(stroke, rate))


def digests(friction_force, state, audio) -> np.ndarray:
    """SHA-256 of the float64 friction force, the int8 state and the float64 audio (3 x 32 bytes)."""
    arrays = (np.asarray(friction_force, "<f8"), np.asarray(state, np.int8), np.asarray(audio, "<f8"))
    return np.frombuffer(b"".join(hashlib.sha256(a.tobytes()).digest() for a in arrays), np.uint8)


def keep(i, case, event_time, event_amplitude, friction_force, state, audio) -> dict:
    """What is recorded of case ``i``."""
    out = {f"{i}_event_time": event_time, f"{i}_event_amplitude": event_amplitude}
    if case[2] == "stribeck":
        out.update({f"{i}_friction_force": friction_force, f"{i}_state": np.asarray(state, np.int8),
                    f"{i}_audio_rms": np.sqrt(np.mean(np.square(audio)))})
    else:
        out[f"{i}_digests"] = digests(friction_force, state, audio)
    return out


def main(out):
    arrays = {}
    for i, case in enumerate(CASES):
        res = play(case)
        arrays.update(keep(i, case, res.event_time, res.event_amplitude, res.friction_force, res.state, res.audio))
    np.savez_compressed(out, **arrays)


if __name__ == "__main__":
    main(sys.argv[1])
