"""Export buttons of the studio: the current table in every format, written under the output folder."""
from __future__ import annotations

from pathlib import Path

from shapedisplay.errors import unknown_key

#: File suffix of each export format the library knows (new formats get ".FORMAT").
SUFFIXES = {"table": ".npz", "json": ".json", "c": ".h", "bin": ".bin", "glb": ".glb", "friction-png": ".png",
            "hjif": ".hjif"}


def formats() -> list[str]:
    """Every format the page offers: the table itself and each of ``shapedisplay export``."""
    from shapedisplay.exchange import FORMATS
    return ["table", *FORMATS]


#: Options the page offers per format (the names of ``shapedisplay export``'s).
OPTIONS = {"friction-png": {"quantity": ("auto", "mu", "normal_force", "breakaway_force"), "bits": ("16", "8")}}


def export_bytes(table, fmt: str, out_dir: Path, stem: str, options: dict | None = None) -> tuple[str, bytes]:
    """Write ``table`` as ``fmt`` to ``out_dir/STEM.SUFFIX`` and return (file name, bytes).

    ``options``: the format's own (:data:`OPTIONS`), as text.
    """
    from shapedisplay.exchange import export_table
    if fmt not in formats():
        raise unknown_key("export format", fmt, formats())
    given = {k: v for k, v in (options or {}).items() if v not in (None, "")}
    for k, v in given.items():
        allowed = OPTIONS.get(fmt, {}).get(k)
        if allowed is None:
            raise unknown_key(f"{fmt} export option", k, OPTIONS.get(fmt, {}))
        if v not in allowed:
            raise unknown_key(f"{fmt} `{k}`", v, allowed)
    if "bits" in given:
        given["bits"] = int(given["bits"])
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{stem}{SUFFIXES.get(fmt, '.' + fmt)}"
    if fmt == "table":
        table.save(path)
    else:
        export_table(table, path, fmt, **given)
    return path.name, path.read_bytes()


def stroke_ahap(table, stroke: dict, out_dir: Path, stem: str) -> tuple[str, bytes]:
    """The AHAP pattern of the page's last stroke (its events and drive), written to ``out_dir/STEM-stroke.ahap``.

    ``stroke``: ``event_time``, ``event_amplitude`` (lists of numbers), ``audio`` (the drive at the
    audio rate) and ``t0`` (s, the stroke's first tick).
    """
    import json

    import numpy as np

    from shapedisplay.errors import InputError
    from shapedisplay.exchange.ahap import ahap_document, check_ahap
    from shapedisplay.render import Renderer
    arrays = {}
    for key in ("event_time", "event_amplitude", "audio"):
        v = stroke.get(key)
        if not isinstance(v, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            raise InputError(f"AHAP stroke `{key}` must be a flat list of numbers")
        arrays[key] = np.asarray(v, dtype=np.float64)
    t0 = stroke.get("t0", 0.0)
    if not isinstance(t0, (int, float)) or isinstance(t0, bool):
        raise InputError("AHAP stroke `t0` must be a number (s)")
    r = Renderer(table)
    doc = ahap_document(arrays["event_time"], arrays["event_amplitude"], arrays["audio"], r.audio_rate,
                        r.device.burst.carrier_hz, t0=float(t0), description=f"{stem}: a stroke played in the studio")
    check_ahap(doc)
    data = (json.dumps(doc, indent=1, allow_nan=False) + "\n").encode()
    from shapedisplay.atomic import write_bytes
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{stem}-stroke.ahap"
    write_bytes(path, data)
    return path.name, data
