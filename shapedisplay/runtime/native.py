"""The C runtime (``shapedisplay/runtime_c/``) as a shared library, through ctypes, and offline play with it.

:func:`library` compiles the C99 runtime with the system C compiler (``$CC``,
else ``cc``, ``gcc`` or ``clang``) into a shared library, once per source
version, in the cache directory (``$XDG_CACHE_HOME/shapedisplay``, by default
``~/.cache/shapedisplay``), and loads it (:mod:`shapedisplay.cbuild`). Building
takes about a second; later loads take about a millisecond. The sources ship
inside the package, so this works from an installed wheel too.

:func:`render_path` plays a whole cursor path offline through that library
(one call from Python; the loop is ``sd_play_path.c``, beside this module): the
same settings (:mod:`.settings`) and the same per-tick arithmetic as the
compiled Python kernels, so the result is the same bit for bit
(``tests/test_native_play.py``), without importing numba. The C runtime has the
models :data:`C_MODELS`; the others play through the Python kernels.
"""
from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from ..cbuild import compiler, load_shared, shared_library_path
from ..errors import InputError
from .layouts import OUTPUTS
from .result import RenderResult
from .settings import RenderSettings, audio_length

#: The C runtime sources, shipped inside the package (``runtime-c/`` in a checkout links here).
RUNTIME_C = Path(__file__).resolve().parent.parent / "runtime_c"
SOURCES = ("sd_pad.c", "sd_exact.c", "sd_render.c", "sd_image.c")
#: The offline loop over a path (uses only ``sd_runtime.h``), built into the same library.
PLAY_SOURCE = Path(__file__).resolve().parent / "sd_play_path.c"
#: Models with a C tick (``sd_model_tick``); ids are shared with the Python registry.
C_MODELS = ("exact", "jump")
#: ``sd_play_path`` status codes (besides 0 = done) and what they mean.
PLAY_STATUS = {-30: "more audio than expected", -31: "more stick-slip events than the buffer holds",
               -32: "more bursts sounding at once than the runtime's event ring holds",
               -33: "a cursor position beyond the runtime's limit"}


#: The per-tick outputs (fields of ``sd_outputs_t``) a :class:`RenderResult` keeps.
RESULT_COLUMNS = ("vx", "vy", "normal_force", "friction_force", "state", "lateral_x", "lateral_y", "skin_stretch")

_LIB = None


def _sources() -> list[Path]:
    return [*(RUNTIME_C / n for n in SOURCES), PLAY_SOURCE]


def library_path() -> Path:
    """The file the library of the current sources is built into (it may not exist yet)."""
    try:
        return shared_library_path("sd_runtime", _sources(), sorted(RUNTIME_C.glob("*.h")))
    except InputError as exc:
        raise InputError(f"the C runtime's {exc}; use the Python engine") from None


def library() -> ctypes.CDLL:
    """Build (once per source version) and load the C runtime as a shared library."""
    global _LIB
    if _LIB is not None:
        return _LIB
    lib = load_shared(library_path(), _sources(), RUNTIME_C, hint="; use the Python engine")
    vp, c_int64 = ctypes.c_void_p, ctypes.c_int64
    lib.sd_renderer_size.restype = ctypes.c_size_t
    lib.sd_image_size.restype = ctypes.c_size_t
    lib.sd_image_load.argtypes = [vp, vp, ctypes.c_size_t]
    lib.sd_image_load.restype = ctypes.c_int
    lib.sd_image_config.argtypes = [vp, vp]
    lib.sd_renderer_init.argtypes = [vp, vp, vp]
    lib.sd_renderer_init.restype = ctypes.c_int
    lib.sd_renderer_reset.argtypes = [vp, ctypes.c_double]
    lib.sd_renderer_step.argtypes = [vp, ctypes.c_double, ctypes.c_double]
    lib.sd_renderer_step.restype = ctypes.c_double
    lib.sd_play_path.argtypes = [vp, vp, vp, c_int64, vp, vp, c_int64, vp, vp, c_int64, vp]
    lib.sd_play_path.restype = ctypes.c_int
    _LIB = lib
    return lib


def unavailable(model_name: str) -> str | None:
    """Why the C runtime cannot play ``model_name`` here (no C tick, no compiler), or None if it can.

    Cheap: builds nothing (a library already built needs no compiler).
    """
    if model_name not in C_MODELS:
        return f"model '{model_name}' has no C tick (the C runtime has {', '.join(C_MODELS)})"
    try:
        built = library_path().is_file()
    except InputError as exc:
        return str(exc)
    if not built and not compiler():
        return "no C compiler (cc, gcc or clang, or $CC) to build the C runtime"
    return None


