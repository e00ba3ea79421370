"""Every broken or hostile input found by attacking the tool is a regression test here.

Each case: only ShapeDisplayError from the API (exit 2 and one line from the
CLI), nothing with NaN accepted, nothing overwritten, memory bounded.
"""
import copy
import fcntl
import json
import os
import struct
import subprocess
import sys
import textwrap
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hostile import documented_checksum, npy_bytes, npz_bytes, small_table, table_bytes, zip_bomb, zip_of
from shapedisplay.errors import FileFormatError, InputError, ModelError, ShapeDisplayError, TableError
from shapedisplay.table.model import FrictionTable
from shapedisplay.cli.main import main

ROOT = Path(__file__).resolve().parent.parent
TENT = ROOT / "assets" / "maps" / "tent_profile.png"


@pytest.fixture(scope="module")
def table():
    return small_table()


@pytest.fixture(scope="module")
def good(table):
    return table_bytes(table)


def parts(table):
    header = copy.deepcopy(table.header())
    header["checksum"] = documented_checksum(header, table.codes)
    return header, {n: np.array(a) for n, a in table.codes.items()}


def resigned(header, arrays, **kw) -> bytes:
    header = dict(header)
    header["checksum"] = documented_checksum(header, arrays)
    return npz_bytes(header, arrays, **kw)


def refused(data: bytes, match: str, cls=TableError):
    with pytest.raises(cls, match=match) as info:
        FrictionTable.from_bytes(data)
    assert "\n" not in str(info.value)
    return str(info.value)


def test_good_table_reads(table, good):
    t = FrictionTable.from_bytes(good)
    assert t.checksum == table.checksum and t.quant["grad_x"].dtype == "float32"


# ------------------------------------------------------------------ crashes of the old loader
def test_damaged_deflate_stream_is_a_table_error(good):
    """zlib.error from a flipped byte inside a compressed entry."""
    z = zipfile.ZipFile(__import__("io").BytesIO(good))
    info = z.getinfo("grad_x.npy")
    start = info.header_offset + 30 + len(info.filename) + len(info.extra)
    bad = bytearray(good)
    for i in range(start + 2, start + min(info.compress_size, 40)):
        bad[i] ^= 0x5A
    refused(bytes(bad), r"entry 'grad_x': unreadable or truncated")


def test_deep_json_is_refused_before_parsing(table):
    header, arrays = parts(table)
    text = "[" * 100_000 + "]" * 100_000
    refused(npz_bytes(header, arrays, header_text=text), r"JSON nests deeper than 32 levels")


def _set_central(data: bytes, name: str, offset: int, fmt: str, value) -> bytes:
    """Edit a field of entry ``name``'s central-directory record (offset from the record start)."""
    bad = bytearray(data)
    pos = bad.find(b"PK\x01\x02" + b"\x00" * 0, 0)
    while pos >= 0:
        nlen = struct.unpack_from("<H", bad, pos + 28)[0]
        if bytes(bad[pos + 46:pos + 46 + nlen]) == name.encode():
            struct.pack_into(fmt, bad, pos + offset, value)
            return bytes(bad)
        pos = bad.find(b"PK\x01\x02", pos + 4)
    raise AssertionError(name)


def test_unknown_compression_method_is_refused(good):
    """NotImplementedError from zipfile for method 99."""
    refused(_set_central(good, "normal_force.npy", 10, "<H", 99), r"compression method 99; only stored")


def test_encrypted_flag_is_refused(good):
    """RuntimeError ('password required') from zipfile for the encryption flag."""
    refused(_set_central(good, "normal_force.npy", 8, "<H", 0x1), r"'normal_force.npy' is encrypted")


