"""``shapedisplay heightmap``: turn a mesh (or another source) into a height map file."""
from __future__ import annotations

import argparse

MESH_HELP = """\
Rasterise the top surface of a 3D model (STL, OBJ, PLY, OFF, GLB, glTF) into
a height field seen from above, and write it as .npy (heights in metres),
.npz (heights + grid), .png (16-bit gray, black = lowest) or back out as a
mesh (.stl / .ply, a closed solid for printing or inspection).

examples:
  shapedisplay heightmap assets/meshes/keycap.stl -o keycap.png --resolution 0.1mm
  shapedisplay heightmap model.glb -o map.npy --grid 512x512 --up y --units m
  shapedisplay heightmap assets/meshes/keycap.stl -o check.stl --resolution 0.2mm
"""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "heightmap", help="rasterise a mesh (or other source) into a height map (.npy/.npz/.png/.stl/.ply)",
        description=MESH_HELP, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", help="mesh file (.stl .obj .ply .off .glb .gltf) or another source file")
    p.add_argument("-o", "--output", required=True,
                   help="output file; suffix picks the format: .npy .npz .png .stl .ply")
    p.add_argument("--resolution", help="sample spacing, e.g. 0.1mm (exclusive with --grid)")
    p.add_argument("--grid", help="grid size ROWSxCOLS, e.g. 512x512 (exclusive with --resolution)")
    p.add_argument("--up", help="axis pointing up: x, y, z, -x, -y, -z (default z) or a direction 'dx,dy,dz'")
    p.add_argument("--units", help="unit of the mesh coordinates: mm, cm, m, in (default mm)")
    p.add_argument("--supersample", type=int,
                   help="k: k x k sub-samples per sample (anti-aliasing; default 1)")
    p.add_argument("--supersample-mode", help="reduce sub-samples by mean (default) or max")
    p.add_argument("--background", help="height where the mesh does not reach (default 0mm)")
    p.add_argument("--margin", help="background border around the footprint (default 0mm)")
    p.add_argument("--size", help="image sources only: physical size WxH, e.g. 60x40mm")
    p.add_argument("--height", help="image sources only: height range LO:HI, e.g. 0:2mm")
    p.add_argument("--method", help="rasteriser: numba (default) or numpy (same answer)")
    p.add_argument("--base-thickness", default="1mm",
                   help="for .stl/.ply output: solid base below the lowest point (default 1mm)")
    p.add_argument("--surface-only", action="store_true",
                   help="for .stl/.ply output: write only the top surface, no walls or base")
    p.set_defaults(func=run)


def _up(text: str):
    if "," in text:
        from shapedisplay.errors import InputError
        try:
            return [float(v) for v in text.split(",")]
        except ValueError:
            raise InputError(f"`--up` direction must be three numbers 'dx,dy,dz' (got {text!r})") from None
    return text


def run(args) -> int:
    from pathlib import Path

    from shapedisplay import mesh
    from shapedisplay_cli.cmd_compile import warnings_as_lines
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
    print(f"{out}: {hf.rows}x{hf.cols} samples (rows x cols), dx={hf.dx * 1e3:.4g} mm, dy={hf.dy * 1e3:.4g} mm, "
          f"heights {lo * 1e3:.4g}..{hi * 1e3:.4g} mm; {desc}")
    if m.get("kind") == "mesh":
        w, h = m["footprint_m"]
        print(f"  mesh: {m['triangles']} triangles from {m['meshes']} mesh(es), "
              f"{m['degenerate_faces_dropped']} degenerate faces dropped, footprint {w * 1e3:.4g} x {h * 1e3:.4g} mm, "
              f"{100 * m['covered_fraction']:.1f}% of samples covered, up={m['up']}, units={m['units']}")
    return 0


#: Mesh-only options and their defaults (None on the command line = not given).
MESH_DEFAULTS = {"up": "z", "units": "mm", "supersample": 1, "supersample_mode": "mean", "background": "0mm",
                 "margin": "0mm", "method": "numba"}


def _load(args, src, mesh):
    from shapedisplay.sources import OPTION_KINDS, check_applicable, load_source

    kind = check_applicable(src, {k: getattr(args, k) for k in OPTION_KINDS})
    if kind == "mesh":
        o = {k: (d if getattr(args, k) is None else getattr(args, k)) for k, d in MESH_DEFAULTS.items()}
        return mesh.mesh_to_heightfield(
            src, resolution=args.resolution, grid=args.grid, up=_up(o["up"]), units=o["units"],
            background=o["background"], supersample=o["supersample"],
            supersample_mode=o["supersample_mode"], margin=o["margin"], method=o["method"],
        )
    opts = {k: v for k, v in (("resolution", args.resolution), ("grid", args.grid),
                              ("size", args.size), ("height_range", args.height)) if v is not None}
    return load_source(src, **opts)
