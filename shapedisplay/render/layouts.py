"""Memory layouts shared by the Python binding and the C engine, each defined once.

Every block of numbers the engine reads or keeps between ticks is a numpy
structured dtype with named fields (``align=True``, so the fields sit where a
C compiler puts the members of the same struct): Python builds parameters and
settings as records and reads the engine's state and outputs through views
of the same memory.

The C side is derived from the same definitions: :func:`c_header` writes
``engine/sd_layout.h`` (structs and enums; ``make generate``),
:func:`ctypes_struct` builds the ctypes view used to call the C library, and
``tests/test_layouts.py`` compiles a C program that prints ``sizeof`` and
``offsetof`` of every member and compares them with these dtypes.

==================  ====================  =======================================================
dtype               C struct              what it holds
==================  ====================  =======================================================
``PAD_STATE``       ``sd_pad_state_t``    pad state kept between ticks (all pad models)
``PAD_PARAMS``      ``sd_pad_params_t``   pad, burst-gain and per-model parameters
``GRID``            ``sd_grid_t``         table canvas: rows, cols, spacing, origin
``RENDER_CONFIG``   ``sd_config_t``       renderer settings (pad parameters, friction, rates, burst)
``RUN_STATE``       ``sd_run_state_t``    online renderer registers and counters
``OUTPUTS``         ``sd_outputs_t``      per-tick outputs of the online renderer
``BURST_STATE``     ``sd_burst_state_t``  burst envelope and carrier kept between ticks
``REACT_DEF``       ``sd_react_def_t``    one reactive widget of a table (press, click, toggle, slider,
                                          moving part); the record of a table image's reaction section
``REACT_KEY``       ``sd_react_key_t``    one keyframe of a moving part
``REACT_STATE``     ``sd_react_state_t``  a reactive widget's state kept between ticks (caller-owned)
``REACT_EVENT``     ``sd_react_event_t``  one event of the reaction queue (press, release, click, ...)
==================  ====================  =======================================================

Numberings shared with C (enums in ``sd_layout.h``): :class:`Slot` (table
channels the renderer reads, :data:`SLOTS` order), :class:`Policy` (burst
overlap policies), the model ids (position in
:data:`shapedisplay.render.models.MODELS`), the reactive widget kinds
(:data:`REACT_KINDS`, ``SD_REACT_*``) and the reaction events
(:data:`EVENT_KINDS`, ``SD_EV_*``, numbered from 1).
"""
from __future__ import annotations

import ctypes
import enum

import numpy as np

f8 = np.float64
i8 = np.int64
i4 = np.int32


def _struct(fields) -> np.dtype:
    return np.dtype([(name, typ) for name, typ, _ in fields], align=True)


#: Field documentation (name -> comment), written into the C header next to each member.
DOCS: dict[str, dict[str, str]] = {}


def _layout(name: str, fields) -> np.dtype:
    dt = _struct(fields)
    DOCS[name] = {n: doc for n, _, doc in fields}
    return dt


# ---------------------------------------------------------------- pad models
PAD_STATE = _layout("PAD_STATE", [
    ("phase", f8, "0 stick, 1 slip"),
    ("x", f8, "spring stretch (pad displacement from rest relative to the finger), m"),
    ("v", f8, "pad velocity, m/s"),
    ("s", f8, "sign of the friction force in slip"),
    ("f", f8, "friction force on the pad at the end of the last tick, N"),
    ("age", f8, "time in the current stick phase while the surface moves, s"),
    ("work_friction", f8, "work of friction on the pad during the last tick, J (exact model)"),
    ("work_damping", f8, "energy dissipated by the damper during the last tick, J (exact model)"),
    ("slip_left", f8, "remaining slip time, s (jump model; inf = steady sliding)"),
    ("x_restick", f8, "spring stretch at the coming re-stick, m (jump model)"),
    ("diverged_at", f8, "time an explicit baseline blew up, s (when diverged != 0)"),
    ("diverged", i8, "1 once an explicit baseline blew up (outputs frozen at zero)"),
    ("truncated", i8, "ticks cut at the safety cap on phase changes"),
    ("n_events", i8, "stick-to-slip events in the last tick"),
    ("memo_valid", i8, "1 if the memo_* fields hold the last slip outcome (jump and exact models)"),
    ("memo_s", f8, "memo input: slip direction"),
    ("memo_x", f8, "memo input: spring stretch at breakaway (exact: at the slip start), m"),
    ("memo_v", f8, "memo input: surface velocity, m/s"),
    ("memo_muk", f8, "memo input: kinetic coefficient"),
    ("memo_n", f8, "memo input: normal force, N"),
    ("memo_slip_time", f8, "memo output: slip time, s"),
    ("memo_x_restick", f8, "memo output: spring stretch at re-stick (exact: from the slip equilibrium), m"),
    ("slip_step", f8, "next slip step the last one proposed, s (stribeck exponential steps; 0 = none)"),
])

