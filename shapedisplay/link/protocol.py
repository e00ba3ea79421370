"""Messages of the device link (protocol version 1); see ``docs/protocol.md``.

Every message is one frame (:mod:`.framing`): ``version | type | seq | body``.
Host requests carry a sequence number the device echoes in its reply, so a
reply is matched to its request and stale or duplicated replies are ignored.
All integers are little-endian; floats are IEEE-754 binary32; positions are
metres, forces newtons, times microseconds.

This module only packs and unpacks bodies; it opens no port and holds no
state. The device side lives in :mod:`.emulator`, the host side in :mod:`.host`.
"""
from __future__ import annotations

import enum
import struct
from dataclasses import dataclass, fields

import numpy as np

#: Version this package speaks; frames with a higher version are refused.
PROTOCOL_VERSION = 1
#: Oldest version this package still understands.
PROTOCOL_MIN_VERSION = 1
#: Sequence number used for unsolicited device frames (BOOT, EVENT, FLOW, OUTPUT).
SEQ_UNSOLICITED = 0xFFFF


class Msg(enum.IntEnum):
    """Message types. Host requests < 0x80 <= device messages."""

    # host -> device
    HELLO = 0x01          # body: host max version u8, host min version u8
    GET_CAPS = 0x02       # no body
    GET_STATUS = 0x03     # no body
    UPLOAD_BEGIN = 0x10   # UploadBegin
    UPLOAD_CHUNK = 0x11   # upload id u16, offset u32, data
    UPLOAD_END = 0x12     # upload id u16, whole-table crc32 u32, size u32
    COMMIT = 0x13         # upload id u16
    ABORT = 0x14          # upload id u16 (informative: the one staged upload is discarded)
    START = 0x20          # mode u8, input u8, flags u8
    STOP = 0x21           # no body
    CURSOR = 0x22         # CursorSample (one or more, back to back)
    ACTUATOR = 0x23       # start sample index u32, n float32 samples
    RESET = 0x3F          # soft reset: as a power cycle (RAM lost, committed table kept)
    # device -> host
    HELLO_REPLY = 0x81    # device version u8, device min version u8, boot count u32
    CAPS = 0x82           # Caps
    STATUS = 0x83         # Status
    ACK = 0x84            # acked type u8, value u32 (meaning per request)
    NAK = 0x85            # acked type u8, Err u16, detail u32, UTF-8 text
    CHUNK_ACK = 0x91      # upload id u16, next expected offset u32
    VERIFIED = 0x92       # upload id u16, crc32 u32, size u32 (table parsed and staged)
    OUTPUT = 0xA0         # sample index u32, timestamp u32 (echo), n float32 actuator samples
    FLOW = 0xA1           # consumed samples u32, queue fill u16, queue capacity u16
    EVENT = 0xE0          # Event code u16, count u32, UTF-8 text
    BOOT = 0xF0           # device version u8, boot count u32 (sent after every reset)


class Err(enum.IntEnum):
    """Error codes carried by NAK and EVENT."""

    OK = 0
    BAD_FRAME = 1          # CRC or COBS failure; seq unknown, so seq=0xFFFF
    VERSION = 2            # frame version newer than the device speaks
    UNKNOWN_TYPE = 3
    BAD_BODY = 4           # body length or contents wrong for the type
    BUSY = 5               # request not allowed in this state (e.g. upload while streaming)
    NO_UPLOAD = 6          # chunk/end/commit without a matching UPLOAD_BEGIN (e.g. after a reset)
    OUT_OF_ORDER = 7       # chunk offset is not the next expected; detail = expected offset
    TOO_LARGE = 8          # table larger than device memory; detail = memory bytes
    CHECKSUM = 9           # whole-table CRC-32 mismatch
    TABLE_INVALID = 10     # table failed to parse or verify; text says why
    NOT_VERIFIED = 11      # commit before a successful UPLOAD_END
    NO_TABLE = 12          # START cursor mode with no committed table
    UNSUPPORTED = 13       # mode or input the device does not offer
    # EVENT-only codes (unsolicited reports)
    UNDERRUN = 32          # a render period passed with no cursor sample; held the last one
    OVERRUN = 33           # cursor sample dropped: queue full (stream faster than the device renders)
    CLIPPED = 34           # actuator samples clipped to the DAC range
    RX_ERRORS = 35         # bad frames received since the last report


