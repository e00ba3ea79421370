"""The one rule for compiling a source into a table: the command line, the studio and the API all use it.

:func:`compile_file` takes a source — a picture or ``.npy`` height map, a
mesh, a scene (``.toml`` file, an SVG mockup, a parsed :class:`Scene` or the
scene's data as a dict), or a ``.glb`` written with haptic textures — and the
options of ``shapedisplay compile`` by name, as unit strings
(``size="40x40mm"``, ``height="0:2mm"``, ``n_base="0.5N"``). It decides what
the source needs:

* a scene keeps its own ``[device]`` and ``[mapping]`` unless ``device`` is
  given; mapping options do not apply to it;
* a ``.glb`` with haptic textures is rebuilt from its textures (the grid is
  the file's: geometry options are refused);
* a mesh is fitted to the device's force range unless the caller chose its
  scale (``n_gain`` or ``height``);
* options that do not apply to the kind of source are refused, naming the
  option as the caller spells it (``flags``: the command line passes
  ``{"n_base": "--n-base", ...}``; from Python the keyword itself).

The same source with the same options gives the same table (checksum) from
every front end.
"""
from __future__ import annotations

import os
from pathlib import Path

from shapedisplay.errors import InputError, unknown_key

#: Options of picture and mesh sources (see :func:`shapedisplay.author.sources.source_options`).
SOURCE_OPTIONS = ("size", "height", "resolution", "channel", "z_units", "up", "units")
#: Options of the height -> force mapping (pictures, meshes and haptic glb files; a scene has its [mapping]).
MAPPING_OPTIONS = ("mapping", "n_base", "n_gain", "slope_gain", "lateral_gain", "skin_stretch", "perceptual")
#: Options of gradient analysis and coding (every source).
ANALYSIS_OPTIONS = ("gradient", "sigma", "window", "order", "max_slope", "limit_walls", "quantize", "weber", "keep")
OPTIONS = SOURCE_OPTIONS + MAPPING_OPTIONS + ANALYSIS_OPTIONS

def _spell(flags: dict | None):
    return lambda name: (flags or {}).get(name, name)


def check_options(options: dict, flags: dict | None = None) -> dict:
    """``options`` with unknown names refused (with the nearest valid one) and None values dropped."""
    for name in options:
        if name not in OPTIONS:
            raise unknown_key("compile option", name, OPTIONS)
    return {k: v for k, v in options.items() if v is not None}


def _text(value, name: str, flag) -> str:
    if not isinstance(value, str):
        raise InputError(f"`{flag(name)}` takes a string with its unit, e.g. {_EXAMPLES.get(name, '...')!r} "
                         f"(got {type(value).__name__} {value!r})")
    return value


_EXAMPLES = {"size": "40x40mm", "height": "0:2mm", "resolution": "0.1mm", "n_base": "0.5N", "n_gain": "2N/mm",
             "lateral_gain": "1N", "skin_stretch": "0.55mm", "sigma": "0.2mm", "window": "1mm"}