PAD_PARAMS = _layout("PAD_PARAMS", [
    ("mass", f8, "pad mass m, kg"),
    ("stiffness", f8, "pad stiffness k, N/m"),
    ("damping", f8, "pad damping c, N s/m"),
    ("burst_gain", f8, "B: burst amplitude per newton of breakaway force"),
    ("max_stick_period", f8, "force a slip after this long stuck, s (0 = off)"),
    ("substep", f8, "largest integration substep, s (stribeck, tanh)"),
    ("karnopp_spring", f8, "Karnopp virtual spring k_K, N/m"),
    ("karnopp_v_threshold", f8, "Karnopp re-stick speed v_T, m/s"),
    ("stribeck_a", f8, "Stribeck decay a"),
    ("stribeck_b", f8, "Stribeck viscous term b"),
    ("stribeck_p", f8, "pre-maximum slope p"),
    ("stribeck_d", f8, "pre-maximum width d"),
    ("stribeck_variant", i8, "0 Stribeck curve, 1 with pre-maximum static region"),
    ("stribeck_tol", f8, "Stribeck slip: local error allowed per step, relative to the pad's scales"),
    ("contactor_amplitude", f8, "lateral contactor amplitude, m"),
    ("contactor_omega", f8, "lateral contactor angular frequency, rad/s"),
    ("tanh_eps", f8, "tanh regularisation width (breakaway slip speed), m/s"),
])

# ---------------------------------------------------------------- table lookup
GRID = _layout("GRID", [
    ("rows", i4, "canvas samples along y"),
    ("cols", i4, "canvas samples along x; sample (r, c) at (x0 + c dx, y0 + r dy)"),
    ("dx", f8, "sample spacing along x, m"),
    ("dy", f8, "sample spacing along y, m"),
    ("x0", f8, "x of column 0, m"),
    ("y0", f8, "y of row 0, m"),
])

#: Table channels the renderer reads, in slot order (C: ``SD_SLOT_*``).
SLOTS = ("normal_force", "friction_scale", "burst_gain", "grad_x", "grad_y", "lateral_x", "lateral_y",
         "skin_stretch", "breakaway_force", "kinetic_force")
#: Slot numbers by name (``vals[Slot.NORMAL_FORCE]`` in a kernel).
Slot = enum.IntEnum("Slot", [(n.upper(), i) for i, n in enumerate(SLOTS)])
NSLOT = len(SLOTS)

#: Burst overlap policies by name (C: ``SD_RETRIGGER``, ``SD_ADD``, ``SD_MAX``).
BURST_POLICIES = {"retrigger": 0, "add": 1, "max": 2}
Policy = enum.IntEnum("Policy", [(n.upper(), i) for n, i in BURST_POLICIES.items()])

