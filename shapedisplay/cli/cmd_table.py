"""``shapedisplay inspect`` and ``shapedisplay export``: read a compiled table."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("inspect", help="summarise a compiled table (grid, channels, sizes, what was left out)",
                       description="Verify a table (version, checksum) and print a summary.")
    p.add_argument("table", help="table file (.npz)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run_inspect)

    p = sub.add_parser("export", help="export a table as JSON (SI arrays), a C99 header or a binary image",
                       description="Export a verified table: JSON holds the grid and every channel in SI units "
                                   "at the sample centres (row-major); C writes static const arrays for firmware; bin "
                                   "writes the binary table image the C runtime loads at run time "
                                   "(docs/table-image.md).")
    p.add_argument("table", help="table file (.npz)")
    p.add_argument("--format", required=True, help="json | c | bin | friction-png | glb")
    p.add_argument("-o", "--output", required=True, help="file to write")
    p.add_argument("--name", help="C symbol prefix (default: output file stem)")
    p.add_argument("--quantity", help="friction-png: auto | mu | normal_force | breakaway_force (default auto: mu "
                                      "where it varies, else breakaway_force, the shape of N)")
    p.add_argument("--bits", type=int, help="friction-png: 8 or 16 bits per pixel (default 16)")
    p.set_defaults(func=run_export)

    p = sub.add_parser("diff", help="compare two tables: grid, channels (largest difference and where), metadata",
                       description="Compare two verified tables. Exit status 0 when identical, 1 when they differ.")
    p.add_argument("a", metavar="A", help="first table (.npz)")
    p.add_argument("b", metavar="B", help="second table (.npz)")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.set_defaults(func=run_diff)


def _g(value) -> str:
    """A header number as ``%g``; anything else (absent, malformed) as written."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f"{value:g}"
    return "?" if value is None else repr(value)


def format_summary(s: dict) -> str:
    """Readable multi-line summary of :meth:`FrictionTable.summary`."""
    g = s["grid"]
    meta = s.get("meta", {})
    lines = [
        f"table format {s['format_version']}, checksum {s['checksum']}",
        f"grid: {g['cols']} x {g['rows']} samples{' (1-D)' if s['is_1d'] else ''}, "
        f"dx={g['dx_m'] * 1e3:.4g} mm, dy={g['dy_m'] * 1e3:.4g} mm, origin ({g['x0_m'] * 1e3:.4g}, "
        f"{g['y0_m'] * 1e3:.4g}) mm, extent {g['cols'] * g['dx_m'] * 1e3:.4g} x {g['rows'] * g['dy_m'] * 1e3:.4g} mm",
    ]
    src = meta.get("source", {})
    if src:
        lines.append(f"source: {src.get('description', '')} (sha256 {str(src.get('sha256', ''))[:16]}...)")
    dev = meta.get("device", {})
    if dev:
        lines.append(f"device: {dev.get('name')} outputs={dev.get('outputs')} tick {_g(dev.get('tick_rate_hz'))} Hz, "
                     f"N range {dev.get('normal_force_range')} N")
    mp = meta.get("mapping", {})
    if mp:
        lines.append(f"mapping: {mp.get('spec')} (n_base {_g(mp.get('n_base'))} N, n_gain {_g(mp.get('n_gain'))} N/m, "
                     f"K_mu {_g(mp.get('slope_friction_gain'))})")
    lines.append("channels:")
    for name, c in s["channels"].items():
        lines.append(f"  {name:<16} {c['dtype']:<8} [{c['min']:.6g}, {c['max']:.6g}] {c['unit']}, "
                     f"max error {c['max_error']:.3g} {c['unit']}")
    left = meta.get("report", {}).get("left_out", {})
    if isinstance(left, dict) and left:
        lines.append("left out:")
        for name, why in left.items():
            lines.append(f"  {name:<16} {why}")
    walls = meta.get("report", {}).get("walls")
    if isinstance(walls, dict) and walls.get("count"):
        from shapedisplay.author.gradients import wall_lines
        lines += wall_lines(walls)
    saved = s["dense_bytes"] - s["stored_bytes"]
    lines.append(f"patches {s['patches']}, blocks {s['blocks']}; stored {s['stored_bytes']} bytes, "
                 f"dense {s['dense_bytes']} bytes, saved {saved} bytes "
                 f"({100 * saved / s['dense_bytes'] if s['dense_bytes'] else 0:.1f} %)")
    return "\n".join(lines)


def run_inspect(args) -> int:
    import json

    from shapedisplay.table.model import FrictionTable

    table = FrictionTable.load(args.table)
    s = table.summary()
    if args.json:
        print(json.dumps(s, indent=2, allow_nan=False))
    else:
        print(format_summary(s))
    return 0


def run_export(args) -> int:
    from shapedisplay.errors import unknown_key
    from shapedisplay.exchange import FORMATS, export_table
    from shapedisplay.table.model import FrictionTable

    if args.format not in FORMATS:
        raise unknown_key("export format", args.format, FORMATS)
    from shapedisplay.cli.cmd_compile import warnings_as_lines
    table = FrictionTable.load(args.table)
    with warnings_as_lines("export"):
        out = export_table(table, args.output, args.format, args.name, quantity=args.quantity, bits=args.bits)
    print(f"wrote {out} ({args.format})")
    return 0


def run_diff(args) -> int:
    import json

    from shapedisplay.table.diff import diff_tables, format_diff
    from shapedisplay.table.model import FrictionTable

    d = diff_tables(FrictionTable.load(args.a), FrictionTable.load(args.b))
    print(json.dumps(d, indent=2, default=str) if args.json else format_diff(d, args.a, args.b))
    return 0 if d["identical"] else 1
