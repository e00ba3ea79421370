"""Exports of a friction-envelope table: JSON (inspection) and a C99 header (firmware).

Both come from the same :class:`~shapedisplay.table.model.FrictionTable` data and
are written atomically.

JSON (:func:`export_json`)
    ``{"format": ..., "format_version": 1, "checksum": ..., "grid": {"rows",
    "cols", "dx_m", "dy_m", "x0_m", "y0_m"}, "channels": {NAME: {"unit",
    "max_error", "values": [[...], ...]}}, "meta": {...}}`` — every stored
    channel decoded to SI units on the whole canvas, at the sample centres,
    row-major (``values[r][c]`` is at ``x0 + c*dx``, ``y0 + r*dy``); for
    scene tables also ``widgets`` (id, type, bounding box, blocks) and
    ``toggles`` (block, initial state, every state's patch, offset and
    channel values), the same map and states as the C header.

C header (:func:`export_c`)
    ``static const`` arrays of the stored codes per channel, the blocks that
    place patches on the canvas, per-channel scale/offset/background/max
    error, the grid, every constant the runtime configuration needs (pad,
    friction, slope-friction gain K_mu, burst, tick and audio rates), the
    table checksum and a CRC-32 of each channel's code bytes; the toggles
    (every state's offset and ``NAME_set_state`` to switch at run time), the
    widget map (``NAME_widgets``, ``NAME_widget_at`` for hit-testing) and,
    after ``sd_runtime.h``, ``NAME_bind`` filling ``sd_table_t`` and
    ``sd_config_t``. See :func:`export_c` for the layout.
"""
from __future__ import annotations

import json
import math
import os
import re
import zlib
from pathlib import Path

import numpy as np

from shapedisplay.atomic import write_text
from shapedisplay.errors import InputError, TableError, unknown_key
from shapedisplay.table.model import CHANNELS, FrictionTable

_C_TYPES = {"uint8": "uint8_t", "uint16": "uint16_t", "float32": "float", "float64": "double"}


def json_document(table: FrictionTable) -> dict:
    """The JSON export as a dict: :meth:`FrictionTable.to_json` plus the widget map and toggle states.

    ``widgets``: :func:`~shapedisplay.table.widgets.widget_map`;
    ``toggles``: :func:`~shapedisplay.table.widgets.toggle_states`, each
    state also with ``channels`` {name: values[rows][cols]} (SI) of the
    toggle's block in that state, and the block's ``row0``/``col0``.
    """
    from shapedisplay.table.widgets import toggle_states, widget_map
    doc = table.to_json()
    doc["widgets"] = widget_map(table)
    toggles = toggle_states(table)
    for t in toggles:
        r0, c0, _ = table.blocks[t["block"]]
        t["row0"], t["col0"] = int(r0), int(c0)
        for st in t["states"]:
            p = st["patch"]
            rows, cols = table.patch_shapes[p]
            off = int(table.patch_offsets()[p])
            st["channels"] = {n: table.quant[n].decode(np.asarray(table.codes[n][off:off + rows * cols]))
                              .reshape(rows, cols).tolist() for n in table.channels}
    doc["toggles"] = toggles
    return doc


def export_json(table: FrictionTable, path: str | os.PathLike) -> Path:
    """Write the dense SI export (module docs) to ``path``; returns the path."""
    doc = json_document(table)
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


def device_of(meta: dict):
    """The device profile a renderer of this table uses (the table's own, else the built-in one)."""
    from shapedisplay.table.devices import DeviceProfile, load_device
    dev = meta.get("device") if isinstance(meta, dict) else None
    try:
        return DeviceProfile.from_json(dev) if isinstance(dev, dict) else load_device(None)
    except TypeError as exc:
        raise TableError(f"C export: table device profile is malformed ({exc})") from None