# ---------------------------------------------------------------- renderer
RENDER_CONFIG = _layout("RENDER_CONFIG", [
    ("pad", PAD_PARAMS, "pad model parameters"),
    ("mu_s", f8, "device static friction coefficient"),
    ("mu_k", f8, "device kinetic friction coefficient"),
    ("k_mu", f8, "slope friction gain (table meta mapping.slope_friction_gain)"),
    ("skin_target", f8, "default skin-stretch target, m"),
    ("normal_force_constant", f8, "N of a table without a normal_force channel, N (C: the channel is required)"),
    ("tick_rate", f8, "Hz, 100 .. 192000"),
    ("audio_rate", f8, "Hz, 1000 .. 384000 (C: 0 = no audio, drive per tick only)"),
    ("carrier_hz", f8, "burst carrier frequency, Hz"),
    ("rise_s", f8, "burst envelope rise, s"),
    ("decay_s", f8, "burst envelope decay, s"),
    ("policy", i4, "burst overlap policy (SD_RETRIGGER, SD_ADD, SD_MAX)"),
    ("model", i4, "pad model id (SD_MODEL_*)"),
])

RUN_STATE = _layout("RUN_STATE", [
    ("tick", f8, "ticks since reset (the next tick's number)"),
    ("xp", f8, "cursor x at the previous tick, m"),
    ("yp", f8, "cursor y at the previous tick, m"),
    ("ax", f8, "pad axis x (follows the motion; a reversal gives a negative pad speed)"),
    ("ay", f8, "pad axis y"),
    ("t0", f8, "cursor time of tick 0, s"),
    ("next_sample", i8, "index of the next audio sample"),
    ("n_recent", i8, "bursts held in the event ring"),
    ("clipped", i8, "audio samples limited to full scale"),
    ("events_total", i8, "stick-to-slip events since reset"),
    ("events_dropped", i8, "events that did not fit the event ring"),
    ("value_faults", i8, "ticks with a non-finite value replaced: table products overflowing (played without "
                         "contact), pad state reset, NaN drive played as 0, skin stretch as 0"),
])

OUTPUTS = _layout("OUTPUTS", [
    ("t", f8, "tick time, s"),
    ("x", f8, "cursor x, m"),
    ("y", f8, "cursor y, m"),
    ("vx", f8, "cursor velocity x, m/s"),
    ("vy", f8, "cursor velocity y, m/s"),
    ("normal_force", f8, "N"),
    ("friction_force", f8, "friction on the pad, N, signed along the pad axis"),
    ("state", f8, "0 stick, 1 slip at the end of the tick"),
    ("lateral_x", f8, "lateral-force cue x, N"),
    ("lateral_y", f8, "lateral-force cue y, N"),
    ("skin_stretch", f8, "skin stretch, m"),
    ("events", f8, "stick-to-slip events in the tick"),
    ("drive", f8, "burst drive at the tick time, in [-1, 1]"),
    ("audio_samples", f8, "audio samples written for the tick"),
    ("pad_speed", f8, "speed of the surface under the finger relative to it, along the pad axis, m/s"),
    ("mu_s", f8, "static friction coefficient of the tick (device, table scale and slope term)"),
    ("mu_k", f8, "kinetic friction coefficient of the tick"),
    ("burst_gain", f8, "burst-gain multiplier of the tick (table channel, 1 if absent)"),
    ("press", f8, "press force of the tick, N (along z; 0 = not pressing)"),
    ("reactions", f8, "reaction events queued in the tick (press, release, click, ...)"),
])

BURST_STATE = _layout("BURST_STATE", [
    ("i_in", i8, "events entered (their time has passed)"),
    ("i_mid", i8, "events whose burst turned from rise to decay (add)"),
    ("i_out", i8, "events whose burst ended (add)"),
    ("te", f8, "start of the playing envelope segment, s (retrigger, max)"),
    ("e0", f8, "envelope at the segment's start (retrigger, max)"),
    ("a", f8, "peak of the segment (retrigger, max)"),
    ("tref", f8, "reference time of add's running sums, s"),
    ("ra", f8, "add: sum of the rising bursts' peaks"),
    ("rat", f8, "add: sum of peak * (event time - tref) of the rising bursts, s"),
    ("q0", f8, "add: decays q0 - 2 q1 x + q2 x^2, x = (t - tref) / decay"),
    ("q1", f8, "add: see q0"),
    ("q2", f8, "add: see q0"),
    ("cc", f8, "carrier cos at the last sample written"),
    ("cs", f8, "carrier sin at the last sample written"),
    ("cj", i8, "index + 1 of the last sample written (-1 before the first)"),
    ("rc", f8, "rotation per sample: cos(2 pi carrier / audio rate)"),
    ("rs", f8, "rotation per sample: sin(2 pi carrier / audio rate)"),
])

