"""``shapedisplay device``: talk to a tactile device over a serial port, or emulate one."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("device", help="query, upload to and play on a device over a serial port; emulate one",
                       description="Device link (protocol in docs/protocol.md). PORT is a device path "
                                   "(/dev/ttyACM0, COM3), a pty path printed by `device emulate`, or a "
                                   "pyserial URL (socket://host:port, rfc2217://...).")
    dsub = p.add_subparsers(dest="device_command", metavar="ACTION")

    def common(q):
        q.add_argument("--baud", type=int, default=921600, help="line rate, bit/s (default 921600)")
        q.add_argument("--timeout", type=float, default=0.5, help="seconds per reply before a retry (default 0.5)")
        q.add_argument("--retries", type=int, default=4, help="resends before giving up (default 4)")

    q = dsub.add_parser("info", help="handshake and print the device's capabilities and status")
    q.add_argument("port", help="serial port or URL")
    q.add_argument("--json", action="store_true", help="print JSON")
    common(q)
    q.set_defaults(func=run_info)

    q = dsub.add_parser("upload", help="upload a table, verify it on the device and commit it")
    q.add_argument("table", help="table file (.npz) or binary table image (export --format bin)")
    q.add_argument("port", help="serial port or URL")
    common(q)
    q.set_defaults(func=run_upload)

    q = dsub.add_parser("play", help="play a stroke on the device (uploads the table if it is not active)")
    q.add_argument("table", help="table file (.npz) or binary table image (export --format bin)")
    q.add_argument("port", help="serial port or URL")
    q.add_argument("--stroke", required=True,
                   help='cursor stroke in mm on the table grid, e.g. "0,0 -> 60,0 @ 50 mm/s" or '
                        '"0,2 <-> 60,2 @ 20 mm/s x3"')
    q.add_argument("--mode", default="cursor", choices=("cursor", "actuator"),
                   help="cursor: device renders (default); actuator: host renders and streams samples")
    q.add_argument("--model", default="jump", help="renderer model for --mode actuator (default jump)")
    q.add_argument("--output", "-o", help="save the actuator samples the device played (.npz)")
    common(q)
    q.set_defaults(func=run_play)

    q = dsub.add_parser("emulate", help="run a device emulator on a pseudo-terminal and print its port")
    q.add_argument("--baud", type=int, default=0,
                   help="pace the pty to this line rate (bit/s, 8N1); 0 = memory speed (default)")
    q.add_argument("--memory", default="256 KiB", help="table memory, e.g. '64 KiB' (default 256 KiB)")
    q.add_argument("--model", default="jump", help="renderer model (default jump)")
    q.add_argument("--tick-rate", "--rate", dest="tick_rate", default="10 kHz",
                   help="renderer tick rate (default 10 kHz; --rate is the same option)")
    q.add_argument("--stream-rate", default="1 kHz", help="cursor sample rate (default 1 kHz)")
    q.add_argument("--queue", type=int, default=64, help="cursor queue capacity, samples (default 64)")
    q.add_argument("--no-renderer", action="store_true", help="emulate a device that only plays actuator streams")
    q.add_argument("--stop-after", type=float, default=None, help="stop after this many seconds (default: Ctrl-C)")
    from shapedisplay.cli.main import old_spelling
    old_spelling(q, "--timeout", "--stop-after", dest="stop_after",
                 why=" (--timeout is the wait for each reply in the other device commands)")
    q.add_argument("--port-file", help="also write the port path to this file")
    q.add_argument("--link", help="also create a symbolic link of this name to the pty (a stable port name)")
    q.set_defaults(func=run_emulate)

    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _session(args):
    """The device on ``args.port`` with the link options; nothing is sent until it is used."""
    from shapedisplay.link.session import DeviceSession
    if args.timeout <= 0 or args.retries < 0:
        from shapedisplay.errors import InputError
        raise InputError(f"`--timeout` must be > 0 and `--retries` >= 0 (got {args.timeout}, {args.retries})")
    return DeviceSession(args.port, baudrate=args.baud, timeout=args.timeout, retries=args.retries)


def run_info(args) -> int:
    import json
    with _session(args) as dev:
        caps, st = dev.caps, dev.status()
    if args.json:
        print(json.dumps({"port": args.port, "caps": caps.to_json(), "status": st.to_json()}, indent=2))
        return 0
    d = caps.to_json()
    print(f"{caps.name} firmware {caps.firmware} on {args.port}, protocol {caps.min_version}..{caps.version}")
    print(f"  renderer: {'yes, models ' + ', '.join(caps.models) if caps.has_renderer else 'no (actuator stream only)'}")
    print(f"  table memory {caps.max_table_bytes} bytes, chunks of {caps.chunk_size} bytes, window {caps.upload_window}")
    print(f"  cursor {caps.stream_rate_hz} Hz into a queue of {caps.queue_capacity}; ticks {caps.tick_rate_hz} Hz "
          f"({caps.samples_per_cursor} actuator samples per cursor sample); force input "
          f"{'yes' if d['force_input'] else 'no'}")
    s = st.to_json()
    print(f"  state {s['state']}, active table crc32 {s['active_crc']} ({st.active_size} bytes), boots {st.boots}")
    print(f"  received {st.rx_frames} frames, {st.rx_bad_frames} bad, {st.rx_duplicates} duplicate, "
          f"{st.rx_version_errors} of a newer version; underruns {st.underruns}, overruns {st.overruns}, "
          f"clipped {st.clipped}")
    return 0


def _print_upload(dev, rep) -> None:
    print(f"uploaded {rep.size} bytes in {rep.chunks} chunks, {rep.seconds:.3f} s "
          f"({rep.throughput_bytes_per_s / 1e3:.1f} kB/s), crc32 {rep.crc32:08x}; committed", flush=True)
    if rep.retransmits or rep.restarts or dev.link.resends:
        print(f"  link repaired: {rep.retransmits} chunk retransmits, {dev.link.resends} request resends, "
              f"{rep.restarts} restarts after a device reset")


def run_upload(args) -> int:
    with _session(args) as dev:
        _print_upload(dev, dev.upload(args.table))       # the table is verified before anything is sent
    return 0


def run_play(args) -> int:
    with _session(args) as dev:
        rep = dev.play(args.table, args.stroke, mode=args.mode, model=args.model, record=args.output or None,
                       on_upload=lambda up: _print_upload(dev, up))
    print(f"played {rep.rendered} of {rep.sent} cursor samples in {rep.seconds:.3f} s on {args.port}")
    for line in rep.problems():
        print(f"warning: {line}")
    if rep.record is not None:
        print(f"wrote {args.output}")
    return 1 if rep.overruns else 0


def run_emulate(args) -> int:
    import signal
    import sys

    from shapedisplay.atomic import write_text
    from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig
    from shapedisplay.errors import InputError
    if args.stop_after is not None and args.stop_after <= 0:
        raise InputError(f"`--stop-after` must be > 0 seconds (got {args.stop_after})")
    cfg = EmulatorConfig.from_text(memory=args.memory, tick_rate=args.tick_rate, stream_rate=args.stream_rate,
                                   queue=args.queue, model=args.model, renderer=not args.no_renderer,
                                   baud=args.baud)
    emu = DeviceEmulator(cfg)
    emu.prepare()                      # compile the renderer before the port is announced
    port = emu.open_pty(link=args.link)
    if args.port_file:
        write_text(args.port_file, port + "\n")
    print(f"device emulator on {port}  (connect with: shapedisplay device info {port}; Ctrl-C stops)", flush=True)
    signal.signal(signal.SIGTERM, lambda *a: (_ for _ in ()).throw(KeyboardInterrupt()))
    try:
        emu.serve(timeout=args.stop_after)
    except KeyboardInterrupt:
        pass
    finally:
        emu.close()
        emu.remove_link()
    for line in emu.log[-20:]:
        print(f"  {line}", file=sys.stderr)
    return 0
