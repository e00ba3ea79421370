"""The WebAssembly C runtime for the studio page, and tables as it loads them.

The page plays tables with the C runtime compiled to WebAssembly
(``engine/wasm/sd_runtime.wasm``, built by ``make -C runtime-c
wasm-package`` and shipped in the package, with its JavaScript wrapper
``sd_wasm.js``): the same C sources as firmware. There is no renderer written
in JavaScript.

:func:`table_payload` gives the module a table: its binary image
(``shapedisplay export --format bin``, validated and bound in place by
``sd_image_load``), the rates, policy and model the Python
:class:`~shapedisplay.render.Renderer` resolves for it, and the pad
parameters of every model the page offers (:data:`~shapedisplay.render.native.C_MODELS`)
as the Python model classes derive them: the image carries only the basic pad
parameters, so the page hands a model's whole block to the module when it
switches to it (``sd_wasm_pad_block``, then ``sd_wasm_configure``).
"""
from __future__ import annotations

import base64
import sys

from shapedisplay.errors import InputError, MissingDependencyError, ShapeDisplayError

_MODULE: bytes | None = None


def module_bytes() -> bytes:
    """The shipped WebAssembly module (a warning if it was built from other C sources)."""
    global _MODULE
    if _MODULE is None:
        from shapedisplay.render.wasm import MODULE, is_current
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
        :class:`~shapedisplay.render.Renderer` resolves them for this table
        (the one place they are validated); ``out_names`` (the renderer's
        per-tick outputs, in C order); ``cursor_gain`` (m/(N s), the device's
        alpha); ``bytes`` (image length); ``models``: for each model the page
        offers, in :data:`~shapedisplay.render.native.C_MODELS` order,
        ``{"id": C model id, "pad": base64}`` with ``pad`` the model's
        :data:`~shapedisplay.render.layouts.PAD_PARAMS` record for this
        table's device (``get_model(name, device).params``) as little-endian
        float64, one per field in field order (integers as whole numbers;
        ``substep`` may be inf, which JSON cannot hold), or ``{"id": ...,
        "error": message}`` for a model that refuses the device;
        ``pad_fields`` (the field names); ``reactions``: the reactive widgets
        (docs/reactive.md) in the engine's order, ``{"id", "kind", "widget"}``
        and a slider's ``axis``, ``thumb_m``, ``cross_m``, ``thumb_r_m``;
        ``widget_ids``: the scene's widget ids (an event's ``widget`` indexes it).
    image : bytes
        The flat binary table image (:func:`shapedisplay.render.image.to_image`).
    """
    from shapedisplay.render import Renderer
    from shapedisplay.render.image import SLOTS, to_image
    from shapedisplay.render.layouts import PAD_PARAMS
    check_model(model)
    py = Renderer(table, model=model)
    image = to_image(table, py.device)
    g = table.grid
    layout = {"grid": {"rows": g.rows, "cols": g.cols, "dx": g.dx, "dy": g.dy, "x0": g.x0, "y0": g.y0},
              "channels": [{"name": n, "slot": s} for s, n in enumerate(SLOTS) if n in table.channels],
              "tick_rate": py.tick_rate, "audio_rate": py.audio_rate, "policy": py.burst_policy,
              "model": model, "cursor_gain": float(py.device.cursor_gain),
              "bytes": len(image), "models": model_blocks(py.device), "pad_fields": list(PAD_PARAMS.names)}
    from shapedisplay.render.reactions import reaction_records, reactions_meta, widget_ids
    played = {int(d["widget"]) for d in reaction_records(table)[0]}
    layout["widget_ids"] = widget_ids(table)
    layout["reactions"] = [{"id": str(e["id"]), "kind": str(e["kind"]), "widget": int(e["widget"]),
                            **{k: e["slider"][k] for k in ("axis", "thumb_m", "cross_m", "thumb_r_m") if "slider" in e}}
                           for e in reactions_meta(table) if int(e["widget"]) in played]
    return layout, image


def check_model(model: str) -> str:
    """``model`` if the page offers it (:data:`~shapedisplay.render.native.C_MODELS`), else an error."""
    from shapedisplay.render.native import C_MODELS
    if model not in C_MODELS:
        raise InputError(f"`model` must be one of {', '.join(C_MODELS)} for the page's C runtime (got {model!r})")
    return model


def model_blocks(device) -> dict:
    """Each offered model's id and pad parameters for ``device`` (see :func:`table_payload`)."""
    import numpy as np

    from shapedisplay.render.layouts import PAD_PARAMS
    from shapedisplay.render.models import MODEL_IDS, get_model
    from shapedisplay.render.native import C_MODELS
    out = {}
    for name in C_MODELS:
        try:
            params = get_model(name, device).params
        except ShapeDisplayError as exc:       # this device's pad cannot play the model: say why in the page
            out[name] = {"id": MODEL_IDS[name], "error": str(exc)}
            continue
        block = np.array([float(params[f]) for f in PAD_PARAMS.names], "<f8")
        out[name] = {"id": MODEL_IDS[name], "pad": base64.b64encode(block.tobytes()).decode("ascii")}
    return out