def build_options(options: dict, flags: dict | None = None):
    """(MappingOptions, CompileOptions) from options by name (unit strings; numbers where unitless)."""
    from shapedisplay.author.compile import CompileOptions
    from shapedisplay.author.forces import MappingOptions
    from shapedisplay.units import parse_quantity

    flag = _spell(flags)
    o = check_options(options, flags)

    def q(name, unit, bare_ok=False):
        if name not in o:
            return None
        v = o[name]
        if bare_ok and isinstance(v, (int, float)) and not isinstance(v, bool):
            return float(v)
        return parse_quantity(_text(v, name, flag), unit, flag(name), bare_ok=bare_ok)

    mapping = MappingOptions.parse(
        o.get("mapping", "height"),
        n_base=q("n_base", "N"),
        n_gain=q("n_gain", "N/m"),
        slope_friction_gain=q("slope_gain", "1", bare_ok=True),
        lateral_gain=q("lateral_gain", "N"),
        skin_stretch=q("skin_stretch", "m"),
        perceptual_exponent=o.get("perceptual"),
    )
    gkw = {}
    if "sigma" in o:
        gkw["sigma"] = q("sigma", "m")
    if "window" in o:
        w = o["window"]
        gkw["window"] = int(w) if isinstance(w, int) or (isinstance(w, str) and w.isdigit()) else w
    if "order" in o:
        gkw["order"] = _integer(o["order"], "order", flag)
    kw = {}
    if "max_slope" in o:
        kw["max_slope"] = _number(o["max_slope"], "max_slope", flag)
    if "weber" in o:
        kw["weber_fraction"] = _number(o["weber"], "weber", flag)
    keep = o.get("keep", ())
    if isinstance(keep, str):
        keep = tuple(k.strip() for k in keep.split(",") if k.strip())
    limit_walls = o.get("limit_walls", True)
    if not isinstance(limit_walls, bool):
        raise InputError(f"`{flag('limit_walls')}` must be True or False (got {limit_walls!r})")
    compile_options = CompileOptions(quantize=o.get("quantize", "auto"), gradient_method=o.get("gradient", "central"),
                                     gradient_kw=gkw, limit_walls=limit_walls, keep=tuple(keep), **kw)
    return mapping, compile_options


def _number(value, name: str, flag) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InputError(f"`{flag(name)}` must be a number (got {value!r})") from None


def _integer(value, name: str, flag) -> int:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not v.is_integer():
        raise InputError(f"`{flag(name)}` must be a whole number (got {value!r})")
    return int(v)


