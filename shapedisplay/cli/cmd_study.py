"""``shapedisplay study``: run a published experiment (a study preset) and write its files."""
from __future__ import annotations

import argparse


def register(sub) -> None:
    from shapedisplay.reports.presets import STUDIES

    presets = "\n".join(f"  {s.name:<13} {s.description}" for s in STUDIES.values())
    p = sub.add_parser("study", help="run a published experiment: " + ", ".join(STUDIES),
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Run a study preset: every condition is played through the renderer; "
                                   "with -o DIR each condition writes a WAV and a trace (.npz), and the folder "
                                   "gets manifest.json, summary.csv and summary.png.\n\npresets:\n" + presets)
    p.add_argument("name", help="preset: " + " | ".join(STUDIES))
    p.add_argument("-o", "--output", help="new (or empty) folder for the study's files; without it only the "
                                          "summary is printed")
    p.add_argument("--only", help="run only the conditions whose name matches this glob, e.g. 'stick-*-dmu0.2'")
    p.add_argument("--list", action="store_true", help="list the preset's conditions and exit")
    p.add_argument("--duration", help="stroke length of the friction preset (default 1 s) or analysed time of "
                                      "imaizumi (default 1 s); the profile presets set their own")
    p.add_argument("--variant", help="imaizumi only: stribeck (default) | premax (pre-maximum static region)")
    p.add_argument("--tick-rate", "--rate", dest="tick_rate", help="tick rate (default: each device's)")
    p.add_argument("--json", action="store_true", help="print the summary rows as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    import json
    import sys

    from shapedisplay.reports.presets import format_summary, get_study, run_study, study_conditions
    from shapedisplay.units import parse_quantity

    study = get_study(args.name)
    dur = parse_quantity(args.duration, "s", "--duration") if args.duration else None
    rate = parse_quantity(args.tick_rate, "Hz", "tick_rate") if args.tick_rate else None
    opts = {"variant": args.variant} if args.variant else {}
    if args.list:
        for c in study_conditions(study, dur, args.only, **opts):
            print(c.name)
        return 0
    progress = None
    if args.output and not args.json:
        def progress(i, n, name):
            print(f"[{i + 1}/{n}] {name}", file=sys.stderr)
    res = run_study(study, args.output, duration=dur, tick_rate=rate, only=args.only, progress=progress, **opts)
    if args.json:
        print(json.dumps(res.rows, indent=2, default=float))
        return 0
    print(f"{study.title}: {len(res.rows)} conditions")
    print(format_summary(res))
    if res.folder is not None:
        print(f"-> {res.folder}/ ({len(res.rows)} WAV + trace pairs, manifest.json, summary.csv, summary.png)")
    return 0
