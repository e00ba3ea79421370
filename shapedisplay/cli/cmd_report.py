"""``shapedisplay report``: accuracy (error against run time) and stability reports."""
from __future__ import annotations

import argparse

_KINDS = ("accuracy", "stability")


def register(sub) -> None:
    p = sub.add_parser(
        "report",
        help="work-precision (accuracy) and stability reports of the renderer models",
        description="Run a report and write DIR/<kind>.json (every number), DIR/<kind>.md and PNG plots. "
                    "'accuracy': every renderer model/tick rate/table setting and scipy solve_ivp peers against "
                    "the exact reference (error vs CPU time). 'stability': >= 1000 stiff and extreme cases with a "
                    "verdict each (stable / physically self-excited / numerically unstable / rejected).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n  shapedisplay report accuracy --quick -o out/report\n"
               "  shapedisplay report stability -o out/report",
    )
    p.add_argument("kind", choices=_KINDS, help="which report")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output directory (created if missing)")
    p.add_argument("--quick", action="store_true", help="fewer cases and settings (under a minute)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots (no matplotlib needed)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=run)


def run(args) -> int:
    import importlib
    import os

    mod = importlib.import_module(f"shapedisplay.reports.{args.kind}")
    out = args.output
    if os.path.exists(out) and not os.path.isdir(out):
        from shapedisplay.errors import InputError
        raise InputError(f"`--output` must be a directory (got the file {out!r})")
    rep = mod.run(out, quick=args.quick, progress=not args.no_progress, plots=not args.no_plots)
    print(mod.terminal_summary(rep))
    files = [f"{args.kind}.json", f"{args.kind}.md"] + list(rep.get("plots", []))
    print(f"wrote {len(files)} files to {out}: " + ", ".join(files))
    return 0
