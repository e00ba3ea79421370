"""``shapedisplay heightmap``: turn a mesh (or another source) into a height map file."""
from __future__ import annotations

import argparse

MESH_HELP = """\
Rasterise the top surface of a 3D model (STL, OBJ, PLY, OFF, GLB, glTF) into
a height field seen from above, and write it as .npy (heights in metres),
.npz (heights + grid), .png (16-bit gray, black = lowest) or back out as a
mesh (.stl / .ply, a closed solid for printing or inspection). Pictures and
arrays are written as the top view (row 0 = the far edge, y up); meshes keep
x, y and z. Pictures and .npy arrays are read the same way, so a picture
taken through heightmap and back keeps its orientation.

examples:
  shapedisplay heightmap assets/meshes/keycap.stl -o keycap.png --resolution 0.1mm
  shapedisplay heightmap model.glb -o map.npy --samples 512x512 --up y --units m
  shapedisplay heightmap assets/meshes/keycap.stl -o check.stl --resolution 0.2mm
  shapedisplay heightmap statue.glb -o statue.png --up y --size 60mm --height 0:3mm
  shapedisplay heightmap icon.png -o icon.stl --size 20x20mm --height 0:1mm
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "heightmap", help="rasterise a mesh (or other source) into a height map (.npy/.npz/.png/.stl/.ply)",
        description=MESH_HELP, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", help="mesh file (.stl .obj .ply .off .glb .gltf) or another source file")
    p.add_argument("-o", "--output", required=True,
                   help="output file; suffix picks the format: .npy .npz .png .stl .ply")
    from shapedisplay.cli.cmd_compile import add_source_arguments
    add_source_arguments(p)
    g = p.add_argument_group("mesh rasterising")
    g.add_argument("--samples", help="grid size in samples, COLSxROWS (width first, as sizes are printed), "
                                     "e.g. 512x256 (exclusive with --resolution)")
    from shapedisplay.cli.main import old_spelling
    old_spelling(g, "--grid", "--samples COLSxROWS", dest="grid",
                 why=" (columns first, as every size is printed; --grid takes ROWSxCOLS)")
    p.set_defaults(grid=None)
    g.add_argument("--supersample", help="k: k x k sub-samples per sample (anti-aliasing; default 1)")
    g.add_argument("--supersample-mode", help="reduce sub-samples by mean (default) or max")
    g.add_argument("--background", help="height where the mesh does not reach (default 0mm)")
    g.add_argument("--margin", help="background border around the footprint (default 0mm)")
    p.add_argument("--base-thickness", default="1mm",
                   help="for .stl/.ply output: solid base below the lowest point (default 1mm)")
    p.add_argument("--surface-only", action="store_true",
                   help="for .stl/.ply output: write only the top surface, no walls or base")
    p.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from shapedisplay.author import mesh
    from shapedisplay.cli.cmd_compile import warnings_as_lines
    from shapedisplay.errors import FileFormatError
    from shapedisplay.units import parse_quantity

    out = Path(args.output)
    if out.suffix.lower() not in mesh.HEIGHTMAP_SUFFIXES:
        raise FileFormatError(f"output '{out}': unsupported suffix '{out.suffix}'; use one of "
                              f"{', '.join(mesh.HEIGHTMAP_SUFFIXES)}")
    base = parse_quantity(args.base_thickness, "m", "--base-thickness")
    src = Path(args.source)
    with warnings_as_lines("heightmap"):   # printed before an error that follows: it often explains it
        hf = _load(args, src, mesh)
    desc = mesh.save_heightmap(hf, out, solid=not args.surface_only, base_thickness=base)
    m = hf.meta
    lo, hi = float(hf.heights.min()), float(hf.heights.max())
    print(f"{out}: {hf.cols} x {hf.rows} samples (cols x rows), dx={hf.dx * 1e3:.4g} mm, dy={hf.dy * 1e3:.4g} mm, "
          f"heights {lo * 1e3:.4g}..{hi * 1e3:.4g} mm; {desc}")
    if m.get("kind") == "mesh":
        w, h = m["footprint_m"]
        print(f"  mesh: {m['triangles']} triangles from {m['meshes']} mesh(es), "
              f"{m['degenerate_faces_dropped']} degenerate faces dropped, footprint {w * 1e3:.4g} x {h * 1e3:.4g} mm, "
              f"{100 * m['covered_fraction']:.1f}% of samples covered, up={m['up']}, units={m['units']}")
    if m.get("scale"):
        print(f"  scale: {m['scale']['rule']}")
    for note in m.get("notes", []):
        print(f"  note: {note}")
    return 0


_MESH_EXTRA = ("samples", "grid", "supersample", "supersample_mode", "background", "margin")


def _load(args, src, mesh):
    from shapedisplay.author.sources import load_source, source_options
    from shapedisplay.cli.cmd_compile import cli_flags
    from shapedisplay.cli.cmd_compile import source_given

    flags = cli_flags()
    return load_source(src, flags=flags, **source_options(src, flags=flags, **source_given(args, _MESH_EXTRA)))
