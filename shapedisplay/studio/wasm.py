"""The C runtime as WebAssembly for the studio page, and tables laid out for it.

The page plays tables with the C runtime (``runtime_c/``) compiled to
WebAssembly: the same C sources as firmware, plus the studio's entry points
(``wasm/sd_studio.c``: load a binary table image from linear memory, step,
read the outputs). There is no renderer written in JavaScript.

:func:`module_bytes` builds the module with clang (``--target=wasm32-wasi``,
libm from wasi-libc, no imports) into a temporary folder when the studio
starts, so it always matches the C sources; a prebuilt ``sd_studio.wasm`` next
to this file (for installs without clang) is used otherwise.

:func:`table_payload` gives the module a table: its binary image
(``shapedisplay export --format bin``, validated and bound in place by
``sd_image_load``) and the rates, policy and model the Python
:class:`~shapedisplay.runtime.Renderer` resolves for it.
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

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


def table_payload(table, model: str = "exact") -> tuple[dict, bytes]:
    """The table as the module loads it: its binary image and what the page needs beside it.

    Returns
    -------
    layout : dict
        ``grid`` (rows, cols, dx, dy, x0, y0); ``channels`` (stored renderer
        channels: name and slot); ``tick_rate``, ``audio_rate`` (Hz),
        ``policy`` and ``model`` (the C runtime's codes) as the Python
        :class:`~shapedisplay.runtime.Renderer` resolves them for this table
        (the one place they are validated); ``out_names`` (the renderer's
        per-tick outputs, in C order); ``cursor_gain`` (m/(N s), the device's
        alpha); ``bytes`` (image length).
    image : bytes
        The flat binary table image (:func:`shapedisplay.runtime.image.to_image`).
    """
    from ..link.c_engine import _MODELS, _POLICIES
    from ..runtime import Renderer
    from ..runtime.image import SLOTS, to_image
    from ..runtime.renderer import OUT_NAMES
    if model not in _MODELS:
        raise InputError(f"the page's C runtime plays models {sorted(_MODELS)} (got {model!r})")
    py = Renderer(table, model=model)
    image = to_image(table, py.device)
    g = table.grid
    layout = {"grid": {"rows": g.rows, "cols": g.cols, "dx": g.dx, "dy": g.dy, "x0": g.x0, "y0": g.y0},
              "channels": [{"name": n, "slot": s} for s, n in enumerate(SLOTS) if n in table.channels],
              "tick_rate": py.tick_rate, "audio_rate": py.audio_rate, "policy": _POLICIES[py.burst_policy],
              "model": _MODELS[model], "out_names": list(OUT_NAMES), "cursor_gain": float(py.device.cursor_gain),
              "bytes": len(image)}
    return layout, image
