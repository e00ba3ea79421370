"""Build step of the runtime: writes the files derived from the model registry and the layouts.

``make generate`` (``python -m shapedisplay.runtime.codegen``) writes

* ``runtime/dispatch.py`` — :func:`model_tick`, :func:`run_ticks` (and
  :func:`run_block` and :func:`run_block_grow`, its one-call forms for
  ``run_kernel``), one
  branch per model of :data:`~.models.MODELS` (numba cannot cache a
  function that picks a kernel from a table of functions, so the branches
  are written out);
* ``runtime_c/sd_layout.h`` — the C structs and enums of :mod:`.layouts`;
* the ``KERNEL_SOURCES_SHA256`` line of every runtime module whose cached
  kernels call kernels (or read constants) in other files.

Why the hash lines: numba's on-disk cache of a function is keyed on the
source file that defines it (its modification time and size), not on the
files of the functions it calls. Change ``pads.py`` and a cached
``renderer.online_step`` would keep running the old pad kernel compiled into
it. The line ``KERNEL_SOURCES_SHA256 = "<sha256 of the files it compiles
in>"`` makes the caller's own file change whenever a callee's file does, so
numba recompiles it. ``--check`` (and ``tests/test_layouts.py``) fails when
any generated text is out of date.
"""
from __future__ import annotations

import argparse
import hashlib
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
C_DIR = HERE.parent / "runtime_c"

#: Runtime modules whose cached kernels use other files, and those files (in generation order).
KERNEL_DEPENDENCIES = {
    "dispatch.py": ("pads.py", "layouts.py", "borrow.py"),
    "bursts.py": ("layouts.py", "exactdiv.py", "borrow.py"),
    "renderer.py": ("dispatch.py", "lookup.py", "bursts.py", "layouts.py", "exactdiv.py", "borrow.py"),
}
_HASH_LINE = re.compile(r'^KERNEL_SOURCES_SHA256 = "[0-9a-f]*"$', re.M)
_OUTS = ("out_f, out_state, out_x, out_v, out_wf, out_wd")
_RENDER_OUTS = "out_f, out_phase"
_ARGS = "prm, t[i - 1], {h}, {V}, N[i], mus[i], muk[i], gain[i], ev_t, ev_a, n_ev"
# render_ticks: mus, muk and gain may hold one value for every tick (shape (1,)): index i & 0 = 0
_RENDER_ARGS = ("prm, t[i - 1], {h}, {V}, N[i], mus[unsigned(i) & ms], muk[unsigned(i) & mk], "
                "gain[unsigned(i) & mg], ev_t, ev_a, n_ev")


def _kernel_call(kernel: str, prepared, args: str, render: bool) -> tuple[str, str]:
    """``(before the loop, call)``: a tick of the model in a loop, through its prepared form if it has one
    (its constants once before the loop; the work terms only on the last tick of ``render_ticks``)."""
    if prepared is None:
        return "", f"pads.{kernel}(st, {args})"
    constants, tick = prepared
    return (f"pc = pads.{constants}(prm)\n        ",
            f"pads.{tick}(st, {args}, pc, {'i == n - 1' if render else 'True'})")


