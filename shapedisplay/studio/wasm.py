"""The C runtime as WebAssembly for the studio page, and tables laid out for it.

The page plays tables with the C runtime (``runtime_c/``) compiled to
WebAssembly: the same C sources as firmware, plus the studio's entry points
(``wasm/sd_studio.c``: bind a table laid out in linear memory, step, read the
outputs). There is no renderer written in JavaScript.

:func:`module_bytes` builds the module with clang (``--target=wasm32-wasi``,
libm from wasi-libc, no imports) into a temporary folder when the studio
starts, so it always matches the C sources; a prebuilt ``sd_studio.wasm`` next
to this file (for installs without clang) is used otherwise.

:func:`table_payload` lays a table out for the module: the block list and the
codes of every stored renderer channel in one little-endian buffer, with a JSON
description (offsets, code types, scales) and the C configuration taken from a
Python :class:`~shapedisplay.runtime.Renderer` (the one place the parameters
are validated).
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from ..errors import InputError, MissingDependencyError

HERE = Path(__file__).resolve().parent
RUNTIME_C = HERE.parent / "runtime_c"
SHIM = HERE / "wasm" / "sd_studio.c"
PREBUILT = HERE / "wasm" / "sd_studio.wasm"
#: Flags: the runtime's own (C99, no FMA contraction) for the wasm32 target with wasi-libc's libm.
WASM_FLAGS = ("--target=wasm32-wasi", "-std=c99", "-O2", "-Wall", "-Wextra", "-ffp-contract=off",
              "-nostartfiles", "-Wl,--no-entry")
#: Where Debian's wasi-libc puts its headers and libraries.
WASI_SYSROOTS = ("/usr/share/wasi-sysroot", "/usr")
_CODE_TYPES = {"uint8": 0, "uint16": 1, "float32": 2, "float64": 3}
_MODULE: bytes | None = None


def _sysroot() -> tuple[str, list[str]] | None:
    for root in WASI_SYSROOTS:
        r = Path(root)
        for inc, lib in ((r / "include" / "wasm32-wasi", r / "lib" / "wasm32-wasi"),
                         (r / "include", r / "lib" / "wasm32-wasi")):
            if (inc / "math.h").is_file() and (lib / "libm.a").is_file():
                return root, ["-isystem", str(inc), f"-L{lib}"]
    return None


def build_module(out: Path) -> Path:
    """Compile the C runtime and the studio entry points to ``out`` (.wasm)."""
    from ..link.c_engine import SOURCES
    clang = shutil.which("clang")
    sysroot = _sysroot()
    if clang is None or sysroot is None:
        raise MissingDependencyError(
            "the studio builds the C runtime to WebAssembly and needs clang, lld and wasi-libc "
            "(Debian: apt-get install clang lld wasi-libc libclang-rt-dev-wasm32, "
            "or run scripts/install-system-deps.sh --with-studio)")
    root, extra = sysroot
    cmd = [clang, *WASM_FLAGS, f"--sysroot={root}", *extra, "-I", str(RUNTIME_C),
           *(str(RUNTIME_C / s) for s in SOURCES), str(SHIM), "-lm", "-o", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if res.returncode != 0:
        last = (res.stderr.strip().splitlines() or ["(no message)"])[-1]
        raise InputError(f"building the WebAssembly runtime failed: {last}")
    return out


def module_bytes() -> bytes:
    """The WebAssembly module (built once per process; the prebuilt one without clang)."""
    global _MODULE
    if _MODULE is None:
        try:
            with tempfile.TemporaryDirectory(prefix="sd-wasm-") as d:
                _MODULE = build_module(Path(d) / "sd_studio.wasm").read_bytes()
        except MissingDependencyError:
            if not PREBUILT.is_file():
                raise
            _MODULE = PREBUILT.read_bytes()
    return _MODULE


def renderer_for(table, model: str = "exact", audio_rate: float | None = None):
    """The Python renderer whose parameters the page's C renderer takes (validates them)."""
    from ..runtime import Renderer
    return Renderer(table, model=model, audio_rate=audio_rate)


def table_payload(table, model: str = "exact") -> tuple[dict, bytes]:
    """Lay ``table`` out for the module.

    Returns
    -------
    layout : dict
        ``grid`` (rows, cols, dx, dy, x0, y0), ``n_blocks``, ``blocks_offset``,
        ``channels`` (per renderer slot: name, slot, offset, code type, scale,
        offset value, background), ``config`` (the C configuration: pad and
        renderer fields), ``bytes`` (payload length) and ``slots`` (the
        renderer's slot names, in C order).
    payload : bytes
        Little-endian int32 blocks (n_blocks x 5: row0, col0, rows, cols,
        offset) then each channel's codes, every part 8-byte aligned.
    """
    from ..link.c_engine import config_values
    from ..runtime.renderer import SLOTS
    py = renderer_for(table, model)
    g = table.grid
    off = table.patch_offsets()
    blocks = np.asarray([[r0, c0, *table.patch_shapes[i], off[i]] for r0, c0, i in table.blocks],
                        dtype="<i4").reshape(-1, 5)
    parts, pos = [], 0

    def put(arr: np.ndarray) -> int:
        nonlocal pos
        start = pos
        data = arr.tobytes()
        pad = (-len(data)) % 8
        parts.append(data + b"\0" * pad)
        pos += len(data) + pad
        return start

    layout = {"grid": {"rows": g.rows, "cols": g.cols, "dx": g.dx, "dy": g.dy, "x0": g.x0, "y0": g.y0},
              "n_blocks": int(blocks.shape[0]), "blocks_offset": put(blocks), "channels": [],
              "slots": list(SLOTS)}
    for slot, name in enumerate(SLOTS):
        if name not in table.channels:
            continue
        q = table.quant[name]
        codes = np.ascontiguousarray(table.codes[name]).astype(np.dtype(q.dtype).newbyteorder("<"), copy=False)
        layout["channels"].append({"name": name, "slot": slot, "offset": put(codes), "dtype": _CODE_TYPES[q.dtype],
                                   "scale": q.scale, "value_offset": q.offset,
                                   "background": table.background[name]})
    layout["config"] = config_values(py)
    layout["bytes"] = pos
    return layout, b"".join(parts)
