"""The WebAssembly C runtime for the studio page, and tables as it loads them.

The page plays tables with the C runtime compiled to WebAssembly
(``runtime_c/wasm/sd_runtime.wasm``, built by ``make -C runtime-c
wasm-package`` and shipped in the package, with its JavaScript wrapper
``sd_wasm.js``): the same C sources as firmware. There is no renderer written
in JavaScript.

:func:`table_payload` gives the module a table: its binary image
(``shapedisplay export --format bin``, validated and bound in place by
``sd_image_load``) and the rates, policy and model the Python
:class:`~shapedisplay.runtime.Renderer` resolves for it.
"""
from __future__ import annotations

import sys

from ..errors import InputError, MissingDependencyError

_MODULE: bytes | None = None


def module_bytes() -> bytes:
    """The shipped WebAssembly module (a warning if it was built from other C sources)."""
    global _MODULE
    if _MODULE is None:
        from ..runtime.wasm import MODULE, is_current
        if not MODULE.is_file():
            raise MissingDependencyError(f"the studio needs the WebAssembly C runtime {MODULE}; "
                                         "build it with: make -C runtime-c wasm-package")
        if not is_current():
            print(f"shapedisplay studio: warning: {MODULE.name} was built from other C sources than the package "
                  "holds; rebuild it with: make -C runtime-c wasm-package", file=sys.stderr)
        _MODULE = MODULE.read_bytes()
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
    from ..link.c_engine import C_MODELS
    from ..runtime import Renderer
    from ..runtime.image import SLOTS, to_image
    if model not in C_MODELS:
        raise InputError(f"the page's C runtime plays models {sorted(C_MODELS)} (got {model!r})")
    py = Renderer(table, model=model)
    image = to_image(table, py.device)
    g = table.grid
    layout = {"grid": {"rows": g.rows, "cols": g.cols, "dx": g.dx, "dy": g.dy, "x0": g.x0, "y0": g.y0},
              "channels": [{"name": n, "slot": s} for s, n in enumerate(SLOTS) if n in table.channels],
              "tick_rate": py.tick_rate, "audio_rate": py.audio_rate, "policy": py.burst_policy,
              "model": model, "cursor_gain": float(py.device.cursor_gain),
              "bytes": len(image)}
    return layout, image
