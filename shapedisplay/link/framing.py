"""Byte framing of the device link: COBS with a 0x00 delimiter and a CRC-32 per frame.

On the wire every message is::

    COBS( version:u8 | type:u8 | seq:u16 LE | body | crc32:u32 LE ) 0x00

The CRC-32 (IEEE 802.3, the polynomial of ``zlib.crc32``) covers the four
header bytes and the body. COBS removes every zero byte from the encoded
frame, so 0x00 marks frame boundaries unambiguously: after any corruption the
receiver resynchronises at the next delimiter and loses at most the frames
the damage touched.

:class:`FrameDecoder` is the receiver. It is fed arbitrary byte strings (any
length, any content) and never raises, never allocates more than one frame
buffer of ``max_frame`` bytes, and counts every defect it discards.
"""
from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

#: Largest payload (header + body + CRC) a frame may carry, bytes.
MAX_FRAME = 2048
#: Header: protocol version, message type, sequence number.
HEADER = struct.Struct("<BBH")
_CRC = struct.Struct("<I")
#: Smallest valid payload: header + CRC, no body.
MIN_FRAME = HEADER.size + _CRC.size


def crc32(data: bytes, start: int = 0) -> int:
    """CRC-32 (IEEE, reflected, init and xor-out 0xFFFFFFFF) of ``data``."""
    return zlib.crc32(data, start) & 0xFFFFFFFF


def cobs_encode(data: bytes) -> bytes:
    """Consistent-overhead byte stuffing: the result holds no 0x00 byte.

    Each zero-separated run of the input becomes blocks of at most 254 bytes,
    each led by a code byte (block length + 1; 255 = full block, no implied
    zero). Overhead is one byte per 254 bytes of input, plus one.
    """
    out = bytearray()
    for part in bytes(data).split(b"\x00"):
        while len(part) >= 254:
            out.append(255)
            out += part[:254]
            part = part[254:]
        out.append(len(part) + 1)
        out += part
    return bytes(out)


def cobs_decode(data: bytes) -> bytes:
    """Invert :func:`cobs_encode`; raise ``ValueError`` on a malformed block."""
    out = bytearray()
    idx = 0
    n = len(data)
    while idx < n:
        code = data[idx]
        if code == 0:
            raise ValueError("COBS: zero byte inside a frame")
        end = idx + code
        if end > n:
            raise ValueError("COBS: block runs past the end of the frame")
        block = data[idx + 1:end]
        if 0 in block:
            raise ValueError("COBS: zero byte inside a frame")
        out += block
        idx = end
        if code < 255 and idx < n:
            out.append(0)
    return bytes(out)


def encode_frame(version: int, msg_type: int, seq: int, body: bytes = b"") -> bytes:
    """Build one complete wire frame, delimiter included.

    Parameters
    ----------
    version : int, 0..255
        Protocol version of the sender.
    msg_type : int, 0..255
        Message type (see :mod:`shapedisplay.link.protocol`).
    seq : int, 0..65535
        Sequence number; replies echo the request's.
    body : bytes
        Message body; header + body + CRC must fit in :data:`MAX_FRAME`.
    """
    payload = HEADER.pack(version, msg_type, seq & 0xFFFF) + bytes(body)
    if len(payload) + _CRC.size > MAX_FRAME:
        raise ValueError(f"frame payload of {len(payload) + _CRC.size} bytes exceeds MAX_FRAME={MAX_FRAME}")
    payload += _CRC.pack(crc32(payload))
    return cobs_encode(payload) + b"\x00"


@dataclass(frozen=True)
class Frame:
    """A received frame whose CRC checked out."""

    version: int
    type: int
    seq: int
    body: bytes


@dataclass
class DecoderStats:
    """What the decoder threw away, by cause (counts of frames)."""

    frames: int = 0        # good frames delivered
    crc_errors: int = 0    # COBS fine, CRC-32 wrong
    cobs_errors: int = 0   # malformed stuffing (dropped/inserted bytes)
    short: int = 0         # shorter than header + CRC (truncated frames)
    oversize: int = 0      # longer than max_frame before a delimiter

    @property
    def bad(self) -> int:
        return self.crc_errors + self.cobs_errors + self.short + self.oversize


class FrameDecoder:
    """Incremental receiver: bytes in, verified :class:`Frame` objects out.

    ``feed`` accepts any bytes and never raises; defects are counted in
    :attr:`stats` and, if ``keep_errors`` is set, reported as strings in the
    returned list so a caller can react at once (e.g. send a NAK).
    Memory is bounded: a run of more than ``max_encoded`` bytes without a
    delimiter is discarded up to the next delimiter.
    """

    def __init__(self, max_frame: int = MAX_FRAME):
        self.max_frame = int(max_frame)
        # COBS adds one byte per 254 plus one.
        self.max_encoded = self.max_frame + self.max_frame // 254 + 2
        self._buf = bytearray()
        self._overflow = False
        self.stats = DecoderStats()

    def reset(self) -> None:
        """Forget any partial frame (after a port reopen)."""
        self._buf.clear()
        self._overflow = False

    def feed(self, data: bytes) -> list:
        """Consume ``data``; return the list of good frames and error strings, in order."""
        out: list = []
        start = 0
        n = len(data)
        while start < n:
            end = data.find(b"\x00", start)
            if end < 0:
                chunk = data[start:]
                if not self._overflow:
                    if len(self._buf) + len(chunk) > self.max_encoded:
                        self._overflow = True
                        self._buf.clear()
                    else:
                        self._buf += chunk
                break
            chunk = data[start:end]
            start = end + 1
            if self._overflow or len(self._buf) + len(chunk) > self.max_encoded:
                self._overflow = False
                self._buf.clear()
                self.stats.oversize += 1
                out.append("oversize")
                continue
            self._buf += chunk
            raw = bytes(self._buf)
            self._buf.clear()
            if not raw:
                continue  # back-to-back delimiters: idle line, not an error
            out.append(self._decode(raw))
        return out

    def _decode(self, raw: bytes):
        try:
            payload = cobs_decode(raw)
        except ValueError:
            self.stats.cobs_errors += 1
            return "cobs"
        if len(payload) < MIN_FRAME:
            self.stats.short += 1
            return "short"
        if len(payload) > self.max_frame:
            self.stats.oversize += 1
            return "oversize"
        body, (crc,) = payload[:-4], _CRC.unpack_from(payload, len(payload) - 4)
        if crc32(body) != crc:
            self.stats.crc_errors += 1
            return "crc"
        version, msg_type, seq = HEADER.unpack_from(body)
        self.stats.frames += 1
        return Frame(version, msg_type, seq, body[HEADER.size:])
