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

example:
  shapedisplay check assets/scenes/phone.toml
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
    p.add_argument("scene", help="scene file (.toml)")
    p.add_argument("--device", help="device profile overriding the scene's (bundled name or TOML path)")
    p.add_argument("--json", action="store_true", help="print the widgets and warnings as JSON")
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
    from shapedisplay.author.scene import check_scene, load_scene

    scene = load_scene(args.scene, device=args.device)
    warnings = check_scene(scene)
    if args.json:
        print(json.dumps({
            "scene": scene.name, "file": scene.path, "device": scene.device.name,
            "canvas": {"width_m": scene.canvas.width, "height_m": scene.canvas.height,
                       "spacing_m": scene.canvas.spacing, "rows": scene.canvas.rows, "cols": scene.canvas.cols,
                       "is_1d": scene.canvas.is_1d},
            "widgets": [{"id": w.id, "type": w.type, "index": w.index, "bbox_m": list(w.bbox)} for w in scene.widgets],
            "warnings": warnings, "valid": True}, indent=2))
        return 0
    c = scene.canvas
    shape = f"{c.width * 1e3:g} mm strip (1-D)" if c.is_1d else f"{c.width * 1e3:g} x {c.height * 1e3:g} mm"
    print(f"scene '{scene.name}' ({scene.path}): {shape}, {c.cols} x {c.rows} samples of "
          f"{c.spacing * 1e3:g} mm, device '{scene.device.name}'")
    for w in scene.widgets:
        x0, y0, x1, y1 = w.bbox
        where = f"x {x0 * 1e3:g}..{x1 * 1e3:g} mm" + ("" if c.is_1d else f", y {y0 * 1e3:g}..{y1 * 1e3:g} mm")
        print(f"  {w.index:>3} {w.id:<16} {w.type:<8} {where}")
    for msg in warnings:
        print(f"warning: {msg}")
    print(f"valid: {len(scene.widgets)} widget(s), {len(warnings)} warning(s)")
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
