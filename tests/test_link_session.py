"""shapedisplay.link.session against the device emulator on a pty: what is uploaded, played and recorded."""
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("serial")

from shapedisplay.errors import FileFormatError, InputError, TableError
from shapedisplay.link import emulator as emulator_module
from shapedisplay.link import session
from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig
from shapedisplay.link.engine import actuator_blocks, render_stream
from shapedisplay.link.framing import crc32
from shapedisplay.link.host import DeviceRefused
from shapedisplay.link.session import DeviceSession, read_recording
from shapedisplay.render import Renderer, parse_stroke
from test_device_render import f32, tent_table

STROKE = "5,0 -> 25,0 @ 200 mm/s"          # 20 mm in 0.1 s: 101 cursor samples at 1 kHz


@pytest.fixture(scope="module")
def table():
    return tent_table()


@pytest.fixture
def table_path(table, tmp_path):
    return table.save(tmp_path / "tent.npz")


def _emulator(**config):
    emu = DeviceEmulator(EmulatorConfig(**config))
    emu.start()
    return emu


@pytest.fixture
def emu():
    e = _emulator(model="jump")
    yield e
    e.close()


@pytest.fixture
def received(monkeypatch):
    """Every table image the emulated firmware verified, as the bytes it received."""
    seen = []
    real = emulator_module.parse_table_image

    def spy(image, max_bytes=None):
        seen.append(bytes(image))
        return real(image, max_bytes)

    monkeypatch.setattr(emulator_module, "parse_table_image", spy)
    return seen


def _played(emu) -> np.ndarray:
    """The drive of every tick the emulator rendered, in order (float64, before the wire's float32)."""
    return np.concatenate([s for _, s in sorted(emu.outputs, key=lambda item: item[0])])


# ------------------------------------------------------------------ upload
def test_upload_sends_the_table_file_bytes(emu, table_path, received):
    image = Path(table_path).read_bytes()
    with DeviceSession(emu.port, timeout=2.0) as dev:
        rep = dev.upload(table_path)
        assert dev.is_active(table_path)
        st = dev.status()
    assert received == [image]
    assert rep.size == len(image) and rep.crc32 == crc32(image) and rep.chunks >= 1
    assert (st.active_crc, st.active_size) == (crc32(image), len(image))
    assert emu.activations == [(crc32(image), len(image))]


def test_upload_of_a_table_in_memory_and_of_a_binary_image(emu, table, tmp_path, received):
    from shapedisplay.render.image import export_image, to_image
    bin_path = export_image(table, tmp_path / "tent.sdt")
    rep = session.upload(table, emu.port, timeout=2.0)                 # the shortcut: open, upload, close
    assert received[-1] == table.to_bytes() and rep.crc32 == crc32(table.to_bytes())
    session.upload(bin_path, emu.port, timeout=2.0)
    assert received[-1] == Path(bin_path).read_bytes() == to_image(table)
    session.upload(to_image(table), emu.port, timeout=2.0)            # bytes as given
    assert received[-1] == to_image(table)
    assert [a[0] for a in emu.activations] == [crc32(table.to_bytes()), crc32(to_image(table)),
                                               crc32(to_image(table))]


def test_checksum_mismatch_is_one_line_and_nothing_is_sent(emu, table_path, tmp_path, received):
    with np.load(table_path) as z:
        arrays = dict(z)
    arrays["normal_force"] = arrays["normal_force"].copy()
    arrays["normal_force"].flat[0] ^= 1                    # one stored code changed, header kept
    tampered = tmp_path / "tampered.npz"
    np.savez(tampered, **arrays)
    with DeviceSession(emu.port, timeout=2.0) as dev:
        for call in (lambda: dev.upload(tampered), lambda: dev.play(tampered, STROKE)):
            with pytest.raises(TableError) as exc:
                call()
            msg = str(exc.value)
            assert "checksum mismatch" in msg and str(tampered) in msg and len(msg.splitlines()) == 1
        assert dev.link.caps is None                       # the port was never even greeted
    with pytest.raises(TableError, match="checksum mismatch"):
        session.upload(tampered.read_bytes(), emu.port)
    assert received == [] and emu.activations == []


def test_table_larger_than_the_device_memory_is_refused_before_sending(table, received):
    emu = _emulator(max_table_bytes=1024)
    try:
        with pytest.raises(DeviceRefused, match="exceeds the device memory of 1024 bytes.*nothing uploaded"):
            session.upload(table, emu.port, timeout=2.0)
        assert received == [] and emu.activations == []
    finally:
        emu.close()


