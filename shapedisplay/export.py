"""Exports of a friction-envelope table: JSON (inspection) and a C99 header (firmware).

Both come from the same :class:`~shapedisplay.table.FrictionTable` data and
are written atomically.

JSON (:func:`export_json`)
    ``{"format": ..., "format_version": 1, "checksum": ..., "grid": {"rows",
    "cols", "dx_m", "dy_m", "x0_m", "y0_m"}, "channels": {NAME: {"unit",
    "max_error", "values": [[...], ...]}}, "meta": {...}}`` — every stored
    channel decoded to SI units on the whole canvas, at the sample centres,
    row-major (``values[r][c]`` is at ``x0 + c*dx``, ``y0 + r*dy``).

C header (:func:`export_c`)
    ``static const`` arrays of the stored codes per channel, the blocks that
    place patches on the canvas, per-channel scale/offset/background/max
    error, the grid, the model parameters, the table checksum and a CRC-32
    of each channel's code bytes. See :func:`export_c` for the layout.
"""
from __future__ import annotations

import json
import math
import os
import re
import zlib
from pathlib import Path

import numpy as np

from .atomic import write_text
from .errors import InputError, TableError, unknown_key
from .table import CHANNELS, FrictionTable

FORMATS = ("json", "c")
_C_TYPES = {"uint8": "uint8_t", "uint16": "uint16_t", "float32": "float", "float64": "double"}


def export_json(table: FrictionTable, path: str | os.PathLike) -> Path:
    """Write the dense SI export (module docs) to ``path``; returns the path."""
    doc = table.to_json()
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False)
    write_text(path, text + "\n")
    return Path(path)


def _c_float(v: float) -> str:
    v = float(v)
    if not math.isfinite(v):
        raise InputError(f"C export: non-finite parameter {v!r}")
    s = repr(v)
    return s if ("e" in s or "." in s) else s + ".0"


def _c_array(values: np.ndarray, per_line: int = 16) -> str:
    if values.dtype.kind == "f":
        items = [_c_float(v) + ("f" if values.dtype == np.float32 else "") for v in values.tolist()]
    else:
        items = [str(int(v)) for v in values.tolist()]
    lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return "{\n    " + ",\n    ".join(lines) + "\n}" if lines else "{0}"


def _section(d, key: str) -> dict:
    v = d.get(key) if isinstance(d, dict) else None
    return v if isinstance(v, dict) else {}


def _pair(v, i: int):
    return v[i] if isinstance(v, (list, tuple)) and len(v) == 2 else None


def _model_params(meta: dict) -> list[tuple[str, float, str]]:
    dev = _section(meta, "device")
    pad, fr, burst = _section(dev, "pad"), _section(dev, "friction"), _section(dev, "burst")
    mp = _section(meta, "mapping")
    vel = meta.get("velocity_range_m_s") or dev.get("velocity_range")
    out = [
        ("pad_mass_kg", pad.get("mass"), "fingerpad mass m"),
        ("pad_stiffness_n_per_m", pad.get("stiffness"), "fingerpad stiffness k"),
        ("pad_damping_ns_per_m", pad.get("damping"), "fingerpad damping c"),
        ("mu_s", fr.get("mu_s"), "static friction coefficient"),
        ("mu_k", fr.get("mu_k"), "kinetic friction coefficient"),
        ("burst_carrier_hz", burst.get("carrier_hz"), "burst carrier frequency"),
        ("burst_rise_s", burst.get("rise_s"), "burst linear rise time"),
        ("burst_decay_s", burst.get("decay_s"), "burst quadratic decay time"),
        ("burst_gain", burst.get("gain"), "burst gain B (amplitude per N)"),
        ("max_stick_period_s", burst.get("max_stick_period_s"), "maximum stick period (0 = off)"),
        ("tick_rate_hz", meta.get("tick_rate_hz", dev.get("tick_rate_hz")), "renderer tick rate"),
        ("velocity_min_m_s", _pair(vel, 0), "lowest cursor speed"),
        ("velocity_max_m_s", _pair(vel, 1), "highest cursor speed"),
        ("normal_force_min_n", _pair(dev.get("normal_force_range"), 0), "device normal-force range, low"),
        ("normal_force_max_n", _pair(dev.get("normal_force_range"), 1), "device normal-force range, high"),
        ("cursor_gain_m_per_ns", dev.get("cursor_gain"), "alpha: cursor velocity per stick force (0 = position)"),
        ("lateral_force_max_n", dev.get("lateral_force_max"), "largest lateral force"),
        ("n_base_n", mp.get("n_base"), "normal force on flat ground (used when normal_force is not stored)"),
        ("slope_friction_gain", mp.get("slope_friction_gain"), "K_mu: mu_eff = mu + K_mu*max(0, grad.v_hat)"),
    ]
    params = []
    for name, v, doc in out:
        if v is None:
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise TableError(f"C export: table parameter `{name}` must be a finite number (got {v!r})")
        params.append((name, float(v), doc))
    return params


