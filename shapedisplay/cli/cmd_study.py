"""``shapedisplay study``: run a published experiment (a study preset) or your own grid, and write its files."""
from __future__ import annotations

import argparse


def register(sub) -> None:
    from shapedisplay.reports.grid import FACTORS
    from shapedisplay.reports.presets import STUDIES

    presets = "\n".join(f"  {s.name:<13} {s.description}" for s in STUDIES.values())
    factors = "\n".join(f"  {f.name:<9} {f.help} (default {f.default})" for f in FACTORS.values())
    p = sub.add_parser("study", help="run a published experiment (" + ", ".join(STUDIES) + ") or your own grid",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       description="Run a study preset: every condition is played through the renderer; "
                                   "with -o DIR each condition writes a WAV and a trace (.npz), and the folder "
                                   "gets manifest.json, summary.csv and summary.png.\n\npresets:\n" + presets +
                                   "\n\n`study grid --factor NAME=V1,V2,... [--factor ...] --repeat N --seed S "
                                   "-o DIR` runs your own full-factorial grid of bumps stroked across their "
                                   "centres: a WAV and a trace per condition, trials.csv (every condition "
                                   "--repeat times, in an order shuffled by --seed) and manifest.json.\n\n"
                                   "grid factors:\n" + factors)
    p.add_argument("name", help="preset: " + " | ".join(STUDIES) + "; or grid (your own factorial design)")
    p.add_argument("-o", "--output", help="new (or empty) folder for the study's files; without it only the "
                                          "summary is printed")
    p.add_argument("--only", help="run only the conditions whose name matches this glob, e.g. 'stick-*-dmu0.2'")
    p.add_argument("--list", action="store_true", help="list the preset's (or grid's) conditions and exit")
    p.add_argument("--duration", help="stroke length of the friction preset (default 1 s) or analysed time of "
                                      "imaizumi (default 1 s); the profile presets set their own")
    p.add_argument("--variant", help="imaizumi only: stribeck (default) | premax (pre-maximum static region)")
    p.add_argument("--factor", action="append", metavar="NAME=V1,V2,...",
                   help="grid only: a factor and its levels with units, e.g. n_top=2N,3N,4N or ramp=5mm,15mm "
                        "(repeat the option for more factors; the others keep their defaults)")
    p.add_argument("--repeat", help="grid only: trials per condition (default 1)")
    p.add_argument("--seed", help="grid only: seed of the shuffled presentation order (default 0)")
    p.add_argument("--tick-rate", "--rate", dest="tick_rate", help="tick rate (default: each device's)")
    p.add_argument("--json", action="store_true", help="print the summary rows (grid: the trial rows) as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    import json
    import sys

    from shapedisplay.errors import InputError
    from shapedisplay.reports.presets import format_summary, get_study, run_study, study_conditions
    from shapedisplay.units import parse_quantity

    if args.name == "grid":
        return run_grid_command(args)
    for option, dest in (("--factor", "factor"), ("--repeat", "repeat"), ("--seed", "seed")):
        if getattr(args, dest) is not None:
            raise InputError(f"`{option}` applies to `study grid` only, not to the preset '{args.name}'")
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


#: Columns of the per-condition table ``study grid`` prints, after the condition and the given factors.
GRID_PRINTED = ("events", "top_burst_amplitude", "top_stick_period_s", "max_friction_n", "clipped")


def run_grid_command(args) -> int:
    import json
    import sys

    from shapedisplay.errors import InputError
    from shapedisplay.reports.grid import FACTORS, parse_factor, plan_grid, run_grid
    from shapedisplay.reports.studies import _cell
    from shapedisplay.units import parse_quantity

    for option, dest in (("--only", "only"), ("--duration", "duration"), ("--variant", "variant")):
        if getattr(args, dest) is not None:
            raise InputError(f"`{option}` applies to the presets, not to `study grid`")
    factors = {}
    for text in args.factor or ():
        name, levels = parse_factor(text)
        if name in factors:
            raise InputError(f"`--factor {text}`: factor {name} is given twice (give its levels in one option, "
                             f"{name}=V1,V2,...)")
        factors[name] = levels
    if not factors:
        raise InputError("`study grid` needs at least one --factor NAME=V1,V2,... (factors: "
                         + ", ".join(FACTORS) + ")")
    repeat = 1 if args.repeat is None else args.repeat
    seed = 0 if args.seed is None else args.seed
    rate = parse_quantity(args.tick_rate, "Hz", "tick_rate") if args.tick_rate else None
    cols = [FACTORS[n].column for n in FACTORS if n in factors]
    if args.list:
        plan = plan_grid(factors, repeat, seed)
        rows = [{"condition": cid, **{FACTORS[n].column: p[n] for n in factors}} for cid, p in plan.conditions]
        print(_table(rows, ("condition", *cols), _cell))
        print(f"{len(plan.conditions)} conditions x {plan.repeat} = {len(plan.trials)} trials")
        return 0
    progress = None
    if args.output and not args.json:
        def progress(i, n, name):
            print(f"[{i + 1}/{n}] {name}", file=sys.stderr)
    res = run_grid(factors, repeat, seed, args.output, tick_rate=rate, progress=progress)
    if args.json:
        print(json.dumps(res.rows, indent=2, default=float))
        return 0
    plan = res.plan
    print(f"Custom grid: {len(plan.conditions)} conditions x {plan.repeat} repetitions = {len(res.rows)} trials "
          f"(seed {plan.seed})")
    print(_table(res.conditions, ("condition", *cols, *GRID_PRINTED), _cell))
    if res.folder is not None:
        print(f"-> {res.folder}/ (trials.csv, {len(res.conditions)} WAV + trace pairs, manifest.json)")
    return 0


def _table(rows, cols, cell) -> str:
    cells = [[cell(r.get(c)) for c in cols] for r in rows]
    width = [max(len(c), *(len(x[i]) for x in cells)) if cells else len(c) for i, c in enumerate(cols)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(cols, width))]
    lines += ["  ".join(x.rjust(w) for x, w in zip(row, width)) for row in cells]
    return "\n".join(lines)
