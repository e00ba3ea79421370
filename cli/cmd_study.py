"""``shapedisplay study``: run a published stimulus set through the pad models."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("study", help="run a published stimulus set (imaizumi: lateral vibration, Stribeck pad)",
                       description="imaizumi: stimuli #0 still, #1 3 Hz 1.25 mm, #2 6 Hz 0.625 mm, "
                                   "#3 6 Hz 1.25 mm, #4 9 Hz 1.25 mm at finger speeds 0.1 and 0.04 m/s; "
                                   "prints mean and max friction per stimulus.")
    p.add_argument("name", help="imaizumi")
    p.add_argument("--duration", default="1 s", help="analysed time per stimulus (default 1 s)")
    p.add_argument("--variant", default="stribeck", help="stribeck | premax (pre-maximum static region)")
    p.add_argument("--rate", default="10 kHz", help="tick rate (default 10 kHz)")
    p.add_argument("--json", action="store_true", help="print JSON rows")
    p.set_defaults(func=run)


def run(args) -> int:
    import json

    from shapedisplay.errors import InputError, unknown_key
    from shapedisplay.runtime.studies import imaizumi_study
    from shapedisplay.units import parse_quantity

    if args.name != "imaizumi":
        raise unknown_key("study", args.name, ["imaizumi"])
    dur = parse_quantity(args.duration, "s", "--duration")
    if not 0 < dur <= 60:
        raise InputError(f"`--duration` must be within 0..60 s (got {args.duration!r})")
    rows = imaizumi_study(duration=dur, tick_rate=parse_quantity(args.rate, "Hz", "--rate"), variant=args.variant)
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"Imaizumi lateral-vibration study ({args.variant}): m=1e-4 kg, k=1e3 N/m, c=1 N*s/m, "
          f"mu_s=2.1, mu_k=1.4, W=1 N")
    print(f"{'stimulus':<18} {'finger':>9} {'mean F':>9} {'max F':>9} {'events':>7} {'stick':>6}")
    for r in rows:
        print(f"{r['stimulus']:<18} {r['finger_speed_m_s'] * 1e3:>5.0f}mm/s {r['mean_friction_n']:>8.4f}N "
              f"{r['max_friction_n']:>8.4f}N {r['events']:>7d} {100 * r['stick_fraction']:>5.1f}%")
    return 0