def c_header(table: FrictionTable, prefix: str = "sd_table") -> str:
    """The C99 header text for ``table`` (see :func:`export_c`)."""
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", prefix or ""):
        raise InputError(f"`name` must be a C identifier (letters, digits, _; got {prefix!r})")
    P, p = prefix.upper(), prefix
    g = table.grid
    off = table.patch_offsets()
    blocks = np.array([[r0, c0, *table.patch_shapes[i], off[i]] for r0, c0, i in table.blocks],
                      dtype=np.int64).reshape(-1, 5)
    n_values = int(off[-1])
    src = str(_section(table.meta, "source").get("description", "")).replace("*/", "* /")
    out = [
        f"/* {p}.h -- shapedisplay friction-envelope table (format version {table.header()['format_version']}).",
        " * Generated by `shapedisplay export --format c`; do not edit.",
        f" * Source: {src}",
        " *",
        " * Canvas: ROWS x COLS samples; sample (r, c) sits at (X0 + c*DX, Y0 + r*DY) metres",
        " * (row-major, r grows with y). Each stored channel NAME has codes NAME_codes[N_VALUES];",
        " * its SI value is  NAME_offset + NAME_scale * code  (float channels: scale 1, offset 0).",
        " * Blocks {row0, col0, rows, cols, offset} place patches on the canvas: canvas sample",
        " * (row0 + i, col0 + j) holds codes[offset + i*cols + j]. Samples outside every block",
        " * hold NAME_background. Blocks never overlap. NAME_crc32 is the CRC-32 (zlib/IEEE) of",
        " * the little-endian code bytes; CHECKSUM is the table file's checksum.",
        " */",
        f"#ifndef {P}_H",
        f"#define {P}_H",
        "#include <stdint.h>",
        "",
        f"#define {P}_FORMAT_VERSION {table.header()['format_version']}",
        f"#define {P}_ROWS {g.rows}",
        f"#define {P}_COLS {g.cols}",
        f"#define {P}_N_BLOCKS {len(blocks)}",
        f"#define {P}_N_VALUES {n_values}",
        f"#define {P}_N_CHANNELS {len(table.channels)}",
        f"#define {P}_DECODE(name, i) ({p}_##name##_offset + {p}_##name##_scale * (double){p}_##name##_codes[i])",
        "",
        f"static const double {p}_dx_m = {_c_float(g.dx)};",
        f"static const double {p}_dy_m = {_c_float(g.dy)};",
        f"static const double {p}_x0_m = {_c_float(g.x0)};",
        f"static const double {p}_y0_m = {_c_float(g.y0)};",
        f'static const char {p}_checksum[] = "{table.checksum()}";',
        f"static const int32_t {p}_blocks[{P}_N_BLOCKS][5] = {{",
        *(f"    {{{', '.join(str(int(v)) for v in b)}}}," for b in blocks),
        "};",
        "",
        "/* model and device parameters (SI) */",
    ]
    for name, value, doc in _model_params(table.meta):
        out.append(f"static const double {p}_{name} = {_c_float(value)};  /* {doc} */")
    for name in table.channels:
        q = table.quant[name]
        codes = np.asarray(table.codes[name])
        le = codes.astype(codes.dtype.newbyteorder("<"), copy=False)
        unit, meaning = CHANNELS[name]
        out += [
            "",
            f"/* channel {name}: {meaning} [{unit}], {q.dtype}, worst-case error {q.max_error:.6g} {unit} */",
            f"#define {P}_HAS_{name.upper()} 1",
            f"static const double {p}_{name}_scale = {_c_float(q.scale)};",
            f"static const double {p}_{name}_offset = {_c_float(q.offset)};",
            f"static const double {p}_{name}_background = {_c_float(table.background[name])};",
            f"static const double {p}_{name}_max_error = {_c_float(q.max_error)};",
            f"static const uint32_t {p}_{name}_crc32 = {zlib.crc32(le.tobytes()) & 0xFFFFFFFF}u;",
            f"static const {_C_TYPES[q.dtype]} {p}_{name}_codes[{P}_N_VALUES] = {_c_array(codes)};",
        ]
    objects = [f"{p}_{n}" for n in ("dx_m", "dy_m", "x0_m", "y0_m", "checksum", "blocks")]
    objects += [f"{p}_{n}" for n, _, _ in _model_params(table.meta)]
    objects += [f"{p}_{n}_{k}" for n in table.channels
                for k in ("scale", "offset", "background", "max_error", "crc32", "codes")]
    out += [
        "",
        "/* Refers to every object above, so that a translation unit using only some of them",
        " * compiles without unused-variable warnings (-Wall -Werror). */",
        f"static inline const void *{p}_object_(int i)",
        "{",
        "    const void *const objects[] = {",
        *(f"        (const void *){'' if o.endswith(('_codes', '_blocks', '_checksum')) else '&'}{o},"
          for o in objects),
        "    };",
        "    return objects[i];",
        "}",
        "",
        f"#endif /* {P}_H */",
        "",
    ]
    return "\n".join(out)


def export_c(table: FrictionTable, path: str | os.PathLike, name: str | None = None) -> Path:
    """Write a C99 header for firmware.

    Parameters
    ----------
    table : FrictionTable
    path : path-like
        Output ``.h`` file.
    name : str, optional
        Identifier prefix of every symbol (default: the file stem, made a C
        identifier). Symbols: ``NAME_ROWS``/``_COLS``/``_N_BLOCKS``/
        ``_N_VALUES`` macros, ``name_dx_m``/``_dy_m``/``_x0_m``/``_y0_m``,
        ``name_blocks[n][5]``, per channel ``name_CH_codes``, ``_scale``,
        ``_offset``, ``_background``, ``_max_error``, ``_crc32`` and
        ``NAME_HAS_CH``; model parameters ``name_pad_mass_kg``, ``name_mu_s`` ...;
        ``name_checksum``; ``NAME_DECODE(CH, i)`` decodes code ``i``.
    """
    path = Path(path)
    if name is None:
        name = re.sub(r"[^A-Za-z0-9_]", "_", path.stem) or "sd_table"
        if name[0].isdigit():
            name = "t_" + name
    write_text(path, c_header(table, name))
    return path


def export_table(table: FrictionTable, path: str | os.PathLike, fmt: str, name: str | None = None) -> Path:
    """Export in ``fmt`` ("json" or "c")."""
    if fmt == "json":
        return export_json(table, path)
    if fmt == "c":
        return export_c(table, path, name)
    raise unknown_key("export format", fmt, FORMATS)
