"""Host <-> emulated device over a real pty: handshake, upload, streaming and every fault."""
import os
import threading
import time

import numpy as np
import pytest

pytest.importorskip("serial")

from shapedisplay.link import protocol as P
from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig, parse_table_image
from shapedisplay.link.framing import crc32, encode_frame
from shapedisplay.link.host import (DeviceDisconnected, DeviceLink, DeviceRefused, DeviceResetError,
                                      LinkError, LinkTimeout, ProtocolVersionError)
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization


class ProbeEngine:
    """Deterministic device engine for link tests: each tick outputs the table's normal force / 10 N."""

    def __init__(self, table, model, tick_rate_hz, stream_rate_hz, input_kind):
        table.require("normal_force")
        self.table = table
        self.per = max(1, tick_rate_hz // stream_rate_hz)

    def render(self, x, y):
        return np.full(self.per, float(self.table.sample("normal_force", x)) / 10.0)


def make_table(cols=64, seed=0, noise=True):
    rng = np.random.default_rng(seed)
    x = np.linspace(0, 1, cols)
    nf = 0.5 + 2.0 * np.exp(-((x - 0.5) / 0.1) ** 2)
    if noise:
        nf = nf + 0.01 * rng.random(cols)   # incompressible: image size grows with cols
    grid = Grid(1, cols, 1e-3, 1e-3)
    chans = {"normal_force": nf[None, :]}
    q = {"normal_force": choose_quantization(nf, "float32")}
    return FrictionTable.from_dense(grid, chans, q, {"tick_rate_hz": 10000})


@pytest.fixture
def image(tmp_path):
    path = make_table(2048).save(tmp_path / "t.npz")
    return path.read_bytes()


@pytest.fixture
def emu():
    e = DeviceEmulator(EmulatorConfig(max_table_bytes=64 * 1024, chunk_size=256, upload_window=4),
                       engine_factory=ProbeEngine)
    e.start()
    yield e
    e.close()


def make_emu(**kw):
    e = DeviceEmulator(EmulatorConfig(**kw), engine_factory=ProbeEngine)
    e.start()
    return e


@pytest.fixture
def link(emu):
    ln = DeviceLink(emu.port, timeout=0.3, retries=4)
    ln.connect()
    yield ln
    ln.close()


# ------------------------------------------------------------------ basics
def test_handshake_and_caps(link, emu):
    caps = link.caps
    assert caps.version == P.PROTOCOL_VERSION and caps.max_table_bytes == 64 * 1024
    assert caps.chunk_size == 256 and caps.samples_per_cursor == 10 and caps.has_renderer
    st = link.status()
    assert st.state == P.State.IDLE and st.active_crc == 0 and st.boots == emu.boots


def test_parse_table_image_round_trip(image):
    t = parse_table_image(image)
    assert t.channels == ["normal_force"]


def test_upload_commits_exact_image(link, emu, image):
    rep = link.upload(image)
    assert rep.size == len(image) and rep.crc32 == crc32(image)
    assert rep.chunks >= len(image) // 256 and rep.retransmits == 0 and rep.restarts == 0
    st = link.status()
    assert st.active_crc == crc32(image) and st.active_size == len(image)
    assert emu.activations == [(crc32(image), len(image))]
    assert emu.active_table.checksum == parse_table_image(image).checksum


def test_stream_renders_on_device(link, emu, image):
    link.upload(image)
    x = np.linspace(0.0, 2.047, 200)
    rep = link.stream(x, paced=False, monitor=True)
    assert rep.sent == 200 and rep.rendered == 200 and rep.overruns == 0, rep.problems()
    table = parse_table_image(image)
    # Positions travel as float32: compare against the host rendering the same float32 positions.
    x32 = x.astype(np.float32).astype(np.float64)
    want = np.repeat(table.sample("normal_force", x32)[:, None] / 10.0, 10, axis=1).ravel()
    np.testing.assert_array_equal(rep.outputs, want.astype(np.float32).astype(np.float64))
    assert rep.missing_outputs == 0
    assert np.all(np.isfinite(rep.latencies_s))


def test_stream_without_table_refused(link):
    with pytest.raises(DeviceRefused, match="NO_TABLE"):
        link.stream(np.zeros(5), paced=False)


def test_actuator_mode_clipping_reported(link, emu):
    blocks = np.zeros((50, 10))
    blocks[10, :3] = 1.5            # three samples beyond full scale
    rep = link.stream(blocks, mode="actuator", paced=False, monitor=True)
    assert rep.rendered == 50 and rep.clipped == 3
    assert rep.outputs[100] == 1.0 and rep.outputs[103] == 0.0 and rep.outputs.size == 500
    assert any("clipped" in p for p in rep.problems())
    assert any(code == P.Err.CLIPPED for code, _, _ in link.events)


# ------------------------------------------------------------------ faults on the line
@pytest.mark.parametrize("kind", ["corrupt", "drop", "truncate", "duplicate"])
@pytest.mark.parametrize("direction", ["rx", "tx"])
def test_line_faults_during_upload_recovered(link, emu, image, kind, direction):
    emu.inject(kind, direction, count=2, after=3)
    rep = link.upload(image)
    st = link.status()
    assert st.active_crc == crc32(image)
    assert emu.activations == [(crc32(image), len(image))]
    assert emu.counters[f"injected_{direction}_{kind}"] == 2
    if kind != "duplicate" and direction == "rx":
        assert rep.retransmits + link.resends >= 1   # the damage was noticed and repaired
    if kind != "duplicate" and direction == "tx":
        assert link.bad_frames_seen >= 1             # lost acks are covered by later cumulative acks
    if direction == "rx" and kind != "duplicate":
        assert st.rx_bad_frames >= 1
    if kind == "duplicate" and direction == "rx":
        assert st.rx_duplicates >= 1


@pytest.mark.parametrize("kind", ["corrupt", "drop", "truncate", "duplicate"])
def test_line_faults_on_requests_retried(link, emu, kind):
    emu.inject(kind, "rx", count=1)
    assert link.status().state == P.State.IDLE
    emu.inject(kind, "tx", count=1)
    assert link.status().state == P.State.IDLE


def test_duplicated_request_runs_once(link, emu, image):
    link.upload(image)
    new = make_table_bytes(seed=3)
    uid = 77
    link.request(P.Msg.UPLOAD_BEGIN, P.UPLOAD_BEGIN.pack(uid, len(new), crc32(new)), (P.Msg.ACK,))
    for off in range(0, len(new), 256):
        link.request(P.Msg.UPLOAD_CHUNK, P.UPLOAD_CHUNK.pack(uid, off) + new[off:off + 256], (P.Msg.CHUNK_ACK,))
    link.request(P.Msg.UPLOAD_END, P.UPLOAD_END.pack(uid, crc32(new), len(new)), (P.Msg.VERIFIED,))
    wire = encode_frame(P.PROTOCOL_VERSION, P.Msg.COMMIT, 4321, P.UPLOAD_ID.pack(uid))
    link._write(wire + wire)                      # the same COMMIT twice on the line
    replies = [link._get_reply(time.monotonic() + 1.0) for _ in range(2)]
    assert [(r.type, r.seq) for r in replies] == [(P.Msg.ACK, 4321)] * 2
    assert emu.activations == [(crc32(image), len(image)), (crc32(new), len(new))]
    assert link.status().rx_duplicates == 1


def make_table_bytes(seed, cols=128):
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        return make_table(cols, seed).save(os.path.join(d, "t.npz")).read_bytes()


def test_garbage_on_line_is_counted_and_link_survives(link, emu):
    link._write(os.urandom(500).replace(b"\x00", b"\x01") + b"\x00" + b"\x00\x00")
    assert link.status().rx_bad_frames >= 1


# ------------------------------------------------------------------ protocol versions
def test_newer_version_frame_refused_by_device(link, emu):
    seq = link.send_frame(P.Msg.GET_STATUS, version=P.PROTOCOL_VERSION + 1)
    f = link._get_reply(time.monotonic() + 2.0)
    assert f.type == P.Msg.NAK and f.seq == seq
    _, code, detail, text = P.unpack_nak(f.body)
    assert code == P.Err.VERSION and detail == P.PROTOCOL_VERSION and "version 2" in text
    assert link.status().rx_version_errors == 1


def test_newer_device_detected_by_host():
    e = make_emu(protocol_version=P.PROTOCOL_VERSION + 1)
    try:
        ln = DeviceLink(e.port, timeout=0.3, retries=1)
        with pytest.raises(ProtocolVersionError, match="speaks protocol 2"):
            ln.connect()
        ln.close()
    finally:
        e.close()


# ------------------------------------------------------------------ device memory and resets
def test_table_larger_than_device_memory(link, emu, tmp_path):
    big = make_table_bytes(seed=1, cols=30000)
    assert len(big) > 64 * 1024
    with pytest.raises(DeviceRefused, match="exceeds the device memory"):
        link.upload(big)
    # The device refuses it too if a host skips the check.
    seq = link.send_frame(P.Msg.UPLOAD_BEGIN, P.UPLOAD_BEGIN.pack(7, len(big), crc32(big)))
    f = link._get_reply(time.monotonic() + 2.0)
    assert f.type == P.Msg.NAK and P.unpack_nak(f.body)[1] == P.Err.TOO_LARGE
    assert link.status().active_crc == 0 and emu.activations == []


def test_reset_mid_upload_restarts_and_never_activates_partial(link, emu, image):
    old = make_table_bytes(seed=5)
    link.upload(old)
    emu.reset_after_chunks = 5
    rep = link.upload(image)
    assert rep.restarts == 1
    assert emu.activations == [(crc32(old), len(old)), (crc32(image), len(image))]
    assert link.status().active_crc == crc32(image)


def test_reset_mid_upload_without_restart_keeps_old_table(link, emu, image):
    old = make_table_bytes(seed=6)
    link.upload(old)
    emu.reset_after_chunks = 3
    with pytest.raises(DeviceResetError, match="no new table is active"):
        link.upload(image, restarts=0)
    link.connect()
    st = link.status()
    assert st.active_crc == crc32(old) and st.state == P.State.IDLE and st.staged_bytes == 0
    assert emu.activations == [(crc32(old), len(old))]


def test_commit_without_verified_upload_refused(link, emu, image):
    # docs/protocol.md: no staged upload of that id is NO_UPLOAD; one whose END has not succeeded, NOT_VERIFIED.
    with pytest.raises(DeviceRefused, match="NO_UPLOAD"):
        link.request(P.Msg.COMMIT, P.UPLOAD_ID.pack(1), (P.Msg.ACK,))
    link.request(P.Msg.UPLOAD_BEGIN, P.UPLOAD_BEGIN.pack(9, 4, 0x1234), (P.Msg.ACK,))
    link.request(P.Msg.UPLOAD_CHUNK, P.UPLOAD_CHUNK.pack(9, 0) + b"abcd", (P.Msg.CHUNK_ACK,))
    with pytest.raises(DeviceRefused, match="NOT_VERIFIED"):
        link.request(P.Msg.COMMIT, P.UPLOAD_ID.pack(9), (P.Msg.ACK,))
    with pytest.raises(DeviceRefused, match="NO_UPLOAD"):
        link.request(P.Msg.COMMIT, P.UPLOAD_ID.pack(8), (P.Msg.ACK,))       # another id
    # An upload whose whole-table CRC disagrees is discarded at END: nothing is staged after it.
    with pytest.raises(DeviceRefused, match="CHECKSUM"):
        link.request(P.Msg.UPLOAD_END, P.UPLOAD_END.pack(9, 0x1234, 4), (P.Msg.VERIFIED,))
    with pytest.raises(DeviceRefused, match="NO_UPLOAD"):
        link.request(P.Msg.COMMIT, P.UPLOAD_ID.pack(9), (P.Msg.ACK,))
    assert emu.activations == []


def test_commit_after_reset_answers_no_upload(link, emu, image):
    uid = 21
    link.request(P.Msg.UPLOAD_BEGIN, P.UPLOAD_BEGIN.pack(uid, len(image), crc32(image)), (P.Msg.ACK,))
    for off in range(0, len(image), 256):
        link.request(P.Msg.UPLOAD_CHUNK, P.UPLOAD_CHUNK.pack(uid, off) + image[off:off + 256], (P.Msg.CHUNK_ACK,))
    link.request(P.Msg.UPLOAD_END, P.UPLOAD_END.pack(uid, crc32(image), len(image)), (P.Msg.VERIFIED,))
    emu.reset()                      # the verified upload is lost; the active table (none) stays
    link.connect()
    with pytest.raises(DeviceRefused, match="NO_UPLOAD") as info:
        link.request(P.Msg.COMMIT, P.UPLOAD_ID.pack(uid), (P.Msg.ACK,))
    assert info.value.code == P.Err.NO_UPLOAD
    assert emu.activations == [] and link.status().active_crc == 0


@pytest.mark.parametrize("how", [True, "boot lost"])
def test_reset_between_verify_and_commit_restarts_the_upload(link, emu, image, how):
    old = make_table_bytes(seed=7)
    link.upload(old)
    emu.reset_after_verify = how         # BOOT seen, or lost: then COMMIT answers NO_UPLOAD, the old table active
    rep = link.upload(image)
    assert rep.restarts == 1 and not rep.commit_confirmed_by_status
    assert emu.activations == [(crc32(old), len(old)), (crc32(image), len(image))]
    assert link.status().active_crc == crc32(image)


def test_corrupt_table_image_rejected_before_commit(link, emu, image):
    bad = bytearray(image)
    bad[len(bad) // 2] ^= 0xFF          # consistent CRC-32 of a damaged file: the table checksum catches it
    with pytest.raises(DeviceRefused, match="TABLE_INVALID"):
        link.upload(bytes(bad))
    assert emu.activations == [] and link.status().active_crc == 0


def test_reset_device_and_reconnect(link, emu, image):
    link.upload(image)
    boots = emu.boots
    link.reset_device()
    assert emu.boots == boots + 1 and link.device_boots == boots + 1
    assert link.status().active_crc == crc32(image)       # committed table survives (flash)
    link.reconnect()
    assert link.status().boots == boots + 1


# ------------------------------------------------------------------ streaming faults
def test_fast_stream_with_backpressure_has_no_overrun(link, emu, image):
    link.upload(image)
    x = np.linspace(0, 0.2, 400)
    rep = link.stream(x, paced=False, backpressure=True, per_frame=8)
    assert rep.overruns == 0 and rep.rendered == 400
    assert rep.backpressure_waits > 0           # the host had to wait for the device


def test_fast_stream_without_backpressure_reports_overrun(link, emu, image):
    link.upload(image)
    x = np.linspace(0, 0.2, 600)
    rep = link.stream(x, paced=False, backpressure=False, per_frame=20)
    assert rep.overruns > 0 and rep.rendered == 600 - rep.overruns
    assert any("faster than the device renders" in p for p in rep.problems())
    assert any(code == P.Err.OVERRUN for code, _, _ in link.events)


def test_underrun_reported_when_host_stalls(link, emu, image):
    link.upload(image)
    link.start()
    link.send_frame(P.Msg.CURSOR, P.pack_cursor(0, 0, 0.1, 0.0))
    time.sleep(0.05)                             # ~50 render periods without samples
    link.send_frame(P.Msg.CURSOR, P.pack_cursor(1, 1000, 0.1, 0.0))
    link.stop()
    st = link.status()
    assert st.underruns >= 10 and st.samples_rendered == 2


def test_duplicated_cursor_frames_rendered_once(link, emu, image):
    link.upload(image)
    emu.inject("duplicate", "rx", count=5, after=2)
    rep = link.stream(np.linspace(0, 0.1, 50), paced=False)
    assert rep.rendered == 50 and rep.duplicates >= 5


def test_reset_during_stream_stops_cleanly(link, emu, image):
    link.upload(image)
    t = threading.Timer(0.05, emu.reset)
    t.start()
    with pytest.raises(DeviceResetError, match="reset during streaming"):
        link.stream(np.linspace(0, 0.1, 2000), paced=True)
    t.join()
    link.connect()
    assert link.status().state == P.State.IDLE


def test_port_disappearing_mid_stream(link, emu, image):
    link.upload(image)
    t = threading.Timer(0.05, emu.vanish)
    t.start()
    t0 = time.monotonic()
    with pytest.raises((DeviceDisconnected, LinkTimeout)):
        link.stream(np.linspace(0, 0.1, 5000), paced=True)
    t.join()
    assert time.monotonic() - t0 < 20
    link.close()
    link.close()   # idempotent


def test_port_disappearing_while_idle_then_request(emu):
    ln = DeviceLink(emu.port, timeout=0.2, retries=1)
    ln.connect()
    emu.vanish()
    with pytest.raises((DeviceDisconnected, LinkTimeout)):
        ln.status()
    ln.close()


def test_open_missing_port_is_one_line_error(tmp_path):
    with pytest.raises(DeviceDisconnected, match="cannot open"):
        DeviceLink(str(tmp_path / "no-such-tty")).connect()


def test_loopback_url_is_recognised():
    ln = DeviceLink("loop://", timeout=0.2, retries=0)
    with pytest.raises(LinkError, match="loopback"):
        ln.connect()
    ln.close()


def test_silent_port_times_out(tmp_path):
    master, slave = os.openpty()
    try:
        ln = DeviceLink(os.ttyname(slave), timeout=0.1, retries=2)
        with pytest.raises(LinkTimeout, match="did not answer HELLO after 3 tries"):
            ln.connect()
        ln.close()
    finally:
        os.close(master)
        os.close(slave)


def test_port_disappearing_mid_upload(link, emu, image):
    emu.vanish_after_chunks = 4
    t0 = time.monotonic()
    with pytest.raises((DeviceDisconnected, LinkTimeout)) as exc:
        link.upload(image)
    assert time.monotonic() - t0 < 20
    assert emu.activations == [] and emu.active_table is None
    assert "disappeared" in str(exc.value) or "no new table is active" in str(exc.value)
    link.close()


def test_two_closers_at_once_close_each_pty_end_once(monkeypatch):
    """The device vanishing in its own thread while its owner closes it: each descriptor is closed once
    (a second close would hit whatever file the process opened next under that number)."""
    from shapedisplay.link import emulator as emulator_module
    closed = []
    real_close = os.close

    def slow_close(fd):
        closed.append(fd)
        time.sleep(0.02)               # widen the window in which a second closer could read the same fd
        real_close(fd)

    e = DeviceEmulator(EmulatorConfig(renderer=False), engine_factory=ProbeEngine)
    e.start()
    ends = (e._master, e._slave)
    monkeypatch.setattr(emulator_module.os, "close", slow_close)
    go = threading.Barrier(2)

    def closer():
        go.wait()
        e.close()

    threads = [threading.Thread(target=closer) for _ in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(30)
    assert sorted(closed) == sorted(ends)
    assert e._master is None and e._slave is None


def test_device_without_renderer_plays_actuator_streams_only(image):
    e = DeviceEmulator(EmulatorConfig(renderer=False), engine_factory=ProbeEngine)
    e.start()
    try:
        with DeviceLink(e.port, timeout=0.5) as ln:
            assert not ln.caps.has_renderer and ln.caps.models == ()
            ln.upload(image)                            # it still stores and verifies tables
            with pytest.raises(DeviceRefused, match="no renderer"):
                ln.start()
            rep = ln.stream(np.full((20, 10), 0.25), mode="actuator", paced=False, monitor=True)
            assert rep.rendered == 20 and np.all(rep.outputs == 0.25)
    finally:
        e.close()


@pytest.mark.parametrize("kw, field", [({"stream_rate_hz": 0}, "stream_rate_hz"), ({"chunk_size": 5000}, "chunk_size"),
                                       ({"tick_rate_hz": 10_000, "stream_rate_hz": 3000}, "multiple"),
                                       ({"queue_capacity": 0}, "queue_capacity")])
def test_emulator_config_checked(kw, field):
    from shapedisplay.errors import InputError
    with pytest.raises(InputError, match=field):
        EmulatorConfig(**kw)


def test_link_arguments_checked():
    from shapedisplay.errors import InputError
    with pytest.raises(InputError, match="timeout"):
        DeviceLink("loop://", timeout=0)


def test_missing_pyserial_is_one_line_install_hint(monkeypatch):
    import sys
    from shapedisplay.errors import MissingDependencyError
    monkeypatch.setitem(sys.modules, "serial", None)      # import serial -> ImportError
    with pytest.raises(MissingDependencyError, match=r"The device link needs serial: pip install 'shapedisplay\[serial\]'"):
        DeviceLink("loop://").connect()


def test_import_does_not_load_pyserial():
    import subprocess
    import sys
    code = ("import sys, shapedisplay.link.host, shapedisplay.link.emulator, shapedisplay.link.protocol; "
            "print('serial' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60).stdout.strip()
    assert out == "False"


def test_reconnect_after_device_reenumerates(tmp_path, image):
    """A USB device that resets disappears and comes back under its stable name; the host reconnects."""
    e = DeviceEmulator(EmulatorConfig(), engine_factory=ProbeEngine)
    stable = str(tmp_path / "ttySHAPE0")
    e.open_pty(link=stable)
    e.start()
    try:
        ln = DeviceLink(stable, timeout=0.3, retries=2)
        ln.connect()
        ln.upload(image)
        old_tty, boots = e.tty, e.boots
        t = threading.Timer(0.05, e.replug, kwargs={"gone_s": 0.3})
        t.start()
        with pytest.raises((DeviceDisconnected, LinkTimeout, DeviceResetError)):
            ln.stream(np.linspace(0, 0.1, 3000), paced=True)
        t.join()
        caps = ln.reconnect(wait_s=5.0)
        assert e.tty != old_tty and e.boots == boots + 1 and caps.version == P.PROTOCOL_VERSION
        st = ln.status()
        assert st.active_crc == crc32(image) and st.state == P.State.IDLE   # the committed table survived
        rep = ln.stream(np.linspace(0, 0.1, 50), paced=False)
        assert rep.rendered == 50
        ln.close()
    finally:
        e.close()


def test_host_gone_mid_stream_and_mid_upload_does_not_block_the_next_host(link, emu, image):
    """A host killed while streaming (or uploading) leaves the device busy; the next HELLO ends that."""
    link.upload(image)
    link.start("cursor")
    link.send_frame(P.Msg.CURSOR, P.pack_cursor(np.arange(3), np.arange(3) * 1000, np.zeros(3), np.zeros(3)))
    link.close()                                   # gone without STOP
    with DeviceLink(emu.port, timeout=0.3, retries=4) as ln:
        assert ln.status().state == P.State.IDLE
        rep = ln.stream(np.linspace(0, 0.1, 20), paced=False)
        assert rep.rendered == 20
        ln.request(P.Msg.UPLOAD_BEGIN, P.UPLOAD_BEGIN.pack(7, len(image), crc32(image)), (P.Msg.ACK,))
        assert ln.status().state == P.State.UPLOADING
    with DeviceLink(emu.port, timeout=0.3, retries=4) as ln:   # gone mid-upload: staging discarded
        st = ln.status()
        assert st.state == P.State.IDLE and st.staged_bytes == 0 and st.active_crc == crc32(image)
        assert ln.stream(np.linspace(0, 0.1, 20), paced=False).rendered == 20
    assert emu.activations == [(crc32(image), len(image))]


def test_damaged_cursor_frames_reported_as_crc_failures(link, emu, image):
    link.upload(image)
    emu.inject("corrupt", "rx", count=3, after=5)
    rep = link.stream(np.linspace(0, 0.1, 60), paced=False)
    assert rep.bad_frames == 3 and rep.rendered == 57
    assert any("3 damaged frames" in line for line in rep.problems())


def test_hung_device_that_stops_reading_is_a_timeout_not_a_hang(monkeypatch):
    """A port that is there but never drained (a frozen device): writes time out with one clear error."""
    from shapedisplay.link import host
    monkeypatch.setattr(host, "WRITE_TIMEOUT_S", 0.3)
    master, slave = os.openpty()          # nobody ever reads the master side
    try:
        ln = DeviceLink(os.ttyname(slave), timeout=0.2, retries=0)
        ln.open()
        t0 = time.monotonic()
        with pytest.raises(LinkTimeout, match="stopped reading"):
            for _ in range(10_000):
                ln.send_frame(P.Msg.CURSOR, bytes(2000))
        assert time.monotonic() - t0 < 10
        ln.close()
    finally:
        os.close(master)
        os.close(slave)


def test_random_requests_never_crash_the_device(link, emu, image):
    """1500 well-framed requests of random type and body: each is refused by validation (no handler
    exception), the committed table survives, and a new host still gets a clean session."""
    import random
    link.upload(image)
    rng = random.Random(7)
    types = [int(t) for t in P.Msg if int(t) < 0x80 and t != P.Msg.RESET]
    for i in range(1500):
        body = bytes(rng.randrange(256) for _ in range(rng.choice([0, 1, 2, 3, 6, 10, 12, 20, 40])))
        link.send_frame(rng.choice(types), body)
        if i % 100 == 99:
            time.sleep(0.01)
    link.close()
    with DeviceLink(emu.port, timeout=0.3, retries=4) as ln:
        st = ln.status()
        assert st.state == P.State.IDLE and st.active_crc == crc32(image)
        assert ln.stream(np.linspace(0, 0.1, 20), paced=False).rendered == 20
    assert not [line for line in emu.log if "handler error" in line]
    assert emu.activations == [(crc32(image), len(image))]


def test_emulator_config_from_text_checks_every_rule():
    from shapedisplay.errors import InputError
    cfg = EmulatorConfig.from_text(memory="64 KiB", tick_rate="20 kHz", stream_rate="2 kHz", queue=16)
    assert (cfg.max_table_bytes, cfg.tick_rate_hz, cfg.stream_rate_hz, cfg.samples_per_cursor) == (65536, 20000, 2000, 10)
    for kw, rule in (({"tick_rate": "10 kHz", "stream_rate": "3 kHz"}, "multiple"),
                     ({"tick_rate": "1000.5 Hz", "stream_rate": "1000.5 Hz"}, "whole number of hertz"),
                     ({"tick_rate": "400 kHz"}, r"`tick_rate_hz` must be an integer in 100\.\.192000"),
                     ({"memory": "12 parsecs"}, "`memory`"), ({"queue": 0}, "`queue_capacity`"),
                     ({"model": "exactt"}, "did you mean 'exact'")):
        with pytest.raises(InputError, match=rule):
            EmulatorConfig.from_text(**kw)
    assert EmulatorConfig.from_text(model="none-needed", renderer=False).renderer is False


def test_each_stream_problem_says_what_to_do():
    """The warnings `device play` prints name the cause and the action, not only the count."""
    from shapedisplay.link.host import StreamReport
    rep = StreamReport(sent=1000, rendered=900, underruns=443, overruns=50, clipped=7, bad_frames=3)
    lines = rep.problems()
    assert len(lines) == 5
    under = next(p for p in lines if "without a new cursor sample" in p)
    assert "443 of 1343" in under and "busy computer" in under and "Play again" in under
    assert "lower the burst gain" in next(p for p in lines if "clipped" in p)
    assert "check the cable" in next(p for p in lines if "damaged" in p)
    assert "backpressure" in next(p for p in lines if "dropped" in p)
    assert "device info PORT" in lines[-1]
    assert StreamReport(sent=10, rendered=10).problems() == []
