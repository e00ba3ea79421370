"""A device that behaves like the firmware, on a pseudo-terminal.

:class:`DeviceEmulator` speaks protocol v1 (:mod:`.protocol`) on the master
side of a pty pair; a host opens the slave path like any serial port. It
keeps the firmware's rules:

* a table is uploaded into a staging buffer of ``max_table_bytes`` (device
  RAM), verified (whole-image CRC-32, then parsed and checksummed like
  :meth:`FrictionTable.load`) and becomes active only on COMMIT; the active
  table survives a reset (flash), the staging buffer does not;
* cursor samples go into a fixed queue of ``queue_capacity`` samples and are
  consumed at ``stream_rate_hz`` by the render thread, which runs the
  device's render engine (:mod:`.engine`, the same renderer as the host); a period with no sample
  counts an underrun (the renderer waits for the sample), a sample arriving at a
  full queue is dropped and counts an overrun; both are reported in EVENT
  frames and in STATUS;
* every bad frame is counted and answered with a NAK (``seq`` 0xFFFF), a
  repeated request (same seq and type) is answered from the reply cache
  without being executed twice, a frame of a newer protocol version is
  refused with a NAK naming the version the device speaks.

Line rate: with ``baud`` > 0 the emulator delivers received bytes no faster
than ``baud / 10`` bytes per second (8N1: ten bit times per byte) and writes
its own bytes at the same pace, so a pty behaves like a UART link of that
speed. ``baud=0`` runs at memory speed.

Fault injection for tests (:meth:`inject`): corrupt, drop, truncate or
duplicate the next frames in either direction, reset mid-upload, vanish.
"""
from __future__ import annotations

import collections
import os
import random
import select
import threading
import time
import tty
from dataclasses import dataclass

import numpy as np

from shapedisplay.table.devices import TICK_RATE_RANGE
from shapedisplay.errors import FileFormatError
from shapedisplay.link import protocol as P
from shapedisplay.link.engine import RenderEngine, warm_engine
from shapedisplay.link.framing import Frame, FrameDecoder, crc32, encode_frame

#: Actuator full scale; a drive sample with ``|value| > 1`` is clipped and counted.
DAC_RANGE = 1.0