def test_huge_npy_shape_is_refused_before_allocating(table):
    """MemoryError from numpy for a .npy header declaring 2**40 elements."""
    header, arrays = parts(table)
    raw = npy_bytes(arrays["normal_force"]).replace(f"({arrays['normal_force'].size},)".encode(),
                                                    b"(1099511627776,)")
    raw = raw[:8] + raw[8:]
    entries = [("header.npy", npy_bytes(np.frombuffer(json.dumps(header).encode(), np.uint8)))]
    entries += [(f"{n}.npy", raw if n == "normal_force" else npy_bytes(a)) for n, a in arrays.items()]
    tracemalloc.start()
    try:
        refused(zip_of(entries), r"entry 'normal_force': (1099511627776 elements exceed|\.npy header is not)")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 8 << 20


def test_patch_of_2_to_the_64_is_a_table_error(table):
    """OverflowError from the layout check for a patch size of 2**64."""
    header, arrays = parts(table)
    header["patches"] = [[2 ** 64, 1]]
    refused(resigned(header, arrays), r"each patch shape must be 2 non-negative integers")


@pytest.mark.parametrize("text", [
    "{'descr': '<u1', 'fortran_order': False, 'shape': (1,,), }",
    "{'descr': '<u1', 'fortran_order': False, 'shape': (__import__('os'),), }",
    "{'descr': [('a', '<u1')], 'fortran_order': False, 'shape': (1,), }",
])
def test_npy_header_is_matched_not_evaluated(table, text):
    """A tokenizer error (and worse) from numpy's evaluation of a .npy header."""
    header, arrays = parts(table)
    body = text.encode() + b" " * ((-(10 + len(text) + 1)) % 64) + b"\n"
    raw = b"\x93NUMPY\x01\x00" + len(body).to_bytes(2, "little") + body + b"\x00"
    entries = [("header.npy", npy_bytes(np.frombuffer(json.dumps(header).encode(), np.uint8)))]
    entries += [(f"{n}.npy", raw if n == "normal_force" else npy_bytes(a)) for n, a in arrays.items()]
    refused(zip_of(entries), r"entry 'normal_force': \.npy header is not in numpy's form")


# ------------------------------------------------------------------ bombs
BOMB_BYTES = 600 << 20
#: Most the resident set may grow while a bomb is refused (after the reader's imports), MB.
BOMB_GROWTH_BOUND_MB = 32


def _peak_rss_mb(code: str) -> tuple[float, str]:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    return float(lines[-1]), "\n".join(lines[:-1])


@pytest.mark.parametrize("mode", ["data", "shape"])
def test_zip_bomb_is_refused_with_bounded_memory(tmp_path, table, mode):
    """A ~600 kB table inflating to 600 MB of zeros peaked at 1.2 GB before the checksum failed."""
    path = tmp_path / "bomb.npz"
    zip_bomb(path, table, BOMB_BYTES, entry="grad_x", mode=mode)
    assert path.stat().st_size < 1 << 20
    code = textwrap.dedent(f"""
        import resource
        from shapedisplay.table.model import FrictionTable
        from shapedisplay.errors import TableError
        from shapedisplay.link.emulator import parse_table_image
        data = open({str(path)!r}, 'rb').read()
        try:
            parse_table_image(b"PK\\x03\\x04")       # imports done before the baseline is taken
        except TableError:
            pass
        base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        for read in (lambda: FrictionTable.load({str(path)!r}), lambda: parse_table_image(data, 1 << 24)):
            try:
                read()
            except TableError as exc:
                print(exc)
        print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024)
    """)
    growth, out = _peak_rss_mb(code)
    print(f"bomb ({mode}): {BOMB_BYTES >> 20} MB inflated, file {path.stat().st_size} bytes, "
          f"peak RSS growth {growth:.1f} MB")
    assert out.count("grad_x") == 2, out
    assert growth < BOMB_GROWTH_BOUND_MB, (growth, out)


def test_header_bomb_is_refused(table):
    header, arrays = parts(table)
    text = json.dumps(header) + " " * (9 << 20)
    refused(npz_bytes(header, arrays, compressed=True, header_text=text), r"entry 'header': .*exceed the limit")


