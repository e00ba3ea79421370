"""Host side of the device link: open a port, handshake, upload, stream, close.

:class:`DeviceLink` talks protocol v1 (``docs/protocol.md``) over anything
pyserial opens: a device name (``/dev/ttyACM0``, ``COM3``), a pty path from
``shapedisplay device emulate``, or a URL (``loop://``, ``socket://host:port``,
``rfc2217://...``; see ``serial.serial_for_url``).

Rules the link keeps:

* every request has a fresh sequence number and is retried (same seq) after
  ``timeout`` seconds, up to ``retries`` times; the device answers a repeat
  from its reply cache, so a retried request never runs twice;
* a NAK for a bad frame (the device saw damage) makes the host resend at once;
* a BOOT frame from the device (it reset) aborts the operation in progress
  with :class:`DeviceResetError`; :meth:`DeviceLink.upload` then handshakes
  again and restarts the upload from the first byte (``restarts`` times);
* a table becomes active only after the device verified the whole image
  (CRC-32 and the table's own checksum) and acknowledged COMMIT;
* cursor streaming honours the device's queue (credit from FLOW frames), so
  the host never sends faster than the device renders unless told to;
* a port that disappears raises :class:`DeviceDisconnected` in every waiting
  call; :meth:`close` is always safe.

A background reader thread drains the port continuously so device output
(OUTPUT, FLOW, EVENT frames) can never block the device.
"""
from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from shapedisplay.errors import InputError, ShapeDisplayError, require
from shapedisplay.link import protocol as P
from shapedisplay.link.framing import Frame, FrameDecoder, crc32, encode_frame

DEFAULT_BAUD = 921_600
WRITE_TIMEOUT_S = 5.0     # a write that cannot go out for this long means nothing reads the line


class LinkError(ShapeDisplayError):
    """The device link failed; the message says how and what state the device is left in."""


class LinkTimeout(LinkError):
    """The device did not answer in time, after every retry."""


class DeviceDisconnected(LinkError, OSError):
    """The port went away (unplugged, emulator stopped)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class DeviceResetError(LinkError):
    """The device reset (sent BOOT) during an operation."""


class DeviceRefused(LinkError):
    """The device answered NAK. ``code`` is a :class:`~.protocol.Err`."""

    def __init__(self, message: str, code: int = 0, detail: int = 0):
        super().__init__(message)
        self.code, self.detail = code, detail


class ProtocolVersionError(LinkError):
    """Host and device share no protocol version."""


@dataclass
class UploadReport:
    """What an upload did. Sizes in bytes, times in seconds."""

    size: int
    crc32: int
    chunks: int = 0
    retransmits: int = 0
    restarts: int = 0
    seconds: float = 0.0
    commit_confirmed_by_status: bool = False   # the COMMIT ack was lost; GET_STATUS showed the table active

    @property
    def throughput_bytes_per_s(self) -> float:
        return self.size / self.seconds if self.seconds > 0 else float("inf")


@dataclass
class StreamReport:
    """What a stream did: counts from the device's STATUS before/after, plus host observations."""

    sent: int = 0
    rendered: int = 0
    underruns: int = 0
    overruns: int = 0
    clipped: int = 0
    duplicates: int = 0
    bad_frames: int = 0                      # frames the device received damaged (CRC/COBS) and dropped
    backpressure_waits: int = 0
    seconds: float = 0.0
    outputs: np.ndarray | None = None        # drive per renderer tick, in order, flat float64 (monitor only)
    latencies_s: np.ndarray | None = None    # (n,) send -> OUTPUT received per cursor sample, s (monitor only)
    missing_outputs: int = 0                 # OUTPUT frames lost on the line (monitor only)
    events: list = field(default_factory=list)

    def problems(self) -> list[str]:
        """One line per fault the device reported during the stream: what happened, why, and what to do."""
        out = []
        if self.overruns:
            out.append(f"device dropped {self.overruns} cursor samples: the host sent them faster than the device "
                       "renders; stream with backpressure on (the default), or lower the stream rate")
        if self.underruns:
            periods = self.rendered + self.underruns
            out.append(f"device ran {self.underruns} of {periods} cursor periods "
                       f"({100 * self.underruns / max(periods, 1):.0f} %) without a new cursor sample and held "
                       "the last position: the host did not send samples on time (a busy computer or a slow "
                       "line), so the stroke played less smoothly than asked; nothing is lost or wrong in the "
                       "table. Play again with fewer programs running, or raise the line rate (--baud)")
        if self.clipped:
            out.append(f"device clipped {self.clipped} actuator samples to full scale: lower the burst gain "
                       "(the device profile's [burst] gain, or play --burst-gain to try a value)")
        if self.bad_frames:
            out.append(f"device received {self.bad_frames} damaged frames (CRC/COBS check failed) and dropped "
                       "them: check the cable and that both ends use the same line rate (--baud)")
        if self.rendered < self.sent - self.overruns - self.bad_frames:     # losses not reported above
            out.append(f"device rendered {self.rendered} of {self.sent} samples sent: play again; if it "
                       "repeats, `shapedisplay device info PORT` shows the device's fault counters")
        return out