# ---------------------------------------------------------------- reactions (docs/reactive.md)
#: Reactive widget kinds by number (C: ``SD_REACT_*``): what a press on the widget does.
REACT_KINDS = ("none", "button", "toggle", "slider", "object", "surface")
#: Reaction events, numbered from 1 in this order (C: ``SD_EV_*``; 0 = no event).
EVENT_KINDS = ("press", "release", "click", "toggle", "value", "grab", "drop")

REACT_DEF = _layout("REACT_DEF", [
    ("kind", i8, "SD_REACT_* (what a press does; 0 = nothing)"),
    ("widget", i8, "index of the widget in the table's scene widgets (an event's widget)"),
    ("block", i8, "toggle: the block whose patch its state selects (-1 = none)"),
    ("offset_a", i8, "toggle: code offset of the patch of state 0"),
    ("offset_b", i8, "toggle: code offset of the patch of state 1"),
    ("state0", i8, "toggle: state at reset (0 or 1)"),
    ("part_row0", i8, "moving part: canvas row of its patch at rest"),
    ("part_col0", i8, "moving part: canvas column of its patch at rest"),
    ("part_rows", i8, "moving part: rows of its patch (0 = the widget has no moving part)"),
    ("part_cols", i8, "moving part: columns of its patch"),
    ("part_offset", i8, "moving part: code offset of its patch"),
    ("axis", i8, "slider: 0 the thumb runs along x, 1 along y"),
    ("n_detents", i8, "slider: detents on the track (0 = none)"),
    ("key0", i8, "moving part: first keyframe"),
    ("n_keys", i8, "moving part: keyframes (0 = none)"),
    ("wrap", i8, "moving part: 1 = its content scrolls through its box at (vx, vy), wrapping"),
    ("x0", f8, "box: left (m); a press inside the box (moved with the part) is the widget's"),
    ("y0", f8, "box: bottom (m)"),
    ("x1", f8, "box: right (m)"),
    ("y1", f8, "box: top (m)"),
    ("press_n", f8, "press threshold, N (0 = the widget does not react to presses)"),
    ("release_n", f8, "release level, N (below press_n: the hysteresis)"),
    ("click_gain", f8, "click drive amplitude, full scale (0 = no click drive)"),
    ("click_hz", f8, "click drive frequency, Hz"),
    ("click_s", f8, "click drive duration, s"),
    ("drop", f8, "click friction transient: fraction of N dropped at the click (0 = none)"),
    ("drop_s", f8, "click friction transient: recovery time, s"),
    ("track0", f8, "slider: lowest thumb centre along the axis, m"),
    ("track_len", f8, "slider: thumb travel, m (value = (centre - track0) / track_len)"),
    ("thumb_c", f8, "slider: thumb centre along the axis at reset, m"),
    ("thumb_r", f8, "slider: thumb radius, m (a press within it grabs the thumb)"),
    ("cross_c", f8, "slider: thumb centre across the axis, m"),
    ("detent0", f8, "slider: thumb centre at the first detent, m"),
    ("detent_step", f8, "slider: thumb travel between detents, m"),
    ("value_step", f8, "slider: change of value that makes a `value` event while dragging"),
    ("vx", f8, "moving part: content velocity x, m/s (wrap)"),
    ("vy", f8, "moving part: content velocity y, m/s (wrap)"),
    ("loop_s", f8, "moving part: keyframe loop period, s (0 = hold the last keyframe)"),
])

REACT_KEY = _layout("REACT_KEY", [
    ("t", f8, "time from reset (within the loop), s; non-decreasing"),
    ("dx", f8, "displacement of the part from rest, x, m"),
    ("dy", f8, "displacement of the part from rest, y, m"),
])

