"""The WebAssembly build of the C runtime, shipped inside the package.

``engine/wasm/sd_runtime.wasm`` is the C runtime (double precision, the
same sources as the host build) compiled with ``clang --target=wasm32-wasi``
against wasi-libc's libm; it imports nothing, so a browser AudioWorklet
instantiates it with an empty import object. ``engine/wasm/sd_wasm.js`` is
its JavaScript wrapper and ``sd_worklet.js`` an AudioWorkletProcessor built
on it (API in ``engine/README.md``). ``make -C runtime-c wasm-package``
rebuilds the shipped module from the sources; ``sd_runtime.wasm.sources``
records the digest of the sources it was built from, and :func:`is_current`
compares it with the sources in the package.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

RUNTIME_C = Path(__file__).resolve().parent.parent / "engine"
WASM_DIR = RUNTIME_C / "wasm"
MODULE = WASM_DIR / "sd_runtime.wasm"
WRAPPER = WASM_DIR / "sd_wasm.js"
WORKLET = WASM_DIR / "sd_worklet.js"


def sources_digest(folder: Path = RUNTIME_C) -> str:
    """sha256 of every module source (``sd_*.c``, ``sd_*.h``) concatenated in name order, as the Makefile."""
    h = hashlib.sha256()
    for p in sorted(list(folder.glob("sd_*.c")) + list(folder.glob("sd_*.h")), key=lambda p: p.name):
        h.update(p.read_bytes())
    return h.hexdigest()


def is_current() -> bool:
    """True if the shipped module was built from the sources in the package."""
    rec = MODULE.with_name(MODULE.name + ".sources")
    return MODULE.is_file() and rec.is_file() and rec.read_text().strip() == sources_digest()