def compile_file(source, device=None, *, flags: dict | None = None, confine: bool = False, **options):
    """Compile ``source`` into a friction-envelope table: the one compile policy.

    Parameters
    ----------
    source : str, Path, HeightField, Scene or dict
        A height field; a picture, ``.npy``, mesh, scene (``.toml``/``.svg``) or haptic
        ``.glb`` file; a :class:`~shapedisplay.author.scene.Scene`; or a
        scene's data as a dict (what its TOML holds: ``canvas``,
        ``widget = [...]`` ...), whose relative file paths resolve from the
        current folder.
    device : str, Path, DeviceProfile or None
        Device profile (a bundled name or a TOML file). None: a scene's own
        ``[device]``, else the built-in Konyo pad.
    flags : dict, optional
        How the caller spells each option, for messages (the command line
        passes ``{"n_base": "--n-base", ...}``); default the keyword itself.
    confine : bool
        Read only files inside the source's folder (the studio sets it):
        every file a scene names, a mesh's companion files.
    **options
        The options of ``shapedisplay compile`` by name (:data:`OPTIONS`),
        quantities as unit strings: ``size="60x4mm"``, ``height="0:2mm"``,
        ``resolution="0.1mm"``, ``mapping="height+slope"``,
        ``n_base="0.5N"``, ``n_gain="2N/mm"``, ``gradient="gaussian"``,
        ``sigma="0.2mm"``, ``quantize="uint16"``, ``limit_walls=False``,
        ``keep="lateral_x,lateral_y"``.

    Returns
    -------
    shapedisplay.author.compile.CompileResult
        ``table`` and ``report`` (the report is also ``table.meta["report"]``).
    """
    from shapedisplay.author.scene import Scene, compile_scene, parse_scene
    from shapedisplay.table.devices import DeviceProfile, load_device

    flag = _spell(flags)
    options = check_options(options, flags)
    mapping, compile_options = build_options(options, flags)
    given_mapping = {k: options.get(k) for k in MAPPING_OPTIONS}
    dev = device if isinstance(device, DeviceProfile) or device is None else str(device)

    from shapedisplay.author.heightfield import HeightField
    if isinstance(source, HeightField):
        from shapedisplay.author.compile import compile_heightfield
        _refuse(options, SOURCE_OPTIONS, "a height field", flag)
        return compile_heightfield(source, dev if isinstance(dev, DeviceProfile) else load_device(dev), mapping,
                                   compile_options)
    if isinstance(source, (dict, Scene)):
        _refuse(options, SOURCE_OPTIONS + MAPPING_OPTIONS, "a scene", flag)
        if isinstance(source, dict):
            source, dev = parse_scene(source, "<scene>", Path.cwd(), device=dev, confine=confine), None
        return compile_scene(source, device=dev, options=compile_options, confine=confine)

    from shapedisplay.author.glb import has_haptic_textures, refuse_geometry_options
    from shapedisplay.author.sources import (HEIGHT_MAP_KINDS, check_applicable, fits_force_range_by_default,
                                             load_source, source_options)

    path = Path(os.fspath(source))
    kind = check_applicable(path, given_mapping, {k: flag(k) for k in MAPPING_OPTIONS},
                            kinds={o: HEIGHT_MAP_KINDS for o in MAPPING_OPTIONS})
    if kind != "table" and has_haptic_textures(path):
        from shapedisplay.author.glb import compile_haptic_glb
        refuse_geometry_options(path, {k: flag(k) for k in SOURCE_OPTIONS},
                                **{k: options.get(k) for k in SOURCE_OPTIONS})
        custom = any(v is not None for v in given_mapping.values())
        return compile_haptic_glb(path, device=dev, mapping=mapping if custom else None, options=compile_options)
    opts = source_options(path, flags={k: flag(k) for k in SOURCE_OPTIONS},
                          **{k: options.get(k) for k in SOURCE_OPTIONS})
    if kind in ("scene", "svg"):
        return compile_scene(path, device=dev, options=compile_options, confine=confine)
    if kind == "table":
        raise InputError(f"source '{path}' is already a table; load it with shapedisplay.load")
    from shapedisplay.author.compile import compile_heightfield
    profile = dev if isinstance(dev, DeviceProfile) else load_device(dev)
    if kind == "mesh" and confine:
        from shapedisplay.author.scene.widgets import check_mesh_confined
        check_mesh_confined(path, f"source '{path.name}'")
    hf = load_source(path, flags={k: flag(k) for k in SOURCE_OPTIONS}, **opts)
    if fits_force_range_by_default(hf, n_gain_given="n_gain" in options, height_given="height" in options):
        from shapedisplay.author.forces import fit_to_force_range
        hf = fit_to_force_range(hf, profile, mapping)
    elif "n_gain" not in options and "height" not in options:
        _warn_unfelt_relief(hf, mapping, flag)
    return compile_heightfield(hf, profile, mapping, compile_options)


def _warn_unfelt_relief(hf, mapping, flag) -> None:
    """A warning when data in its own units (a scan, float heights) give a force relief under one force JND:
    the table would be flat to the finger, and the option that fits it is named."""
    if not mapping.height or mapping.n_gain <= 0:
        return
    import warnings

    from shapedisplay.author.perception import FORCE_WEBER, figure
    relief = mapping.n_gain * float(hf.heights.max() - hf.heights.min())
    ref = max(mapping.n_base, figure("force_weber_min_force"))
    if 0 < relief < FORCE_WEBER * ref:
        warnings.warn(f"the relief is {relief:.3g} N of normal force ({mapping.n_gain * 1e-3:g} N/mm over "
                      f"{(hf.heights.max() - hf.heights.min()) * 1e6:.4g} um), under one force step a finger tells "
                      f"apart ({FORCE_WEBER * ref:.3g} N: {FORCE_WEBER * 100:g} % of {ref:g} N): fit it onto a felt "
                      f"range with `{flag('height')}` LO:HI (e.g. 0:1mm) or set `{flag('n_gain')}`")


def _refuse(options: dict, names, what: str, flag) -> None:
    for name in names:
        if name in options:
            raise InputError(f"`{flag(name)}` does not apply to {what} (its file sets it)")
