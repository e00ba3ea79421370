"""Pictures the studio page shows: the top-view colour map of a channel and the 3D snapshot.

The top view is drawn the same way up as the 3D preview: x to the right, y up
the screen (table row 0, at y0, is the bottom line of the picture). One
picture pixel per table sample; the page scales it.
"""
from __future__ import annotations

import io

import numpy as np

from shapedisplay.errors import InputError, unknown_key

#: Viridis at 16 evenly spaced points (the preview's default colour map), 8-bit RGB.
VIRIDIS = np.array([(68, 1, 84), (72, 26, 108), (71, 47, 125), (65, 68, 135), (57, 86, 140), (49, 104, 142),
                    (42, 120, 142), (35, 136, 142), (31, 152, 139), (34, 168, 132), (53, 183, 121),
                    (84, 197, 104), (122, 209, 81), (165, 219, 54), (210, 226, 27), (253, 231, 37)],
                   dtype=np.float64)
#: Rows of the picture of a 1-D table (one row stretched so that it can be seen and hovered).
ROWS_1D = 24


def channel_range(table, channel: str) -> tuple[float, float]:
    """(min, max) of a channel over the canvas, SI units."""
    values = table.dense(channel)
    return float(values.min()), float(values.max())


def colour_map_png(table, channel: str, scale: tuple | None = None) -> bytes:
    """PNG (RGB) of ``channel`` over the canvas, viridis from its min to its max (or ``scale`` = (lo, hi),
    a locked colour scale: values beyond it take the end colours), y up."""
    from PIL import Image
    table.require(channel)
    values = table.dense(channel)
    lo, hi = channel_range(table, channel) if scale is None else (float(scale[0]), float(scale[1]))
    u = (values - lo) * (1.0 / (hi - lo)) if hi > lo else np.zeros_like(values)
    idx = np.clip(np.rint(u * 255.0), 0, 255).astype(np.uint8)[::-1]        # y up: last row on top
    img = np.ascontiguousarray(_LUT[idx])
    if img.shape[0] == 1:
        img = np.repeat(img, ROWS_1D, axis=0)
    buf = io.BytesIO()
    Image.fromarray(img, "RGB").save(buf, format="PNG", compress_level=1)
    return buf.getvalue()


def _lut() -> np.ndarray:
    """256 x 3 uint8: :data:`VIRIDIS` interpolated linearly at 256 levels."""
    pos = np.linspace(0.0, len(VIRIDIS) - 1, 256)
    i0 = np.minimum(np.floor(pos).astype(np.int64), len(VIRIDIS) - 2)
    w = (pos - i0)[:, None]
    return np.round(VIRIDIS[i0] * (1.0 - w) + VIRIDIS[i0 + 1] * w).astype(np.uint8)


_LUT = _lut()


def check_stroke(stroke) -> dict:
    """The page's recorded stroke as float64 arrays, or InputError naming the key and the rule.

    ``stroke`` (parsed JSON) must be an object whose keys are trace arrays
    (``viewer.TRACE_ARRAYS``) and whose values are flat lists of numbers; what
    the numbers must satisfy (finite, equal lengths, ...) the trace checks.
    """
    from shapedisplay.viewer import TRACE_ARRAYS
    if not isinstance(stroke, dict):
        raise InputError(f"snapshot `stroke` must be a JSON object of arrays (got {type(stroke).__name__})")
    out = {}
    for key, value in stroke.items():
        if key not in TRACE_ARRAYS:
            raise unknown_key("snapshot stroke array", str(key)[:40], TRACE_ARRAYS)
        if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                  for v in value):
            raise InputError(f"snapshot `stroke.{key}` must be a flat list of numbers "
                             f"(got {type(value).__name__}{' with other items' if isinstance(value, list) else ''})")
        out[key] = np.asarray(value, dtype=np.float64)
    return out


def snapshot_png(table, channel: str = "normal_force", stroke: dict | None = None,
                 size: str = "1200x800") -> bytes:
    """The 3D preview of ``table`` (off-screen, as ``shapedisplay preview -o``), with the last stroke.

    ``stroke`` holds the page's recording: per-tick arrays ``t, x, y,
    normal_force, friction_force, state`` (s, m, N) and the events
    ``event_time, event_amplitude``.
    """
    from PIL import Image

    from shapedisplay import viewer
    arrays = check_stroke(stroke) if stroke else None     # a malformed stroke is refused before any work
    model = viewer.model_from_table(table)
    trace = None
    if arrays is not None:
        trace = viewer.Trace(**{k: arrays.get(k, np.zeros(0)) for k in viewer.TRACE_ARRAYS},
                             table_checksum=table.checksum, source="studio")
    preview = viewer.render(model, channel, trace=trace, size=size, off_screen=True)
    try:
        img = preview.screenshot()
    finally:
        preview.close()
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")
    return buf.getvalue()
