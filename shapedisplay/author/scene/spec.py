"""The scene file format: parsing and validation.

A scene is a TOML file::

    [scene]                     # optional: name, description
    name = "phone"

    [canvas]
    size = "100x180 mm"         # or pixels = "1080x1920" with dpi = 160;
                                # a single length ("120 mm") makes a 1-D strip
    resolution = "0.5 mm"       # sample spacing

    [device]
    profile = "handheld-stick"  # bundled name or a path to a device TOML

    [mapping]                   # how height becomes force
    n_base = "0.5 N"            # N1, the force on flat ground
    n_gain = "1 N/mm"           # extra normal force per mm of height
    direction = "symmetric"     # or "one-sided": bump uphill, dent downhill

    [defaults]                  # any widget key; [defaults.button] for one type
    ramp = "10 mm"

    [[widget]]
    id = "call"
    type = "button"
    position = "10,20 mm"       # lower-left corner (x, y); or center = "x,y mm"
    size = "30x16 mm"
    height = "2 mm"             # or force = "2.5 N", force_step = "2 N", level = 3

Every length, force and stiffness carries its unit; lengths may also be given
in ``px`` when the canvas states a ``dpi``. Coordinates are in the canvas
frame: x along columns, y along rows (row index grows with y), origin at the
canvas corner, samples at ``(c * resolution, r * resolution)``. With
``[canvas] origin = "top-left"`` the file's y runs down from the top edge
instead (a ``position`` is then the top-left corner); the table is the same.

Placement rules (documented in the README):

* widget boxes are **snapped** to the sample grid (the corner to the nearest
  sample, the size to a whole number of samples), so identical widgets give
  identical patches and are stored once;
* a widget reaching **outside the canvas is clipped, with a warning** stating
  by how much; a widget entirely outside is an error;
* overlapping widgets combine by their ``overlap`` rule (``max`` by default;
  ``min``, ``add``, ``over`` = later widget wins); overlapping widgets with
  different rules are an error.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from shapedisplay.table.container import too_deep
from shapedisplay.table.devices import toml_module
from shapedisplay.errors import FileFormatError, InputError, did_you_mean
from shapedisplay.author.forces import DEFAULT_SLOPE_FRICTION_GAIN, MappingOptions
from shapedisplay.author.scene.fields import Canvas, Ctx, SceneError, Widget, check_keys, choice, length, number, pair, quantity
from shapedisplay.author.scene.widgets import WIDGET_TYPES, place_widget
from shapedisplay.author.scene.reactions import REACTION_KEYS, finish_reactions, reaction_keys

SECTIONS = ("scene", "canvas", "device", "mapping", "defaults", "widget")
CANVAS_KEYS = ("size", "pixels", "dpi", "resolution", "origin")
#: [canvas] origin: where y = 0 is and which way y runs in the file (the table is the same either way).
ORIGINS = ("bottom-left", "top-left")
SCENE_KEYS = ("name", "description")
DEVICE_KEYS = ("profile",)
#: [mapping] key -> (unit or kind, meaning). The values become a forces.MappingOptions.
MAPPING_KEYS = {
    "n_base": ("N", "N1, normal force on flat ground"),
    "n_gain": ("N/m", "extra normal force per metre of height"),
    "direction": ("choice", "symmetric | one-sided (bump uphill, dent downhill)"),
    "slope_friction": ("1", "K_mu of the one-sided slope friction"),
    "lateral": ("choice", "off | gradient | normal"),
    "lateral_gain": ("N", "K of F_lat = -K grad h"),
    "skin_stretch": ("m", "skin-stretch target at breakaway"),
}
DIRECTIONS = ("symmetric", "one-sided")
LATERAL = ("off", "gradient", "normal")
#: Largest canvas accepted (samples), checked before anything is allocated.
MAX_CANVAS_SAMPLES = 4096 * 4096
#: Most [[widget]] entries a scene may hold, checked before any widget is read (docs/limits.md).
MAX_WIDGETS = 10_000
#: Deepest nesting of tables and arrays in a scene (``[[widget]]`` values: 3 levels; a 2-D data
#: layer: 5). Checked on the text before the TOML parser, which recurses once per level, runs,
#: and on the parsed data (dotted keys nest without brackets) before anything walks it.
MAX_NESTING = 32
#: Keys outside [[widget]] that name a file, as (table, key). A widget type declares its file
#: keys with the kind "file" in its keys (widgets.py); :func:`path_keys` lists them all, and
#: the reader resolves every one through ``Ctx.file``, which keeps it inside the scene's folder
#: when asked (the studio).
PATH_KEYS = (("device", "profile"),)


@dataclass(frozen=True)
class Scene:
    """A validated scene."""

    path: str
    name: str
    description: str
    canvas: Canvas
    device: object              # devices.DeviceProfile
    device_source: str
    mapping: MappingOptions     # how height becomes force ([mapping]; defaults are MappingOptions')
    widgets: tuple              # of Widget
    warnings: tuple = ()
    levels: dict = field(default_factory=dict)
    direction: str = "symmetric"  # [mapping] direction: "symmetric" or "one-sided"
    #: What the legibility check reads (docs/perception.md): ``{"contrast": {id: what was asked and the
    #: force chosen}, "distinct_from": {id: [ids]}}``.
    perception: dict = field(default_factory=dict)
    #: Reactive widgets (docs/reactive.md, author/scene/reactions.py): ``{id: {"kind", "press_n", "release_n",
    #: "click", "motion"}}``.
    reactions: dict = field(default_factory=dict)

    def widget(self, wid: str) -> Widget:
        for w in self.widgets:
            if w.id == wid:
                return w
        raise InputError(f"scene '{self.path}': no widget '{wid}'{did_you_mean(wid, [w.id for w in self.widgets])}")


# --------------------------------------------------------------- files a scene names
def widget_file_keys(wtype: str | None = None) -> tuple:
    """The keys of widget type ``wtype`` (of any type when None) that name a file."""
    types = WIDGET_TYPES.values() if wtype is None else [WIDGET_TYPES[wtype]]
    return tuple(sorted({k for wt in types for k, kind in wt.keys.items() if kind == "file"}))


def path_keys() -> list:
    """Every key of a scene that names a file, as written: ``device.profile``, ``defaults.file``,
    ``defaults.image.file``, ..., ``widget.file`` (one entry per widget type that has it)."""
    out = [f"{sec}.{key}" for sec, key in PATH_KEYS]
    out += [f"defaults.{k}" for k in widget_file_keys()]
    out += [f"defaults.{t}.{k}" for t in sorted(WIDGET_TYPES) for k in widget_file_keys(t)]
    out += [f"widget.{k}" for k in widget_file_keys()]
    return out


def is_device_path(value) -> bool:
    """True if a device profile value is a path (a separator or a suffix), not a bundled name."""
    if not isinstance(value, str):
        return True
    return "/" in value or "\\" in value or Path(value).suffix != ""


def path_refs(data: dict) -> list:
    """``(where, field_path, value)`` of every file the parsed scene ``data`` names (see :data:`PATH_KEYS`)."""
    refs = []
    for sec, key in PATH_KEYS:
        table = data.get(sec)
        if isinstance(table, dict) and key in table and is_device_path(table[key]):
            refs.append(("", f"{sec}.{key}", table[key]))
    defaults = data.get("defaults")
    if isinstance(defaults, dict):
        for k in widget_file_keys():
            if k in defaults:
                refs.append(("", f"defaults.{k}", defaults[k]))
        for t in WIDGET_TYPES:
            if isinstance(defaults.get(t), dict):
                refs += [("", f"defaults.{t}.{k}", defaults[t][k]) for k in widget_file_keys(t) if k in defaults[t]]
    widgets = data.get("widget")
    widgets = [widgets] if isinstance(widgets, dict) else widgets
    for i, w in enumerate(widgets if isinstance(widgets, list) else []):
        if isinstance(w, dict):
            known = isinstance(w.get("type"), str) and w["type"] in WIDGET_TYPES
            keys = widget_file_keys(w["type"]) if known else widget_file_keys()
            refs += [(f"widget[{i}] '{w.get('id', i)}'", f"widget[{i}].{k}", w[k]) for k in keys if k in w]
    return refs


def _device_source(src, ctx: Ctx):
    """What :func:`load_device` reads for the scene's ``device.profile`` value ``src``."""
    from shapedisplay.table.devices import BUNDLED_DEVICES
    if not ctx.confine:
        if isinstance(src, str) and (src.endswith(".toml") or "/" in src):
            cand = ctx.base_dir / src
            return cand if cand.exists() else src
        return src
    if is_device_path(src):
        return ctx.file("", "device.profile", src)
    bundled = BUNDLED_DEVICES / f"{src}.toml"      # a name: only a bundled profile, never a file of the cwd
    if not bundled.is_file():
        from shapedisplay.errors import unknown_key
        raise SceneError(f"scene '{ctx.path}': `device.profile`: "
                         f"{unknown_key('device', src, (p.stem for p in BUNDLED_DEVICES.glob('*.toml')))}")
    return bundled