def run_config(meta: dict) -> list[tuple[str, float, str]]:
    """Every value the runtime's configuration needs, as (name, SI value, meaning).

    From the device profile the renderer would use for this table and the
    table's mapping: nothing is left for the firmware to pass by hand (the
    slope-friction gain ``K_mu`` is 0 when the mapping has no slope term).
    """
    from shapedisplay.units import parse_quantity
    dev = device_of(meta)
    mp = _section(meta, "mapping")
    tick = meta.get("tick_rate_hz", dev.tick_rate_hz)
    vel = meta.get("velocity_range_m_s") or dev.velocity_range
    sst = 0.0
    if isinstance(dev.extra.get("skin_stretch"), dict) and "target" in dev.extra["skin_stretch"]:
        sst = parse_quantity(dev.extra["skin_stretch"]["target"], "m", "skin_stretch.target")
    out = [
        ("pad_mass_kg", dev.pad.mass, "fingerpad mass m"),
        ("pad_stiffness_n_per_m", dev.pad.stiffness, "fingerpad stiffness k"),
        ("pad_damping_ns_per_m", dev.pad.damping, "fingerpad damping c"),
        ("mu_s", dev.friction.mu_s, "static friction coefficient"),
        ("mu_k", dev.friction.mu_k, "kinetic friction coefficient"),
        ("burst_carrier_hz", dev.burst.carrier_hz, "burst carrier frequency"),
        ("burst_rise_s", dev.burst.rise_s, "burst linear rise time"),
        ("burst_decay_s", dev.burst.decay_s, "burst quadratic decay time"),
        ("burst_gain", dev.burst.gain, "burst gain B (amplitude per N)"),
        ("max_stick_period_s", dev.burst.max_stick_period_s, "maximum stick period (0 = off)"),
        ("tick_rate_hz", tick, "renderer tick rate"),
        ("audio_rate_hz", dev.audio_rate_hz, "audio sample rate of the burst output"),
        ("velocity_min_m_s", _pair(list(vel), 0), "lowest cursor speed"),
        ("velocity_max_m_s", _pair(list(vel), 1), "highest cursor speed"),
        ("normal_force_min_n", dev.normal_force_range[0], "device normal-force range, low"),
        ("normal_force_max_n", dev.normal_force_range[1], "device normal-force range, high"),
        ("cursor_gain_m_per_ns", dev.cursor_gain, "alpha: cursor velocity per stick force (0 = position)"),
        ("lateral_force_max_n", dev.lateral_force_max, "largest lateral force"),
        ("skin_target_m", sst, "skin-stretch target where the table stores none"),
        ("slope_friction_gain", mp.get("slope_friction_gain", 0.0) or 0.0,
         "K_mu: mu_eff = mu + K_mu*max(0, grad.v_hat) (0 = no slope friction)"),
    ]
    if "n_base" in mp:   # the runtime's N where the table stores no normal_force (NAME_bind sets it)
        out.append(("n_base_n", mp["n_base"], "normal force on flat ground (used when normal_force is not stored)"))
    params = []
    for name, v, doc in out:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise TableError(f"C export: table parameter `{name}` must be a finite number (got {v!r})")
        params.append((name, float(v), doc))
    return params


_C_DTYPE_ENUM = {"uint8": "SD_U8", "uint16": "SD_U16", "float32": "SD_F32", "float64": "SD_F64"}
_C_SLOTS = ("normal_force", "friction_scale", "burst_gain", "grad_x", "grad_y", "lateral_x", "lateral_y",
            "skin_stretch", "breakaway_force", "kinetic_force")


def _c_ident(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9]+", "_", str(text)).strip("_").upper() or "X"
    return "_" + s if s[0].isdigit() else s


def _c_string(text: str) -> str:
    """A C string literal of ``text`` (UTF-8; anything outside printable ASCII as octal escapes)."""
    return '"' + "".join(chr(b) if 32 <= b < 127 and chr(b) not in '"\\?' else f"\\{b:03o}"
                         for b in str(text).encode("utf-8")) + '"'