# ------------------------------------------------------------------ NaN and wrong types with a valid checksum
@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_float_channel_is_refused(table, value):
    header, arrays = parts(table)
    arrays["grad_x"][3] = value
    refused(resigned(header, arrays), r"channel 'grad_x': values must be finite \(1 NaN/inf")


@pytest.mark.parametrize("edit, match", [
    (lambda h: h["device"]["pad"].update(mass="heavy"), r"header 'device.pad.mass' must be a finite number"),
    (lambda h: h["device"].update(normal_force_range=True), r"header 'device.normal_force_range' must be 2"),
    (lambda h: h["device"]["friction"].update(mu_k=0.9), r"not a valid device profile .*mu_k"),
    (lambda h: h["device"].update(colour="red"), r"header 'device' has unknown key 'colour'"),
    (lambda h: h["mapping"].update(slope_friction_gain="0.2"), r"header 'mapping.slope_friction_gain' must be"),
    (lambda h: h["mapping"].update(height=1), r"header 'mapping.height' must be true or false"),
    (lambda h: h.update(tick_rate_hz=[1]), r"header 'header.tick_rate_hz' must be a finite number"),
    (lambda h: h.update(velocity_range_m_s=[1, 0]), r"header 'velocity_range_m_s' must be 2 finite numbers"),
    (lambda h: h["report"].update(anything=10 ** 400), r"header 'report' holds a NaN or infinite number"),
    (lambda h: h["channels"]["normal_force"].update(max_error=-1.0), r"'channels.normal_force.max_error' must be"),
    (lambda h: h["channels"]["normal_force"].update(unit="mN"), r"'channels.normal_force.unit' must be 'N'"),
    (lambda h: h["grid"].update(x0_m=1e300), r"header 'grid.x0_m' must be within"),
    (lambda h: h.update(scene={"widgets": [{"bbox_m": [0, 0, "1", 1]}]}), r"scene.widgets\[0\].bbox_m"),
    (lambda h: h.update(scene={"toggles": {"t": {"block": 99, "states": {"on": 0}, "state": "on"}}}),
     r"scene.toggles.t.block' is 99"),
])
def test_wrong_header_values_are_refused_with_a_valid_checksum(table, edit, match):
    header, arrays = parts(table)
    edit(header)
    refused(resigned(header, arrays), match)


def test_integer_codes_that_decode_beyond_a_float_are_refused():
    from shapedisplay.table.model import Grid, choose_quantization
    vals = np.linspace(0.5, 3.0, 12).reshape(3, 4)
    t = FrictionTable.from_dense(Grid(3, 4, 1e-3, 1e-3), {"normal_force": vals},
                                 {"normal_force": choose_quantization(vals, "uint16")})
    header, arrays = parts(t)
    header["channels"]["normal_force"]["scale"] = 1e307
    refused(resigned(header, arrays), r"decoded values overflow")


@pytest.mark.parametrize("token", ["NaN", "Infinity", "-Infinity"])
def test_nan_in_header_json_is_refused(table, token):
    header, arrays = parts(table)
    text = json.dumps(header).replace('"unit": "N"', f'"unit": "N", "note": {token}', 1)
    refused(npz_bytes(header, arrays, header_text=text), r"numbers must be finite")


def test_accepted_header_survives_play_and_json_export(tmp_path, table):
    """What the loader accepts, play and export accept too (no TypeError later)."""
    header, arrays = parts(table)
    header["report"]["note"] = ["free", {"form": True}, None]
    path = tmp_path / "t.npz"
    path.write_bytes(resigned(header, arrays))
    assert main(["play", str(path), "--stroke", "0:8mm @ 20mm/s", "-o", str(tmp_path / "o.wav")]) == 0
    assert main(["export", str(path), "--format", "json", "-o", str(tmp_path / "t.json")]) == 0
    json.loads((tmp_path / "t.json").read_text(), parse_constant=lambda c: pytest.fail(c))


