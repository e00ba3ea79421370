"""``shapedisplay preview``: 3D view of a source, scene or table, with a played stroke."""
from __future__ import annotations

import argparse
import re

PREVIEW_HELP = """\
Show a height map, mesh, scene or compiled table as a 3D surface coloured by
a channel, with a colour bar in physical units, an x/y/z triad labelled in
mm, a legend, walls (slope >= 1) overlaid in red and the vertical
exaggeration stated on screen. With --trace, the played stroke is drawn on
the surface (stick/slip segments, bursts sized by amplitude) with a chart of
N and friction force along it marking the widgets crossed; the trace must
come from this table.

Without -o a window opens: drag to orbit, scroll to zoom, click or hover for
a read-out of position, height and every channel, space replays the stroke.
With -o the picture is rendered off-screen (no display or GPU needed; on
Debian/Ubuntu it needs libegl1 libegl-mesa0 libgl1-mesa-dri, see
scripts/install-system-deps.sh).

colour channels: height, normal_force (N), breakaway_force, kinetic_force,
lateral (|F_lat|), slope, walls, and any other channel the table stores.

examples:
  shapedisplay compile assets/scenes/phone.toml -o out/phone.npz
  shapedisplay play out/phone.npz --stroke "62,2 -> 62,156 @ 30mm/s" -o out/phone.wav --trace-out out/phone-trace.npz
  shapedisplay preview out/phone.npz --color N -o phone.png
  shapedisplay preview out/phone.npz --trace out/phone-trace.npz -o shot.png
  shapedisplay preview assets/scenes/phone.toml --color slope
  shapedisplay preview assets/meshes/keycap.stl --resolution 0.1mm -o keycap.png
  shapedisplay preview assets/scenes/terrain.png --size 120x80mm --height 0:2mm -o map.png --pixels 1200x800
  shapedisplay preview tray.glb --up y --units m --view top -o tray.png

A picture is shown as the top view it is (x to the right, y up the screen):
--view top shows it the way an image viewer does.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "preview", help="3D preview of a source, scene or table (window, or PNG with -o)",
        description=PREVIEW_HELP, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("input", metavar="SOURCE|TABLE",
                   help="compiled table (.npz), scene (.toml), image (.png/.npy) or mesh (.stl .obj .ply ...)")
    p.add_argument("--trace", help="played stroke (.npz from 'shapedisplay play'); needs the table it was played on")
    p.add_argument("--color", "--colour", dest="color", default="height",
                   help="channel colouring the surface (default height; N = normal_force)")
    p.add_argument("-o", "--output", help="write a PNG off-screen instead of opening a window")
    p.add_argument("--pixels", default="1600x1000", help="picture/window size in pixels WxH (default 1600x1000)")
    p.add_argument("--exaggeration", default="auto",
                   help="vertical exaggeration: auto (relief about 15%% of the width) or a number")
    p.add_argument("--view", default="iso", help="camera: iso (default), top or side")
    p.add_argument("--scene", help="scene file (.toml) whose widget outlines and ids are drawn on a table")
    p.add_argument("--cmap", default="viridis", help="colour map (default viridis)")
    p.add_argument("--no-chart", action="store_true", help="do not draw the N/friction chart of the stroke")
    from shapedisplay.cli.cmd_compile import add_source_arguments
    from shapedisplay.cli.main import old_spelling
    add_source_arguments(p)
    old_spelling(p, "--extent", "--size", dest="size", why=" (the physical size, as in compile)")
    p.set_defaults(func=run)


#: A size of bare whole numbers, ``1200x800``: a picture size in pixels (a physical size has a unit).
_PIXELS = re.compile(r"^\s*\d+\s*[x×]\s*\d+\s*$")


def picture_size(args) -> tuple[str | None, str]:
    """(physical size, pixel size) from the options; ``--size 1200x800`` without a unit is a pixel size.

    ``--size`` is the physical size in every command (with its unit, ``120x80mm``);
    the picture size in pixels is ``--pixels``. A value of bare whole numbers
    cannot be a physical size (units are required), so ``--size`` given one is
    read as the picture size in pixels, with a note saying to write ``--pixels``.
    """
    import sys
    size = getattr(args, "size", None)
    if size is not None and _PIXELS.match(size):
        print(f"shapedisplay preview: note: --size {size} without a unit is read as the picture size in pixels, "
              f"as before; write --pixels {size.strip()} (--size is the physical size, e.g. 120x80mm)",
              file=sys.stderr)
        return None, size
    return size, args.pixels


def run(args) -> int:
    from shapedisplay import viewer
    from shapedisplay.author.sources import source_options
    from shapedisplay.cli.cmd_compile import cli_flags, source_given

    size, pixels = picture_size(args)
    args.size = size
    flags = cli_flags()
    opts = source_options(args.input, flags=flags, **source_given(args))
    model = viewer.load_model(args.input, scene=args.scene, flags=flags, **opts)
    trace = viewer.load_trace(args.trace) if args.trace else None
    preview = viewer.render(model, args.color, trace=trace, exaggeration=args.exaggeration, size=pixels,
                            off_screen=bool(args.output), view=args.view, cmap=args.cmap,
                            chart=not args.no_chart)
    try:
        if args.output:
            path = preview.save(args.output)
            print(f"wrote {path} ({preview.channel}, vertical exaggeration x{preview.exaggeration:g})")
        else:
            preview.show()
    finally:
        preview.close()
    return 0