def _stick_fast_branch(mid: int, kernel: str, with_work: bool, render: bool = False, prepared=None) -> str:
    """One model's branch of ``run_ticks`` (``render``: of ``render_ticks``, which stores friction and phase only)."""
    if render:
        stores = ("out_f[u] = fe\n"
                  "                    out_phase[u] = 0")
        keep = "xa = x\n                    " if with_work else ""
        last_work = ("            Vi = V[n - 1]\n"
                     "            h = t[n - 1] - t[n - 2]\n"
                     "            fa = k * xa + c * Vi\n"
                     "            st.work_friction = fa * Vi * h + 0.5 * k * Vi * Vi * h * h\n"
                     "            st.work_damping = c * Vi * Vi * h\n") if with_work else \
            ("            st.work_friction = 0.0\n"
             "            st.work_damping = 0.0\n")
        outs, store = _RENDER_OUTS, "_store_render"
        start = "xa = x\n        " if with_work else ""
        args, mus_u = _RENDER_ARGS, "mus[u & ms]"
    else:
        work = ("out_wf[u] = fa * Vi * h + 0.5 * k * Vi * Vi * h * h\n"
                "                    out_wd[u] = c * Vi * Vi * h") if with_work else \
            ("out_wf[u] = 0.0\n"
             "                    out_wd[u] = 0.0")
        stores = ("out_f[u] = fe\n"
                  "                    out_state[u] = 0.0\n"
                  "                    out_x[u] = xe\n"
                  "                    out_v[u] = Vi\n"
                  f"                    {work}")
        keep = ""
        last_work = ("            st.work_friction = out_wf[n - 1]\n"
                     "            st.work_damping = out_wd[n - 1]\n")
        outs, store = _OUTS, "_store"
        start = ""
        args, mus_u = _ARGS, "mus[u]"
    before, call = _kernel_call(kernel, prepared, args.format(h="h", V="Vi"), render)
    return f'''    if model == {mid}:
        # Stuck ticks (the common case) run inline with the stretch in a register; the
        # kernel runs when a breakaway may happen or the pad slips. Same arithmetic as
        # pads._stuck_whole_tick.
        k = prm.stiffness
        c = prm.damping
        fast_ok = prm.max_stick_period == 0.0
        {before}x = st.x
        {start}phase = st.phase
        synced = True
        i = 1
        while i < n:
            if fast_ok and phase == 0.0:
                # a run of stuck ticks, in a loop of its own (its values stay in registers)
                while i < n:
                    u = unsigned(i)
                    Vi = V[u]
                    h = t[u] - t[unsigned(i - 1)]
                    xe = x + Vi * h
                    fa = k * x + c * Vi
                    fe = k * xe + c * Vi
                    thr = {mus_u} * N[u]
                    if not (abs(fa) < thr and abs(fe) < thr):
                        break
                    {keep}x = xe
                    {stores}
                    synced = False
                    i += 1
                if i == n:
                    break
            Vi = V[i]
            h = t[i] - t[i - 1]
            if not synced:
                st.x = x
            n_ev = {call}
            {store}(st, i, {outs})
            x = st.x
            phase = st.phase
            synced = True
            i += 1
        if not synced:
            st.x = x
            st.v = V[n - 1]
            st.f = out_f[n - 1]
{last_work}            st.n_events = 0
        return n_ev
'''


def _plain_branch(mid: int, kernel: str, render: bool = False, prepared=None) -> str:
    store, outs, args = ("_store_render", _RENDER_OUTS, _RENDER_ARGS) if render else ("_store", _OUTS, _ARGS)
    before, call = _kernel_call(kernel, prepared, args.format(h="t[i] - t[i - 1]", V="V[i]"), render)
    return f'''    if model == {mid}:
        {before}for i in range(1, n):
            n_ev = {call}
            {store}(st, i, {outs})
        return n_ev
'''


def _tick_loop(name: str, outs: str, store: str, doc: str, branches: str, masks: str = "") -> str:
    """Text of one generated tick loop over every model (``run_ticks``, ``render_ticks``): the same
    prologue, tick 0 stored with ``store``, then each model's branch (``masks``: lines after the
    prologue)."""
    return f'''@njit(cache=True)
def {name}(model, state, params, t, V, N, mus, muk, gain, {outs},
{" " * (len(name) + 5)}ev_t, ev_a):
{doc}    st = state[0]
    prm = params[0]
    # the event rows as the kernels take them: without a reference count to change at every call
    ev_t = borrowed(ev_t)
    ev_a = borrowed(ev_a)
    n = t.shape[0]
    n_ev = 0
    if n == 0:
        return 0
    st.work_friction = 0.0
    st.work_damping = 0.0
    {store}(st, 0, {outs})
{masks}{branches}    return n_ev
'''


_RUN_TICKS_DOC = '''    """Offline fast path: advance model number ``model`` over ``n`` ticks.

    ``state`` and ``params`` are one-element PAD_STATE and PAD_PARAMS arrays
    (the state is updated in place).

    Tick ``i`` runs from ``t[i-1]`` to ``t[i]`` with inputs ``V[i], N[i], ...``
    (tick 0 has zero length and only reports the initial state). Writes
    per-tick outputs (state at the end of the tick) into ``out_*`` (shape
    (n,)) and returns the total number of events (may exceed ``ev_t.size``;
    then only the first ``ev_t.size`` are stored). The model branch is taken
    once, outside the tick loop.
    """
'''

