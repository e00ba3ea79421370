"""``shapedisplay play``: render a stroke, trace or force recording over a table to WAV/trace/plot."""
from __future__ import annotations

STROKE_HELP = ('cursor stroke in mm on the table grid: "0,10 -> 60,10 -> 60,30 @ 20 mm/s", back and forth '
               '"0,2 <-> 60,2 @ 20mm/s x3", 1-D "0:60mm @ 50mm/s"; segments joined by ";" with presses: '
               '"62,30 -> 62,60 @ 30mm/s; press 2N 150ms; -> 90,60 @ 20mm/s press 1N"')


#: Reaction events printed at most (the trace and --json hold them all).
REACTIONS_SHOWN = 40


def register(sub) -> None:
    p = sub.add_parser("play", help="play a table with the stick-slip renderer (WAV, trace, plot)",
                       description="Render a cursor stroke over a compiled table with a stick-slip model and "
                                   "write the burst audio (WAV), the per-tick trace (.npz) and a plot. "
                                   "Outside the table the edge value is held.")
    p.add_argument("table", help="table file (.npz)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--stroke", help=STROKE_HELP)
    src.add_argument("--cursor-csv", help="recorded cursor path, CSV t,x,y[,press] (s, mm, N; header x_m,y_m for metres)")
    src.add_argument("--force-csv", help="pointing-stick force recording, CSV t,fx[,fy[,fz]] (s, N; fz is the press); v = alpha f "
                                         "with alpha = the device's cursor_gain (a device that has one)")
    from shapedisplay.cli.main import old_spelling
    old_spelling(src, "--trace", "--cursor-csv", dest="cursor_csv",
                 why=" (--trace names a played trace .npz, as in preview and --trace-out)")
    old_spelling(src, "--force", "--force-csv", dest="force_csv", why=" (--force means overwrite elsewhere)")
    p.add_argument("--start", default="0,0", help="start position for --force-csv, 'x,y' in mm (default 0,0)")
    p.add_argument("--device", help="device profile (TOML path or bundled name); overrides the table's")
    p.add_argument("--model", default="exact", help="exact | jump | karnopp | stribeck | tanh | euler | rk4 (default exact)")
    p.add_argument("--tick-rate", "--rate", dest="tick_rate",
                   help="renderer tick rate, e.g. 10kHz (default: the device's; --rate is the same option)")
    p.add_argument("--audio-rate", help="audio sample rate, e.g. 48kHz (default: the device's)")
    p.add_argument("--sample-format", default="float32", help="WAV sample format: float32 | int16 (default float32)")
    old_spelling(p, "--format", "--sample-format", dest="sample_format", why=" (--format names a file format in export)")
    p.add_argument("--burst-policy", default="retrigger", help="retrigger | add | max (default retrigger)")
    p.add_argument("--burst-gain", help="burst gain B in 1/N (full scale per newton of breakaway force), "
                                        "e.g. 0.25; overrides the device's")
    p.add_argument("--max-stick-period", help="force a slip after this long stuck, e.g. 50ms (default off)")
    p.add_argument("-o", "--output", required=True, help="WAV file to write")
    p.add_argument("--trace-out", help="write the per-tick trace (.npz)")
    p.add_argument("--plot", help="write a plot (.png/.pdf/.svg; needs matplotlib)")
    p.add_argument("--ahap", help="write the stroke as an Apple Core Haptics pattern (.ahap): a transient per "
                                  "burst and intensity curves following the drive envelope")
    p.add_argument("--ahap-envelope", default="on", choices=("on", "off"),
                   help="off: transients only, no envelope curves (Core Haptics scales every event by them)")
    p.add_argument("--drive-csv", help="write the drive at the audio rate as CSV t_s,drive")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    import json
    import sys

    from shapedisplay.table.devices import load_device
    from shapedisplay.errors import InputError
    from shapedisplay.render.cursor import load_force_csv, load_trace_csv, parse_stroke
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.exchange.outputs import play_to_files
    from shapedisplay.render.sinks import SAMPLE_FORMATS, check_plot_path
    from shapedisplay.errors import unknown_key
    from shapedisplay.table.model import FrictionTable
    from shapedisplay.units import parse_quantity

    if args.sample_format not in SAMPLE_FORMATS:
        raise unknown_key("--sample-format", args.sample_format, SAMPLE_FORMATS)
    if args.plot:
        check_plot_path(args.plot)          # before any work: format known, matplotlib installed
    table = FrictionTable.load(args.table)
    device = load_device(args.device) if args.device else None
    if args.burst_gain is not None:
        from dataclasses import replace

        from shapedisplay.render.settings import device_for_table
        gain = parse_quantity(args.burst_gain, "1/N", "--burst-gain", bare_ok=True)
        base = device if device is not None else device_for_table(table)
        device = base.with_(burst=replace(base.burst, gain=gain))
    rate = parse_quantity(args.tick_rate, "Hz", "tick_rate") if args.tick_rate else None
    arate = parse_quantity(args.audio_rate, "Hz", "--audio-rate") if args.audio_rate else None
    msp = parse_quantity(args.max_stick_period, "s", "--max-stick-period") if args.max_stick_period else None
    r = Renderer(table, device=device, model=args.model, tick_rate=rate, audio_rate=arate,
                 burst_policy=args.burst_policy, max_stick_period=msp)
    if args.stroke is not None:
        cursor = parse_stroke(args.stroke, r.tick_rate)
    elif args.cursor_csv is not None:
        cursor = load_trace_csv(args.cursor_csv)
    else:
        try:
            sx, sy = (float(v) * 1e-3 for v in args.start.split(","))
        except ValueError:
            raise InputError(f"`--start` must be 'x,y' in mm (got {args.start!r})") from None
        cursor = load_force_csv(args.force_csv, r.device.cursor_gain, r.tick_rate, (sx, sy))
    source = (f"stroke {args.stroke}" if args.stroke is not None else
              f"cursor {args.cursor_csv}" if args.cursor_csv is not None else f"force {args.force_csv}")
    res = play_to_files(r, cursor, args.output, args.sample_format, trace=args.trace_out, plot=args.plot,
                        table_checksum=table.checksum, ahap=args.ahap, drive_csv=args.drive_csv,
                        ahap_envelope=args.ahap_envelope == "on", description=f"{args.table}: {source}")
    s = res.summary()
    reactions = [{"t_s": float(t), "kind": str(k), "widget": str(w), "value": float(v)}
                 for k, w, t, v in zip(res.event_kind, res.event_widget, res.event_t, res.event_value)]
    if s["events_dropped"]:
        print(f"shapedisplay play: warning: {s['events_dropped']} bursts sounded while more than half of the "
              "engine's event ring was still sounding; their audio is missing (the trace keeps the events)",
              file=sys.stderr)
    if args.json:
        print(json.dumps({**s, "reaction_events": reactions}, indent=2))
    else:
        print(f"{s['model']} at {s['tick_rate_hz']:g} Hz: {s['ticks']} ticks over {s['duration_s']:.4g} s, "
              f"{s['events']} stick-slip events, max friction {s['max_friction_n']:.4g} N, "
              f"slip {100 * s['slip_fraction']:.1f} % of the time")
        print(f"audio: {s['audio_samples']} samples at {s['audio_rate_hz']:g} Hz ({args.sample_format}) -> {args.output}; "
              f"peak {s['peak']:.3g}, clipped {s['clipped']} samples"
              + (" (lower the burst gain)" if s["clipped"] else ""))
        if reactions:
            print(f"reactions: {len(reactions)} events (docs/reactive.md)")
            for e in reactions[:REACTIONS_SHOWN]:
                value = {"toggle": f" -> state {e['value']:g}", "value": f" = {e['value']:.3f}",
                         "drop": f" at {e['value']:.3f}" if e["value"] else "",
                         "click": f" (detent {e['value']:g})" if e["value"] else ""}.get(e["kind"], "")
                print(f"  {e['t_s']:9.4f} s  {e['kind']:<7} {e['widget']}{value}")
            if len(reactions) > REACTIONS_SHOWN:
                print(f"  ... and {len(reactions) - REACTIONS_SHOWN} more" + (" (all in the trace)" if args.trace_out else ""))
        if args.trace_out:
            print(f"trace -> {args.trace_out}")
        if args.plot:
            print(f"plot -> {args.plot}")
        if args.ahap:
            print(f"AHAP -> {args.ahap} ({s['events']} transients)")
        if args.drive_csv:
            print(f"drive CSV -> {args.drive_csv}")
    return 0
