"""``shapedisplay check SCENE.toml`` and ``shapedisplay new scene NAME``.

Scenes are compiled by ``shapedisplay compile SCENE.toml -o TABLE``.
"""
from __future__ import annotations

import argparse

CHECK_HELP = """\
Validate a scene file without compiling it: parse every widget, place it on
the grid and report errors (one line: widget, field, rule, value) and
warnings (clipping, snapping, heights beyond the device's force range,
detents too dense to feel apart). Exit status 0 when valid, 2 on an error.

--perception adds the legibility check (docs/perception.md): canonical
strokes across every widget at slow, typical and fast exploration speeds,
played with the device's pad model, give each widget's contrast against
flat ground in JNDs of the cue that carries it, and the verdicts detectable,
continuous, saturated and stretch; widgets of one type (and pairs a scene
marks distinct_from) less than 1 JND apart get a feel-alike warning. It also
takes a compiled scene table (.npz). Warnings are advice: the exit status
stays 0.

example:
  shapedisplay check assets/scenes/phone.toml
  shapedisplay check assets/scenes/phone.toml --perception
  shapedisplay check assets/scenes/phone.toml --perception --json
"""

NEW_HELP = """\
Write a commented scene template to start from.

example:
  shapedisplay new scene myscreen          # writes myscreen.toml
  shapedisplay new scene myscreen -o screens/home.toml
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("check", help="validate a scene file (.toml) without compiling it",
                              description=CHECK_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="scene file (.toml); with --perception also a compiled scene table (.npz)")
    p.add_argument("--device", help="device profile overriding the scene's (bundled name or TOML path)")
    p.add_argument("--json", action="store_true", help="print the widgets and warnings as JSON")
    p.add_argument("--perception", action="store_true",
                   help="also check legibility: each widget's contrast in JNDs, detectable / continuous / "
                        "saturated / stretch, feel-alike pairs (docs/perception.md)")
    p.set_defaults(func=run_check)

    n = subparsers.add_parser("new", help="write a commented template (new scene NAME)",
                              description=NEW_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    kinds = n.add_subparsers(dest="kind", metavar="KIND")
    s = kinds.add_parser("scene", help="a scene of tactile widgets", description=NEW_HELP,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("name", help="scene name (file NAME.toml unless -o is given)")
    s.add_argument("-o", "--output", help="file to write (default: NAME.toml)")
    s.add_argument("--overwrite", action="store_true", help="overwrite an existing file")
    from shapedisplay.cli.main import old_spelling
    old_spelling(s, "--force", "--overwrite", dest="overwrite", flag=True)
    s.set_defaults(func=run_new_scene)
    n.set_defaults(func=_new_usage(n))


def _new_usage(parser):
    def run(args) -> int:
        parser.print_help()
        return 2
    return run


def run_check(args) -> int:
    import json
    from pathlib import Path
    from shapedisplay.author.scene import check_scene, load_scene

    perception = getattr(args, "perception", False)
    if perception and Path(args.scene).suffix.lower() not in (".toml", ".svg"):
        return _check_table(args)
    scene = load_scene(args.scene, device=args.device)
    warnings = check_scene(scene)
    rep = None
    if perception:
        from shapedisplay.reports.perception import check_perception
        rep = check_perception(scene)
    contrast = scene.perception.get("contrast", {})
    if args.json:
        widgets = [{"id": w.id, "type": w.type, "index": w.index, "bbox_m": list(w.bbox)} for w in scene.widgets]
        out = {
            "scene": scene.name, "file": scene.path, "device": scene.device.name,
            "canvas": {"width_m": scene.canvas.width, "height_m": scene.canvas.height,
                       "spacing_m": scene.canvas.spacing, "rows": scene.canvas.rows, "cols": scene.canvas.cols,
                       "is_1d": scene.canvas.is_1d},
            "widgets": widgets, "warnings": warnings, "valid": True}
        if contrast:
            out["contrast"] = contrast
        if rep is not None:
            _merge_perception(out, rep)
        print(json.dumps(out, indent=2))
        return 0
    c = scene.canvas
    shape = f"{c.width * 1e3:g} mm strip (1-D)" if c.is_1d else f"{c.width * 1e3:g} x {c.height * 1e3:g} mm"
    print(f"scene '{scene.name}' ({scene.path}): {shape}, {c.cols} x {c.rows} samples of "
          f"{c.spacing * 1e3:g} mm, device '{scene.device.name}'")
    for w in scene.widgets:
        x0, y0, x1, y1 = w.bbox
        where = f"x {x0 * 1e3:g}..{x1 * 1e3:g} mm" + ("" if c.is_1d else f", y {y0 * 1e3:g}..{y1 * 1e3:g} mm")
        print(f"  {w.index:>3} {w.id:<16} {w.type:<8} {where}")
    for wid, c in contrast.items():
        print(f"  contrast: '{wid}' {c['asked']} (against {c['against']}) -> force {c['force_n']:.4g} N "
              f"({c['cue'].replace('_', ' ')} at {c['speed_m_s'] * 1e3:.3g} mm/s"
              + ("" if c["within_device"] else ", beyond the device's force range: clamped") + ")")
    for msg in warnings:
        print(f"warning: {msg}")
    tail = ""
    if rep is not None:
        from shapedisplay.reports.perception import format_perception
        for line in format_perception(rep):
            print(line)
        for msg in rep["warnings"]:
            print(f"warning: {msg}")
        tail = f"; perception: {len(rep['warnings'])} warning(s)"
    print(f"valid: {len(scene.widgets)} widget(s), {len(warnings)} warning(s){tail}")
    return 0


def _merge_perception(out: dict, rep: dict) -> None:
    """Each widget's perception record into its ``widgets`` entry; the pairs and the rest beside them."""
    by_id = {r["id"]: r for r in rep["widgets"]}
    for w in out["widgets"]:
        w.update({k: v for k, v in by_id.get(w["id"], {}).items() if k not in ("id", "type")})
    out["pairs"] = rep["pairs"]
    out["perception"] = {k: v for k, v in rep.items() if k not in ("widgets", "pairs")}


def _check_table(args) -> int:
    """``check TABLE --perception``: the legibility check of a compiled scene table."""
    import json
    from shapedisplay.reports.perception import check_perception, format_perception
    from shapedisplay.table.model import FrictionTable
    table = FrictionTable.load(args.scene)
    if args.device:
        from shapedisplay.errors import InputError
        raise InputError("`--device`: a compiled table plays on the device it was compiled for; "
                         "check the scene to try another device")
    rep = check_perception(table)
    if args.json:
        out = {"table": str(args.scene), "widgets": [dict(r) for r in rep["widgets"]]}
        out["pairs"] = rep["pairs"]
        out["perception"] = {k: v for k, v in rep.items() if k not in ("widgets", "pairs")}
        print(json.dumps(out, indent=2))
        return 0
    print(f"table '{args.scene}': {len(rep['widgets'])} widget(s)")
    for line in format_perception(rep):
        print(line)
    for msg in rep["warnings"]:
        print(f"warning: {msg}")
    return 0


def run_new_scene(args) -> int:
    from pathlib import Path
    from shapedisplay.atomic import write_text
    from shapedisplay.errors import InputError
    from shapedisplay.author.scene.template import render_template

    out = Path(args.output) if args.output else Path(f"{args.name}.toml")
    if out.exists() and not args.overwrite:
        raise InputError(f"output '{out}': file exists; choose another name or pass --overwrite")
    write_text(out, render_template(args.name, str(out)))
    print(f"wrote {out}: check it with `shapedisplay check {out}`")
    return 0