class Mode(enum.IntEnum):
    """START modes."""

    CURSOR = 0      # host streams cursor samples; the device renders locally
    ACTUATOR = 1    # host streams rendered actuator samples (device without a renderer)


class Input(enum.IntEnum):
    """What a cursor sample's (x, y) mean."""

    POSITION = 0    # metres
    FORCE = 1       # newtons on a force-to-velocity stick (v = alpha f)


class State(enum.IntEnum):
    IDLE = 0
    UPLOADING = 1
    VERIFIED = 2
    STREAMING = 3


#: START flags.
FLAG_MONITOR = 0x01   # send an OUTPUT frame per rendered cursor sample
#: CAPS flags.
CAP_RENDERER = 0x01
CAP_ACTUATOR_STREAM = 0x02
CAP_FORCE_INPUT = 0x04
CAP_MONITOR = 0x08


def _pack_text(text: str, limit: int = 200) -> bytes:
    return text.encode("utf-8")[:limit]


def _unpack_text(data: bytes) -> str:
    return data.decode("utf-8", errors="replace")


@dataclass(frozen=True)
class Caps:
    """Device capabilities (reply to GET_CAPS)."""

    version: int                # protocol version the device speaks
    min_version: int
    flags: int                  # CAP_* bits
    max_table_bytes: int        # largest table image the device can hold
    chunk_size: int             # largest UPLOAD_CHUNK data, bytes
    upload_window: int          # chunks the device buffers before acking (sliding window)
    queue_capacity: int         # cursor samples the device buffers
    stream_rate_hz: int         # cursor samples per second it consumes
    tick_rate_hz: int           # renderer ticks per second
    samples_per_cursor: int     # actuator samples rendered per cursor sample
    name: str = ""
    firmware: str = ""
    models: tuple = ()

    _FMT = struct.Struct("<BBHIHBHHIH")

    def pack(self) -> bytes:
        text = "\n".join([self.name, self.firmware, ",".join(self.models)])
        return self._FMT.pack(self.version, self.min_version, self.flags, self.max_table_bytes,
                              self.chunk_size, self.upload_window, self.queue_capacity,
                              self.stream_rate_hz, self.tick_rate_hz, self.samples_per_cursor) + _pack_text(text)

    @classmethod
    def unpack(cls, body: bytes) -> "Caps":
        n = cls._FMT.size
        if len(body) < n:
            raise ValueError(f"CAPS body of {len(body)} bytes, need >= {n}")
        vals = cls._FMT.unpack_from(body)
        parts = (_unpack_text(body[n:]).split("\n") + ["", "", ""])[:3]
        models = tuple(m for m in parts[2].split(",") if m)
        return cls(*vals, name=parts[0], firmware=parts[1], models=models)

    @property
    def has_renderer(self) -> bool:
        return bool(self.flags & CAP_RENDERER)

    def to_json(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["models"] = list(self.models)
        d["renderer"] = self.has_renderer
        d["actuator_stream"] = bool(self.flags & CAP_ACTUATOR_STREAM)
        d["force_input"] = bool(self.flags & CAP_FORCE_INPUT)
        return d


@dataclass(frozen=True)
class Status:
    """Device state and fault counters (reply to GET_STATUS)."""

    state: int
    mode: int
    active_crc: int             # CRC-32 of the committed table image, 0 if none
    active_size: int            # bytes of the committed table image, 0 if none
    staged_bytes: int           # bytes received of the upload in progress
    boots: int                  # resets since power-up (incl. the first boot)
    rx_frames: int              # good frames received
    rx_bad_frames: int          # frames dropped for CRC/COBS/length
    rx_duplicates: int          # requests answered from the reply cache
    rx_version_errors: int      # frames of a newer protocol version
    underruns: int
    overruns: int
    clipped: int
    samples_rendered: int       # cursor samples consumed
    ticks_rendered: int         # renderer ticks
    queue_fill: int
    queue_capacity: int

    _FMT = struct.Struct("<BB" + "I" * 13 + "HH")

    def pack(self) -> bytes:
        return self._FMT.pack(*(getattr(self, f.name) for f in fields(self)))

    @classmethod
    def unpack(cls, body: bytes) -> "Status":
        if len(body) != cls._FMT.size:
            raise ValueError(f"STATUS body of {len(body)} bytes, need {cls._FMT.size}")
        return cls(*cls._FMT.unpack(body))

    def to_json(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["state"] = State(self.state).name.lower() if self.state in State._value2member_map_ else self.state
        d["mode"] = Mode(self.mode).name.lower() if self.mode in Mode._value2member_map_ else self.mode
        d["active_crc"] = f"{self.active_crc:08x}"
        return d


# ---------------------------------------------------------------- small bodies
HELLO = struct.Struct("<BB")
HELLO_REPLY = struct.Struct("<BBI")
UPLOAD_BEGIN = struct.Struct("<HII")     # upload id, total size, whole-table crc32
UPLOAD_CHUNK = struct.Struct("<HI")      # upload id, offset (+ data)
UPLOAD_END = struct.Struct("<HII")       # upload id, crc32, size
UPLOAD_ID = struct.Struct("<H")
CHUNK_ACK = struct.Struct("<HI")
VERIFIED = struct.Struct("<HII")
START = struct.Struct("<BBB")
ACK = struct.Struct("<BI")
NAK = struct.Struct("<BHI")
FLOW = struct.Struct("<IHH")
EVENT = struct.Struct("<HI")
BOOT = struct.Struct("<BI")
OUTPUT = struct.Struct("<II")            # sample index, timestamp echo (+ float32 samples)
ACTUATOR = struct.Struct("<I")           # first sample index (+ float32 samples)

#: One cursor sample: index u32, timestamp u32 (us), x f32, y f32 (m or N).
CURSOR_DTYPE = np.dtype([("index", "<u4"), ("t_us", "<u4"), ("x", "<f4"), ("y", "<f4")])


def pack_cursor(index, t_us, x, y) -> bytes:
    """Pack cursor samples (scalars or equal-length arrays) into a CURSOR body."""
    idx = np.atleast_1d(np.asarray(index, dtype=np.int64))
    rec = np.zeros(idx.size, dtype=CURSOR_DTYPE)
    rec["index"] = idx & 0xFFFFFFFF
    rec["t_us"] = np.atleast_1d(np.asarray(t_us, dtype=np.int64)) & 0xFFFFFFFF
    rec["x"] = x
    rec["y"] = y
    return rec.tobytes()


def unpack_cursor(body: bytes) -> np.ndarray:
    """CURSOR body -> structured array of :data:`CURSOR_DTYPE`; ValueError if ragged."""
    if len(body) == 0 or len(body) % CURSOR_DTYPE.itemsize:
        raise ValueError(f"CURSOR body of {len(body)} bytes is not a multiple of {CURSOR_DTYPE.itemsize}")
    return np.frombuffer(body, dtype=CURSOR_DTYPE)


def pack_samples(samples) -> bytes:
    """float samples -> little-endian float32 bytes."""
    return np.asarray(samples, dtype="<f4").tobytes()


def unpack_samples(data: bytes) -> np.ndarray:
    if len(data) % 4:
        raise ValueError(f"sample block of {len(data)} bytes is not a multiple of 4")
    with np.errstate(invalid="ignore"):
        return np.frombuffer(data, dtype="<f4").astype(np.float64)


def pack_nak(acked_type: int, code: Err, detail: int = 0, text: str = "") -> bytes:
    return NAK.pack(acked_type & 0xFF, int(code), detail & 0xFFFFFFFF) + _pack_text(text)


def unpack_nak(body: bytes) -> tuple[int, int, int, str]:
    if len(body) < NAK.size:
        raise ValueError(f"NAK body of {len(body)} bytes, need >= {NAK.size}")
    t, code, detail = NAK.unpack_from(body)
    return t, code, detail, _unpack_text(body[NAK.size:])


def pack_event(code: Err, count: int, text: str = "") -> bytes:
    return EVENT.pack(int(code), count & 0xFFFFFFFF) + _pack_text(text)


def unpack_event(body: bytes) -> tuple[int, int, str]:
    if len(body) < EVENT.size:
        raise ValueError(f"EVENT body of {len(body)} bytes, need >= {EVENT.size}")
    code, count = EVENT.unpack_from(body)
    return code, count, _unpack_text(body[EVENT.size:])


def err_name(code: int) -> str:
    return Err(code).name if code in Err._value2member_map_ else f"error {code}"


def msg_name(msg_type: int) -> str:
    return Msg(msg_type).name if msg_type in Msg._value2member_map_ else f"0x{msg_type:02x}"
