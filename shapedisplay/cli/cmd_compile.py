"""``shapedisplay compile``: height map, mesh or scene -> friction-envelope table."""
from __future__ import annotations

import argparse


def register(sub) -> None:
    p = sub.add_parser(
        "compile",
        help="compile a height map, mesh or scene into a friction-envelope table",
        description="Compile SOURCE (picture .png/.jpg/.tif/.svg/..., .npy array, AFM/SPM scan .txt/.gsf, "
                    ".stl/.obj/.ply/.off/.glb/.gltf mesh, .toml scene or .svg mockup) into a table. Quantities "
                    "take units: '60x4mm', '0:2mm', '0.5N', '2N/mm'. A picture is the top view: x to the right, y up.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example:\n  shapedisplay compile map.png -o t.npz --size 60x4mm --height 0:2mm "
               "--mapping height --n-base 0.5N --n-gain 2N/mm",
    )
    p.add_argument("source", nargs="+", help="picture (an SVG icon too) or .npy height map, instrument scan "
                                             "(.txt/.gsf), mesh, scene (.toml) or SVG mockup (.svg); several sources "
                                             "compile into the folder given with -o")
    p.add_argument("-o", "--output", required=True, help="table file to write (.npz), or a folder (DIR/) for "
                                                         "several sources: DIR/<stem>.npz each")
    p.add_argument("--device", help="device profile: TOML file or bundled name (default: built-in Konyo pad)")
    add_source_arguments(p)
    g = p.add_argument_group("mapping (images and meshes; a scene has its [mapping])")
    g.add_argument("--mapping", default="height",
                   help="terms joined by '+': height, slope, lateral, lateral-normal, stretch, perceptual "
                        "(default height)")
    g.add_argument("--n-base", help="normal force on flat ground N1, e.g. 0.5N (default 0.5 N)")
    g.add_argument("--n-gain", help="height gain G in N = N1 + G*h, e.g. 2N/mm (default 1 N/mm)")
    g.add_argument("--slope-gain", help="K_mu of the one-sided slope friction, per unit slope (default 0.2)")
    g.add_argument("--lateral-gain", help="K of the lateral cue F = -K grad h, e.g. 1N (default 1 N)")
    g.add_argument("--skin-stretch", help="skin-stretch target, e.g. 0.55mm")
    g.add_argument("--perceptual", help="power-law exponent beta or a name (bumpiness, friction, vibration)")
    g = p.add_argument_group("analysis and coding")
    g.add_argument("--gradient", default="central", help="central | gaussian | savgol (default central)")
    g.add_argument("--sigma", help="gaussian gradient: smoothing sigma, e.g. 0.2mm")
    g.add_argument("--window", help="savgol gradient: window in samples (odd) or a length, e.g. 1mm")
    g.add_argument("--order", type=int, help="savgol gradient: polynomial order (default 2)")
    g.add_argument("--max-slope", help="steepest renderable slope (default 1 = 45 deg; 'inf' = none)")
    g.add_argument("--no-limit-walls", action="store_true", help="do not clip wall slopes")
    g.add_argument("--quantize", default="auto", help="auto | uint8 | uint16 | float32 | float64 (default auto)")
    g.add_argument("--weber", help="friction Weber fraction for auto quantization (default 0.1)")
    g.add_argument("--keep", help="comma-separated channels to store even if the device does not use them")
    p.add_argument("--json", action="store_true", help="print the compile report as JSON")
    p.add_argument("--no-perception", action="store_true",
                   help="scenes: skip the legibility check (docs/perception.md) in the report")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=run)


def add_source_arguments(p) -> None:
    """The options of picture and mesh sources, the same on compile, preview and heightmap."""
    g = p.add_argument_group("picture and mesh sources")
    g.add_argument("--size",
                   help="pictures: physical width x height, e.g. 60x4mm (instrument scans state theirs); meshes: "
                        "WxH stretches the footprint, one length (e.g. 60mm) scales the whole model")
    g.add_argument("--height", help="LO:HI, e.g. 0:2mm: integer pictures map gray 0 and full scale onto it; float "
                                    "data and meshes have their range fitted onto it")
    g.add_argument("--resolution", help="sample spacing, e.g. 0.1mm (pictures: instead of the size; meshes: grid step)")
    g.add_argument("--channel", help="colour pictures: luminance (ITU-R BT.709, default), r, g, b, a, or normal "
                                     "(integrate a tangent-space normal map)")
    g.add_argument("--z-units", help="unit of float data (.npy, float TIFF): m (default), mm, um, nm; "
                                     "instrument scans (.txt/.gsf) state theirs")
    g.add_argument("--up", help="mesh axis that points up: x, y, z, -x, -y, -z or a vector dx,dy,dz (default z)")
    g.add_argument("--units", help="length unit of the mesh coordinates: mm (default), cm, m, in")