REACT_STATE = _layout("REACT_STATE", [
    ("pressed", f8, "1 from a press on the widget until its release"),
    ("state", f8, "toggle: the state whose patch plays (0 or 1)"),
    ("grabbed", f8, "1 while the finger holds the widget (slider thumb, object)"),
    ("dx", f8, "moving part: displacement from rest, x, m (wrap: content offset)"),
    ("dy", f8, "moving part: displacement from rest, y, m"),
    ("grab_x", f8, "cursor minus the part's displacement at the grab, x, m (slider: along the axis)"),
    ("grab_y", f8, "cursor minus the part's displacement at the grab, y, m"),
    ("thumb", f8, "slider: thumb centre along the axis, m"),
    ("value", f8, "slider: (thumb - track0) / track_len, 0 .. 1"),
    ("reported", f8, "slider: value of the last `value` event"),
    ("region", f8, "slider: detents at or below the thumb centre"),
    ("clock", f8, "moving part: time along its keyframes, s"),
])

REACT_EVENT = _layout("REACT_EVENT", [
    ("kind", i8, "SD_EV_* (press, release, click, toggle, value, grab, drop)"),
    ("widget", i8, "widget index in the table's scene widgets"),
    ("tick", i8, "tick number (time t0 + tick / tick_rate)"),
    ("value", f8, "toggle: the new state; value: the slider's value; click: detent number (0 = a press click)"),
])

#: Everything the online renderer keeps between ticks, in one record (Python only: the C
#: renderer, ``sd_renderer_t``, holds the same members next to its event ring and audio block).
ONLINE = np.dtype([
    ("pad", PAD_STATE),
    ("cfg", RENDER_CONFIG),
    ("run", RUN_STATE),
    ("out", OUTPUTS),
    ("bursts", BURST_STATE),
    ("grid", GRID),
    ("slot_channel", i8, (NSLOT,)),   # packed channel of each slot, -1 if the table lacks it
    ("vals", f8, (NSLOT,)),           # slot values of the current tick
    ("scratch", f8, (NSLOT,)),        # packed channel values of the current tick
], align=True)

#: Every shared layout: dtype name -> (dtype, C type name).
LAYOUTS = {
    "PAD_STATE": (PAD_STATE, "sd_pad_state_t"),
    "PAD_PARAMS": (PAD_PARAMS, "sd_pad_params_t"),
    "GRID": (GRID, "sd_grid_t"),
    "RENDER_CONFIG": (RENDER_CONFIG, "sd_config_t"),
    "RUN_STATE": (RUN_STATE, "sd_run_state_t"),
    "OUTPUTS": (OUTPUTS, "sd_outputs_t"),
    "BURST_STATE": (BURST_STATE, "sd_burst_state_t"),
    "REACT_DEF": (REACT_DEF, "sd_react_def_t"),
    "REACT_KEY": (REACT_KEY, "sd_react_key_t"),
    "REACT_STATE": (REACT_STATE, "sd_react_state_t"),
    "REACT_EVENT": (REACT_EVENT, "sd_react_event_t"),
}


def record(dtype: np.dtype, **values) -> np.ndarray:
    """A zeroed one-element structured array of ``dtype`` with ``values`` set (its ``[0]`` is the record)."""
    a = np.zeros(1, dtype)
    for k, v in values.items():
        a[k] = v
    return a


# ---------------------------------------------------------------- C views
_CTYPES = {np.dtype(f8): ctypes.c_double, np.dtype(i8): ctypes.c_int64, np.dtype(i4): ctypes.c_int32}
_CNAMES = {np.dtype(f8): "sd_real", np.dtype(i8): "int64_t", np.dtype(i4): "int32_t"}
#: field kinds of the X-macro field lists in sd_layout.h (f8 = a real, double in this module's records)
_CKINDS = {np.dtype(f8): "F64", np.dtype(i8): "I64", np.dtype(i4): "I32"}
_ctypes_cache: dict = {}


def _c_name(dt: np.dtype) -> str:
    for name, (d, cname) in LAYOUTS.items():
        if d == dt:
            return cname
    raise KeyError(dt)


