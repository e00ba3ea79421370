"""Runtime stick-slip renderer: plays a friction-envelope table as the cursor moves.

Runtime side only: imports ``table``, ``devices``, ``units``, ``errors`` and
``atomic`` and nothing from the authoring side. Submodules:

* :mod:`.layouts` — the named memory layouts of the kernels (numpy structured
  dtypes, used as numba records) and the numberings shared with the C runtime;
* :mod:`.pads` — numba per-tick kernels of every pad/friction model;
* :mod:`.models` — ``MODELS`` registry, :func:`simulate_pad` (no table);
* :mod:`.dispatch` — kernel by model id (generated from ``MODELS``);
* :mod:`.cursor` — strokes, recorded traces and force input;
* :mod:`.bursts` — burst envelope, carrier and overlap policies;
* :mod:`.lookup` — numba bilinear lookup in packed tables;
* :mod:`.renderer` — :class:`Renderer` (offline ``render`` and online ``step``);
* :mod:`.settings` — a renderer's validated settings (numba-free; both engines use them);
* :mod:`.native` — the C runtime as a shared library (ctypes) and offline play through it;
* :mod:`.play` — :class:`PathRenderer`: offline play with the C runtime or the numba kernels;
* :mod:`.codegen` — the build step (``make generate``) that writes
  ``dispatch.py``, ``runtime_c/sd_layout.h`` and the kernel-source hashes.

Adding a pad model
------------------
1. **Kernel**: ``NAME_tick(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev)``
   in :mod:`.pads`, ``@njit(cache=True)``, reading and writing named fields of
   the :data:`~.layouts.PAD_STATE` record ``st`` and the
   :data:`~.layouts.PAD_PARAMS` record ``prm`` (a parameter the model needs is
   a named field there, with its unit in the comment).
2. **Class and registry line**: a :class:`~.models.PadModel` subclass with
   ``name``, ``kernel = Kernel("NAME_tick")`` (named, imported on first use) and a ``pack()`` that fills its
   parameters, appended to :data:`~.models.MODELS` (its position is its model
   id, in Python and C alike).
3. ``make generate``: writes the model's branches in :mod:`.dispatch`, its
   ``SD_MODEL_NAME`` id in ``runtime_c/sd_layout.h`` and the kernel-source
   hashes. Nothing else dispatches on model ids.
4. **C function** (if the firmware should offer it): ``sd_NAME_tick`` with the
   ``sd_tick_fn`` signature in ``runtime_c/``, and its line in the ``TICKS``
   table of ``sd_render.c``; ``tests/test_c_runtime.py`` holds it to the
   Python kernel bit for bit.

Why ``make generate`` also writes hashes: numba keys the on-disk cache of a
compiled function on its own source file only, so a cached function that
calls a kernel in another file would keep the old kernel after that file
changed. Each module whose cached kernels call into other files carries a
``KERNEL_SOURCES_SHA256`` line with the hash of those files (see
:mod:`.codegen`); ``tests/test_layouts.py`` fails while any is stale.
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
    "RenderResult": "result",
    "PathRenderer": "play",
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
