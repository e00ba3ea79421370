"""Shared test vectors of the C runtime's three targets (host, WebAssembly, Cortex-M4F).

Every target plays the same binary table image with the same settings and
stroke; the outputs are compared with the Python renderer. Input of
``sd_vectors image`` (and of the wasm and M4 harnesses): i64 image size, the
image, zero padding to 8 bytes, i64 policy, i64 model, f64 tick rate, f64
audio rate, i64 n, f64 x[n], f64 y[n]. Output: f64 out[n][15]
(renderer.OUT_NAMES), i64 n_audio, f64 audio[n_audio], i64 clipped, events,
events dropped.
"""
import struct

import numpy as np

from shapedisplay.runtime import renderer as R_
from shapedisplay.runtime.image import to_image

MODELS = {"jump": 0, "exact": 1}

# (table dtype, stroke, policy, tick rate, audio rate, model): the cases every target runs
CASES = [
    ("uint16", "diagonal", "retrigger", 10_000.0, 48_000.0, "jump"),
    ("uint16", "diagonal", "retrigger", 10_000.0, None, "exact"),
    ("float32", "teleports", "max", 4_000.0, 48_000.0, "exact"),
    ("uint8", "circles", "add", 4_000.0, 44_100.0, "jump"),
]


def image_payload(image: bytes, r, x, y) -> bytes:
    x = np.asarray(x, "<f8")
    y = np.asarray(y, "<f8")
    pad = b"\0" * (-len(image) % 8)
    return (struct.pack("<q", len(image)) + image + pad
            + struct.pack("<qq", r._policy, MODELS[r.model.name]) + struct.pack("<dd", r.tick_rate, r.audio_rate)
            + struct.pack("<q", x.size) + x.tobytes() + y.tobytes())


def parse_outputs(raw: bytes, n: int):
    nout = len(R_.OUT_NAMES)
    outs = np.frombuffer(raw[:8 * n * nout], "<f8").reshape(n, nout)
    pos = 8 * n * nout
    (na,) = struct.unpack_from("<q", raw, pos)
    audio = np.frombuffer(raw[pos + 8:pos + 8 + 8 * na], "<f8")
    counters = struct.unpack_from("<qqq", raw, pos + 8 + 8 * na)
    return outs, audio, counters


def case_setup(dtype, kind, policy, tick, audio, model, seconds=0.25):
    """Table, Python renderer, stroke and image of one case."""
    from test_c_runtime import stroke, widget_table
    from shapedisplay.runtime import Renderer
    table = widget_table(dtype)
    r = Renderer(table, model=model, tick_rate=tick, audio_rate=audio, burst_policy=policy)
    x, y = stroke(int(seconds * tick), kind)
    return table, r, x, y, to_image(table)
