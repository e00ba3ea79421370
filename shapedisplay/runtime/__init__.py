"""Runtime stick-slip renderer: plays a friction-envelope table as the cursor moves.

Runtime side only: imports ``table``, ``devices``, ``units``, ``errors`` and
``atomic`` and nothing from the authoring side. Submodules:

* :mod:`.pads` — numba per-tick kernels of every pad/friction model;
* :mod:`.models` — ``MODELS`` registry, :func:`simulate_pad` (no table);
* :mod:`.cursor` — strokes, recorded traces and force input;
* :mod:`.bursts` — burst envelope, carrier and overlap policies;
* :mod:`.lookup` — numba bilinear lookup in packed tables;
* :mod:`.renderer` — :class:`Renderer` (offline ``render`` and online ``step``).
"""
from __future__ import annotations

import importlib

_LAZY = {
    "MODELS": "models",
    "PadModel": "models",
    "PadResult": "models",
    "simulate_pad": "models",
    "get_model": "models",
    "Renderer": "renderer",
    "RenderResult": "renderer",
    "CursorPath": "cursor",
    "parse_stroke": "cursor",
    "load_trace_csv": "cursor",
    "force_input": "cursor",
    "BURST_POLICIES": "bursts",
    "render_bursts": "bursts",
}


def __getattr__(name):
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'shapedisplay.runtime' has no attribute {name!r}")


__all__ = list(_LAZY)
