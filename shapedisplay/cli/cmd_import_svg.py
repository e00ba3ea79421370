"""``shapedisplay import-svg MOCK.svg -o SCENE.toml``: an SVG mockup as a scene file to edit."""
from __future__ import annotations

import argparse

HELP = """\
Read a UI mockup exported from a design tool as SVG and write the equivalent
scene TOML. Elements name their widget type with data-widget="button", a
class "sd-button" or an id such as "button-ok"; every other data-* attribute
is a widget key (data-height="1.5 mm", data-detents="5"). The <svg> element's
width and height give the canvas size (e.g. width="80mm"), its data-*
attributes the resolution, device and mapping. Groups and transforms are
applied; y is flipped so the scene looks like the mockup from above.
`shapedisplay compile MOCK.svg` compiles the mockup directly to the same table.

example:
  shapedisplay import-svg assets/scenes/settings-mockup.svg -o settings.toml
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("import-svg", help="write the scene (.toml) of an SVG UI mockup",
                              description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("svg", help="SVG mockup (.svg)")
    p.add_argument("-o", "--output", required=True, help="scene file to write (.toml)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    from shapedisplay.cli.main import old_spelling
    old_spelling(p, "--force", "--overwrite", dest="overwrite", flag=True)
    p.set_defaults(func=run)


def run(args) -> int:
    from shapedisplay.author.scene import import_svg

    res = import_svg(args.svg, args.output, overwrite=args.overwrite)
    for w in res["warnings"]:
        print(f"warning: {w}")
    for n in res["notes"]:
        print(f"note: {n}")
    print(f"wrote {res['path']} ({res['widgets']} widgets)")
    return 0