def source_given(args, extra=()) -> dict:
    """{option name: text or None} of the source options on the command line."""
    given = {"size": args.size}
    for name in ("height", "resolution", "channel", "z_units", "up", "units") + tuple(extra):
        given[name] = getattr(args, name)
    return given


class warnings_as_lines:
    """Context manager: print each library warning as one line ``shapedisplay CMD: warning: ...``.

    Printed on exit, also when an error follows (a unit warning often
    explains the error).
    """

    def __init__(self, command: str):
        self.command = command

    def __enter__(self):
        import warnings
        self._ctx = warnings.catch_warnings(record=True)
        self._caught = self._ctx.__enter__()
        warnings.simplefilter("always")
        return self

    def __exit__(self, *exc):
        import sys

        from shapedisplay.cli.main import printable
        self._ctx.__exit__(*exc)
        for w in self._caught:
            print(f"shapedisplay {self.command}: warning: {printable(str(w.message))}", file=sys.stderr)
        return False


#: Source options of the commands beyond compile's (heightmap's mesh sampling).
_MORE_SOURCE_OPTIONS = ("samples", "grid", "supersample", "supersample_mode", "background", "margin")


def cli_flags() -> dict:
    """How the command line spells every option the library names, for its messages: ``n_base`` -> ``--n-base``."""
    from shapedisplay.author.policy import OPTIONS
    flags = {name: "--" + name.replace("_", "-") for name in (*OPTIONS, *_MORE_SOURCE_OPTIONS)}
    flags["limit_walls"] = "--no-limit-walls"
    return flags


def compile_options(args) -> dict:
    """The compile options given on the command line, by name (None = not given), for the compile policy."""
    from shapedisplay.author.policy import OPTIONS
    given = {name: getattr(args, name, None) for name in OPTIONS if name != "limit_walls"}
    if given.get("mapping") == "height":          # the default: a scene keeps its own [mapping]
        given["mapping"] = None
    given["limit_walls"] = False if getattr(args, "no_limit_walls", False) else None
    return given


def compile_source(args, source):
    """Compile one source with the options in ``args`` (:func:`shapedisplay.author.policy.compile_file`)."""
    from shapedisplay.author.policy import compile_file
    with warnings_as_lines("compile"):
        return compile_file(source, device=args.device, flags=cli_flags(), **compile_options(args))


def run(args) -> int:
    import json

    from shapedisplay.author.batch import is_batch
    from shapedisplay.author.compile import format_report

    if is_batch(args.source, args.output):
        return run_batch(args)
    result = compile_source(args, args.source[0])
    out = result.table.save(args.output)
    report = dict(result.report)
    if "widgets" in report and not args.no_perception:      # a scene: will each widget be felt and told apart?
        from shapedisplay.author.scene import load_scene
        from shapedisplay.reports.perception import check_perception
        report["perception"] = check_perception(result.table, scene=load_scene(args.source[0], device=args.device))
    if args.json:
        print(json.dumps(report, indent=2, allow_nan=False))
    elif not args.quiet:
        print(format_report(report))
        if "widgets" in report:
            from shapedisplay.author.scene import format_widget_report
            print(format_widget_report(report))
        if "perception" in report:
            from shapedisplay.reports.perception import format_perception
            print("\n".join(format_perception(report["perception"])))
        print(f"wrote {out}")
    return 0


def run_batch(args) -> int:
    """Several sources into one folder: one progress bar, then a summary table."""
    import json
    import sys

    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
    from rich.table import Table

    from shapedisplay.author.batch import plan_outputs, summary_row
    from shapedisplay.errors import ShapeDisplayError

    plan = plan_outputs(args.source, args.output)
    rows, reports = [], []
    with Progress(TextColumn("compile"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.description}"),
                  TimeElapsedColumn(), console=Console(stderr=True), disable=args.quiet) as bar:
        task = bar.add_task("", total=len(plan))
        for src, out in plan:
            bar.update(task, description=str(src))
            try:
                result = compile_source(args, src)
                result.table.save(out)
                rows.append(summary_row(src, out, result))
                reports.append({"source": str(src), "output": str(out), "report": result.report})
            except ShapeDisplayError as exc:
                rows.append(summary_row(src, None, error=str(exc)))
                reports.append({"source": str(src), "error": str(exc)})
            bar.advance(task)
    failed = [r for r in rows if r["status"] != "ok"]
    if args.json:
        print(json.dumps(reports, indent=2, allow_nan=False))
    elif not args.quiet:
        cols = ("source", "output", "samples", "size_mm", "channels", "stored_bytes", "saved", "status")
        table = Table(title=f"compiled {len(rows) - len(failed)} of {len(rows)} sources into {args.output}")
        for col in cols:
            table.add_column(col.replace("_", " "), overflow="fold")
        for r in rows:
            table.add_row(*(str(r.get(c, "")) for c in cols))
        Console().print(table)
    for r in failed:
        print(f"shapedisplay compile: error: {r['status'][len('error: '):]}", file=sys.stderr)
    return 2 if failed else 0