_RENDER_TICKS_DOC = '''    """:func:`run_ticks` for the offline render, which keeps only the friction force and the phase:
    ``out_f`` float64 and ``out_phase`` int8 (the phase converted as numpy's ``astype`` does), shape
    (n,). The same model arithmetic, state and events as :func:`run_ticks`; the other four rows are not
    written (less memory traffic per tick). Each of ``mus``, ``muk`` and ``gain`` has shape (n,) or (1,),
    one value for every tick (not written out per tick, nor read per tick).
    """
'''

_RENDER_MASKS = """    ms = unsigned(-1 if mus.shape[0] == n else 0)
    mk = unsigned(-1 if muk.shape[0] == n else 0)
    mg = unsigned(-1 if gain.shape[0] == n else 0)
"""


def dispatch_source(registry) -> str:
    """Text of ``runtime/dispatch.py`` for ``registry`` = ((name, kernel name, stick fast path, prepared kernel),
    ...) (:func:`~.models.registry_entries`)."""
    entries = "".join(f"    ({n!r}, {k!r}, {f!r}, {p!r}),\n" for n, k, f, p in registry)
    ticks = "".join(f"    if model == {i}:\n"
                    f"        return pads.{k}(st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev)\n"
                    for i, (_, k, _, _) in enumerate(registry))
    branches = "".join(_stick_fast_branch(i, k, f == "with_work", prepared=p) if f else _plain_branch(i, k, prepared=p)
                       for i, (_, k, f, p) in enumerate(registry))
    render_branches = "".join(_stick_fast_branch(i, k, f == "with_work", True, p) if f
                              else _plain_branch(i, k, True, p) for i, (_, k, f, p) in enumerate(registry))
    run_ticks = _tick_loop("run_ticks", _OUTS, "_store", _RUN_TICKS_DOC, branches)
    render_ticks = _tick_loop("render_ticks", _RENDER_OUTS, "_store_render", _RENDER_TICKS_DOC, render_branches,
                              _RENDER_MASKS)
    return f'''"""Kernel dispatch by model id. GENERATED by `make generate` from runtime.models.MODELS: do not edit.

A model id is the position of the model in ``MODELS`` (``SD_MODEL_*`` in
C). numba caches these functions on disk; a table of kernel functions
indexed at run time cannot be cached, so each model gets its branch here,
written out by :mod:`.codegen`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from . import pads
from .borrow import borrowed, unsigned
from .layouts import PAD_PARAMS, PAD_STATE

#: (model name, kernel in pads, stick fast path, prepared kernel) per model id; models.check_dispatch checks it
#: against MODELS.
REGISTRY = (
{entries})
#: See shapedisplay.runtime.codegen: numba's cache does not notice changes to the kernels in pads.py
#: or to the layouts run_block views its arguments as.
KERNEL_SOURCES_SHA256 = ""


@njit(cache=True)
def model_tick(model, st, prm, t0, h, V, N, mus, muk, gain, ev_t, ev_a, n_ev):
    """Advance model number ``model`` by one tick (signature in :mod:`.pads`); an unknown id does nothing."""
{ticks}    return n_ev


@njit(cache=True)
def _store(st, i, out_f, out_state, out_x, out_v, out_wf, out_wd):
    out_f[i] = st.f
    out_state[i] = st.phase
    out_x[i] = st.x
    out_v[i] = st.v
    out_wf[i] = st.work_friction
    out_wd[i] = st.work_damping


{run_ticks}

#: Float64 words of a PAD_STATE (run_block keeps the final state in row 8 of its block).
STATE_WORDS = PAD_STATE.itemsize // 8


@njit(cache=True)
def run_block(model, init, params, t, V, N, mus, muk, gain, block):
    """:func:`run_ticks` as :func:`~.models.run_kernel` calls it, in one call from Python, everything
    written into one float64 block.

    ``init`` is the initial PAD_STATE and ``params`` the PAD_PARAMS, each as the float64 view of a
    one-element array (not changed; numba checks a plain float64 array's type in a fraction of the
    time it takes for a structured one). ``block`` is float64 ``(9, n)`` with ``n >= STATE_WORDS``:
    rows 0-5 get the per-tick outputs (friction, phase, x, v, work of friction, work of damping),
    rows 6 and 7 the event times and amplitudes (room for ``n`` events), row 8 starts with the final
    state. Returns ``(n_events, truncated)``, the state's ``truncated`` count (read here: a field of
    a record costs far more from Python); with more than ``n`` events only the first ``n`` are
    stored (:func:`run_block_grow` then runs the path again). Two integers back: numba turns each
    array it returns into a Python object (about 0.4 us each), and on a path of a few hundred ticks
    the call itself costs about as much as the tick loop.
    """
    prm = params.view(PAD_PARAMS)
    srow = block[8]
    srow[:STATE_WORDS] = init
    state = srow[:STATE_WORDS].view(PAD_STATE)
    n_ev = run_ticks(model, state, prm, t, V, N, mus, muk, gain, block[0], block[1], block[2], block[3],
                     block[4], block[5], block[6], block[7])
    return n_ev, state[0].truncated


@njit(cache=True)
def run_block_grow(model, init, params, t, V, N, mus, muk, gain, block, cap):
    """:func:`run_block` for the paths it cannot hold: ``block`` float64 ``(6, n)`` (the per-tick
    outputs only), ``cap`` the first size of the event buffer (grown and the run repeated from
    ``init`` when a path has more events). Returns ``(state, events, truncated)``: the final
    one-element PAD_STATE array, the ``(2, n_events)`` event times and amplitudes and the state's
    ``truncated`` count.
    """
    prm = params.view(PAD_PARAMS)
    while True:
        state = init.copy().view(PAD_STATE)
        ev = np.empty((2, cap))
        n_ev = run_ticks(model, state, prm, t, V, N, mus, muk, gain, block[0], block[1], block[2], block[3],
                         block[4], block[5], ev[0], ev[1])
        if n_ev <= cap:
            return state, ev[:, :n_ev].copy(), state[0].truncated
        cap = n_ev + 64


@njit(cache=True)
def _store_render(st, i, out_f, out_phase):
    out_f[i] = st.f
    out_phase[i] = st.phase


{render_ticks}'''


