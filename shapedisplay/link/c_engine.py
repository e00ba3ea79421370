"""The C runtime (``runtime-c/``) as the emulator's rendering engine, through ctypes.

``shapedisplay device emulate --engine c`` compiles the C99 runtime with the
system C compiler into a shared library (once per source version, in a cache
directory), binds the uploaded table to it and renders every tick in C, so
the whole path host -> pty -> firmware renderer runs the code a
microcontroller would. The C runtime is bit-identical to the Python renderer
(``tests/test_c_runtime.py``), so the samples are the same as with the
default Python engine.

Only for the emulator on a development machine: it needs the repository's
``runtime-c/`` sources and a C compiler.
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
from .emulator import RenderEngine

#: The C runtime sources, shipped inside the package (``runtime-c/`` in a checkout links here).
RUNTIME_C = Path(__file__).resolve().parent.parent / "runtime_c"
SOURCES = ("sd_pad.c", "sd_exact.c", "sd_render.c")
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared")
_SLOTS = ("normal_force", "friction_scale", "burst_gain", "grad_x", "grad_y", "lateral_x", "lateral_y",
          "skin_stretch", "breakaway_force", "kinetic_force")
_DTYPES = {"uint8": (0, np.uint8), "uint16": (1, np.uint16), "float32": (2, np.float32), "float64": (3, np.float64)}
_MODELS = {"jump": 0, "exact": 1}
_POLICIES = {"retrigger": 0, "add": 1, "max": 2}


class _PadParams(ctypes.Structure):
    _fields_ = [(n, ctypes.c_double) for n in ("mass", "stiffness", "damping", "burst_gain", "max_stick_period",
                                                "sig", "wn2", "disc", "wd", "tp", "e_tp")] + \
               [("under", ctypes.c_int), ("prepared", ctypes.c_int)]


class _Config(ctypes.Structure):
    _fields_ = [("pad", _PadParams)] + \
               [(n, ctypes.c_double) for n in ("mu_s", "mu_k", "k_mu", "skin_target", "tick_rate", "audio_rate",
                                               "carrier_hz", "rise_s", "decay_s")] + \
               [("policy", ctypes.c_int), ("model", ctypes.c_int)]


class _Channel(ctypes.Structure):
    _fields_ = [("codes", ctypes.c_void_p), ("dtype", ctypes.c_int), ("scale", ctypes.c_double),
                ("offset", ctypes.c_double), ("background", ctypes.c_double)]


class _Table(ctypes.Structure):
    _fields_ = [("rows", ctypes.c_int32), ("cols", ctypes.c_int32), ("dx", ctypes.c_double),
                ("dy", ctypes.c_double), ("x0", ctypes.c_double), ("y0", ctypes.c_double),
                ("n_blocks", ctypes.c_int32), ("blocks", ctypes.c_void_p),
                ("slot", ctypes.POINTER(_Channel) * len(_SLOTS))]


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
    lib.sd_renderer_init.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Table), ctypes.POINTER(_Config)]
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
        from ..runtime import renderer as R
        from ..runtime import pads
        if model not in _MODELS:
            raise InputError(f"the C engine offers models {sorted(_MODELS)} (got {model!r})")
        py = Renderer(table, model=model, tick_rate=tick_rate)
        self.device = py.device
        lib = library()
        p = py.model.params
        b = py.device.burst
        cfg = _Config()
        cfg.pad.mass, cfg.pad.stiffness, cfg.pad.damping = p[pads.P_M], p[pads.P_K], p[pads.P_C]
        cfg.pad.burst_gain, cfg.pad.max_stick_period = p[pads.P_B], p[pads.P_TMAX]
        cfg.mu_s, cfg.mu_k = py._cfg[R.CFG_MUS], py._cfg[R.CFG_MUK]
        cfg.k_mu, cfg.skin_target = py._cfg[R.CFG_KMU], py._cfg[R.CFG_SST]
        cfg.tick_rate, cfg.audio_rate = py.tick_rate, py.audio_rate
        cfg.carrier_hz, cfg.rise_s, cfg.decay_s = b.carrier_hz, b.rise_s, b.decay_s
        cfg.policy, cfg.model = _POLICIES[py.burst_policy], _MODELS[model]
        g = table.grid
        off = table.patch_offsets()
        # keep every buffer the C side points to alive as long as this object
        self._blocks = np.ascontiguousarray(
            [[r0, c0, *table.patch_shapes[i], off[i]] for r0, c0, i in table.blocks], dtype=np.int32).reshape(-1, 5)
        self._codes, self._channels = [], []
        tab = _Table(g.rows, g.cols, g.dx, g.dy, g.x0, g.y0, len(self._blocks), self._blocks.ctypes.data)
        for i, name in enumerate(_SLOTS):
            if name not in table.channels:
                continue
            q = table.quant[name]
            code, np_type = _DTYPES[q.dtype]
            arr = np.ascontiguousarray(table.codes[name], dtype=np.dtype(np_type).newbyteorder("="))
            ch = _Channel(arr.ctypes.data, code, q.scale, q.offset, table.background[name])
            self._codes.append(arr)
            self._channels.append(ch)
            tab.slot[i] = ctypes.pointer(ch)
        self._table, self._cfg = tab, cfg
        self._state = ctypes.create_string_buffer(lib.sd_renderer_size())
        rc = lib.sd_renderer_init(self._state, ctypes.byref(tab), ctypes.byref(cfg))
        if rc != 0:
            raise InputError(f"the C renderer refused the table or parameters (code {rc})")
        self._step = lib.sd_renderer_step
        self._lib = lib

    def reset(self, t0: float = 0.0) -> None:
        self._lib.sd_renderer_reset(self._state, t0)

    def step(self, x: float, y: float) -> float:
        return self._step(self._state, x, y)


class CEngine(RenderEngine):
    """Emulator engine (the :class:`~.emulator.RenderEngine` interface) rendering every tick in C."""

    def __init__(self, table, model: str, tick_rate_hz: int, stream_rate_hz: int, input_kind: int):
        super().__init__(table, model, tick_rate_hz, stream_rate_hz, input_kind,
                         renderer=CRenderer(table, model=model, tick_rate=float(tick_rate_hz)))
