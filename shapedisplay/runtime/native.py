"""The C runtime (``shapedisplay/runtime_c/``) as a shared library, through ctypes, and offline play with it.

:func:`library` loads the C99 runtime, compiled when the package is built or
installed into the extension module ``shapedisplay._engine`` (``setup.py``:
every ``runtime_c/sd_*.c`` but ``sd_wasm.c``, and ``sd_play_path.c``), with
ctypes. Nothing is compiled at run time: no C compiler is needed to play.

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

from ..errors import InputError
from .layouts import OUTPUTS
from .result import RenderResult
from .settings import RenderSettings, audio_length

#: The C runtime sources, shipped inside the package (``runtime-c/`` in a checkout links here).
RUNTIME_C = Path(__file__).resolve().parent.parent / "runtime_c"
#: The runtime's model-independent sources (``setup.py`` builds every ``runtime_c/sd_*.c`` but ``sd_wasm.c``).
SOURCES = ("sd_pad.c", "sd_exact.c", "sd_render.c", "sd_image.c", "sd_stribeck.c", "sd_karnopp.c", "sd_baselines.c")
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

#: The extension module the C runtime is compiled into (``setup.py``).
EXTENSION = "shapedisplay._engine"

_LIB = None


def library_path() -> Path:
    """The file of the compiled C runtime (the extension module :data:`EXTENSION`).

    Raises :class:`InputError` where it is missing (a broken install).
    """
    from ..extensions import extension_path
    return extension_path(EXTENSION, "the compiled C runtime")


def library() -> ctypes.CDLL:
    """Load the compiled C runtime (once per process) with its functions' argument types declared."""
    global _LIB
    if _LIB is not None:
        return _LIB
    from ..extensions import load_extension
    sources = [*(p for p in sorted(RUNTIME_C.glob("sd_*.[ch]")) if p.name != "sd_wasm.c"), PLAY_SOURCE]
    lib = load_extension(library_path(), "the compiled C runtime", sources)
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
    """Why the C runtime cannot play ``model_name`` (it has no C tick for it), or None if it can.

    Cheap: loads nothing. A missing compiled runtime (a broken install) is
    not a reason here: :func:`library` raises :class:`InputError` for it.
    """
    if model_name not in C_MODELS:
        return f"model '{model_name}' has no C tick (the C runtime has {', '.join(C_MODELS)})"
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
    runtime is missing or refuses the settings.
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