def _with_hash(text: str, digest: str, name: str) -> str:
    if len(_HASH_LINE.findall(text)) != 1:
        raise SystemExit(f"{name}: expected one line `KERNEL_SOURCES_SHA256 = \"...\"`")
    return _HASH_LINE.sub(f'KERNEL_SOURCES_SHA256 = "{digest}"', text)


def generated_files(root: Path = HERE) -> dict[Path, str]:
    """Every generated file and its text as it should be (reads the current sources under ``root``)."""
    from .models import MODELS, registry_entries
    texts: dict[str, str] = {"dispatch.py": dispatch_source(registry_entries())}
    for name, deps in KERNEL_DEPENDENCIES.items():
        current = texts.get(name)
        if current is None:
            current = (root / name).read_text()
        blob = b"".join((texts[d] if d in texts else (root / d).read_text()).encode() for d in deps)
        texts[name] = _with_hash(current, hashlib.sha256(blob).hexdigest(), name)
    from .layouts import c_header
    out = {root / n: t for n, t in texts.items()}
    out[root.parent / "runtime_c" / "sd_layout.h"] = c_header(list(MODELS))
    return out


def stale_files(root: Path = HERE) -> list[Path]:
    """Generated files whose text on disk differs from what ``make generate`` would write."""
    return [p for p, text in generated_files(root).items() if not p.is_file() or p.read_text() != text]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m shapedisplay.runtime.codegen", description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only report files that are out of date (exit 1)")
    args = ap.parse_args(argv)
    if args.check:
        stale = stale_files()
        for p in stale:
            print(f"out of date: {p} (run `make generate`)", file=sys.stderr)
        return 1 if stale else 0
    for p, text in generated_files().items():
        if not p.is_file() or p.read_text() != text:
            p.write_text(text)
            print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