def _firmware_sections(table: FrictionTable, P: str, p: str) -> tuple[list[str], list[str]]:
    """Header lines for the toggles, the widget map and the runtime binding; objects to reference."""
    from shapedisplay.table.widgets import toggle_states, widget_map
    toggles = toggle_states(table)
    widgets = widget_map(table)
    lines, objects = [], []
    n_states = max((len(t["states"]) for t in toggles), default=0)
    lines += [
        "",
        "/* ---- toggles: every state is stored; switch one at run time with",
        f" *   {p}_set_state(blocks, {P}_TOGGLE_<ID>, {P}_TOGGLE_<ID>_<STATE>)",
        f" * on a writable copy of {p}_blocks (it writes the state's offset into the toggle's block). */",
        f"#define {P}_N_TOGGLES {len(toggles)}",
        f"#define {P}_TOGGLE_STATES_MAX {n_states}",
    ]
    for i, t in enumerate(toggles):
        T = f"{P}_TOGGLE_{_c_ident(t['id'])}"
        lines.append(f"#define {T} {i}  /* '{t['id']}': block {t['block']}, initially '{t['state']}' */")
        for j, st in enumerate(t["states"]):
            lines.append(f"#define {T}_{_c_ident(st['name'])} {j}  /* patch {st['patch']}, offset {st['offset']} */")
    if toggles:
        lines += [
            f"/* per toggle: block, number of states, initial state */",
            f"static const int32_t {p}_toggles[{P}_N_TOGGLES][3] = {{",
            *(f"    {{{t['block']}, {len(t['states'])}, "
              f"{[s['name'] for s in t['states']].index(t['state'])}}}," for t in toggles),
            "};",
            f"/* per toggle and state: offset of the state's patch in the code arrays (-1 = no such state) */",
            f"static const int32_t {p}_toggle_offsets[{P}_N_TOGGLES][{P}_TOGGLE_STATES_MAX] = {{",
            *(f"    {{{', '.join(str(s['offset']) for s in t['states'])}"
              f"{''.join(', -1' for _ in range(n_states - len(t['states'])))}}}," for t in toggles),
            "};",
        ]
        objects += [f"{p}_toggles", f"{p}_toggle_offsets"]
    lines += [
        "/* Point a toggle's block at one of its states; returns 0, or -1 for an unknown toggle/state. */",
        f"static inline int {p}_set_state(int32_t blocks[][5], int toggle, int state)",
        "{",
    ]
    if toggles:
        lines += [
            f"    if (toggle < 0 || toggle >= {P}_N_TOGGLES || state < 0 || state >= {p}_toggles[toggle][1])",
            "        return -1;",
            f"    blocks[{p}_toggles[toggle][0]][4] = {p}_toggle_offsets[toggle][state];",
            "    return 0;",
        ]
    else:
        lines += ["    (void)blocks; (void)toggle; (void)state;", "    return -1;"]
    lines += ["}"]

    lines += [
        "",
        "/* ---- widget map for hit-testing: id, type, bounding box (m; x right, y up the screen),",
        " * block holding the widget (-1 = none), toggle index (-1 = not a toggle). */",
        f"#define {P}_N_WIDGETS {len(widgets)}",
        f"typedef struct {{ const char *id; const char *type; double x0_m, y0_m, x1_m, y1_m;",
        f"                 int32_t block; int32_t toggle; }} {p}_widget_t;",
    ]
    for i, w in enumerate(widgets):
        lines.append(f"#define {P}_WIDGET_{_c_ident(w['id'])} {i}")
    if widgets:
        lines += [f"static const {p}_widget_t {p}_widgets[{P}_N_WIDGETS] = {{"]
        for w in widgets:
            x0, y0, x1, y1 = (_c_float(v) for v in w["bbox_m"])
            blk = w["blocks"][0] if w["blocks"] else -1
            tog = -1 if w["toggle"] is None else w["toggle"]
            lines.append(f"    {{{_c_string(w['id'])}, {_c_string(w['type'])}, {x0}, {y0}, {x1}, {y1}, {blk}, {tog}}},")
        lines += ["};"]
        objects.append(f"{p}_widgets")
    lines += [
        "/* Index of the first widget whose bounding box holds (x, y) in metres, or -1. */",
        f"static inline int {p}_widget_at(double x_m, double y_m)",
        "{",
    ]
    if widgets:
        lines += [
            "    int i;",
            f"    for (i = 0; i < {P}_N_WIDGETS; i++)",
            f"        if (x_m >= {p}_widgets[i].x0_m && x_m <= {p}_widgets[i].x1_m"
            f" && y_m >= {p}_widgets[i].y0_m && y_m <= {p}_widgets[i].y1_m)",
            "            return i;",
            "    return -1;",
        ]
    else:
        lines += ["    (void)x_m; (void)y_m;", "    return -1;"]
    lines += ["}"]

    # binding to the C runtime, compiled only where sd_runtime.h was included first
    lines += [
        "",
        "/* ---- binding to the C runtime (when sd_runtime.h is included before this header):",
        f" *   static int32_t blocks[{P}_N_BLOCKS][5];  static sd_table_t T;  static sd_config_t C;",
        f" *   {p}_bind(&T, &C, blocks);   -- copies {p}_blocks into blocks, fills T and C from this header",
        " *   sd_renderer_init(&R, &T, &C);",
        f" * Channel code types: {P}_<CHANNEL>_DTYPE (SD_U8, SD_U16, SD_F32, SD_F64). */",
    ]
    for name in table.channels:
        lines.append(f"#define {P}_{name.upper()}_DTYPE {_C_DTYPE_ENUM[table.quant[name].dtype]}")
    # the coarse block index of the binary image: a lookup tests at most MAX_TILE_BLOCKS blocks per corner
    from shapedisplay.render.image import tile_index
    off = table.patch_offsets()
    blk = np.array([[r0, c0, *table.patch_shapes[i], off[i]] for r0, c0, i in table.blocks],
                   dtype=np.int64).reshape(-1, 5)
    tr, tc, ty, tx, start, entries = tile_index(table.grid.rows, table.grid.cols, blk)
    longest = int(np.diff(start).max()) if start.size > 1 else 0
    lines += [
        f"#define {P}_TILE_ROWS {tr}",
        f"#define {P}_TILE_COLS {tc}",
        f"#define {P}_TILES_Y {ty}",
        f"#define {P}_TILES_X {tx}",
        f"#define {P}_MAX_TILE_BLOCKS {longest}   /* blocks tested per lookup corner, at most */",
        f"static const uint32_t {p}_tile_start[{P}_TILES_Y * {P}_TILES_X + 1] = {_c_array(start.astype(np.uint32))};",
        f"static const uint32_t {p}_tile_list[{max(len(entries), 1)}] = "
        f"{_c_array(entries.astype(np.uint32)) if len(entries) else '{0}'};",
    ]
    objects += [f"{p}_tile_start", f"{p}_tile_list"]
    # reactive widgets (docs/reactive.md): the records the engine plays, indices to read their states by
    from shapedisplay.render.layouts import EVENT_KINDS, REACT_DEF, REACT_KEY, REACT_KINDS
    from shapedisplay.render.reactions import reaction_records, reactions_meta
    rdefs, rkeys = reaction_records(table)
    rids = [str(e.get("id")) for e in reactions_meta(table)]
    lines += [
        "",
        "/* ---- reactive widgets (docs/reactive.md): the engine presses, clicks, flips toggles, moves slider thumbs,",
        " * objects and surfaces itself. With sd_runtime.h: the state of reactive widget i is R.react.state[i]",
        f" * (sd_react_state_t: pressed, state, grabbed, dx, dy, thumb, value, ...; i = {P}_REACT_<ID>); events",
        " * (sd_react_event_t: kind SD_EV_PRESS .. SD_EV_DROP, widget = NAME_WIDGET_<ID>, tick, value) wait in",
        " * R.react.queue until taken with sd_react_pop(&R, &ev); play a tick with sd_renderer_step_press(). */",
        f"#define {P}_N_REACT {len(rdefs)}",
        f"#define {P}_N_REACT_KEYS {len(rkeys)}",
        *(f"#define {P}_REACT_{_c_ident(wid)} {i}  /* '{wid}': {REACT_KINDS[int(d['kind'])]} */"
          for i, (wid, d) in enumerate(zip(rids, rdefs))),
        "/* event kinds, numbered as SD_EV_*: " + ", ".join(f"{i + 1} {k}" for i, k in enumerate(EVENT_KINDS)) + " */",
    ]

    def rec(r, dt):
        return "{" + ", ".join((f"(int64_t){int(r[f])}" if dt[f].kind == "i" else _c_real(float(r[f])))
                               for f in dt.names) + "}"
    lines += ["#ifdef SD_RUNTIME_H"]
    if len(rdefs):
        lines += [f"static const sd_react_def_t {p}_react[{P}_N_REACT] = {{",
                  *(f"    {rec(r, REACT_DEF)}," for r in rdefs), "};"]
    if len(rkeys):
        lines += [f"static const sd_react_key_t {p}_react_keys[{P}_N_REACT_KEYS] = {{",
                  *(f"    {rec(r, REACT_KEY)}," for r in rkeys), "};"]
    for name in table.channels:
        lines.append(f"static const sd_channel_t {p}_channel_{name} = {{{p}_{name}_codes, {P}_{name.upper()}_DTYPE, (sd_real)"
                     f"{p}_{name}_scale, (sd_real){p}_{name}_offset, (sd_real){p}_{name}_background}};")
    cfg = dict((n, v) for n, v, _ in run_config(table.meta))
    from shapedisplay.render.settings import constant_normal_force
    n_const = float(constant_normal_force(table) or 0.0)
    lines += [
        f"static inline void {p}_bind(sd_table_t *T, sd_config_t *C, int32_t blocks[][5])",
        "{",
        "    static const sd_config_t zero_config;   /* settings this header does not give are 0 */",
        "    int i, j;",
        "    *C = zero_config;",
        f"    for (i = 0; i < {P}_N_BLOCKS; i++)",
        "        for (j = 0; j < 5; j++)",
        f"            blocks[i][j] = {p}_blocks[i][j];",
        f"    T->grid.rows = {P}_ROWS;",
        f"    T->grid.cols = {P}_COLS;",
        f"    T->grid.dx = (sd_real){p}_dx_m;",
        f"    T->grid.dy = (sd_real){p}_dy_m;",
        f"    T->grid.x0 = (sd_real){p}_x0_m;",
        f"    T->grid.y0 = (sd_real){p}_y0_m;",
        f"    T->n_blocks = {P}_N_BLOCKS;",
        "    T->blocks = (const int32_t (*)[5])blocks;",
        f"    T->tile_rows = {P}_TILE_ROWS;   /* the block index: O(1) lookup */",
        f"    T->tile_cols = {P}_TILE_COLS;",
        f"    T->tiles_y = {P}_TILES_Y;",
        f"    T->tiles_x = {P}_TILES_X;",
        f"    T->tile_start = {p}_tile_start;",
        f"    T->tile_list = {p}_tile_list;",
        "    for (i = 0; i < SD_NSLOT; i++)",
        "        T->slot[i] = 0;",
    ]
    for name in table.channels:
        if name in _C_SLOTS:
            lines.append(f"    T->slot[SD_SLOT_{name.upper()}] = &{p}_channel_{name};")
    lines += [
        f"    T->n_react = {P}_N_REACT;   /* reactive widgets: the engine plays them */",
        f"    T->react = {p + '_react' if len(rdefs) else '0'};",
        f"    T->n_react_keys = {P}_N_REACT_KEYS;",
        f"    T->react_keys = {p + '_react_keys' if len(rkeys) else '0'};",
    ]
    lines += [
        f"    C->pad.mass = (sd_real){p}_pad_mass_kg;",
        f"    C->pad.stiffness = (sd_real){p}_pad_stiffness_n_per_m;",
        f"    C->pad.damping = (sd_real){p}_pad_damping_ns_per_m;",
        f"    C->pad.burst_gain = (sd_real){p}_burst_gain;",
        f"    C->pad.max_stick_period = (sd_real){p}_max_stick_period_s;",
        f"    C->mu_s = (sd_real){p}_mu_s;",
        f"    C->mu_k = (sd_real){p}_mu_k;",
        f"    C->k_mu = (sd_real){p}_slope_friction_gain;",
        f"    C->skin_target = (sd_real){p}_skin_target_m;",
        f"    C->normal_force_constant = (sd_real){n_const!r};   /* N where the table stores no normal_force */",
        f"    C->tick_rate = (sd_real){p}_tick_rate_hz;",
        f"    C->audio_rate = (sd_real){p}_audio_rate_hz;",
        f"    C->carrier_hz = (sd_real){p}_burst_carrier_hz;",
        f"    C->rise_s = (sd_real){p}_burst_rise_s;",
        f"    C->decay_s = (sd_real){p}_burst_decay_s;",
        "    C->policy = SD_RETRIGGER;",
        "    C->model = SD_MODEL_JUMP;",
        "}",
        *_use_model_lines(table, p),
        "#endif /* SD_RUNTIME_H */",
    ]
    assert "slope_friction_gain" in cfg
    return lines, objects