# --------------------------------------------------------------- limits on the text and the data
_TOML_TOKENS = re.compile(r'''
      "{3}(?:[^\\]|\\.)*?"{3,5}     # multi-line basic string
    | '{3}.*?'{3,5}                 # multi-line literal string
    | "(?:[^"\\\n]|\\.)*"         # basic string
    | '[^'\n]*'                     # literal string
    | \#[^\n]*                      # comment
    | [\[\]{}]                       # brackets: the only thing counted
''', re.S | re.X)


def check_toml_nesting(text: str, where: str) -> None:
    """Refuse TOML text whose brackets nest deeper than :data:`MAX_NESTING` (before parsing it)."""
    pos = too_deep(text, _TOML_TOKENS, MAX_NESTING)
    if pos is not None:
        line = text.count("\n", 0, pos) + 1
        raise FileFormatError(f"{where}: tables and arrays nest more than {MAX_NESTING} levels deep "
                              f"at line {line}, beyond the limit of {MAX_NESTING} (docs/limits.md)")


def check_data_nesting(data, where: str) -> None:
    """Refuse parsed scene data nested deeper than :data:`MAX_NESTING` (an iterative walk).

    The file's top level is level 0: ``[[widget]]`` is 1, a widget's table 2, an array in it 3.
    """
    stack = [(data, 0)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_NESTING:
            raise FileFormatError(f"{where}: tables and arrays (dotted keys count) nest more than "
                                  f"{MAX_NESTING} levels deep, beyond the limit of {MAX_NESTING} (docs/limits.md)")
        children = node.values() if isinstance(node, dict) else node
        stack.extend((c, depth + 1) for c in children if isinstance(c, (dict, list)))


# --------------------------------------------------------------- loading
def load_scene(path, device=None, confine: bool = False) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str or Path
        The scene TOML, or an SVG mockup (``.svg``, read by
        :func:`shapedisplay.author.scene.svg.svg_scene_data`).
    device : DeviceProfile, str, Path or None
        Overrides the scene's ``[device] profile`` (a profile, a bundled name
        or a path).
    confine : bool
        Refuse, naming the key and the path, every file the scene names
        (:func:`path_keys`; an SVG's ``data-device``, ``data-file``) that
        does not resolve, symlinks followed, inside the scene's folder. The
        studio sets it; a command line may read files anywhere.

    Returns
    -------
    Scene
        With widgets placed on the grid, parameters in SI units and the
        warnings gathered while validating (clipping, snapping, detents).
    """
    p = Path(path)
    if p.suffix.lower() == ".svg":           # a UI mockup: the scene it shows (scene/svg.py)
        from shapedisplay.author.scene.svg import svg_scene_data
        origins: dict = {}
        return parse_scene(svg_scene_data(p, origins=origins), str(p), p.resolve().parent, device=device,
                           confine=confine, origins=origins)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileFormatError(f"scene '{p}': no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"scene '{p}': unreadable ({exc})") from None
    check_toml_nesting(text, f"scene '{p}'")
    tomllib = toml_module()
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"scene '{p}': invalid TOML ({exc})") from None
    return parse_scene(data, str(p), p.resolve().parent, device=device, confine=confine)


def import_svg(path, output, *, overwrite: bool = False) -> dict:
    """Write the scene of an SVG mockup as a scene TOML to edit, atomically; validate it first.

    Returns ``{"widgets": n, "notes": [...], "warnings": [...], "path": output}``.
    Refuses to overwrite the SVG itself, or an existing file unless ``overwrite``.
    """
    from shapedisplay.atomic import atomic_path
    from shapedisplay.author.scene.svg import scene_toml, svg_scene_data

    path, output = Path(path), Path(output)
    if output.suffix.lower() != ".toml":
        raise InputError(f"`-o`: the scene file must end in .toml (got '{output}')")
    if output.exists() and (output.resolve() == path.resolve() or not overwrite):
        raise InputError(f"`-o`: '{output}' exists; remove it or pass --overwrite to replace it")
    notes: list = []
    data = svg_scene_data(path, notes)
    scene = parse_scene(data, str(path), path.resolve().parent)   # the checks compiling the SVG makes
    with atomic_path(output) as tmp:
        tmp.write_text(scene_toml(data, path.name), encoding="utf-8")
    return {"widgets": len(scene.widgets), "notes": notes, "warnings": list(scene.warnings), "path": str(output)}


def parse_scene(data: dict, path: str = "<scene>", base_dir: Path | None = None, device=None,
                confine: bool = False, origins: dict | None = None) -> Scene:
    """Validate parsed TOML ``data`` into a :class:`Scene` (see :func:`load_scene`).

    ``origins`` maps field paths to what they were written as (an SVG's attributes), for messages.
    """
    from shapedisplay.table.devices import DeviceProfile, load_device

    ctx = Ctx(path, Path(base_dir) if base_dir is not None else Path.cwd(), confine=confine, origins=origins)
    if not isinstance(data, dict):
        raise SceneError(f"scene '{path}': must be a table of sections (got {type(data).__name__})")
    check_data_nesting(data, f"scene '{path}'")
    raw_widgets = data.get("widget", [])
    if isinstance(raw_widgets, list) and len(raw_widgets) > MAX_WIDGETS:
        raise SceneError(f"scene '{path}': {len(raw_widgets)} [[widget]] entries, more than the limit of "
                         f"{MAX_WIDGETS} (MAX_WIDGETS, docs/limits.md); split the scene")
    if confine:                             # every file the scene names, before any is read
        for where, field_path, value in path_refs(data):
            ctx.file(where, field_path, value)
    check_keys(data, SECTIONS, ctx, "", "", "section")
    for sec in ("scene", "canvas", "device", "mapping", "defaults"):
        if sec in data and not isinstance(data[sec], dict):
            raise ctx.error("", sec, f"must be a table [{sec}] (got {data[sec]!r})")
    meta = data.get("scene", {})
    check_keys(meta, SCENE_KEYS, ctx, "", "scene.")
    name = str(meta.get("name", Path(path).stem))
    description = str(meta.get("description", ""))

    canvas = _parse_canvas(data.get("canvas"), ctx)
    ctx.dpi, ctx.is_1d = canvas.dpi, canvas.is_1d

    dev_raw = data.get("device", {})
    check_keys(dev_raw, DEVICE_KEYS, ctx, "", "device.")
    if isinstance(device, DeviceProfile):
        dev, dev_src = device, device.name
    else:
        src = device if device is not None else dev_raw.get("profile")
        if src is not None and not isinstance(src, (str, Path)):
            raise ctx.error("", "device.profile", f"must be a bundled device name or a path (got {src!r})")
        named = src
        if src is not None and device is None:
            src = _device_source(src, ctx)
        try:
            dev = load_device(src)
        except InputError as exc:
            raise SceneError(f"scene '{path}': `device.profile`: {exc}") from None
        if src is None:
            dev_src = "default"
        else:                               # a bundled profile is recorded by its name
            dev_src = str(src) if is_device_path(named) else str(named)

    mapping, direction = _parse_mapping(data.get("mapping", {}), ctx)
    defaults = data.get("defaults", {})
    type_defaults = {t: defaults[t] for t in WIDGET_TYPES if isinstance(defaults.get(t), dict)}
    common_defaults = {k: v for k, v in defaults.items() if k not in type_defaults}
    all_keys = set()
    for wt in WIDGET_TYPES.values():
        all_keys |= set(wt.keys)
    all_keys |= {"levels", "level_force"}
    check_keys(common_defaults, sorted(all_keys | set(WIDGET_TYPES)), ctx, "", "defaults.")
    for t, d in type_defaults.items():
        check_keys(d, WIDGET_TYPES[t].keys, ctx, "", f"defaults.{t}.")
    for t in WIDGET_TYPES:
        if t in common_defaults:
            raise ctx.error("", f"defaults.{t}", f"must be a table [defaults.{t}] of {t} keys "
                                                 f"(got {common_defaults[t]!r})")
    for k in ("id", "type", "position", "center", "from", "to"):
        if k in common_defaults:
            raise ctx.error("", f"defaults.{k}", "cannot have a default; give it per widget")
    levels = {
        "levels": number(common_defaults.pop("levels", 5), "defaults.levels", ctx, lo=1, integer=True),
        "level_force": quantity(common_defaults.pop("level_force", "4 N"), "N", "defaults.level_force", ctx),
    }
    if levels["level_force"] <= 0:
        raise ctx.error("", "defaults.level_force", f"must be a force > 0 (got {levels['level_force']} N)")

    raw_widgets = data.get("widget", [])
    if isinstance(raw_widgets, dict):
        raw_widgets = [raw_widgets]
    if not isinstance(raw_widgets, list) or not raw_widgets:
        raise SceneError(f"scene '{path}': the scene is empty: add at least one [[widget]] "
                         f"(types: {', '.join(sorted(WIDGET_TYPES))})")
    widgets, seen, perception = [], {}, {"contrast": {}, "distinct_from": {}}
    deferred = []                           # widgets whose `contrast` is against another widget
    reactive: dict = {}                     # reaction keys per widget id (reactions.py)
    for i, raw in enumerate(raw_widgets):
        if not isinstance(raw, dict):
            raise ctx.error(f"widget[{i}]", f"widget[{i}]", f"must be a table [[widget]] (got {raw!r})")
        wid = str(raw.get("id", f"{raw.get('type', 'widget')}-{i}"))
        where = f"widget[{i}] '{wid}'"
        if wid in seen:
            raise ctx.error(where, f"widget[{i}].id", f"must be unique; '{wid}' is also widget[{seen[wid]}]")
        seen[wid] = i
        if "type" not in raw:
            raise ctx.error(where, f"widget[{i}].type", f"is required; one of {', '.join(sorted(WIDGET_TYPES))}")
        wtype = raw["type"]
        if not isinstance(wtype, str) or wtype not in WIDGET_TYPES:
            hint = did_you_mean(str(wtype), WIDGET_TYPES)
            raise ctx.error(where, f"widget[{i}].type",
                            f"names an unknown widget type {wtype!r}{hint}; valid: {', '.join(sorted(WIDGET_TYPES))}")
        wt = WIDGET_TYPES[wtype]
        check_keys(raw, list(wt.keys) + list(PERCEPTION_KEYS) + list(REACTION_KEYS), ctx, where, f"widget[{i}].")
        raw, asked = _perception_keys(raw, wt, i, where, ctx, perception)
        raw, react = reaction_keys(raw, wt, i, where, ctx, canvas.is_1d)
        if react is not None:
            reactive[wid] = react
        merged = {k: v for k, v in common_defaults.items() if k in wt.keys}
        merged.update(type_defaults.get(wtype, {}))
        # strength keys from defaults must not fight the widget's own choice
        own_strength = [k for k in wt.strength_keys if k in raw]
        if own_strength or asked:
            for k in wt.strength_keys:
                merged.pop(k, None)
        merged.update(raw)
        if asked and asked["over"] is not None:
            deferred.append((wt, merged, i, wid, asked))
            continue
        if asked:
            merged["force"] = _contrast_force(asked, mapping.n_base, dev, mapping, ctx, where, i, perception, wid)
        widgets.append(place_widget(wt, merged, i, wid, canvas, mapping, levels, dev, ctx))
    while deferred:                         # `contrast = "2 jnd over ID"`: once ID is placed
        placed = {w.id: w for w in widgets}
        ready = [d for d in deferred if d[4]["over"] in placed]
        if not ready:
            wt, merged, i, wid, asked = deferred[0]
            ref = asked["over"]
            known = ref in seen
            raise ctx.error(f"widget[{i}] '{wid}'", f"widget[{i}].contrast",
                            (f"is against '{ref}', whose own contrast is against this chain again (a cycle)"
                             if known else f"names no widget '{ref}'{did_you_mean(ref, list(seen))}")
                            + f" (got {asked['text']!r})")
        for d in ready:
            deferred.remove(d)
            wt, merged, i, wid, asked = d
            where = f"widget[{i}] '{wid}'"
            ref = placed[asked["over"]]
            if ref.type not in CONTRAST_REFERENCES or "height" not in ref.params:
                raise ctx.error(where, f"widget[{i}].contrast",
                                f"must be against a {', '.join(CONTRAST_REFERENCES)} ('{ref.id}' is a {ref.type}) "
                                f"(got {asked['text']!r})")
            lo, hi = dev.normal_force_range
            n_ref = min(max(mapping.n_base + mapping.n_gain * ref.params["height"], lo), hi)
            merged["force"] = _contrast_force(asked, n_ref, dev, mapping, ctx, where, i, perception, wid)
            widgets.append(place_widget(wt, merged, i, wid, canvas, mapping, levels, dev, ctx))
    widgets.sort(key=lambda w: w.index)
    for wid, others in perception["distinct_from"].items():
        for other in others:
            if other not in seen or other == wid:
                i = seen[wid]
                raise ctx.error(f"widget[{i}] '{wid}'", f"widget[{i}].distinct_from",
                                ("must name other widgets, not the widget itself" if other == wid else
                                 f"names no widget '{other}'{did_you_mean(other, list(seen))}") + f" (got {other!r})")
    reactions = finish_reactions(widgets, reactive, ctx, dev)
    return Scene(path, name, description, canvas, dev, dev_src, mapping, tuple(widgets),
                 tuple(ctx.warnings), levels, direction=direction, perception=perception, reactions=reactions)


# --------------------------------------------------------------- legibility keys
#: Keys any widget may carry for the legibility check (docs/perception.md): ``contrast`` asks for a
#: strength in JNDs, ``distinct_from`` lists widgets that must not feel alike.
PERCEPTION_KEYS = ("contrast", "distinct_from")
#: Widget types whose strength ``contrast`` sets: a plateau, against flat ground or another widget.
CONTRAST_TYPES = ("button", "dent", "well")
#: Widget types a ``contrast = "... over ID"`` may name: their ``height`` is their main feature.
CONTRAST_REFERENCES = ("button", "dent", "well", "ridge", "edge", "groove")
_CONTRAST = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*jnds?\s*(?:(over|under)\s+(\S+))?\s*$", re.I)


def _perception_keys(raw: dict, wt, i: int, where: str, ctx: Ctx, perception: dict) -> tuple[dict, dict | None]:
    """``raw`` without the legibility keys, and the parsed ``contrast`` (None if not asked);
    ``distinct_from`` goes into ``perception`` (checked once every id is known)."""
    if not any(k in raw for k in PERCEPTION_KEYS):
        return raw, None
    fp = f"widget[{i}]."
    wid = str(raw.get("id", f"{raw.get('type', 'widget')}-{i}"))
    if "distinct_from" in raw:
        v = raw["distinct_from"]
        ids = [v] if isinstance(v, str) else v
        if not isinstance(ids, list) or not ids or not all(isinstance(x, str) for x in ids):
            raise ctx.error(where, fp + "distinct_from", f"must be a list of widget ids such as [\"app-1\"] (got {v!r})")
        perception["distinct_from"][wid] = list(dict.fromkeys(ids))
    asked = None
    if "contrast" in raw:
        text = raw["contrast"]
        m = _CONTRAST.match(text) if isinstance(text, str) else None
        if wt.name not in CONTRAST_TYPES:
            raise ctx.error(where, fp + "contrast", f"sets the strength of a {', '.join(CONTRAST_TYPES)} only "
                                                    f"(this is a {wt.name}) (got {text!r})")
        if m is None or not 0 < float(m.group(1)) <= 100:
            raise ctx.error(where, fp + "contrast", f"must look like \"3 jnd\" or \"2 jnd over ID\" (\"under ID\"), "
                                                    f"0 < jnd <= 100 (got {text!r})")
        given = [k for k in wt.strength_keys if k in raw]
        if given:
            raise ctx.error(where, fp + given[0], f"conflicts with `{fp}contrast`: give only one of contrast, "
                                                  f"{', '.join(wt.strength_keys)}")
        asked = {"text": text, "jnd": float(m.group(1)), "over": m.group(3),
                 "under": (m.group(2) or "").lower() == "under", "sign": getattr(wt, "sign", 1)}
    return {k: v for k, v in raw.items() if k not in PERCEPTION_KEYS}, asked


def _contrast_force(asked: dict, n_ref: float, dev, mapping, ctx: Ctx, where: str, i: int, perception: dict,
                    wid: str) -> str:
    """The ``force`` value that gives the asked contrast (closed form, author/perception.py), recorded."""
    from shapedisplay.author.perception import solve_contrast, typical_speed
    fp = f"widget[{i}].contrast"
    if mapping.n_gain <= 0:
        raise ctx.error(where, fp, f"needs `mapping.n_gain` > 0 to turn a force into a height "
                                   f"(got n_gain={mapping.n_gain} N/m)")
    jnds = asked["jnd"] * asked["sign"] * (-1 if asked["under"] else 1)
    speed = typical_speed(dev)
    try:
        n, cue = solve_contrast(n_ref, jnds, dev, speed, mapping)
    except ValueError as exc:
        raise ctx.error(where, fp, f"cannot be reached: {exc} (got {asked['text']!r})") from None
    if (n - mapping.n_base) * asked["sign"] <= 0:
        side = "above" if asked["sign"] > 0 else "below"
        raise ctx.error(where, fp, f"asks for {n:.4g} N, not {side} flat ground ({mapping.n_base:g} N) as a "
                                   f"{'raised' if asked['sign'] > 0 else 'sunk'} widget must be (got {asked['text']!r})")
    lo, hi = dev.normal_force_range
    perception["contrast"][wid] = {
        "asked": asked["text"], "jnd": jnds, "against": asked["over"] or "flat ground", "reference_n": n_ref,
        "force_n": n, "cue": cue, "speed_m_s": speed, "within_device": bool(lo <= n <= hi)}
    return f"{n!r} N"


def _parse_canvas(raw, ctx: Ctx) -> Canvas:
    if raw is None:
        raise SceneError(f"scene '{ctx.path}': `canvas` is required: [canvas] size = \"100x180 mm\" "
                         f"(or pixels = \"1080x1920\" with dpi = 160)")
    check_keys(raw, CANVAS_KEYS, ctx, "", "canvas.")
    dpi = None
    if "dpi" in raw:
        dpi = number(raw["dpi"], "canvas.dpi", ctx, lo=1e-9)
    ctx.dpi = dpi
    if "size" in raw and "pixels" in raw:
        raise ctx.error("", "canvas.pixels", "cannot be given together with `canvas.size`; keep one")
    if "pixels" in raw:
        if dpi is None:
            raise ctx.error("", "canvas.pixels", f"needs `canvas.dpi` to give the physical size (got {raw['pixels']!r})")
        text = str(raw["pixels"]).replace("px", "").strip()
        parts = [s.strip() for s in text.split("x")]
        try:
            nums = [float(s) for s in parts]
        except ValueError:
            raise ctx.error("", "canvas.pixels", f"must look like '1080x1920' or '1080' (got {raw['pixels']!r})") from None
        if len(nums) not in (1, 2) or any(not (n > 0 and math.isfinite(n)) for n in nums):
            raise ctx.error("", "canvas.pixels", f"must be one or two pixel counts > 0 (got {raw['pixels']!r})")
        width = nums[0] * 0.0254 / dpi
        height = nums[1] * 0.0254 / dpi if len(nums) == 2 else 0.0
    elif "size" in raw:
        size = raw["size"]
        two_d = isinstance(size, list) or (isinstance(size, str) and "x" in size.replace("px", ""))
        if two_d:
            width, height = pair(size, "x", "canvas.size", ctx)
        else:
            width, height = length(size, "canvas.size", ctx), 0.0
        if not width > 0 or (two_d and not height > 0):
            raise ctx.error("", "canvas.size", f"must be lengths > 0 (got {size!r})")
    else:
        raise ctx.error("", "canvas.size", "is required (e.g. size = \"100x180 mm\"; a single length makes a 1-D strip)")
    spacing = length(raw.get("resolution", "0.5 mm"), "canvas.resolution", ctx, positive=True)
    origin = choice(raw.get("origin", "bottom-left"), ORIGINS, "canvas.origin", ctx)
    canvas = Canvas(width, height, spacing, dpi, origin)
    if width < spacing or (not canvas.is_1d and height < spacing):
        raise ctx.error("", "canvas.resolution",
                        f"must be finer than the canvas ({spacing * 1e3:g} mm for a "
                        f"{width * 1e3:g} x {height * 1e3:g} mm canvas)")
    n = canvas.rows * canvas.cols
    if n > MAX_CANVAS_SAMPLES:
        raise ctx.error("", "canvas.resolution",
                        f"gives {_count(canvas.cols)} x {_count(canvas.rows)} = {_count(n)} samples, more than the limit of "
                        f"{MAX_CANVAS_SAMPLES}; use a coarser resolution (got {spacing * 1e3:g} mm)")
    return canvas


def _count(n: int) -> str:
    """A sample count for a message: exact, or in e-notation when it is absurd."""
    return str(n) if n < 10 ** 12 else f"~1e{len(str(n)) - 1}"


def _parse_mapping(raw: dict, ctx: Ctx) -> tuple[MappingOptions, str]:
    """[mapping] -> (forces.MappingOptions, direction). Keys not given keep MappingOptions' defaults."""
    check_keys(raw, MAPPING_KEYS, ctx, "", "mapping.")
    out: dict = {}
    direction = None
    for key, value in raw.items():
        unit = MAPPING_KEYS[key][0]
        fp = f"mapping.{key}"
        if key == "direction":
            direction = choice(value, DIRECTIONS, fp, ctx)
        elif key == "lateral":
            out["lateral"] = choice(value, LATERAL, fp, ctx)
        elif key == "slope_friction":
            out["slope_friction_gain"] = number(value, fp, ctx, lo=0.0)
        elif unit == "m":
            out[key] = length(value, fp, ctx, nonneg=True)
        else:
            out[key] = quantity(value, unit, fp, ctx)
    if out.get("n_base", 0.0) < 0:
        raise ctx.error("", "mapping.n_base", f"must be a force >= 0 (got {out['n_base']} N)")
    if out.get("lateral_gain", 0.0) < 0:
        raise ctx.error("", "mapping.lateral_gain", f"must be >= 0 (got {out['lateral_gain']} N)")
    if direction is None:
        direction = "one-sided" if out.get("slope_friction_gain", 0.0) > 0 else "symmetric"
    if direction == "one-sided":
        out.setdefault("slope_friction_gain", DEFAULT_SLOPE_FRICTION_GAIN)
        if out["slope_friction_gain"] <= 0:
            raise ctx.error("", "mapping.slope_friction",
                            f"must be > 0 when direction = \"one-sided\" (got {out['slope_friction_gain']})")
    elif out.get("slope_friction_gain", 0.0) > 0:
        raise ctx.error("", "mapping.slope_friction",
                        f"needs direction = \"one-sided\" (got slope_friction={out['slope_friction_gain']} "
                        f"with direction = \"symmetric\")")
    try:
        return MappingOptions(height=True, **out), direction
    except InputError as exc:
        raise SceneError(f"scene '{ctx.path}': [mapping]: {exc}") from None