# ------------------------------------------------------------------ traces
def test_trace_reader_is_bounded_and_checks_values(tmp_path):
    from shapedisplay.render.sinks import read_trace
    p = tmp_path / "t.npz"
    n = 5
    arrays = {k: np.zeros(n) for k in ("t", "x", "y", "vx", "vy", "normal_force", "friction_force", "lateral_x",
                                       "lateral_y", "skin_stretch")}
    arrays["t"] = np.arange(n) * 1e-4
    arrays.update(state=np.zeros(n, np.int8), event_time=np.zeros(0), event_amplitude=np.zeros(0))
    np.savez(p, **arrays)
    assert read_trace(p)["t"].size == n
    p.write_bytes(p.read_bytes()[:200])
    with pytest.raises(FileFormatError, match="unreadable or truncated"):
        read_trace(p)
    arrays["x"] = np.array([0, 1, np.nan, 0, 0.0])
    np.savez(p, **arrays)
    with pytest.raises(FileFormatError, match="'x' holds NaN"):
        read_trace(p)


def test_preview_loader_refuses_a_truncated_table_in_one_line(tmp_path, good):
    from shapedisplay.viewer import load_model
    p = tmp_path / "t.npz"
    p.write_bytes(good[: len(good) // 2])
    with pytest.raises(TableError, match="unreadable or truncated"):
        load_model(p)


# ------------------------------------------------------------------ data loss
def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def compiled(tmp_path, capsys):
    t = tmp_path / "t.npz"
    assert run(["compile", TENT, "-o", t, "--size", "60x4mm", "--height", "0:2mm"], capsys)[0] == 0
    return t


def _snapshot(folder: Path) -> dict:
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


@pytest.mark.parametrize("argv, needle", [
    (["compile", "{png}", "-o", "{png}", "--size", "60x4mm", "--height", "0:2mm"], "`-o` '{png}' is the input SOURCE"),
    (["play", "{t}", "--stroke", "0:5mm @ 50mm/s", "-o", "{t}"], "is the input TABLE"),
    (["play", "{t}", "--stroke", "0:5mm @ 50mm/s", "-o", "{d}/o.wav", "--trace-out", "{t}"],
     "`--trace-out` '{t}' is the input TABLE"),
    (["play", "{t}", "--stroke", "0:5mm @ 50mm/s", "-o", "{d}/o.wav", "--trace-out", "{d}/o.wav"],
     "also the output of `-o`"),
    (["play", "{t}", "--stroke", "0:5mm @ 50mm/s", "-o", "{d}/o.wav", "--trace-out", "{d}/./o.wav"],
     "also the output of `-o`"),
    (["export", "{t}", "--format", "json", "-o", "{t}"], "is the input TABLE"),
    (["heightmap", "{stl}", "-o", "{stl}"], "is the input"),
])
def test_output_equal_to_an_input_is_refused(tmp_path, compiled, capsys, argv, needle):
    png = tmp_path / "in.png"
    png.write_bytes(TENT.read_bytes())
    stl = tmp_path / "in.stl"
    stl.write_bytes((ROOT / "assets/meshes/keycap.stl").read_bytes())
    fill = dict(png=png, t=compiled, d=tmp_path, stl=stl)
    before = _snapshot(tmp_path)
    code, out, err = run([a.format(**fill) for a in argv], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and needle.format(**fill) in err, err
    assert _snapshot(tmp_path) == before


def test_link_never_replaces_a_file(tmp_path, capsys):
    victim = tmp_path / "notes.txt"
    victim.write_text("keep me")
    code, out, err = run(["device", "emulate", "--link", victim, "--stop-after", "1", "--no-renderer"], capsys)
    assert code == 2 and "refusing to replace it" in err and len(err.strip().splitlines()) == 1
    assert victim.read_text() == "keep me" and not victim.is_symlink()
    code, out, err = run(["device", "emulate", "--link", tmp_path / "missing" / "x", "--stop-after", "1",
                          "--no-renderer"], capsys)
    assert code == 2 and "does not exist" in err


def test_emulator_link_is_removed_on_exit(tmp_path, capsys):
    pytest.importorskip("serial")
    link = tmp_path / "port"
    code, out, err = run(["device", "emulate", "--link", link, "--stop-after", "0.2", "--no-renderer"], capsys)
    assert code == 0 and "device emulator on" in out
    assert not os.path.lexists(link)


def test_report_into_an_unwritable_place_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, out, err = run(["report", "stability", "--quick", "--no-plots", "--no-progress", "-o", blocker / "r"],
                         capsys)
    assert code == 2 and "cannot write" in err and len(err.strip().splitlines()) == 1


def test_stale_part_files_are_removed_live_ones_kept(tmp_path):
    from shapedisplay.atomic import write_text
    stale = tmp_path / ".out.abcd1234.part.txt"
    stale.write_text("left by a killed writer")
    live = tmp_path / ".out.live5678.part.txt"
    live.write_text("being written")
    fd = os.open(live, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)                # a writer that is still running holds the lock
    other = tmp_path / ".other.abcd1234.part.txt"
    other.write_text("another output's")
    try:
        write_text(tmp_path / "out.txt", "new")
    finally:
        os.close(fd)
    assert (tmp_path / "out.txt").read_text() == "new"
    assert not stale.exists() and live.exists() and other.exists()


def test_sigkill_during_a_write_leaves_a_part_file_that_the_next_write_removes(tmp_path):
    code = textwrap.dedent(f"""
        import os, signal
        from shapedisplay.atomic import atomic_path
        with atomic_path({str(tmp_path / 't.npz')!r}) as tmp:
            tmp.write_bytes(b'partial')
            os.kill(os.getpid(), signal.SIGKILL)
    """)
    subprocess.run([sys.executable, "-c", code], timeout=60)
    parts_left = list(tmp_path.glob(".t.*.part.npz"))
    assert len(parts_left) == 1 and not (tmp_path / "t.npz").exists()
    small_table().save(tmp_path / "t.npz")
    assert list(tmp_path.glob(".t.*.part.npz")) == [] and FrictionTable.load(tmp_path / "t.npz")


# ------------------------------------------------------------------ limits before allocating
@pytest.mark.parametrize("stroke", ["0,2 <-> 60,2 @ 20mm/s x30000000", "0,2 <-> 60,2 @ 20mm/s x1000000000",
                                    "0,2 <-> 60,2 @ 20mm/s x" + "9" * 40])
def test_repeated_stroke_is_refused_before_its_points_are_built(stroke):
    from shapedisplay.render.cursor import parse_stroke
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match="ticks of one offline render"):
            parse_stroke(stroke, 10_000)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20


def test_csv_recordings_are_capped_while_read(tmp_path, monkeypatch):
    from shapedisplay.render import cursor
    p = tmp_path / "trace.csv"
    p.write_text("".join(f"{i * 1e-3},{i},0\n" for i in range(50)))
    monkeypatch.setattr(cursor, "MAX_TICKS", 20)
    with pytest.raises(FileFormatError, match="more than 20 rows"):
        cursor.load_trace_csv(p)
    monkeypatch.setattr(cursor, "MAX_CSV_BYTES", 100)
    with pytest.raises(FileFormatError, match="exceed the limit of 100"):
        cursor.load_force_csv(p, 0.08, 1000)


def test_binary_stl_declaring_too_many_triangles_is_refused(tmp_path, monkeypatch):
    from shapedisplay.author import mesh, meshfiles
    monkeypatch.setattr(meshfiles, "MAX_MESH_TRIANGLES", 10)
    p = tmp_path / "m.stl"
    p.write_bytes(b"\0" * 80 + struct.pack("<I", 11) + b"\0" * 50 * 11)
    with pytest.raises(FileFormatError, match="11 triangles exceed the limit of 10"):
        mesh.load_mesh(p)


# ------------------------------------------------------------------ physics inputs
def test_stribeck_refuses_a_pad_it_cannot_resolve(table):
    from shapedisplay.table.devices import DeviceProfile, PadParams
    from shapedisplay.render.renderer import Renderer
    tiny = DeviceProfile(pad=PadParams(mass=1e-12, stiffness=20.0, damping=0.01))   # h*omega_n 447: the tick resolves it
    with pytest.raises(ModelError, match="model 'stribeck' cannot resolve this pad"):
        Renderer(table, device=tiny, model="stribeck")
    Renderer(table, device=DeviceProfile(pad=PadParams(mass=1e-7, stiffness=2000.0, damping=0.01)), model="stribeck")


@pytest.mark.parametrize("model", ["jump", "stribeck", "tanh", "exact"])
@pytest.mark.parametrize("where", [1e300, -1e300, 2e3])
def test_absurd_positions_are_refused(table, model, where):
    from shapedisplay.render.cursor import CursorPath, parse_stroke
    t = np.arange(10) * 1e-4
    with pytest.raises(InputError, match=r"must be within \+-1000 m"):
        CursorPath(t, np.where(t > 4e-4, where, 0.0), np.zeros(10), 10_000.0, "jump")
    with pytest.raises(InputError, match="lies beyond"):
        parse_stroke(f"0,0 -> {where * 1e3:g},0 @ 10mm/s", 10_000)


def test_absurd_speed_is_refused():
    from shapedisplay.render.cursor import parse_stroke
    with pytest.raises(InputError, match=r"speed must be <= 1000 m/s"):
        parse_stroke("0,0 -> 10,0 @ 1e9 m/s", 10_000)


# ------------------------------------------------------------------ device
def test_device_answers_table_invalid_and_discards_the_upload(table):
    pytest.importorskip("serial")
    from shapedisplay.link import protocol as P
    from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig
    from shapedisplay.link.host import DeviceLink, DeviceRefused
    header, arrays = parts(table)
    arrays["grad_x"][0] = np.nan
    bad = resigned(header, arrays)
    emu = DeviceEmulator(EmulatorConfig(renderer=False))
    emu.start()
    try:
        with DeviceLink(emu.port, timeout=1.0, retries=2) as link:
            with pytest.raises(DeviceRefused, match=r"TABLE_INVALID: table rejected: .*'grad_x': values must be "
                                                    r"finite") as info:
                link.upload(bad)
            assert "\n" not in str(info.value)
            st = link.status()
            assert st.state == P.State.IDLE and st.active_crc == 0 and emu._upload is None
            assert emu.activations == []
    finally:
        emu.close()


@pytest.mark.parametrize("committed", [True, False])
def test_lost_commit_ack_is_settled_by_asking_the_device(table, committed, monkeypatch):
    pytest.importorskip("serial")
    from shapedisplay.link import protocol as P
    from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig
    from shapedisplay.link.framing import crc32
    from shapedisplay.link.host import DeviceLink, LinkError, LinkTimeout
    image = table_bytes(table)
    emu = DeviceEmulator(EmulatorConfig(renderer=False))
    emu.start()
    try:
        with DeviceLink(emu.port, timeout=0.5, retries=1) as link:
            real = link.request

            def lossy(msg_type, body=b"", expect=(), **kw):
                if msg_type == P.Msg.COMMIT:
                    if committed:
                        real(msg_type, body, expect, **kw)      # the device commits; every ack is lost
                    raise LinkTimeout("device did not answer COMMIT after 2 tries (0.5 s each)")
                return real(msg_type, body, expect, **kw)
            monkeypatch.setattr(link, "request", lossy)
            if committed:
                rep = link.upload(image)
                assert rep.commit_confirmed_by_status and emu.activations == [(crc32(image), len(image))]
            else:
                with pytest.raises(LinkError, match="the new table is not active"):
                    link.upload(image)
                assert emu.activations == []
    finally:
        emu.close()


def test_every_cli_error_of_this_file_is_one_line(tmp_path, capsys, good):
    """The CLI face of the loader: a damaged table is exit 2 and one line, no traceback."""
    p = tmp_path / "t.npz"
    p.write_bytes(_set_central(good, "normal_force.npy", 10, "<H", 99))
    for argv in (["inspect", p], ["play", p, "--stroke", "0:5mm @ 5mm/s", "-o", tmp_path / "o.wav"],
                 ["export", p, "--format", "json", "-o", tmp_path / "o.json"]):
        code, out, err = run(argv, capsys)
        assert code == 2 and len(err.strip().splitlines()) == 1 and "compression method 99" in err
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.npz"]


@pytest.mark.parametrize("model", ["exact", "jump", "stribeck", "tanh", "karnopp"])
def test_online_step_holds_absurd_positions_and_counts_them(table, model):
    """A stream (device host, studio) cannot be refused sample by sample: the last valid position is held."""
    import math

    from shapedisplay.render.renderer import Renderer
    r = Renderer(table, model=model)
    for x in (0.0, 0.001, 1e300, 0.002, -1e300, float("nan"), 0.003, 1e3, 0.004, float("inf"), 0.005):
        drive = r.step(x, 0.002)
        assert math.isfinite(drive) and all(math.isfinite(v) for v in r.outputs().values()), (model, x)
    assert r.held_positions == 4
    r.reset()
    assert r.held_positions == 0


_CONTACTOR_TOML = (ROOT / "shapedisplay" / "table" / "data" / "devices" / "lateral-contactor.toml").read_text()


@pytest.mark.parametrize("value, shown", [("0.0", "0.0"), ("0.5", "0.5"), ('"fast"', "fast"), ("-1e-6", "-1e-06"),
                                          ("nan", "nan")])
def test_stribeck_tolerance_out_of_range_is_refused(tmp_path, compiled, capsys, value, shown):
    """``[stribeck] tolerance`` of a profile: exit 2, one line naming the key, the range and the value; no output."""
    dev = tmp_path / "dev.toml"
    dev.write_text(_CONTACTOR_TOML.replace("[stribeck]\n", f"[stribeck]\ntolerance = {value}\n"))
    before = _snapshot(tmp_path)
    code, out, err = run(["play", compiled, "--stroke", "0:5mm @ 50mm/s", "--device", dev, "--model", "stribeck",
                          "-o", tmp_path / "o.wav"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "stribeck" in err and "tolerance" in err and shown in err, err
    assert _snapshot(tmp_path) == before


def test_stribeck_tolerance_option_and_profile_key(tmp_path, compiled, capsys):
    from shapedisplay.table.devices import load_device
    from shapedisplay.render.models import get_model
    dev = tmp_path / "dev.toml"
    dev.write_text(_CONTACTOR_TOML.replace("[stribeck]\n", "[stribeck]\ntolerance = 1e-5\n"))
    assert get_model("stribeck", load_device(dev)).pack()["stribeck_tol"] == 1e-5
    assert get_model("stribeck", load_device(dev), tolerance=1e-7).pack()["stribeck_tol"] == 1e-7
    assert get_model("stribeck", load_device("lateral-contactor")).pack()["stribeck_tol"] == 1e-13
    with pytest.raises(InputError, match=r"`tolerance` must be a number from 1e-14 to 0.001 \(got 0\)"):
        get_model("stribeck", load_device(dev), tolerance=0)
    code, out, err = run(["play", compiled, "--stroke", "0:5mm @ 50mm/s", "--device", dev, "--model", "stribeck",
                          "-o", tmp_path / "o.wav"], capsys)
    assert code == 0, err
    assert (tmp_path / "o.wav").stat().st_size > 44


def _stl_near_float32_max(path: Path, s: float = 3e38) -> None:
    """A 184-byte binary STL: two triangles with coordinates near 1e38 (float32's largest is 3.4e38)."""
    tris = [((-s, -s, 0), (s, -s, 0), (-s, s, s)), ((s, -s, 0), (s, s, s), (-s, s, s))]
    data = b"\0" * 80 + struct.pack("<I", len(tris))
    for t in tris:
        data += struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *v) for v in t) + b"\0\0"
    path.write_bytes(data)
    assert len(data) == 184


@pytest.mark.parametrize("s", [1e38, 3e38])
def test_compile_writes_no_table_its_reader_refuses(tmp_path, capsys, s):
    """Coordinates near 1e38 compiled (exit 0) into a table `inspect` refused (grid.dx_m 1.17e+33)."""
    stl, out = tmp_path / "huge.stl", tmp_path / "t.npz"
    _stl_near_float32_max(stl, s)
    code, stdout, err = run(["compile", stl, "-o", out], capsys)
    assert code == 2 and not stdout and not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["huge.stl"]
    assert "Traceback" not in err and "RuntimeWarning" not in err and "overflow" not in err
    errors = [line for line in err.splitlines() if ": error: " in line]
    assert errors == err.splitlines()[-1:], err          # before it at most the size warning that explains it
    assert errors[0].startswith(f"shapedisplay compile: error: table '{out}': header 'grid.dx_m' must be within "
                                f"0..1000 (got ")
    assert errors[0].endswith("; not written (the table reader would refuse it)")


def test_table_writer_and_reader_share_one_rule(table, tmp_path):
    """The rule that refuses a table on reading refuses it on writing: save, to_bytes; nothing left behind."""
    import dataclasses
    from shapedisplay.table.model import Grid
    far = dataclasses.replace(table, grid=Grid(table.grid.rows, table.grid.cols, 2e3, table.grid.dy))
    for write in (lambda: far.save(tmp_path / "far.npz"), far.to_bytes):
        with pytest.raises(TableError, match=r"header 'grid.dx_m' must be within 0..1000 \(got 2000.0\); not "
                                             r"written \(the table reader would refuse it\)") as e:
            write()
        assert "\n" not in str(e.value)
    assert list(tmp_path.iterdir()) == []
    assert FrictionTable.from_bytes(table.to_bytes()).checksum == table.checksum


def test_error_lines_escape_control_and_bidi_characters(table, tmp_path, capsys):
    """A quoted name with NUL, ESC and a right-to-left override is printed as escapes, on one line."""
    header, arrays = parts(table)
    evil = "n\x00\x1b[2J\u202eexe.txt"
    header["channels"][evil] = header["channels"].pop(next(iter(header["channels"])))
    path = tmp_path / "evil.npz"
    path.write_bytes(resigned(header, arrays))
    code, out, err = run(["inspect", path], capsys)
    assert code == 2 and not out
    assert err.count("\n") == 1 and "\x00" not in err and "\x1b" not in err and "\u202e" not in err
    assert r"unknown channel 'n\x00\x1b[2J\u202eexe.txt'" in err, err


def test_no_numpy_warning_before_a_mesh_error(tmp_path, capsys):
    """Coordinates of 1e150 and 1e300 overflowed the area products: numpy warnings, then a traceback or an error."""
    for c in ("1e150", "1e300"):
        obj = tmp_path / f"huge{c}.obj"
        obj.write_text(f"v -{c} -{c} 0\nv {c} -{c} 0\nv -{c} {c} {c}\nv {c} {c} {c}\nf 1 2 3\nf 2 4 3\n")
        for extra in ([], ["--size", "60mm"]):
            code, out, err = run(["compile", obj, "-o", tmp_path / "t.npz", *extra], capsys)
            assert code == 2 and err.count("\n") == 1, err
            assert err.startswith(f"shapedisplay compile: error: mesh '{obj}': vertex coordinates must be within "
                                  f"+-1e+60 (file units; shapedisplay.author.meshfiles.MAX_COORDINATE): 4 vertices beyond")
    assert sorted(p.suffix for p in tmp_path.iterdir()) == [".obj", ".obj"]