def _c_real(v: float) -> str:
    v = float(v)
    return "(sd_real)HUGE_VAL" if v == math.inf else f"(sd_real){v!r}"


def _use_model_lines(table: FrictionTable, p: str) -> list[str]:
    """``name_use_model(C, model)``: every pad parameter of each model a table is played with, as the
    package derives them from the table's device (:func:`~.runtime.models.get_model`), so firmware plays
    the same model the package does. A model the device cannot run is left out (the function returns -1)."""
    from shapedisplay.errors import ShapeDisplayError
    from shapedisplay.render.layouts import PAD_PARAMS
    from shapedisplay.render.models import get_model
    from shapedisplay.render.native import C_MODELS
    from shapedisplay.render.settings import device_for_table
    dev = device_for_table(table)
    lines = ["/* Play `model` (SD_MODEL_EXACT, _JUMP, _KARNOPP, _STRIBECK) with the pad parameters the package derives",
             " * from the table's device; returns 0, or -1 (C left unchanged) for a model this header does not carry. */",
             f"static inline int {p}_use_model(sd_config_t *C, int model)", "{", "    switch (model) {"]
    for name in C_MODELS:
        try:
            params = get_model(name, dev).params
        except ShapeDisplayError as exc:
            lines.append(f"    /* {name}: not offered by this device ({str(exc).splitlines()[0]}) */")
            continue
        lines.append(f"    case SD_MODEL_{name.upper()}:")
        for field in PAD_PARAMS.names:
            v = params[field]
            value = f"(int64_t){int(v)}" if PAD_PARAMS[field].kind == "i" else _c_real(v)
            lines.append(f"        C->pad.{field} = {value};")
        lines.append("        break;")
    lines += ["    default:", "        return -1;", "    }", "    C->model = model;", "    return 0;", "}"]
    return lines


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
        "#include <math.h>",
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
        f'static const char {p}_checksum[] = "{table.checksum}";',
        f"static const int32_t {p}_blocks[{P}_N_BLOCKS][5] = {{",
        *(f"    {{{', '.join(str(int(v)) for v in b)}}}," for b in blocks),
        "};",
        "",
        "/* model and device parameters (SI) */",
    ]
    for name, value, doc in run_config(table.meta):
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
    fw_lines, fw_objects = _firmware_sections(table, P, p)
    out += fw_lines
    objects = [f"{p}_{n}" for n in ("dx_m", "dy_m", "x0_m", "y0_m", "checksum", "blocks")]
    objects += [f"{p}_{n}" for n, _, _ in run_config(table.meta)]
    objects += [f"{p}_{n}_{k}" for n in table.channels
                for k in ("scale", "offset", "background", "max_error", "crc32", "codes")]
    objects += fw_objects
    out += [
        "",
        "/* Refers to every object above, so that a translation unit using only some of them",
        " * compiles without unused-variable warnings (-Wall -Werror). */",
        f"static inline const void *{p}_object_(int i)",
        "{",
        "    const void *const objects[] = {",
        *(f"        (const void *){'' if o.endswith(('_codes', '_blocks', '_checksum', '_toggles', '_toggle_offsets', '_widgets', '_tile_start', '_tile_list')) else '&'}{o},"
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
        ``NAME_HAS_CH``, ``NAME_CH_DTYPE``; every runtime constant
        (:func:`run_config`: ``name_pad_mass_kg``, ``name_mu_s``,
        ``name_slope_friction_gain``, ``name_audio_rate_hz`` ...);
        ``name_checksum``; ``NAME_DECODE(CH, i)`` decodes code ``i``;
        toggles ``NAME_TOGGLE_<ID>[_<STATE>]``, ``name_toggles``,
        ``name_toggle_offsets``, ``name_set_state()``; the widget map
        ``NAME_WIDGET_<ID>``, ``name_widgets``, ``name_widget_at()``; after
        ``sd_runtime.h``, ``name_bind()``.
    """
    path = Path(path)
    if name is None:
        name = re.sub(r"[^A-Za-z0-9_]", "_", path.stem) or "sd_table"
        if name[0].isdigit():
            name = "t_" + name
    write_text(path, c_header(table, name))
    return path


def export_table(table: FrictionTable, path: str | os.PathLike, fmt: str, name: str | None = None) -> Path:
    """Export in ``fmt`` (any format of :data:`shapedisplay.exchange.FORMATS`)."""
    from shapedisplay.exchange import export_table as _export
    return _export(table, path, fmt, name)
