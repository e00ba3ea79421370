"""The C engine (``shapedisplay/engine/``) as a shared library, through ctypes.

The C99 runtime is the one implementation of what plays a table: table
lookup, every pad model, bursts and the renderer's state. It is compiled when
the package is built or installed into the extension module
``shapedisplay._engine`` (``setup.py``: every ``engine/sd_*.c`` but
``sd_wasm.c``, and the host entry points ``sd_play_path.c`` beside this
module); :func:`library` loads it with ctypes and declares the functions the
Python side calls. Nothing is compiled at run time: no C compiler is needed
to play. :class:`~.renderer.Renderer`, :func:`~.models.run_kernel` and
:mod:`.bursts` are the bindings built on it.
"""
from __future__ import annotations

import ctypes
import functools
from pathlib import Path

import numpy as np

from shapedisplay.errors import InputError

#: The C runtime sources, shipped inside the package (``runtime-c/`` in a checkout links here).
RUNTIME_C = Path(__file__).resolve().parent.parent / "engine"
#: The runtime's model-independent sources (``setup.py`` builds every ``engine/sd_*.c`` but ``sd_wasm.c``).
SOURCES = ("sd_pad.c", "sd_exact.c", "sd_render.c", "sd_image.c", "sd_stribeck.c", "sd_karnopp.c", "sd_baselines.c",
           "sd_react.c")
#: The offline loop over a path (uses only ``sd_runtime.h``), built into the same library.
PLAY_SOURCE = Path(__file__).resolve().parent / "sd_play_path.c"
#: The models a table is played with (the C ticks of ``sd_model_tick``; every model of
#: :data:`~.models.MODELS` has one, these are the ones offered to designers and devices: the baselines
#: euler, rk4 and tanh serve the reports).
C_MODELS = ("exact", "jump", "karnopp", "stribeck")
#: ``sd_play_path`` status codes: more events than the buffer given (the binding grows it and plays again).
PLAY_EVENTS_FULL = -31
#: ``sd_play_path``: more reaction events than the buffer given (grown likewise).
PLAY_REACT_FULL = -32
#: ``sd_pad_run``: no tick for this model id.
RUN_UNKNOWN_MODEL = -34

#: The extension module the C runtime is compiled into (``setup.py``).
EXTENSION = "shapedisplay._engine"

_LIB = None


def library_path() -> Path:
    """The file of the compiled C runtime (the extension module :data:`EXTENSION`).

    Raises :class:`InputError` where it is missing (a broken install).
    """
    from shapedisplay.extensions import extension_path
    return extension_path(EXTENSION, "the compiled C runtime")


def library() -> ctypes.CDLL:
    """Load the compiled C runtime (once per process) with its functions' argument types declared."""
    global _LIB
    if _LIB is not None:
        return _LIB
    from shapedisplay.extensions import load_extension
    sources = [*(p for p in sorted(RUNTIME_C.glob("sd_*.[ch]")) if p.name != "sd_wasm.c"),
               *sorted(PLAY_SOURCE.parent.glob("sd_*.c")), PLAY_SOURCE.parent.parent / "_module.c"]
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
    lib.sd_renderer_step_press.argtypes = [vp, ctypes.c_double, ctypes.c_double, ctypes.c_double]
    lib.sd_renderer_step_press.restype = ctypes.c_double
    lib.sd_react_pop.argtypes = [vp, vp]
    lib.sd_react_pop.restype = ctypes.c_int
    lib.sd_react_restart.argtypes = [vp, ctypes.c_double]
    lib.sd_react_restart.restype = None
    lib.sd_play_path.argtypes = [vp, vp, vp, vp, c_int64, vp, vp, c_int64, vp, vp, c_int64, vp, c_int64, vp]
    lib.sd_play_path.restype = ctypes.c_int
    c_int, c_double = ctypes.c_int, ctypes.c_double
    lib.sd_pad_run.argtypes = [c_int, vp, vp, vp, c_int64, vp, vp, vp, vp, vp, c_int, c_int, c_int, vp, vp, vp, vp,
                               vp, vp, c_int64]
    lib.sd_pad_run.restype = c_int64
    lib.sd_friction_limits.argtypes = [vp, vp, vp, c_int64, vp, vp]
    lib.sd_friction_limits.restype = None
    lib.sd_renderer_layout.argtypes = [vp]
    lib.sd_renderer_layout.restype = None
    lib.sd_render_events.argtypes = [vp, vp, ctypes.c_long, c_double, c_double, c_int64, c_double, c_double,
                                     c_double, c_int, c_int, vp]
    lib.sd_render_events.restype = ctypes.c_long
    _LIB = lib
    return lib


#: Names of :func:`renderer_layout`'s entries (``sd_renderer_layout``): byte offsets of the parts of an
#: ``sd_renderer_t`` the binding reads, the event ring's and the audio block's sizes, and the reactions'
#: parts (widget states, counts, the build's ``SD_MAX_REACTIVE``).
LAYOUT_NAMES = ("out", "run", "pad", "audio", "ev_t", "ev_a", "position_faults", "event_ring", "audio_block_max",
                "n_audio", "react_state", "react_n", "max_reactive", "react_total", "react_dropped", "react_skipped",
                "react_held")


@functools.cache
def renderer_layout() -> dict:
    """Where the parts of a renderer state lie (:data:`LAYOUT_NAMES` -> int), as the compiled engine has them."""
    off = np.zeros(len(LAYOUT_NAMES), np.int64)
    library().sd_renderer_layout(off.ctypes.data)
    return dict(zip(LAYOUT_NAMES, (int(v) for v in off)))


def address(a: np.ndarray) -> int:
    """The address of the first byte of the C-contiguous array ``a`` (for a ctypes ``void *`` argument).

    About a third of the cost of ``a.ctypes.data`` for a writable array (a short run passes a dozen)."""
    try:
        return ctypes.addressof(ctypes.c_char.from_buffer(a))
    except (TypeError, ValueError):         # read-only or empty
        return a.ctypes.data


def aligned_buffer(nbytes: int) -> np.ndarray:
    """``nbytes`` zeroed bytes, 8-byte aligned (a uint8 view of float64 storage): C structs live in it."""
    return np.zeros((nbytes + 7) // 8, np.float64).view(np.uint8)[:nbytes]