class TableImage:
    """A table bound in the C runtime: its binary image, loaded in place as firmware loads an upload.

    The image buffer is 8-byte aligned and lives as long as this object.
    """

    def __init__(self, table, device):
        from .image import to_image
        lib = library()
        data = to_image(table, device)
        self._buf = np.zeros((len(data) + 7) // 8, dtype=np.uint64)
        ctypes.memmove(self._buf.ctypes.data, data, len(data))
        self.handle = ctypes.create_string_buffer(lib.sd_image_size())
        rc = lib.sd_image_load(self.handle, self._buf.ctypes.data, len(data))
        if rc != 0:
            raise InputError(f"the C runtime refused the table image (code {rc})")


class PathPlayError(InputError):
    """The C runtime cannot play this path as the offline renderer does (see :data:`PLAY_STATUS`)."""


def render_path(table, settings: RenderSettings, cursor) -> RenderResult:
    """Render ``cursor`` over ``table`` offline in the C runtime, with ``settings`` (:func:`.settings.render_settings`).

    Same arguments and result as :meth:`.renderer.Renderer.render` (``mu_s`` is
    None). A cursor path off the tick grid is resampled to the tick rate.
    Raises :class:`PathPlayError` where the runtime's fixed buffers would play
    differently (then use the Python engine), :class:`InputError` if the C
    runtime cannot be built or refuses the settings.
    """
    from .cursor import CursorPath
    if settings.model.name not in C_MODELS:
        raise InputError(f"the C runtime offers models {list(C_MODELS)} (got {settings.model.name!r})")
    if not isinstance(cursor, CursorPath):
        raise InputError(f"`cursor` must be a CursorPath (got {type(cursor).__name__})")
    cp = cursor if cursor.tick_rate == settings.tick_rate else cursor.resample(settings.tick_rate)
    n_audio = audio_length(cp.duration, settings.audio_rate)   # refuse an impossible stream before the work
    n = cp.t.size
    t0 = float(cp.t[0]) if n else 0.0
    if not np.array_equal(cp.t, t0 + np.arange(n) / settings.tick_rate):
        # the runtime counts time as t0 + k / tick_rate; other sample times would shift events by an ulp
        raise PathPlayError("the C runtime plays cursor samples at t0 + k / tick_rate; this path's times differ")
    lib = library()
    image = TableImage(table, settings.device)
    state = ctypes.create_string_buffer(lib.sd_renderer_size())
    rc = lib.sd_renderer_init(state, image.handle, settings.config.ctypes.data)
    if rc != 0:
        raise InputError(f"the C runtime refused the table or parameters (code {rc})")
    lib.sd_renderer_reset(state, t0)
    x = np.ascontiguousarray(cp.x, dtype=np.float64)
    y = np.ascontiguousarray(cp.y, dtype=np.float64)
    out = np.empty(n, OUTPUTS)
    audio = np.empty(n_audio)
    ev_cap = 4 * n + 4096
    ev = np.empty((2, ev_cap))
    counts = np.zeros(3, np.int64)
    rc = lib.sd_play_path(state, x.ctypes.data, y.ctypes.data, n, out.ctypes.data, audio.ctypes.data, n_audio,
                          ev[0].ctypes.data, ev[1].ctypes.data, ev_cap, counts.ctypes.data)
    if rc != 0:
        raise PathPlayError(f"the C runtime cannot play this path as the offline renderer does: "
                            f"{PLAY_STATUS.get(rc, f'code {rc}')}")
    na, ne, clipped = (int(c) for c in counts)
    if na != n_audio:
        raise PathPlayError(f"the C runtime wrote {na} audio samples where {n_audio} were expected")
    col = {name: np.ascontiguousarray(out[name]) for name in RESULT_COLUMNS}
    return RenderResult(cp.t.copy(), cp.x.copy(), cp.y.copy(), col["vx"], col["vy"], col["normal_force"],
                        col["friction_force"], col["state"].astype(np.int8), col["lateral_x"], col["lateral_y"],
                        col["skin_stretch"], ev[0, :ne].copy(), ev[1, :ne].copy(), audio, settings.audio_rate,
                        clipped, settings.model.name, settings.tick_rate, settings.burst_policy, None)
