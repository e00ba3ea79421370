"""``shapedisplay studio``: edit a tactile screen in the browser and feel it while you edit."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser(
        "studio", help="serve a local web app: top view, report, scene editor, live feel in the browser",
        description="Serve SOURCE (scene .toml, image, mesh or table .npz) as a local web app on 127.0.0.1: "
                    "a top view of the table, the compile report, a scene editor and live stick-slip feel "
                    "(the C runtime as WebAssembly in the browser's audio thread). Saving the scene recompiles "
                    "and swaps the table without a reload. Prints the URL (with its access token).")
    p.add_argument("source", help="scene (.toml or .svg mockup), image (.png/.svg icon/.npy), mesh or table (.npz)")
    p.add_argument("--device", help="device profile: bundled name or TOML under the source's folder")
    p.add_argument("--port", type=int, default=None,
                   help="TCP port (default 8765, or the next free one up to 8784 when it is taken; 0 = any free port)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1, this computer only)")
    p.add_argument("--allow-remote", action="store_true",
                   help="allow --host to be a non-loopback address (prints a warning)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    p.add_argument("--out", help="output folder for exports (default: studio-out beside the source)")
    p.add_argument("--model", default="exact",
                   help="pad model the page starts with: exact | jump | karnopp | stribeck (default exact; "
                        "the page's model selector switches between them)")
    g = p.add_argument_group("image and mesh sources")
    g.add_argument("--size", help="image: physical width x height, e.g. 60x4mm")
    g.add_argument("--height", help="image: heights of gray 0 and full scale, e.g. 0:2mm")
    g.add_argument("--resolution", help="image or mesh: sample spacing, e.g. 0.1mm")
    p.set_defaults(func=run)


def run(args) -> int:
    from shapedisplay.author.sources import source_options
    from shapedisplay.cli.cmd_compile import cli_flags
    from shapedisplay.studio.server import serve

    given = {"size": args.size, "height": args.height, "resolution": args.resolution}
    source_options(args.source, flags=cli_flags(), **given)   # refused options fail here, before the server starts
    serve(args.source, device=args.device, port=args.port, host=args.host, allow_remote=args.allow_remote,
          open_browser=not args.no_browser, out_dir=args.out, options=given, model=args.model)
    return 0