# ------------------------------------------------------------------ play
def test_play_records_what_the_device_played(emu, table, table_path, tmp_path, received):
    emu.record_outputs = True
    uploads = []
    out = tmp_path / "played.npz"
    with DeviceSession(emu.port, timeout=2.0) as dev:
        rep = dev.play(table_path, STROKE, record=out, on_upload=uploads.append)
    assert rep.upload is not None and uploads == [rep.upload]
    assert received == [Path(table_path).read_bytes()]
    assert rep.record == out and rep.sent == rep.rendered == 101 and rep.overruns == 0, rep.problems()
    rec = read_recording(out)
    played = _played(emu)
    assert played.size == 1 + 100 * 10 and np.count_nonzero(played) > 100        # bursts were played
    np.testing.assert_array_equal(rec["drive"], f32(played))                       # the wire carries float32
    np.testing.assert_array_equal(rec["drive"], rep.drive)
    # and what the device played is the renderer's drive for that stroke
    cursor = parse_stroke(STROKE, 1000.0)
    host = render_stream(Renderer(table, model="jump", tick_rate=10_000.0), f32(cursor.x), f32(cursor.y), 10)
    np.testing.assert_array_equal(rec["drive"], f32(host))
    assert rec["tick_rate_hz"] == 10_000 and rec["stream_rate_hz"] == 1000
    assert rec["latency_s"].shape == (101,) and np.all(rec["latency_s"] > 0)
    with np.load(out) as z:                                # a plain .npz, as before
        assert sorted(z.files) == sorted(session.RECORDING_ARRAYS)


def test_play_uploads_only_when_the_table_is_not_active(emu, table_path, received):
    with DeviceSession(emu.port, timeout=2.0) as dev:
        first = dev.play(table_path, STROKE)
        second = dev.play(table_path, STROKE)
    assert first.upload is not None and second.upload is None
    assert len(received) == 1 and len(emu.activations) == 1
    assert first.drive is None and first.record is None                     # nothing asked to be recorded


def test_play_actuator_mode_streams_the_host_render(table, table_path, tmp_path, received):
    emu = _emulator(renderer=False)                        # a device that only plays actuator streams
    emu.record_outputs = True
    try:
        with DeviceSession(emu.port, timeout=2.0) as dev:
            with pytest.raises(InputError, match="has no renderer; use --mode actuator"):
                dev.play(table_path, STROKE)
            rep = dev.play(table_path, STROKE, mode="actuator", record=tmp_path / "a.npz")
        assert rep.upload is None and received == [] and rep.sent == rep.rendered == 100
        cursor = parse_stroke(STROKE, 1000.0)
        blocks = actuator_blocks(Renderer(table, model="jump", tick_rate=10_000.0), cursor.x, cursor.y, 10)
        rec = read_recording(tmp_path / "a.npz")
        np.testing.assert_array_equal(rec["drive"], f32(blocks.ravel()))
        np.testing.assert_array_equal(rec["drive"], f32(_played(emu)))
    finally:
        emu.close()


def test_play_shortcut_takes_a_cursor_path_at_the_stream_rate(emu, table, received):
    rep = session.play(table, parse_stroke(STROKE, 1000.0), emu.port, timeout=2.0)
    assert rep.rendered == 101 and received == [table.to_bytes()]
    with pytest.raises(InputError, match="sampled at 10000.0 Hz.*1000 Hz"):
        session.play(table, parse_stroke(STROKE, 10_000.0), emu.port, timeout=2.0)


@pytest.mark.parametrize("kwargs, stroke, message", [
    ({"record": "/no/such/dir/p.npz"}, STROKE, "directory '/no/such/dir' does not exist"),
    ({}, "0,0 -> 10,0", "needs a speed"),
    ({"mode": "audio"}, STROKE, "`mode` must be one of cursor, actuator"),
])
def test_bad_input_is_refused_before_anything_is_uploaded(emu, table_path, received, kwargs, stroke, message):
    with DeviceSession(emu.port, timeout=2.0) as dev:
        with pytest.raises(InputError) as exc:
            dev.play(table_path, stroke, **kwargs)
    assert message in str(exc.value) and len(str(exc.value).splitlines()) == 1
    assert received == [] and emu.activations == []


# ------------------------------------------------------------------ recordings
def test_recording_round_trip_and_foreign_files(tmp_path, table_path):
    drive = np.linspace(-1, 1, 21)
    lat = np.array([1e-3, np.nan, 2e-3])
    path = session.write_recording(tmp_path / "r.npz", drive, lat, 10_000, 1000)
    rec = read_recording(path)
    np.testing.assert_array_equal(rec["drive"], drive)
    np.testing.assert_array_equal(rec["latency_s"], lat)                  # a lost OUTPUT stays NaN
    assert (rec["tick_rate_hz"], rec["stream_rate_hz"]) == (10_000, 1000)
    with pytest.raises(FileFormatError, match="this is a table, not a device recording"):
        read_recording(table_path)
    with pytest.raises(FileFormatError, match="no such file"):
        read_recording(tmp_path / "missing.npz")
    with pytest.raises(FileFormatError, match="directory .* does not exist"):
        session.write_recording(tmp_path / "no" / "r.npz", drive, lat, 10_000, 1000)