def ctypes_struct(dtype: np.dtype) -> type:
    """The ctypes Structure with the fields of ``dtype`` (same names, types, offsets and size)."""
    if dtype in _ctypes_cache:
        return _ctypes_cache[dtype]
    fields = []
    for name in dtype.names:
        sub = dtype.fields[name][0]
        fields.append((name, ctypes_struct(sub) if sub.names else _CTYPES[sub]))
    cls = type(_c_name(dtype), (ctypes.Structure,), {"_fields_": fields})
    if ctypes.sizeof(cls) != dtype.itemsize:      # would mean numpy and ctypes align differently
        raise AssertionError(f"{cls.__name__}: ctypes size {ctypes.sizeof(cls)} != dtype size {dtype.itemsize}")
    _ctypes_cache[dtype] = cls
    return cls


def c_header(model_names) -> str:
    """Text of ``engine/sd_layout.h``: the structs and enums above, for the C runtime.

    ``model_names`` are the pad model names in id order (the registry).
    """
    out = ["/* sd_layout.h -- memory layouts and numberings shared with the Python runtime.",
           " *",
           " * GENERATED from shapedisplay/render/layouts.py and the model registry by `make generate`;",
           " * do not edit. tests/test_layouts.py checks that this file is current and that a C compiler",
           " * places every member at the offset numpy gives it. */",
           "#ifndef SD_LAYOUT_H", "#define SD_LAYOUT_H", "", "#include <stdint.h>", "",
           "/* sd_real: the real type of the runtime -- double in the reference build (bit-exact with the",
           " * Python records, whose reals are float64), float with -DSD_SINGLE (single-precision FPUs). */",
           "#ifndef SD_REAL_DEFINED", "#define SD_REAL_DEFINED", "#ifdef SD_SINGLE", "typedef float sd_real;",
           "#else", "typedef double sd_real;", "#endif", "#endif", ""]
    out.append("/* pad models (ids shared with shapedisplay.render.models.MODELS) */")
    out.append("enum {")
    out += [f"    SD_MODEL_{n.upper()} = {i}," for i, n in enumerate(model_names)]
    out += [f"    SD_NMODEL = {len(model_names)}", "};", ""]
    out.append("/* burst overlap policies */")
    out.append("enum { " + ", ".join(f"SD_{n.upper()} = {i}" for n, i in BURST_POLICIES.items()) + " };")
    out.append("")
    out.append("/* renderer slots: the table channels the renderer reads */")
    out.append("enum {")
    out += [f"    SD_SLOT_{n.upper()} = {i}," for i, n in enumerate(SLOTS)]
    out += [f"    SD_NSLOT = {NSLOT}", "};", ""]
    out.append("/* reactive widget kinds and reaction events (docs/reactive.md) */")
    out.append("enum { " + ", ".join(f"SD_REACT_{n.upper()} = {i}" for i, n in enumerate(REACT_KINDS)) + " };")
    out.append("enum { SD_EV_NONE = 0, " + ", ".join(f"SD_EV_{n.upper()} = {i + 1}" for i, n in enumerate(EVENT_KINDS))
               + f", SD_NEV = {len(EVENT_KINDS) + 1} }};")
    out.append("")
    for name, (dt, cname) in LAYOUTS.items():
        out.append(f"/* {name} */")
        out.append("typedef struct {")
        docs = DOCS[name]
        for field in dt.names:
            sub = dt.fields[field][0]
            ctype = _c_name(sub) if sub.names else _CNAMES[sub]
            out.append(f"    {ctype} {field};".ljust(36) + f"/* {docs[field]} */")
        out.append(f"}} {cname};")
        # X-macro list of the members in record order (kind F64/I64/I32, or the layout name of a nested
        # record): readers and writers that convert field by field (little-endian files, the
        # single-precision build). The records have no padding: field order is byte order.
        kinds = [_CKINDS[dt.fields[f][0]] if not dt.fields[f][0].names
                 else next(n for n, (d, _) in LAYOUTS.items() if d == dt.fields[f][0]) for f in dt.names]
        out.append(f"#define SD_FIELDS_{name}(X) \\")
        out += [f"    X({k}, {f}) \\" for k, f in zip(kinds[:-1], dt.names[:-1])]
        out.append(f"    X({kinds[-1]}, {dt.names[-1]})")
        out.append("")
    out.append("#endif")
    return "\n".join(out) + "\n"
