"""The C runtime (``shapedisplay/runtime_c/``) as the emulator's rendering engine, through ctypes.

``shapedisplay device emulate --engine c`` compiles the C99 runtime with the
system C compiler into a shared library (once per source version, in a cache
directory), loads the uploaded table into it as its binary table image (in
place, as firmware does with ``sd_image_load``) and renders every tick in C, so
the whole path host -> pty -> firmware renderer runs the code a
microcontroller would. The C runtime is bit-identical to the Python renderer
(``tests/test_c_runtime.py``), so the samples are the same as with the
default Python engine.

It needs a C compiler; the C sources ship inside the package
(``shapedisplay/runtime_c/``, which ``runtime-c/`` in a checkout links to), so
it works from an installed wheel too.
"""
from __future__ import annotations

import ctypes

import numpy as np

from ..errors import InputError
from ..runtime.layouts import RENDER_CONFIG, ctypes_struct
from ..runtime.native import C_MODELS, RUNTIME_C, library  # noqa: F401 (their home is runtime.native)
from .engine import RenderEngine

_Config = ctypes_struct(RENDER_CONFIG)


class CRenderer:
    """A C renderer bound to a table, with the :class:`~shapedisplay.runtime.Renderer` step interface.

    Parameters are taken from a Python ``Renderer`` built for the same table
    (the one place they are validated), so both play the same model.
    """

    def __init__(self, table, model: str = "jump", tick_rate: float | None = None):
        from ..runtime import Renderer
        from ..runtime.image import to_image
        if model not in C_MODELS:
            raise InputError(f"the C engine offers models {sorted(C_MODELS)} (got {model!r})")
        py = Renderer(table, model=model, tick_rate=tick_rate)
        self.device = py.device
        lib = library()
        # the table goes to C as its binary image, loaded in place as firmware loads an upload;
        # the buffer is 8-byte aligned (uint64) and lives as long as this object
        data = to_image(table, py.device)
        self._image_buf = np.zeros((len(data) + 7) // 8, dtype=np.uint64)
        ctypes.memmove(self._image_buf.ctypes.data, data, len(data))
        self._image = ctypes.create_string_buffer(lib.sd_image_size())
        rc = lib.sd_image_load(self._image, self._image_buf.ctypes.data, len(data))
        if rc != 0:
            raise InputError(f"the C runtime refused the table image (code {rc})")
        cfg = _Config()
        lib.sd_image_config(self._image, ctypes.byref(cfg))
        cfg.tick_rate, cfg.audio_rate = py.tick_rate, py.audio_rate
        cfg.policy, cfg.model = int(py.config["policy"]), int(py.config["model"])     # numbered as in C
        self._cfg = cfg
        self._state = ctypes.create_string_buffer(lib.sd_renderer_size())
        # sd_image_t starts with its sd_table_t: the image object's address is the table's
        rc = lib.sd_renderer_init(self._state, self._image, ctypes.byref(cfg))
        if rc != 0:
            raise InputError(f"the C renderer refused the table or parameters (code {rc})")
        self._step = lib.sd_renderer_step
        self._lib = lib

    def reset(self, t0: float = 0.0) -> None:
        self._lib.sd_renderer_reset(self._state, t0)

    def step(self, x: float, y: float) -> float:
        return self._step(self._state, x, y)


class CEngine(RenderEngine):
    """Emulator engine (the :class:`~.engine.RenderEngine` interface) rendering every tick in C."""

    def __init__(self, table, model: str, tick_rate_hz: int, stream_rate_hz: int, input_kind: int):
        super().__init__(table, model, tick_rate_hz, stream_rate_hz, input_kind,
                         renderer=CRenderer(table, model=model, tick_rate=float(tick_rate_hz)))
