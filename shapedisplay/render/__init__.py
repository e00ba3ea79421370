"""Runtime stick-slip renderer: plays a friction-envelope table as the cursor moves.

Runtime side only: imports ``table``, ``devices``, ``units``, ``errors`` and
``atomic`` and nothing from the authoring side. The C engine
(``shapedisplay/engine/``, compiled into the extension
``shapedisplay._engine``) is the one implementation of what plays a table;
these modules bind it. Submodules:

* :mod:`.layouts` — the named memory layouts (numpy structured dtypes, the C
  engine's structs byte for byte) and the numberings shared with C;
* :mod:`.models` — ``MODELS`` registry (parameters of each pad model),
  :func:`run_kernel` (a model's C tick over per-tick inputs),
  :func:`simulate_pad` (no table);
* :mod:`.cursor` — strokes, recorded traces and force input;
* :mod:`.bursts` — burst envelope, carrier and overlap policies (the engine's bursts over a list of events);
* :mod:`.renderer` — :class:`Renderer` (offline ``render`` and online ``step``);
* :mod:`.settings` — a renderer's validated settings;
* :mod:`.native` — the C engine as a shared library (ctypes);
* :mod:`.codegen` — the build step (``make generate``) that writes
  ``engine/sd_layout.h``.

Adding a pad model
------------------
1. **C tick**: ``sd_NAME_tick`` with the ``sd_tick_fn`` signature in
   ``engine/`` (its own ``sd_NAME.c``, which ``setup.py``, the WebAssembly
   and the M4F builds pick up), reading and writing the members of
   ``sd_pad_state_t`` and ``sd_pad_params_t`` (a parameter the model needs
   is a named field of :data:`~.layouts.PAD_PARAMS`, with its unit in the
   comment), and its line in the ``TICKS`` table of ``sd_render.c``.
2. **Class and registry line**: a :class:`~.models.PadModel` subclass with
   ``name`` and a ``pack()`` that fills its parameters, appended to
   :data:`~.models.MODELS` (its position is its model id, in Python and C
   alike).
3. ``make generate``: writes its ``SD_MODEL_NAME`` id (and any new field) in
   ``engine/sd_layout.h``; ``pip install -e .`` rebuilds the engine.
4. **Tests** against independent answers: closed forms, ``scipy.integrate.solve_ivp``
   at tight tolerance, the published figures.
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
    raise AttributeError(f"module 'shapedisplay.render' has no attribute {name!r}")


__all__ = list(_LAZY)