@dataclass(frozen=True)
class EmulatorConfig:
    """What the emulated firmware offers. Rates in Hz, sizes in bytes."""

    name: str = "shapedisplay-emulator"
    firmware: str = "1.0"
    protocol_version: int = P.PROTOCOL_VERSION
    max_table_bytes: int = 256 * 1024   # staging RAM for one table image
    chunk_size: int = 1024               # largest UPLOAD_CHUNK payload
    upload_window: int = 4               # chunks in flight before an ack is needed
    queue_capacity: int = 64             # cursor samples buffered
    stream_rate_hz: int = 1000           # cursor samples consumed per second
    tick_rate_hz: int = 10_000           # renderer ticks per second
    model: str = "jump"                  # renderer model used for CURSOR mode
    renderer: bool = True                # False: actuator-stream-only device
    baud: int = 0                        # 0 = memory speed; else pace bytes to baud/10 per s
    flow_every: int = 8                  # send FLOW after this many consumed samples
    event_interval_s: float = 0.05       # at most one EVENT of a kind per interval

    def __post_init__(self):
        from shapedisplay.errors import InputError
        from shapedisplay.link.framing import MAX_FRAME
        ints = {"max_table_bytes": (1, 2**31), "chunk_size": (1, MAX_FRAME - 64), "upload_window": (1, 255),
                "queue_capacity": (1, 65535), "stream_rate_hz": (1, 65535), "tick_rate_hz": tuple(int(r) for r in TICK_RATE_RANGE),
                "baud": (0, 100_000_000), "flow_every": (1, 65535), "protocol_version": (1, 255)}
        for name, (lo, hi) in ints.items():
            v = getattr(self, name)
            if not (isinstance(v, int) and lo <= v <= hi):
                raise InputError(f"emulator `{name}` must be an integer in {lo}..{hi} (got {v!r})")
        if self.tick_rate_hz % self.stream_rate_hz:
            raise InputError(f"emulator `tick_rate_hz` must be a multiple of `stream_rate_hz` "
                             f"(got {self.tick_rate_hz}, {self.stream_rate_hz})")

    @classmethod
    def from_text(cls, memory="256 KiB", tick_rate="10 kHz", stream_rate="1 kHz", queue: int = 64,
                  model: str = "jump", renderer: bool = True, baud: int = 0) -> "EmulatorConfig":
        """A configuration from the texts a user types (units written out); every rule is checked here.

        ``memory`` a byte size (1 KiB .. 2 GiB), ``tick_rate`` and
        ``stream_rate`` frequencies in whole hertz, ``model`` a renderer model
        (ignored without a renderer); the record's own rules (ranges, the tick
        rate a multiple of the stream rate) are checked on construction.
        """
        from shapedisplay.errors import InputError, unknown_key
        from shapedisplay.units import parse_byte_size, parse_quantity
        mem = parse_byte_size(memory, "memory", lo=1024, hi=2**31)
        rates = {}
        for name, text in (("tick_rate_hz", tick_rate), ("stream_rate_hz", stream_rate)):
            v = parse_quantity(text, "Hz", name)
            if v != int(v):
                raise InputError(f"emulator `{name}` must be a whole number of hertz (got {text!r})")
            rates[name] = int(v)
        if renderer:
            from shapedisplay.render.models import MODELS
            if model not in MODELS:
                raise unknown_key("model", model, MODELS)
        # ranges, the multiple rule, queue and baud: __post_init__, the one place for the record's rules
        return cls(max_table_bytes=mem, queue_capacity=queue, model=model, renderer=renderer, baud=baud, **rates)

    @property
    def samples_per_cursor(self) -> int:
        return max(1, self.tick_rate_hz // self.stream_rate_hz)

    def caps(self) -> P.Caps:
        flags = P.CAP_ACTUATOR_STREAM | P.CAP_MONITOR
        if self.renderer:
            flags |= P.CAP_RENDERER | P.CAP_FORCE_INPUT
        models = (self.model,) if self.renderer else ()
        return P.Caps(self.protocol_version, min(self.protocol_version, P.PROTOCOL_MIN_VERSION), flags,
                      self.max_table_bytes, self.chunk_size, self.upload_window, self.queue_capacity,
                      self.stream_rate_hz, self.tick_rate_hz, self.samples_per_cursor,
                      name=self.name, firmware=self.firmware, models=models)


#: Most bytes of channel data an uploaded image may unpack to, per byte of table memory
#: (a compressed table of flat regions inflates; a zip bomb stops here).
TABLE_EXPANSION = 64


def check_link_path(link: str) -> None:
    """Refuse a ``--link`` name that would replace a file the emulator did not create.

    Only a missing name or a symbolic link to a device node (a stale link of an
    earlier emulator, ``/dev/pts/N``) may be (re)placed; the folder must exist.
    """
    parent = os.path.dirname(os.path.abspath(link))
    if not os.path.isdir(parent):
        raise FileFormatError(f"`--link` '{link}': folder '{parent}' does not exist")
    if os.path.islink(link):
        if not os.readlink(link).startswith("/dev/"):
            raise FileFormatError(f"`--link` '{link}' is a link to '{os.readlink(link)}', not to a device; "
                                  f"refusing to replace it")
    elif os.path.lexists(link):
        raise FileFormatError(f"`--link` '{link}' exists and is not a link to a device; refusing to replace it "
                              f"(give a new name)")


def parse_table_image(image: bytes, max_bytes: int | None = None):
    """Parse and verify an uploaded table: the bytes of a table file (.npz) or a binary table
    image (``export --format bin``, recognised by its magic, as firmware loads it).

    Goes through the same bounded reader as a table file; ``max_bytes`` caps
    the channel data it may unpack to. Returns a
    :class:`~shapedisplay.table.model.FrictionTable`; raises
    :class:`~shapedisplay.errors.TableError` naming what is wrong.
    """
    from shapedisplay.render.image import is_image, read_image
    from shapedisplay.table.model import FrictionTable
    if is_image(image):
        return read_image(image, "uploaded table image")
    return FrictionTable.from_bytes(image, "uploaded table", max_bytes=max_bytes)


class _Fault:
    def __init__(self, kind: str, direction: str, count: int, after: int):
        self.kind, self.direction, self.count, self.after = kind, direction, count, after


class DeviceEmulator:
    """Firmware stand-in on a pty. Use :meth:`open_pty` then :meth:`start`, or :meth:`serve`."""

    FAULTS = ("corrupt", "drop", "truncate", "duplicate")

    def __init__(self, config: EmulatorConfig | None = None, engine_factory=None, seed: int = 0):
        self.config = config or EmulatorConfig()
        self.engine_factory = engine_factory or RenderEngine
        self._rng = random.Random(seed)
        self._master = self._slave = None
        self.port = None
        self._decoder = FrameDecoder()
        self._wlock = threading.RLock()
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._io_thread = None
        self._tx_thread = None
        self._txq = collections.deque()
        self._txcond = threading.Condition()
        self._render_thread = None
        self._faults: list[_Fault] = []
        self._rx_t = self._tx_t = 0.0
        self.boots = 0
        self.log: list[str] = []                # human-readable event log
        self.activations: list[tuple] = []      # (crc32, size) of every committed table, in order
        self.active_table = None
        self.active_crc = 0
        self.active_size = 0
        self.outputs: list = []                 # (index, samples) rendered, when record_outputs
        self.record_outputs = False
        self.reset_after_chunks = None          # test hook: power-cycle after N accepted chunks
        self.reset_after_verify = False         # test hook: power-cycle once after VERIFIED ("boot lost": BOOT damaged)
        self.vanish_after_chunks = None         # test hook: the port disappears after N accepted chunks
        self.counters = collections.Counter()
        self._prepared = False
        self._power_on()

    # ------------------------------------------------------------ lifecycle
    def _power_on(self) -> None:
        with self._lock:
            self.boots += 1
            self._upload = None           # dict(id, size, crc, buf, expected, verified table)
            self.state = P.State.IDLE
            self.mode = P.Mode.CURSOR
            self._cache = None            # (seq, type, [wire frames])
            self._queue = collections.deque()
            self._qcond = threading.Condition(self._lock)
            self._streaming = False
            self._last_index = -1
            self._session_consumed = 0
            self._engine = None
            self._monitor = False
            self._last_event = {}
            self._chunks_accepted = 0
            self._decoder.reset()

    def prepare(self) -> None:
        """Load and compile the renderer (firmware has it built in before it boots). Idempotent."""
        if (not self._prepared and self.config.renderer and isinstance(self.engine_factory, type)
                and issubclass(self.engine_factory, RenderEngine)):
            warm_engine(self.config.model, self.config.tick_rate_hz, self.config.stream_rate_hz,
                        self.engine_factory)
        self._prepared = True

    def open_pty(self, link: str | None = None) -> str:
        """Create the pty pair; return the path a host should open.

        With ``link``, a symbolic link of that name points at the pty (a stable
        device name, as udev's ``/dev/serial/by-id/...``) and is returned; it is
        moved to the new pty when the device re-enumerates (:meth:`replug`).
        """
        master, slave = os.openpty()
        tty.setraw(slave)          # no echo, no line editing, before any host opens it
        self._master, self._slave = master, slave
        self.tty = os.ttyname(slave)
        if link is not None:
            if link != getattr(self, "_link", None):
                check_link_path(link)
            tmp = f"{link}.{os.getpid()}.tmp"
            try:
                os.symlink(self.tty, tmp)
                os.replace(tmp, link)
            except OSError as exc:
                for fd in (master, slave):
                    os.close(fd)
                self._master = self._slave = None
                raise FileFormatError(f"`--link` '{link}': cannot create the link ({exc.strerror or exc})") from None
            self._link = link
        self.port = link or getattr(self, "_link", None) or self.tty
        return self.port

    def start(self) -> str:
        """Open the pty (if needed) and run the device in background threads; return the port."""
        self.prepare()
        if self._master is None:
            self.open_pty()
        self._stop.clear()
        self._io_thread = threading.Thread(target=self._io_loop, name="emulator-io", daemon=True)
        self._io_thread.start()
        if self.config.baud > 0:
            self._tx_thread = threading.Thread(target=self._tx_loop, name="emulator-tx", daemon=True)
            self._tx_thread.start()
        self._send(P.Msg.BOOT, P.SEQ_UNSOLICITED, P.BOOT.pack(self.config.protocol_version, self.boots))
        return self.port

    def serve(self, timeout: float | None = None) -> None:
        """Run in the foreground until ``timeout`` seconds pass or KeyboardInterrupt."""
        self.start()
        try:
            if timeout is None:
                while self._io_thread.is_alive():
                    self._io_thread.join(0.5)
            else:
                self._io_thread.join(timeout)
        finally:
            self.close()
            self.remove_link()

    def remove_link(self) -> None:
        """Remove the stable link this device created, if it still points at one of its ptys."""
        link = getattr(self, "_link", None)
        if link and os.path.islink(link) and os.readlink(link).startswith("/dev/"):
            try:
                os.unlink(link)
            except OSError:
                pass
        self._link = None

    def close(self) -> None:
        """Stop the threads and close both pty ends (the port disappears)."""
        self._stop.set()
        self._stop_render()
        for th in (self._io_thread, self._tx_thread):
            if th is not None and th is not threading.current_thread():
                th.join(10.0)
        # Take the descriptors under the write lock and clear them before closing: two closers at once
        # (the device vanishing in its own thread while its owner closes it) close each pty end once.
        # A second close of a number the process has since reused would close someone else's file.
        with self._wlock:
            fds = (self._master, self._slave)
            self._master = self._slave = None
        for fd in fds:
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass

    def vanish(self) -> None:
        """Test hook: the port disappears (USB unplugged) while the host may be using it."""
        self.log.append("port vanished")
        self.close()

    def replug(self, gone_s: float = 0.2) -> str:
        """Test hook: a USB device resets and re-enumerates.

        The port disappears, the device reboots (RAM lost, committed table kept),
        and after ``gone_s`` seconds a new port appears (the stable link, if any,
        follows it). Returns the new port.
        """
        self.log.append("replug")
        self.close()
        self._power_on()
        time.sleep(gone_s)
        self._master = None
        self.open_pty(getattr(self, "_link", None))
        return self.start()

    def reset(self) -> None:
        """Power-cycle: RAM (staging buffer, queue, reply cache) is lost, the committed table kept."""
        self._stop_render()
        self._power_on()
        self.log.append(f"reset (boot {self.boots})")
        self._send(P.Msg.BOOT, P.SEQ_UNSOLICITED, P.BOOT.pack(self.config.protocol_version, self.boots))

    def inject(self, kind: str, direction: str = "rx", count: int = 1, after: int = 0) -> None:
        """Damage the next ``count`` frames (after skipping ``after``) going ``direction``.

        ``kind`` is one of corrupt (flip a byte), drop (lose one byte),
        truncate (lose the second half, delimiter included), duplicate (send
        or receive the frame twice). ``direction`` "rx" = host to device,
        "tx" = device to host.
        """
        if kind not in self.FAULTS or direction not in ("rx", "tx"):
            raise ValueError(f"fault must be one of {self.FAULTS} and direction rx|tx (got {kind!r}, {direction!r})")
        with self._lock:
            self._faults.append(_Fault(kind, direction, count, after))

    def _damage(self, wire: bytes, direction: str) -> bytes:
        with self._lock:
            for f in self._faults:
                if f.direction != direction or f.count <= 0:
                    continue
                if f.after > 0:
                    f.after -= 1
                    return wire
                f.count -= 1
                self.counters[f"injected_{direction}_{f.kind}"] += 1
                body = wire[:-1]
                if f.kind == "corrupt":
                    b = bytearray(wire)
                    pos = self._rng.randrange(len(body))
                    b[pos] ^= 1 << self._rng.randrange(8)
                    if b[pos] == 0:
                        b[pos] = 0x55 if wire[pos] != 0x55 else 0xAA
                    return bytes(b)
                if f.kind == "drop":
                    pos = self._rng.randrange(len(body))
                    return wire[:pos] + wire[pos + 1:]
                if f.kind == "truncate":
                    return wire[:max(1, len(body) // 2)]
                return wire + wire   # duplicate
        return wire

    # ------------------------------------------------------------ wire
    def _pace(self, n: int, which: str, since: float | None = None) -> None:
        """Sleep until ``n`` bytes have crossed the line (8N1) after ``since`` (default now).

        The line is busy back to back: a transfer starts when the previous one ended or when
        its bytes became available, whichever is later, so a late wake-up loses no capacity.
        """
        baud = self.config.baud
        if baud <= 0:
            return
        now = time.monotonic()
        attr = "_rx_t" if which == "rx" else "_tx_t"
        t = max(getattr(self, attr), now if since is None else since) + n * 10.0 / baud
        setattr(self, attr, t)
        if t > now:
            time.sleep(t - now)

    def _send(self, msg_type: int, seq: int, body: bytes = b"", req: Frame | None = None) -> None:
        wire = encode_frame(self.config.protocol_version, msg_type, seq, body)
        if req is not None:
            with self._lock:
                if self._cache is not None and self._cache[:2] == (req.seq, req.type):
                    self._cache[2].append(wire)
        self._write(self._damage(wire, "tx"))

    def _write(self, wire: bytes) -> None:
        """Queue ``wire`` for the transmit thread (full duplex: sending never stalls receiving)."""
        if self.config.baud <= 0:
            self._write_now(wire)
            return
        with self._txcond:
            self._txq.append((time.monotonic(), wire))
            self._txcond.notify()

    def _write_now(self, wire: bytes) -> None:
        with self._wlock:
            fd = self._master
            if fd is None:
                return
            view = memoryview(wire)
            while view:
                try:
                    n = os.write(fd, view)
                except BlockingIOError:
                    time.sleep(0.001)
                    continue
                except OSError:
                    return
                view = view[n:]

    def _tx_loop(self) -> None:
        while True:
            with self._txcond:
                while not self._txq and not self._stop.is_set():
                    self._txcond.wait(0.05)
                if self._stop.is_set():
                    return
                t_enq, wire = self._txq.popleft()
            self._pace(len(wire), "tx", t_enq)   # the last byte leaves the UART at the paced time
            self._write_now(wire)

    def _io_loop(self) -> None:
        fd = self._master
        pending = b""
        while not self._stop.is_set():
            try:
                r, _, _ = select.select([fd], [], [], 0.05)
                if not r:
                    continue
                data = os.read(fd, 1024)
            except (OSError, ValueError):
                break
            if not data:
                break
            self._pace(len(data), "rx")
            # Apply rx faults frame by frame: split at delimiters.
            pending += data
            while b"\x00" in pending:
                wire, pending = pending.split(b"\x00", 1)
                self._receive(self._damage(wire + b"\x00", "rx"))
            if len(pending) > 2 * self._decoder.max_encoded:
                self._receive(pending)
                pending = b""

    def _receive(self, data: bytes) -> None:
        for item in self._decoder.feed(data):
            if isinstance(item, Frame):
                try:
                    self._dispatch(item)
                except Exception as exc:  # firmware must not die on one bad request
                    self.log.append(f"handler error {exc!r}")
                    self._nak(item, P.Err.BAD_BODY, 0, f"{type(exc).__name__}: {exc}")
            else:
                self.counters["rx_bad_frames"] += 1
                self._send(P.Msg.NAK, P.SEQ_UNSOLICITED,
                           P.pack_nak(0, P.Err.BAD_FRAME, self.counters["rx_bad_frames"], f"bad frame ({item})"))

    # ------------------------------------------------------------ replies
    def _reply(self, req: Frame, msg_type: int, body: bytes = b"") -> None:
        self._send(msg_type, req.seq, body, req=req)

    def _nak(self, req: Frame, code: P.Err, detail: int = 0, text: str = "") -> None:
        self.log.append(f"NAK {P.msg_name(req.type)} {code.name}: {text}")
        self._reply(req, P.Msg.NAK, P.pack_nak(req.type, code, detail, text))

    def _event(self, code: P.Err, count: int, text: str) -> None:
        now = time.monotonic()
        if now - self._last_event.get(code, -1e9) < self.config.event_interval_s:
            return
        self._last_event[code] = now
        self._send(P.Msg.EVENT, P.SEQ_UNSOLICITED, P.pack_event(code, count, text))

    def _dispatch(self, f: Frame) -> None:
        self.counters["rx_frames"] += 1
        if f.version > self.config.protocol_version:
            self.counters["rx_version_errors"] += 1
            self._nak(f, P.Err.VERSION, self.config.protocol_version,
                      f"frame of protocol version {f.version}; this device speaks version "
                      f"{self.config.protocol_version}")
            return
        if f.type in (P.Msg.CURSOR, P.Msg.ACTUATOR):
            self._on_stream(f)
            return
        with self._lock:
            if self._cache is not None and self._cache[0] == f.seq and self._cache[1] == f.type:
                self.counters["rx_duplicates"] += 1
                wires = list(self._cache[2])
            else:
                wires = None
                self._cache = (f.seq, f.type, [])
        if wires is not None:
            for w in wires:
                self._write(self._damage(w, "tx"))
            return
        handler = self._HANDLERS.get(f.type)
        if handler is None:
            self._nak(f, P.Err.UNKNOWN_TYPE, f.type, f"unknown message type {P.msg_name(f.type)}")
            return
        handler(self, f)

    # ------------------------------------------------------------ handlers
    def _on_hello(self, f: Frame) -> None:
        if len(f.body) < P.HELLO.size:
            return self._nak(f, P.Err.BAD_BODY, 0, "HELLO body too short")
        host_max, host_min = P.HELLO.unpack_from(f.body)
        v = self.config.protocol_version
        if host_max < v and host_max < P.PROTOCOL_MIN_VERSION:
            return self._nak(f, P.Err.VERSION, v, f"host speaks up to version {host_max}; device needs {v}")
        self._new_session()
        self._reply(f, P.Msg.HELLO_REPLY, P.HELLO_REPLY.pack(v, min(v, P.PROTOCOL_MIN_VERSION), self.boots))

    def _new_session(self) -> None:
        """A HELLO opens a session: a stream or an unfinished upload left by a host that went away
        (killed, unplugged) ends here, so it cannot block the new host; the active table stays."""
        if self._streaming:
            self._stop_render()
            self.log.append("stream of the previous session stopped")
        with self._lock:
            self._queue.clear()
            self._engine = None
            if self._upload is not None:
                self.log.append(f"upload {self._upload['id']} of the previous session discarded")
            self._upload = None
            self.state = P.State.IDLE

    def _on_caps(self, f: Frame) -> None:
        self._reply(f, P.Msg.CAPS, self.config.caps().pack())

    def status(self) -> P.Status:
        c = self.counters
        up = self._upload
        return P.Status(int(self.state), int(self.mode), self.active_crc, self.active_size,
                        up["expected"] if up else 0, self.boots, c["rx_frames"], c["rx_bad_frames"],
                        c["rx_duplicates"], c["rx_version_errors"], c["underruns"], c["overruns"],
                        c["clipped"], c["samples_rendered"], c["ticks_rendered"],
                        len(self._queue), self.config.queue_capacity)

    def _on_status(self, f: Frame) -> None:
        self._reply(f, P.Msg.STATUS, self.status().pack())

    def _on_begin(self, f: Frame) -> None:
        if len(f.body) != P.UPLOAD_BEGIN.size:
            return self._nak(f, P.Err.BAD_BODY, 0, "UPLOAD_BEGIN body must be 10 bytes")
        uid, size, crc = P.UPLOAD_BEGIN.unpack(f.body)
        if self._streaming:
            return self._nak(f, P.Err.BUSY, 0, "cannot upload while streaming; send STOP first")
        if size == 0:
            return self._nak(f, P.Err.BAD_BODY, 0, "table size must be > 0 bytes")
        if size > self.config.max_table_bytes:
            return self._nak(f, P.Err.TOO_LARGE, self.config.max_table_bytes,
                             f"table of {size} bytes exceeds device memory of {self.config.max_table_bytes} bytes")
        self._upload = {"id": uid, "size": size, "crc": crc, "buf": bytearray(size), "expected": 0, "table": None}
        self.state = P.State.UPLOADING
        self._chunks_accepted = 0
        self.log.append(f"upload {uid} begins: {size} bytes")
        self._reply(f, P.Msg.ACK, P.ACK.pack(f.type, uid))

    def _upload_for(self, f: Frame, uid: int):
        up = self._upload
        if up is None or up["id"] != uid:
            self._nak(f, P.Err.NO_UPLOAD, 0, f"no upload {uid} in progress (device reset or never begun)")
            return None
        return up

    def _on_chunk(self, f: Frame) -> None:
        if len(f.body) < P.UPLOAD_CHUNK.size:
            return self._nak(f, P.Err.BAD_BODY, 0, "UPLOAD_CHUNK body too short")
        uid, off = P.UPLOAD_CHUNK.unpack_from(f.body)
        data = f.body[P.UPLOAD_CHUNK.size:]
        up = self._upload_for(f, uid)
        if up is None:
            return
        if len(data) == 0 or len(data) > self.config.chunk_size or off + len(data) > up["size"]:
            return self._nak(f, P.Err.BAD_BODY, up["expected"],
                             f"chunk of {len(data)} bytes at offset {off} does not fit the {up['size']}-byte table "
                             f"(chunk size <= {self.config.chunk_size})")
        if up["table"] is not None:
            return self._nak(f, P.Err.BUSY, up["expected"], "upload already verified; COMMIT or ABORT")
        exp = up["expected"]
        if off + len(data) <= exp:
            self.counters["rx_duplicates"] += 1          # repeated chunk: ack again, write nothing
        elif off != exp:
            return self._nak(f, P.Err.OUT_OF_ORDER, exp, f"chunk at offset {off}; expected {exp}")
        else:
            up["buf"][off:off + len(data)] = data
            up["expected"] = exp = off + len(data)
            self._chunks_accepted += 1
        self._reply(f, P.Msg.CHUNK_ACK, P.CHUNK_ACK.pack(uid, exp))
        if self.reset_after_chunks is not None and self._chunks_accepted >= self.reset_after_chunks:
            self.reset_after_chunks = None
            self.reset()
        if self.vanish_after_chunks is not None and self._chunks_accepted >= self.vanish_after_chunks:
            self.vanish_after_chunks = None
            threading.Thread(target=self.vanish, daemon=True).start()

    def _on_end(self, f: Frame) -> None:
        if len(f.body) != P.UPLOAD_END.size:
            return self._nak(f, P.Err.BAD_BODY, 0, "UPLOAD_END body must be 10 bytes")
        uid, crc, size = P.UPLOAD_END.unpack(f.body)
        up = self._upload_for(f, uid)
        if up is None:
            return
        if up["expected"] != up["size"] or size != up["size"]:
            return self._nak(f, P.Err.BAD_BODY, up["expected"],
                             f"received {up['expected']} of {up['size']} bytes; END says {size}")
        actual = crc32(bytes(up["buf"]))
        if actual != crc or actual != up["crc"]:
            self._upload = None
            self.state = P.State.IDLE
            return self._nak(f, P.Err.CHECKSUM, actual,
                             f"whole-table CRC-32 is {actual:08x}, host says {crc:08x}; upload discarded")
        from shapedisplay.errors import ShapeDisplayError
        try:
            table = parse_table_image(bytes(up["buf"]), max_bytes=TABLE_EXPANSION * self.config.max_table_bytes)
            if self.config.renderer:
                self.engine_factory(table, self.config.model, self.config.tick_rate_hz,
                                    self.config.stream_rate_hz, P.Input.POSITION)
        except Exception as exc:  # noqa: BLE001 - firmware answers every rejected image the same way
            self._upload = None          # the staged upload is discarded whatever the reason
            self.state = P.State.IDLE
            reason = str(exc) if isinstance(exc, ShapeDisplayError) else f"{type(exc).__name__}: {exc}"
            return self._nak(f, P.Err.TABLE_INVALID, 0, "table rejected: " + " ".join(reason.split())[:400])
        up["table"] = table
        self.state = P.State.VERIFIED
        self._reply(f, P.Msg.VERIFIED, P.VERIFIED.pack(uid, actual, up["size"]))
        if self.reset_after_verify:
            if self.reset_after_verify == "boot lost":
                self.inject("corrupt", "tx")     # the host never sees BOOT; its COMMIT finds nothing staged
            self.reset_after_verify = False
            self.reset()

    def _on_commit(self, f: Frame) -> None:
        if len(f.body) != P.UPLOAD_ID.size:
            return self._nak(f, P.Err.BAD_BODY, 0, "COMMIT body must be 2 bytes")
        (uid,) = P.UPLOAD_ID.unpack(f.body)
        if self._streaming:
            return self._nak(f, P.Err.BUSY, 0, "cannot commit while streaming; send STOP first")
        up = self._upload_for(f, uid)          # none staged (a reset, never begun): NO_UPLOAD
        if up is None:
            return
        if up["table"] is None:
            return self._nak(f, P.Err.NOT_VERIFIED, 0, f"upload {uid} is not verified; nothing committed")
        self.active_table = up["table"]
        self.active_crc, self.active_size = up["crc"], up["size"]
        self.activations.append((self.active_crc, self.active_size))
        self._upload = None
        self.state = P.State.IDLE
        self.log.append(f"table {self.active_crc:08x} ({self.active_size} bytes) committed")
        self._reply(f, P.Msg.ACK, P.ACK.pack(f.type, self.active_crc))

    def _on_abort(self, f: Frame) -> None:
        self._upload = None
        if self.state in (P.State.UPLOADING, P.State.VERIFIED):
            self.state = P.State.IDLE
        self._reply(f, P.Msg.ACK, P.ACK.pack(f.type, 0))

    def _on_start(self, f: Frame) -> None:
        if len(f.body) != P.START.size:
            return self._nak(f, P.Err.BAD_BODY, 0, "START body must be 3 bytes")
        mode, inp, flags = P.START.unpack(f.body)
        if self._streaming:
            return self._nak(f, P.Err.BUSY, 0, "already streaming")
        if self._upload is not None:
            return self._nak(f, P.Err.BUSY, 0, "an upload is in progress; finish or ABORT it")
        if mode not in (P.Mode.CURSOR, P.Mode.ACTUATOR) or inp not in (P.Input.POSITION, P.Input.FORCE):
            return self._nak(f, P.Err.UNSUPPORTED, mode, f"mode {mode} / input {inp} not offered")
        engine = None
        if mode == P.Mode.CURSOR:
            if not self.config.renderer:
                return self._nak(f, P.Err.UNSUPPORTED, mode, "this device has no renderer; use actuator mode")
            if self.active_table is None:
                return self._nak(f, P.Err.NO_TABLE, 0, "no committed table; upload one first")
            from shapedisplay.errors import ShapeDisplayError
            try:
                engine = self.engine_factory(self.active_table, self.config.model, self.config.tick_rate_hz,
                                             self.config.stream_rate_hz, inp)
            except ShapeDisplayError as exc:
                return self._nak(f, P.Err.UNSUPPORTED, mode, str(exc))
        with self._lock:
            self.mode = P.Mode(mode)
            self._engine = engine
            self._monitor = bool(flags & P.FLAG_MONITOR)
            self._queue.clear()
            self._last_index = -1
            self._session_consumed = 0
            self._streaming = True
            self.state = P.State.STREAMING
        self._render_thread = threading.Thread(target=self._render_loop, name="emulator-render", daemon=True)
        self._render_thread.start()
        self._reply(f, P.Msg.ACK, P.ACK.pack(f.type, mode))

    def _on_stop(self, f: Frame) -> None:
        with self._lock:
            if self._streaming:
                # Finish what is queued, then acknowledge from the render thread.
                self._queue.append(("stop", f))
                self._qcond.notify()
                return
        self._reply(f, P.Msg.ACK, P.ACK.pack(f.type, self.counters["samples_rendered"]))

    def _on_reset(self, f: Frame) -> None:
        self._reply(f, P.Msg.ACK, P.ACK.pack(f.type, self.boots))
        self.reset()

    _HANDLERS = {
        P.Msg.HELLO: _on_hello, P.Msg.GET_CAPS: _on_caps, P.Msg.GET_STATUS: _on_status,
        P.Msg.UPLOAD_BEGIN: _on_begin, P.Msg.UPLOAD_CHUNK: _on_chunk, P.Msg.UPLOAD_END: _on_end,
        P.Msg.COMMIT: _on_commit, P.Msg.ABORT: _on_abort, P.Msg.START: _on_start, P.Msg.STOP: _on_stop,
        P.Msg.RESET: _on_reset,
    }

    # ------------------------------------------------------------ streaming
    def _on_stream(self, f: Frame) -> None:
        want = P.Mode.CURSOR if f.type == P.Msg.CURSOR else P.Mode.ACTUATOR
        if not self._streaming or self.mode != want:
            self._event(P.Err.BUSY, 1, f"{P.msg_name(f.type)} ignored: not streaming in {want.name.lower()} mode")
            return
        try:
            if f.type == P.Msg.CURSOR:
                rec = P.unpack_cursor(f.body)
                items = [(int(r["index"]), int(r["t_us"]), float(r["x"]), float(r["y"])) for r in rec]
            else:
                (first,) = P.ACTUATOR.unpack_from(f.body)
                s = P.unpack_samples(f.body[P.ACTUATOR.size:])
                per = self.config.samples_per_cursor
                if s.size == 0 or s.size % per:
                    raise ValueError(f"ACTUATOR block of {s.size} samples; must be a multiple of {per}")
                items = [(first + i, 0, s[i * per:(i + 1) * per], None) for i in range(s.size // per)]
        except (ValueError, IndexError) as exc:
            self.counters["rx_bad_frames"] += 1
            self._event(P.Err.RX_ERRORS, self.counters["rx_bad_frames"], f"malformed stream frame: {exc}")
            return
        dropped = 0
        with self._lock:
            for item in items:
                if item[0] <= self._last_index:
                    self.counters["rx_duplicates"] += 1
                    continue
                if sum(1 for q in self._queue if q[0] != "stop") >= self.config.queue_capacity:
                    dropped += 1
                    continue
                self._last_index = item[0]
                self._queue.append(item)
            if dropped:
                self.counters["overruns"] += dropped
            self._qcond.notify()
        if dropped:
            self._event(P.Err.OVERRUN, self.counters["overruns"],
                        f"{self.counters['overruns']} cursor samples dropped: queue of "
                        f"{self.config.queue_capacity} full (stream faster than the device renders)")

    def _stop_render(self) -> None:
        th = self._render_thread
        with self._lock:
            self._streaming = False
            self._qcond.notify_all()
        if th is not None and th is not threading.current_thread():
            th.join(2.0)
        self._render_thread = None

    def _render_loop(self) -> None:
        """Render queued samples at their timestamps (the host's clock), like a DAC clocked by the stream.

        The first sample anchors the host clock to the device clock; sample i is due at
        ``anchor + t_i`` (CURSOR: its ``t_us``; ACTUATOR: ``index / stream_rate``) and is never
        rendered before it is due, so a host sending faster than its timestamps fills the queue
        (overrun at a full queue). A late sample is rendered on arrival (lateness never
        accumulates); every whole period that passes with no sample due is an underrun. The
        anchor slews earlier (2 % of a period per sample) when samples arrive ahead of it.
        """
        period = 1.0 / self.config.stream_rate_hz
        anchor = None         # device time of the host's t = 0
        expect = None         # when the next sample is due if the stream keeps its rate
        t_first = None
        consumed_since_flow = 0
        while True:
            with self._lock:
                while self._streaming and not self._queue:
                    if expect is None:
                        self._qcond.wait(0.05)
                        continue
                    left = expect + period - time.monotonic()
                    if left <= 0:
                        break
                    self._qcond.wait(left)
                if not self._streaming:
                    return
                item = self._queue.popleft() if self._queue else None
            if item is not None and item[0] == "stop":
                self._finish_stop(item[1])
                return
            if item is None:
                # A whole period past the next sample's due time: the actuator holds (no new drive),
                # the renderer does not advance, so its time stays locked to the samples rendered.
                self.counters["underruns"] += 1
                self._event(P.Err.UNDERRUN, self.counters["underruns"],
                            f"{self.counters['underruns']} cursor periods without a new cursor sample "
                            "(the host sent late; the last position held)")
                expect += period
                continue
            index, t_us, x, y = item
            stamp = t_us if self.mode == P.Mode.CURSOR else int(round(index * period * 1e6))
            if t_first is None:
                t_first = stamp
                anchor = time.monotonic()
            rel = ((stamp - t_first) & 0xFFFFFFFF) * 1e-6     # u32 microseconds wrap
            now = time.monotonic()
            if now - rel < anchor:
                # Samples arrive earlier than the first one suggested (it was delayed): slew the
                # anchor earlier by at most 2 % of a period per sample, so a late first sample adds
                # no lasting latency while a host sending ahead of its timestamps still waits.
                anchor = max(now - rel, anchor - 0.02 * period)
            due = anchor + rel
            if now < due:
                time.sleep(due - now)
            expect = due + period if expect is None else max(expect, due + period)
            if self.mode == P.Mode.CURSOR:
                out = self._engine.render(x, y)
            else:
                out = np.asarray(x, dtype=np.float64)
            out = np.where(np.isfinite(out), out, 0.0)
            n_clip = int(np.count_nonzero(np.abs(out) > DAC_RANGE))
            if n_clip:
                self.counters["clipped"] += n_clip
                out = np.clip(out, -DAC_RANGE, DAC_RANGE)
                self._event(P.Err.CLIPPED, self.counters["clipped"],
                            f"{self.counters['clipped']} actuator samples clipped to +/-{DAC_RANGE}")
            self.counters["ticks_rendered"] += out.size
            self.counters["samples_rendered"] += 1
            self._session_consumed += 1
            consumed_since_flow += 1
            if self.record_outputs:
                self.outputs.append((index, out.copy()))
            if self._monitor:
                self._send(P.Msg.OUTPUT, P.SEQ_UNSOLICITED, P.OUTPUT.pack(index, t_us) + P.pack_samples(out))
            if consumed_since_flow >= self.config.flow_every:
                consumed_since_flow = 0
                self._send(P.Msg.FLOW, P.SEQ_UNSOLICITED,
                           P.FLOW.pack(self._session_consumed & 0xFFFFFFFF, len(self._queue),
                                       self.config.queue_capacity))

    def _finish_stop(self, f: Frame) -> None:
        with self._lock:
            self._streaming = False
            self.state = P.State.IDLE
            self._engine = None
        self._send(P.Msg.FLOW, P.SEQ_UNSOLICITED,
                   P.FLOW.pack(self._session_consumed & 0xFFFFFFFF, 0, self.config.queue_capacity))
        self._reply(f, P.Msg.ACK, P.ACK.pack(f.type, self.counters["samples_rendered"]))
