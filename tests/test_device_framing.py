"""Framing of the device link: COBS, CRC-32, the incremental decoder, message bodies."""
import struct

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st, HealthCheck

from shapedisplay.link import framing, protocol
from shapedisplay.link.framing import (Frame, FrameDecoder, cobs_decode, cobs_encode, crc32,
                                         encode_frame)

FUZZ = settings(max_examples=1000, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def test_crc32_check_value():
    # The standard CRC-32 check value of "123456789".
    assert crc32(b"123456789") == 0xCBF43926


@pytest.mark.parametrize("data, encoded", [
    (b"", b"\x01"),
    (b"\x00", b"\x01\x01"),
    (b"\x00\x00", b"\x01\x01\x01"),
    (b"\x11\x22\x00\x33", b"\x03\x11\x22\x02\x33"),
    (b"\x11\x22\x33\x44", b"\x05\x11\x22\x33\x44"),
    (b"\x11\x00\x00\x00", b"\x02\x11\x01\x01\x01"),
])
def test_cobs_known_vectors(data, encoded):
    # Vectors from Cheshire & Baker's COBS paper / the Wikipedia table.
    assert cobs_encode(data) == encoded
    assert cobs_decode(encoded) == data


@pytest.mark.parametrize("n", [253, 254, 255, 508, 509, 1000])
def test_cobs_long_runs(n):
    data = bytes(range(1, 256)) * 4
    data = data[:n]
    enc = cobs_encode(data)
    assert 0 not in enc
    assert len(enc) <= n + n // 254 + 1
    assert cobs_decode(enc) == data


@given(st.binary(max_size=700))
@settings(max_examples=400, deadline=None)
def test_cobs_round_trip(data):
    enc = cobs_encode(data)
    assert 0 not in enc
    assert cobs_decode(enc) == data


@given(st.integers(0, 255), st.integers(0, 255), st.integers(0, 0xFFFF), st.binary(max_size=300))
@settings(max_examples=300, deadline=None)
def test_frame_round_trip(version, msg_type, seq, body):
    wire = encode_frame(version, msg_type, seq, body)
    assert wire.count(0) == 1 and wire.endswith(b"\x00")
    assert FrameDecoder().feed(wire) == [Frame(version, msg_type, seq, body)]


def test_frame_too_large_refused():
    with pytest.raises(ValueError, match="MAX_FRAME"):
        encode_frame(1, 2, 3, bytes(framing.MAX_FRAME))


def test_decoder_split_feeding_and_idle_delimiters():
    frames = [encode_frame(1, t, t * 7, bytes([t]) * t) for t in range(1, 40)]
    wire = b"\x00\x00" + b"\x00".join(frames)
    dec = FrameDecoder()
    got = []
    for i in range(0, len(wire), 3):
        got += dec.feed(wire[i:i + 3])
    assert [f.type for f in got] == list(range(1, 40))
    assert dec.stats.bad == 0


def test_each_single_bit_flip_is_detected():
    wire = encode_frame(1, 0x11, 42, bytes(range(200)))
    for pos in range(len(wire) - 1):
        for bit in range(8):
            bad = bytearray(wire)
            bad[pos] ^= 1 << bit
            dec = FrameDecoder()
            out = dec.feed(bytes(bad))
            # A flip may create a zero (splitting the frame) but never a good frame.
            assert not any(isinstance(o, Frame) for o in out), (pos, bit)


def test_dropped_byte_truncation_and_resync():
    good = encode_frame(1, 5, 1, b"payload")
    nxt = encode_frame(1, 6, 2, b"next")
    dec = FrameDecoder()
    # Dropped byte, then a truncated frame running into the next one, then a clean frame.
    out = dec.feed(good[:3] + good[4:] + good[:5] + nxt + good)
    frames = [o for o in out if isinstance(o, Frame)]
    assert [f.type for f in frames] == [5]     # only the last, clean frame
    assert dec.stats.bad == 2


def test_short_frame_counted():
    dec = FrameDecoder()
    assert dec.feed(cobs_encode(b"\x01\x02") + b"\x00") == ["short"]
    assert dec.stats.short == 1


def test_oversize_run_is_dropped_and_decoder_recovers():
    dec = FrameDecoder(max_frame=64)
    out = dec.feed(b"\x05" * 1000)
    assert out == [] and len(dec._buf) == 0
    out = dec.feed(b"\x00" + encode_frame(1, 9, 9, b"ok"))
    assert out[0] == "oversize" and out[1] == Frame(1, 9, 9, b"ok")


@given(st.lists(st.one_of(st.binary(max_size=80),
                          st.sampled_from([b"\x00", encode_frame(1, 0x22, 3, b"abc")])), max_size=12))
@FUZZ
def test_fuzz_decoder_never_raises(chunks):
    dec = FrameDecoder(max_frame=128)
    for c in chunks:
        for item in dec.feed(c):
            assert isinstance(item, (Frame, str))
        assert len(dec._buf) <= dec.max_encoded
    # A clean frame after any garbage and a delimiter is always recovered.
    out = dec.feed(b"\x00" + encode_frame(1, 7, 7, b"sync"))
    assert out[-1] == Frame(1, 7, 7, b"sync")


@given(st.binary(min_size=1, max_size=300), st.data())
@FUZZ
def test_fuzz_mutated_frames_never_pass_as_different_good_frames(body, data):
    wire = bytearray(encode_frame(1, 0x11, 5, body))
    n_mut = data.draw(st.integers(1, 4))
    for _ in range(n_mut):
        kind = data.draw(st.sampled_from(["flip", "drop", "insert"]))
        pos = data.draw(st.integers(0, len(wire) - 1))
        if kind == "flip":
            wire[pos] ^= data.draw(st.integers(1, 255))
        elif kind == "drop" and len(wire) > 1:
            del wire[pos]
        else:
            wire.insert(pos, data.draw(st.integers(0, 255)))
    out = FrameDecoder().feed(bytes(wire))
    for item in out:
        if isinstance(item, Frame):
            # CRC-32 lets corruption through with odds 2^-32: any good frame must be the original.
            assert item == Frame(1, 0x11, 5, body)


@given(st.binary(max_size=64))
@settings(max_examples=1000, deadline=None)
def test_fuzz_body_parsers_raise_only_valueerror(body):
    for parse in (protocol.Caps.unpack, protocol.Status.unpack, protocol.unpack_cursor,
                  protocol.unpack_nak, protocol.unpack_event, protocol.unpack_samples):
        try:
            parse(body)
        except (ValueError, struct.error):
            pass


def test_caps_and_status_round_trip():
    caps = protocol.Caps(1, 1, protocol.CAP_RENDERER | protocol.CAP_MONITOR, 65536, 1024, 4, 64,
                         1000, 10000, 10, name="emu", firmware="0.1", models=("jump", "exact"))
    assert protocol.Caps.unpack(caps.pack()) == caps
    st_ = protocol.Status(*range(17))
    assert protocol.Status.unpack(st_.pack()) == st_


def test_cursor_pack_round_trip():
    body = protocol.pack_cursor([1, 2], [1000, 2000], [0.01, 0.02], [0.0, -0.5])
    rec = protocol.unpack_cursor(body)
    assert rec["index"].tolist() == [1, 2] and rec["t_us"].tolist() == [1000, 2000]
    assert np.allclose(rec["x"], [0.01, 0.02]) and rec["y"][1] == -0.5
    with pytest.raises(ValueError):
        protocol.unpack_cursor(body[:-1])


def test_bulk_random_fuzz_of_the_decoder():
    """20 000 random inputs (bytes with many delimiters, valid frames cut at random) on top of the
    hypothesis runs: the decoder never raises, stays bounded, and always resyncs on a clean frame."""
    rng = np.random.default_rng(2024)
    good = encode_frame(1, 0x22, 3, b"abc")
    dec = FrameDecoder(max_frame=128)
    for i in range(20_000):
        n = int(rng.integers(0, 120))
        data = bytearray(rng.integers(0, 256, n, dtype=np.uint8).tobytes())
        if n and i % 3 == 0:
            for pos in rng.integers(0, n, 1 + n // 16):
                data[pos] = 0                                          # many delimiters
        if i % 5 == 0:
            cut = int(rng.integers(0, len(good)))
            data += good[:cut] if i % 2 else good[cut:]               # truncated frame
        for item in dec.feed(bytes(data)):
            assert isinstance(item, (Frame, str))
        assert len(dec._buf) <= dec.max_encoded
        if i % 1000 == 999:
            assert dec.feed(b"\x00" + encode_frame(1, 7, i, b"sync"))[-1] == Frame(1, 7, i, b"sync")
    assert dec.stats.bad > 1000
