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
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..runtime.layouts import RENDER_CONFIG, ctypes_struct
from .engine import RenderEngine

#: The C runtime sources, shipped inside the package (``runtime-c/`` in a checkout links here).
RUNTIME_C = Path(__file__).resolve().parent.parent / "runtime_c"
SOURCES = ("sd_pad.c", "sd_exact.c", "sd_render.c", "sd_image.c")
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared")
#: Models with a C tick (``sd_model_tick``); ids are shared with the Python registry.
C_MODELS = ("exact", "jump")
_Config = ctypes_struct(RENDER_CONFIG)


_LIB = None


def library() -> ctypes.CDLL:
    """Build (once per source version) and load the C runtime as a shared library."""
    global _LIB
    if _LIB is not None:
        return _LIB
    srcs = [RUNTIME_C / n for n in SOURCES]
    if not all(p.is_file() for p in srcs):
        raise InputError(f"the C engine needs the runtime-c sources (not found in {RUNTIME_C}); "
                         "use the default Python engine")
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        raise InputError("the C engine needs a C compiler (cc, gcc or clang); use the default Python engine")
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in [*srcs, *sorted(RUNTIME_C.glob("*.h"))])
                            + " ".join(CFLAGS).encode()).hexdigest()[:16]
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "shapedisplay"
    lib_path = cache / f"sd_runtime-{digest}.so"
    if not lib_path.is_file():
        cache.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=cache) as d:
            tmp = Path(d) / lib_path.name
            res = subprocess.run([cc, *CFLAGS, "-I", str(RUNTIME_C), *map(str, srcs), "-lm", "-o", str(tmp)],
                                 capture_output=True, text=True, timeout=300)
            if res.returncode != 0:
                raise InputError(f"building the C engine failed: {res.stderr.strip().splitlines()[-1:]}")
            os.replace(tmp, lib_path)
    lib = ctypes.CDLL(str(lib_path))
    lib.sd_renderer_size.restype = ctypes.c_size_t
    lib.sd_image_size.restype = ctypes.c_size_t
    lib.sd_image_load.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t]
    lib.sd_image_load.restype = ctypes.c_int
    lib.sd_image_config.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Config)]
    lib.sd_renderer_init.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.POINTER(_Config)]
    lib.sd_renderer_init.restype = ctypes.c_int
    lib.sd_renderer_reset.argtypes = [ctypes.c_void_p, ctypes.c_double]
    lib.sd_renderer_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double]
    lib.sd_renderer_step.restype = ctypes.c_double
    _LIB = lib
    return lib


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