def _drain(q: "queue.Queue") -> None:
    """Discard everything waiting in ``q`` (stale replies or outputs of an earlier exchange)."""
    while True:
        try:
            q.get_nowait()
        except queue.Empty:
            return


def open_serial(port: str, baudrate: int = DEFAULT_BAUD, read_timeout: float = 0.02):
    """Open ``port`` (a device path or a pyserial URL) with pyserial; raise a one-line error."""
    serial = require("serial", "serial", "The device link")
    try:
        ser = serial.serial_for_url(port, baudrate=baudrate, timeout=read_timeout, write_timeout=WRITE_TIMEOUT_S,
                                    do_not_open=True)
        if hasattr(ser, "exclusive") and not port.startswith(("loop:", "socket:", "rfc2217:", "spy:")):
            try:
                ser.exclusive = True
            except (ValueError, AttributeError):
                pass
        ser.open()
    except (serial.SerialException, ValueError, OSError) as exc:
        raise DeviceDisconnected(f"port '{port}': cannot open ({exc})") from None
    return ser


class DeviceLink:
    """A connection to one device.

    Parameters
    ----------
    port : str
        Device path or pyserial URL.
    baudrate : int
        Line rate, bit/s (ignored by ptys and URLs without a line).
    timeout : float
        Seconds to wait for each reply before retrying.
    retries : int
        Resends of a request before :class:`LinkTimeout`.
    """

    def __init__(self, port: str, baudrate: int = DEFAULT_BAUD, timeout: float = 0.5, retries: int = 4):
        if timeout <= 0 or retries < 0:
            raise InputError(f"`timeout` must be > 0 and `retries` >= 0 (got {timeout}, {retries})")
        self.port, self.baudrate, self.timeout, self.retries = port, baudrate, float(timeout), int(retries)
        self._ser = None
        self._reader = None
        self._closing = threading.Event()
        self._failure: BaseException | None = None
        self._replies: queue.Queue = queue.Queue()
        self._outputs: queue.Queue = queue.Queue()
        self._flow = threading.Condition()
        self._consumed = 0
        self._seq = 0
        self._decoder = FrameDecoder()
        self._wlock = threading.Lock()
        self.events: list[tuple[int, int, str]] = []   # (Err code, count, text) from EVENT frames
        self.boots_seen = 0
        self._boot_flag = threading.Event()
        self.caps: P.Caps | None = None
        self.device_version: int | None = None
        self.device_boots: int | None = None
        self.bad_frames_seen = 0
        self.resends = 0

    # ------------------------------------------------------------ open/close
    def open(self) -> "DeviceLink":
        """Open the port and start the reader thread (no handshake)."""
        self._closing.clear()
        self._failure = None
        self._decoder.reset()
        self._ser = open_serial(self.port, self.baudrate)
        try:
            self._ser.reset_input_buffer()
        except Exception:  # noqa: BLE001  (some URL handlers lack it; pyserial raises its own types)
            pass
        self._reader = threading.Thread(target=self._read_loop, name=f"link-reader {self.port}", daemon=True)
        self._reader.start()
        return self

    def connect(self) -> P.Caps:
        """Open if needed, handshake (HELLO) and read the capabilities."""
        if self._ser is None:
            self.open()
        for attempt in range(3):
            try:
                return self._handshake()
            except DeviceResetError:
                if attempt == 2:
                    raise
                # the device (re)booted during the handshake: greet it again

    def _handshake(self) -> P.Caps:
        self._drain_replies()
        self._boot_flag.clear()
        f = self.request(P.Msg.HELLO, P.HELLO.pack(P.PROTOCOL_VERSION, P.PROTOCOL_MIN_VERSION), (P.Msg.HELLO_REPLY,))
        if len(f.body) < P.HELLO_REPLY.size:
            raise LinkError(f"port '{self.port}': malformed HELLO reply ({len(f.body)} bytes)")
        ver, vmin, boots = P.HELLO_REPLY.unpack_from(f.body)
        if vmin > P.PROTOCOL_VERSION or ver < P.PROTOCOL_MIN_VERSION:
            raise ProtocolVersionError(
                f"device on '{self.port}' speaks protocol {vmin}..{ver}; this host speaks "
                f"{P.PROTOCOL_MIN_VERSION}..{P.PROTOCOL_VERSION} (update shapedisplay or the firmware)")
        self.device_version, self.device_boots = ver, boots
        c = self.request(P.Msg.GET_CAPS, b"", (P.Msg.CAPS,))
        try:
            self.caps = P.Caps.unpack(c.body)
        except ValueError as exc:
            raise LinkError(f"port '{self.port}': malformed CAPS reply ({exc})") from None
        self._boot_flag.clear()
        return self.caps

    def reconnect(self, wait_s: float = 5.0) -> P.Caps:
        """Close, reopen the same port (waiting up to ``wait_s`` for it to reappear) and handshake."""
        self.close()
        deadline = time.monotonic() + wait_s
        while True:
            try:
                self.open()
                break
            except DeviceDisconnected:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)
        return self.connect()

    def close(self) -> None:
        """Stop the reader and close the port. Safe to call twice or after a failure."""
        self._closing.set()
        ser, self._ser = self._ser, None
        if ser is not None:
            try:
                ser.close()
            except Exception:  # noqa: BLE001  (closing a vanished port may raise anything)
                pass
        if self._reader is not None and self._reader is not threading.current_thread():
            self._reader.join(1.0)
        self._reader = None

    def __enter__(self) -> "DeviceLink":
        try:
            self.connect()
        except BaseException:
            self.close()            # a failed handshake leaves no port open
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------ wire
    def _read_loop(self) -> None:
        ser = self._ser
        while not self._closing.is_set():
            try:
                data = ser.read(max(1, ser.in_waiting))
            except Exception as exc:  # noqa: BLE001  (pyserial raises SerialException, OSError, TypeError on close)
                if not self._closing.is_set():
                    self._fail(DeviceDisconnected(f"port '{self.port}' disappeared ({exc})"))
                return
            if data:
                for item in self._decoder.feed(data):
                    if isinstance(item, Frame):
                        self._on_frame(item)
                    else:
                        self.bad_frames_seen += 1

    def _fail(self, exc: BaseException) -> None:
        self._failure = exc
        self._replies.put(None)
        self._outputs.put(None)
        with self._flow:
            self._flow.notify_all()

    def _on_frame(self, f: Frame) -> None:
        t = f.type
        if t == P.Msg.OUTPUT:
            if len(f.body) >= P.OUTPUT.size:
                idx, t_us = P.OUTPUT.unpack_from(f.body)
                self._outputs.put((time.perf_counter(), idx, t_us, P.unpack_samples(f.body[P.OUTPUT.size:])))
        elif t == P.Msg.FLOW:
            if len(f.body) == P.FLOW.size:
                consumed, _, _ = P.FLOW.unpack(f.body)
                with self._flow:
                    self._consumed = consumed
                    self._flow.notify_all()
        elif t == P.Msg.EVENT:
            try:
                self.events.append(P.unpack_event(f.body))
            except ValueError:
                self.bad_frames_seen += 1
        elif t == P.Msg.BOOT:
            self.boots_seen += 1
            self._boot_flag.set()
            self._replies.put(f)
            with self._flow:
                self._flow.notify_all()
        elif t < 0x80:
            # Our own request came back: the port is a loopback, not a device.
            self._replies.put(f)
        else:
            self._replies.put(f)

    def _check(self) -> None:
        if self._failure is not None:
            raise self._failure
        if self._ser is None:
            raise LinkError(f"port '{self.port}' is not open")

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) % 0xFFFF     # 0xFFFF is reserved for unsolicited frames
        return self._seq

    def _write(self, wire: bytes) -> None:
        self._check()
        try:
            with self._wlock:
                self._ser.write(wire)
        except Exception as exc:  # noqa: BLE001  (SerialException, OSError, SerialTimeoutException)
            if self._failure is None:
                if type(exc).__name__ == "SerialTimeoutException":
                    # The port is there but nothing drains it: a hung device (or a flow-control stall).
                    self._fail(LinkTimeout(f"device on '{self.port}' stopped reading: a write of {len(wire)} "
                                           f"bytes did not go out within {WRITE_TIMEOUT_S:g} s"))
                else:
                    self._fail(DeviceDisconnected(f"port '{self.port}' disappeared while writing ({exc})"))
            raise self._failure from None

    def send_frame(self, msg_type: int, body: bytes = b"", seq: int | None = None,
                   version: int = P.PROTOCOL_VERSION) -> int:
        """Send one frame without waiting; return its seq. (Low level; tests use it for raw frames.)"""
        seq = self._next_seq() if seq is None else seq
        self._write(encode_frame(version, msg_type, seq, body))
        return seq

    def _get_reply(self, deadline: float):
        left = deadline - time.monotonic()
        if left <= 0:
            return "timeout"
        try:
            f = self._replies.get(timeout=left)
        except queue.Empty:
            return "timeout"
        if f is None:
            self._check()
            return "timeout"
        return f

    def request(self, msg_type: int, body: bytes, expect: tuple, timeout: float | None = None,
                retries: int | None = None) -> Frame:
        """Send a request and wait for its reply, retrying on silence or damage.

        Returns the reply frame (one of ``expect``). Raises
        :class:`DeviceRefused` on a NAK, :class:`DeviceResetError` if the
        device reset meanwhile, :class:`LinkTimeout` after the last retry,
        :class:`DeviceDisconnected` if the port vanished.
        """
        timeout = self.timeout if timeout is None else timeout
        retries = self.retries if retries is None else retries
        seq = self._next_seq()
        wire = encode_frame(P.PROTOCOL_VERSION, msg_type, seq, body)
        name = P.msg_name(msg_type)
        for attempt in range(retries + 1):
            if attempt:
                self.resends += 1
            self._write(wire)
            deadline = time.monotonic() + timeout
            while True:
                f = self._get_reply(deadline)
                if f == "timeout":
                    break
                if f.version > P.PROTOCOL_VERSION:
                    raise ProtocolVersionError(
                        f"device on '{self.port}' speaks protocol {f.version}; this host speaks "
                        f"{P.PROTOCOL_MIN_VERSION}..{P.PROTOCOL_VERSION} (update shapedisplay or the firmware)")
                if f.type == P.Msg.BOOT:
                    if msg_type == P.Msg.HELLO:
                        break        # the device just booted: greet it again
                    raise DeviceResetError(f"device on '{self.port}' reset during {name}")
                if f.type < 0x80:
                    raise LinkError(f"port '{self.port}' echoes our own frames: it is a loopback, not a device")
                if f.type == P.Msg.NAK and f.seq == P.SEQ_UNSOLICITED:
                    # The device saw a damaged frame: maybe this request, maybe a stream frame sent
                    # before it (those are never resent). Resend now (a duplicate runs once); the NAK
                    # is no answer, so it costs no try and the deadline stays (no hang under a flood).
                    self.resends += 1
                    self._write(wire)
                    continue
                if f.seq != seq:
                    continue         # a stale or duplicated reply to an older request
                if f.type == P.Msg.NAK:
                    self._raise_nak(f, name)
                if f.type in expect:
                    return f
                raise LinkError(f"device answered {name} with {P.msg_name(f.type)}; expected "
                                f"{'/'.join(P.msg_name(e) for e in expect)}")
        raise LinkTimeout(f"device on '{self.port}' did not answer {name} after {retries + 1} tries "
                          f"({timeout:g} s each)")

    def _raise_nak(self, f: Frame, what: str):
        try:
            _, code, detail, text = P.unpack_nak(f.body)
        except ValueError:
            raise LinkError(f"device refused {what} with a malformed NAK") from None
        if code == P.Err.VERSION:
            raise ProtocolVersionError(f"device on '{self.port}' refused {what}: {text}")
        raise DeviceRefused(f"device refused {what}: {P.err_name(code)}: {text}", code, detail)

    # ------------------------------------------------------------ queries
    def status(self) -> P.Status:
        f = self.request(P.Msg.GET_STATUS, b"", (P.Msg.STATUS,))
        try:
            return P.Status.unpack(f.body)
        except ValueError as exc:
            raise LinkError(f"port '{self.port}': malformed STATUS reply ({exc})") from None

    def reset_device(self) -> None:
        """Ask the device to reset; wait for its BOOT and handshake again."""
        self._boot_flag.clear()
        self.request(P.Msg.RESET, b"", (P.Msg.ACK,))
        deadline = time.monotonic() + max(2.0, 4 * self.timeout)
        while not self._boot_flag.is_set():
            self._check()
            if time.monotonic() > deadline:
                raise LinkTimeout(f"device on '{self.port}' did not boot after RESET")
            time.sleep(0.005)
        self._drain_replies()
        self.connect()

    def _drain_replies(self) -> None:
        _drain(self._replies)

    # ------------------------------------------------------------ upload
    def upload(self, image: bytes, restarts: int = 2, progress=None) -> UploadReport:
        """Upload a table image (the bytes of a table file), verify and commit it.

        The device verifies the whole-image CRC-32 and parses the table before
        COMMIT; only then does the table become active. A device reset during
        the upload restarts it from the first byte, up to ``restarts`` times.
        ``progress(done_bytes, total_bytes)`` is called after each acked chunk.
        """
        image = bytes(image)
        if self.caps is None:
            self.connect()
        report = UploadReport(size=len(image), crc32=crc32(image))
        if len(image) > self.caps.max_table_bytes:
            raise DeviceRefused(f"table image of {len(image)} bytes exceeds the device memory of "
                                f"{self.caps.max_table_bytes} bytes ({self.caps.name}); nothing uploaded",
                                P.Err.TOO_LARGE, self.caps.max_table_bytes)
        t0 = time.perf_counter()
        for attempt in range(restarts + 1):
            try:
                self._upload_once(image, report, progress)
                break
            except DeviceResetError:
                if attempt == restarts:
                    raise DeviceResetError(f"device on '{self.port}' kept resetting during upload "
                                           f"({restarts + 1} attempts); no new table is active") from None
                report.restarts += 1
                self._drain_replies()
                self.connect()
        report.seconds = time.perf_counter() - t0
        return report

    def _upload_once(self, image: bytes, report: UploadReport, progress) -> None:
        size, crc = len(image), report.crc32
        uid = self._next_seq()
        if self._boot_flag.is_set():
            self._boot_flag.clear()
            raise DeviceResetError(f"device on '{self.port}' reset before upload")
        self.request(P.Msg.UPLOAD_BEGIN, P.UPLOAD_BEGIN.pack(uid, size, crc), (P.Msg.ACK,))
        chunk = max(1, min(self.caps.chunk_size, 2048 - 64))
        window = max(1, self.caps.upload_window) * chunk
        acked = 0          # device's next expected offset
        nxt = 0            # next offset to send
        live: dict[int, int] = {}       # seq -> offset of chunks in flight
        tries = 0
        while acked < size:
            while nxt < size and nxt - acked < window:
                n = min(chunk, size - nxt)
                seq = self.send_frame(P.Msg.UPLOAD_CHUNK, P.UPLOAD_CHUNK.pack(uid, nxt) + image[nxt:nxt + n])
                live[seq] = nxt
                report.chunks += 1
                nxt += n
            f = self._get_reply(time.monotonic() + self.timeout)
            if f == "timeout":
                tries += 1
                if tries > self.retries:
                    raise LinkTimeout(f"device on '{self.port}' stopped acknowledging upload chunks at byte "
                                      f"{acked} of {size} ({self.retries + 1} tries); no new table is active")
                report.retransmits += 1
                nxt, live = acked, {}
                continue
            if f.type == P.Msg.BOOT:
                raise DeviceResetError(f"device on '{self.port}' reset at byte {acked} of {size}")
            if f.type == P.Msg.CHUNK_ACK and f.seq in live:
                u, expected = P.CHUNK_ACK.unpack(f.body)
                if u == uid and expected > acked:
                    acked = expected
                    tries = 0
                    if progress is not None:
                        progress(acked, size)
                live.pop(f.seq, None)
                continue
            if f.type == P.Msg.NAK:
                _, code, detail, text = P.unpack_nak(f.body)
                if f.seq == P.SEQ_UNSOLICITED or (f.seq in live and code == P.Err.OUT_OF_ORDER):
                    # Damage on the line: go back to what the device has.
                    if code == P.Err.OUT_OF_ORDER:
                        acked = max(acked, detail)
                    report.retransmits += 1
                    nxt, live = acked, {}
                    continue
                if f.seq in live:
                    if code == P.Err.NO_UPLOAD:
                        raise DeviceResetError(f"device on '{self.port}' lost the upload at byte {acked}: {text}")
                    raise DeviceRefused(f"device refused upload chunk: {P.err_name(code)}: {text}", code, detail)
        # Verification parses and checksums the whole table on the device: allow it more time.
        slow = max(self.timeout, 2.0)
        try:
            self.request(P.Msg.UPLOAD_END, P.UPLOAD_END.pack(uid, crc, size), (P.Msg.VERIFIED,), timeout=slow)
        except DeviceRefused as exc:
            if exc.code == P.Err.NO_UPLOAD:
                raise DeviceResetError(f"device on '{self.port}' lost the upload before UPLOAD_END: {exc}") from None
            raise
        try:
            self.request(P.Msg.COMMIT, P.UPLOAD_ID.pack(uid), (P.Msg.ACK,), timeout=slow)
        except (LinkTimeout, DeviceRefused) as exc:
            # Every acknowledgement may have been lost after the device committed (a resent COMMIT
            # then finds nothing staged: NO_UPLOAD), or the device reset before COMMIT (NO_UPLOAD
            # too): ask the device what is true instead of guessing.
            if isinstance(exc, DeviceRefused) and exc.code not in (P.Err.NO_UPLOAD, P.Err.NOT_VERIFIED):
                raise
            self._confirm_commit(report, exc)

    def _confirm_commit(self, report: UploadReport, cause: LinkError) -> None:
        """After a COMMIT without a usable answer: read the device state and report what is true."""
        try:
            st = self.status()
        except LinkError as exc:
            raise LinkTimeout(f"device on '{self.port}' did not acknowledge COMMIT ({cause}) and did not "
                              f"answer a status query ({exc}); whether the new table is active is unknown") from None
        if st.active_crc == report.crc32 and st.active_size == report.size:
            report.commit_confirmed_by_status = True
            return
        if isinstance(cause, DeviceRefused) and cause.code == P.Err.NO_UPLOAD:
            # Nothing staged and the new table not active: the device reset after UPLOAD_END.
            raise DeviceResetError(f"device on '{self.port}' lost the verified upload before COMMIT ({cause})")
        raise LinkError(f"device on '{self.port}' did not acknowledge COMMIT ({cause}); its status shows table "
                        f"{st.active_crc:08x} ({st.active_size} bytes) active, not the new {report.crc32:08x}: "
                        f"the new table is not active")

    # ------------------------------------------------------------ streaming
    def start(self, mode: str = "cursor", input: str = "position", monitor: bool = False) -> None:
        """Enter streaming. ``mode`` cursor|actuator, ``input`` position|force."""
        modes = {"cursor": P.Mode.CURSOR, "actuator": P.Mode.ACTUATOR}
        inputs = {"position": P.Input.POSITION, "force": P.Input.FORCE}
        if mode not in modes or input not in inputs:
            raise InputError(f"`mode` must be cursor|actuator and `input` position|force (got {mode!r}, {input!r})")
        self._drain_outputs()
        with self._flow:
            self._consumed = 0
        self._boot_flag.clear()
        self.request(P.Msg.START, P.START.pack(modes[mode], inputs[input], P.FLAG_MONITOR if monitor else 0),
                     (P.Msg.ACK,))

    def stop(self, timeout: float = 5.0) -> int:
        """Leave streaming once the device has rendered what it queued; return samples rendered."""
        f = self.request(P.Msg.STOP, b"", (P.Msg.ACK,), timeout=timeout, retries=1)
        return P.ACK.unpack(f.body)[1]

    def _drain_outputs(self) -> None:
        _drain(self._outputs)

    def _wait_credit(self, sent: int, capacity: int, timeout: float) -> bool:
        """Block until fewer than ``capacity`` samples are queued at the device. True if it waited."""
        with self._flow:
            if sent - self._consumed < capacity:
                return False
            deadline = time.monotonic() + timeout
            while sent - self._consumed >= capacity:
                self._check()
                if self._boot_flag.is_set():
                    raise DeviceResetError(f"device on '{self.port}' reset during streaming; stream stopped")
                left = deadline - time.monotonic()
                if left <= 0:
                    raise LinkTimeout(f"device on '{self.port}' stopped consuming cursor samples "
                                      f"({sent - self._consumed} queued for {timeout:g} s)")
                self._flow.wait(left)
            return True

    def stream(self, x, y=None, mode: str = "cursor", input: str = "position", paced: bool = True,
               backpressure: bool = True, monitor: bool = False, per_frame: int = 1) -> StreamReport:
        """Stream cursor samples (or, in actuator mode, rendered sample blocks) and stop.

        Parameters
        ----------
        x, y : ndarray of shape (n,), float
            Cursor positions (m) or forces (N), one per device stream period.
            In ``mode="actuator"`` ``x`` has shape (n, samples_per_cursor):
            rendered actuator samples, full scale 1.0; ``y`` is unused.
        paced : bool
            Send at the device's stream rate (sample i at t0 + i/rate).
        backpressure : bool
            Never have more samples in flight than the device queue holds.
        monitor : bool
            Ask for an OUTPUT frame per rendered sample; the report then holds
            the actuator samples and the send-to-output latency of each.
        per_frame : int
            Cursor samples packed per frame (unpaced bulk streaming).
        """
        if self.caps is None:
            self.connect()
        caps = self.caps
        x = np.asarray(x, dtype=np.float64)
        n = x.shape[0]
        if mode == "cursor":
            y = np.zeros(n) if y is None else np.asarray(y, dtype=np.float64)
            if y.shape != (n,) or x.ndim != 1:
                raise InputError(f"`x` and `y` must both have shape (n,) (got {x.shape}, {y.shape})")
        elif x.ndim != 2 or x.shape[1] != caps.samples_per_cursor:
            raise InputError(f"actuator blocks must have shape (n, {caps.samples_per_cursor}) (got {x.shape})")
        if not np.all(np.isfinite(x)) or (y is not None and not np.all(np.isfinite(y))):
            raise InputError("cursor or actuator samples hold NaN or infinity")
        before = self.status()
        self.start(mode, input, monitor)
        period = 1.0 / caps.stream_rate_hz
        rep = StreamReport()
        send_t = np.zeros(n)
        t0 = time.perf_counter()
        per_frame = max(1, int(per_frame))
        try:
            i = 0
            while i < n:
                k = min(per_frame, n - i)
                if backpressure:
                    rep.backpressure_waits += self._wait_credit(i + k - 1, caps.queue_capacity, 5.0)
                if paced:
                    wait = t0 + i * period - time.perf_counter()
                    if wait > 0:
                        time.sleep(wait)
                if self._boot_flag.is_set():
                    raise DeviceResetError(f"device on '{self.port}' reset during streaming at sample {i}; "
                                           "stream stopped")
                idx = np.arange(i, i + k)
                if mode == "cursor":
                    body = P.pack_cursor(idx, np.rint(idx * period * 1e6).astype(np.int64), x[i:i + k], y[i:i + k])
                    msg = P.Msg.CURSOR
                else:
                    body = P.ACTUATOR.pack(i) + P.pack_samples(x[i:i + k].ravel())
                    msg = P.Msg.ACTUATOR
                send_t[i:i + k] = time.perf_counter()
                self.send_frame(msg, body)
                i += k
            rep.sent = n
            self.stop(timeout=max(5.0, 2 * n * period))
        except DeviceResetError:
            self._boot_flag.clear()
            raise
        rep.seconds = time.perf_counter() - t0
        after = self.status()
        rep.rendered = after.samples_rendered - before.samples_rendered
        rep.underruns = after.underruns - before.underruns
        rep.overruns = after.overruns - before.overruns
        rep.clipped = after.clipped - before.clipped
        rep.duplicates = after.rx_duplicates - before.rx_duplicates
        rep.bad_frames = after.rx_bad_frames - before.rx_bad_frames
        rep.events = list(self.events)
        if monitor:
            got: dict = {}
            lat = np.full(n, np.nan)
            while len(got) < n:
                try:
                    item = self._outputs.get(timeout=0.2)
                except queue.Empty:
                    break
                if item is None:
                    self._check()
                    break
                t_rx, idx, _, samples = item
                if idx < n:
                    got[idx] = samples
                    lat[idx] = t_rx - send_t[idx]
            rep.missing_outputs = n - len(got)
            rep.outputs = (np.concatenate([got[i] for i in sorted(got)]) if got else np.zeros(0))
            rep.latencies_s = lat
        return rep
