"""The binary table image: writer, Python reader, the C loader, and the image alone enough to play the table."""
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapedisplay.errors import TableError
from shapedisplay.render import image as I
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization

from runtime_vectors import CASES, case_setup, image_payload, parse_outputs
from test_c_runtime import CDIR, CFLAGS, LIB, _cc, assert_outputs_equal, py_render, widget_table


def _reseal(buf: bytearray) -> bytes:
    """Recompute the CRC after a deliberate edit (an attack that passes the CRC)."""
    struct.pack_into("<I", buf, len(buf) - 4, zlib.crc32(bytes(buf[:-4])) & 0xFFFFFFFF)
    return bytes(buf)


def test_image_round_trip_keeps_the_table():
    for table in (widget_table("uint16"), widget_table("float32", sparse=False), widget_table("uint8")):
        img = I.to_image(table)
        assert len(img) % 4 == 0 and img[:4] == b"SDTI"
        back = I.read_image(img)
        assert back.checksum == table.checksum
        for name in table.channels:
            np.testing.assert_array_equal(back.codes[name], table.codes[name])


def test_image_slots_are_the_renderer_and_c_slots():
    import re
    from shapedisplay.render.renderer import SLOTS
    assert I.SLOTS == SLOTS
    header = (CDIR / "sd_layout.h").read_text()         # the C enums, generated from runtime.layouts
    enum = re.search(r"enum \{\s*(SD_SLOT_NORMAL_FORCE.*?)SD_NSLOT", header, re.S).group(1)
    entries = [e.split("=")[0].strip() for e in enum.split(",") if e.strip()]
    assert entries == [f"SD_SLOT_{n.upper()}" for n in SLOTS]
    assert [int(e.split("=")[1]) for e in enum.split(",") if e.strip()] == list(range(len(SLOTS)))


def test_image_header_holds_the_renderer_settings():
    from shapedisplay.render import Renderer
    table = widget_table("uint16")
    h = I.parse_header(I.to_image(table))
    r = Renderer(table, model="jump")
    assert h["param_0"] == r.device.pad.mass and h["param_5"] == r.device.friction.mu_s
    assert h["param_7"] == 0.4                       # slope_friction_gain of the mapping
    assert h["param_9"] == r.tick_rate and h["param_10"] == r.audio_rate
    assert h["slot_mask"] == sum(1 << i for i, n in enumerate(I.SLOTS) if n in table.channels)


def test_export_bin_cli_and_refusals(tmp_path):
    table = widget_table("uint16")
    src = tmp_path / "t.npz"
    table.save(src)
    out = tmp_path / "t.sdt"
    res = subprocess.run([sys.executable, "-m", "shapedisplay", "export", str(src), "--format", "bin", "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    data = out.read_bytes()
    assert I.read_image(data, str(out)).checksum == table.checksum
    with pytest.raises(TableError, match="CRC mismatch"):
        I.read_image(data[:600] + bytes([data[600] ^ 1]) + data[601:])
    with pytest.raises(TableError, match="truncated or padded"):
        I.read_image(data[:-8])
    with pytest.raises(TableError, match="not a shapedisplay table image"):
        I.read_image(b"PK\x03\x04" + data[4:])
    with pytest.raises(TableError, match="version must be one of 1, 2"):
        I.read_image(_reseal(bytearray(data[:4] + b"\x03\x00" + data[6:])))
    with pytest.raises(TableError, match="576-byte header"):    # a version 2 image has the longer header
        I.read_image(_reseal(bytearray(data[:4] + b"\x02\x00" + data[6:])))


@given(st.lists(st.tuples(st.integers(0, 60), st.integers(0, 90), st.integers(1, 12), st.integers(1, 20)),
                min_size=0, max_size=40))
@settings(max_examples=60, deadline=None)
def test_tile_index_lists_every_block_of_every_cell(rects):
    """Looking a cell up through its tile finds the same block as scanning all blocks."""
    rows, cols = 64, 96
    occupied = np.full((rows, cols), -1)
    blocks = []
    for r0, c0, nr, nc in rects:           # keep the non-overlapping ones inside the canvas
        nr, nc = min(nr, rows - r0), min(nc, cols - c0)
        if (occupied[r0:r0 + nr, c0:c0 + nc] >= 0).any():
            continue
        occupied[r0:r0 + nr, c0:c0 + nc] = len(blocks)
        blocks.append([r0, c0, nr, nc, 0])
    b = np.array(blocks, "<i4").reshape(-1, 5)
    tr, tc, ty, tx, start, entries = I.tile_index(rows, cols, b)
    assert ty * tx <= min(I.MAX_TILES, 4 * len(blocks) + 1)
    for r in range(rows):
        for c in range(cols):
            t = (r // tr) * tx + c // tc
            found = [k for k in entries[start[t]:start[t + 1]]
                     if b[k, 0] <= r < b[k, 0] + b[k, 2] and b[k, 1] <= c < b[k, 1] + b[k, 3]]
            assert found == ([] if occupied[r, c] < 0 else [occupied[r, c]])


@pytest.fixture(scope="module")
def sd_vectors_image(tmp_path_factory):
    out = tmp_path_factory.mktemp("c-image") / "sd_vectors"
    srcs = [str(CDIR / n) for n in (*LIB, "tool_vectors.c")]
    res = subprocess.run([_cc(), *CFLAGS, "-I", str(CDIR), *srcs, "-lm", "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return out


def _run_image(exe, payload, tmp_path):
    fin, fout = tmp_path / "img.in", tmp_path / "img.out"
    fin.write_bytes(payload)
    return subprocess.run([str(exe), "image", str(fin), str(fout)], capture_output=True, text=True,
                          timeout=120), fout


@pytest.mark.parametrize("dtype, kind, policy, tick, audio, model", CASES)
def test_c_runtime_plays_the_image_bit_exact(sd_vectors_image, tmp_path, dtype, kind, policy, tick, audio, model):
    """A standalone firmware-style player given the image and nothing but the model, policy and rates plays what
    the host's Renderer plays from the table and its device: the image carries every setting."""
    table, r, x, y, img = case_setup(dtype, kind, policy, tick, audio, model)
    po, pa, (pclip, pev) = py_render(r, x, y)
    res, fout = _run_image(sd_vectors_image, image_payload(img, r, x, y), tmp_path)
    assert res.returncode == 0, res.stderr
    co, ca, (cclip, cev, cdrop, cfault) = parse_outputs(fout.read_bytes(), len(x))
    assert pev > 20 and cev == pev and cclip == pclip and cdrop == 0 and cfault == 0
    assert_outputs_equal(co, po)
    np.testing.assert_array_equal(ca, pa)


def test_c_loader_refuses_damaged_images(sd_vectors_image, tmp_path):
    table, r, x, y, img = case_setup("uint16", "diagonal", "retrigger", 10_000.0, None, "jump", seconds=0.01)
    h = I.parse_header(img)

    def code(data):
        res, _ = _run_image(sd_vectors_image, image_payload(data, r, x, y), tmp_path)
        assert res.returncode == 4, res.stderr
        return int(res.stderr.split("(")[1].split(")")[0])

    assert code(img[:-8]) == -10                                   # size field disagrees
    assert code(img[:100]) == -10                                  # shorter than a header
    assert code(img[:700] + bytes([img[700] ^ 0x10]) + img[701:]) == -13   # CRC
    assert code(b"SDTX" + img[4:]) == -11
    bad = bytearray(img)                                           # a block reaching past the codes
    struct.pack_into("<i", bad, h["blocks_off"] + 16, h["n_values"])
    assert code(_reseal(bad)) == -14
    bad = bytearray(img)                                           # a tile list naming a missing block
    struct.pack_into("<I", bad, h["tile_list_off"], 1000)
    assert code(_reseal(bad)) == -14
    bad = bytearray(img)                                           # channel data past the end
    struct.pack_into("<I", bad, 224 + 4, len(img) - 8)
    assert code(_reseal(bad)) == -14
    bad = bytearray(img)                                           # a NaN scale
    struct.pack_into("<d", bad, 224 + 8, float("nan"))
    assert code(_reseal(bad)) == -16
    bad = bytearray(img)                                           # a huge canvas
    struct.pack_into("<ii", bad, 16, 1 << 30, 1 << 30)
    assert code(_reseal(bad)) == -14


def test_float_channel_nan_codes_are_refused(sd_vectors_image, tmp_path):
    """A float32 code that is NaN (an image made by something else) never reaches the renderer."""
    g = Grid(1, 8, 1e-3, 1e-3)
    nf = np.linspace(0.5, 2.0, 8)[None, :]
    table = FrictionTable.from_dense(g, {"normal_force": nf}, {"normal_force": choose_quantization(nf, "float32")})
    img = bytearray(I.to_image(table))
    h = I.parse_header(bytes(img))
    struct.pack_into("<f", img, h["normal_force_data_off"] + 8, float("inf"))
    from shapedisplay.render import Renderer
    r = Renderer(table, model="jump")
    res, _ = _run_image(sd_vectors_image, image_payload(_reseal(img), r, [0.0, 1e-4], [0.0, 0.0]), tmp_path)
    assert res.returncode == 4 and "(-16)" in res.stderr


def test_constant_n_table_image_plays_bit_exact(sd_vectors_image, tmp_path):
    """A table without normal_force carries its constant N in the image (param 14); the image alone plays it as
    the host's Renderer plays the table."""
    from shapedisplay.table.devices import load_device
    from shapedisplay.render import Renderer
    from shapedisplay.reports.presets import constant_table
    dev = load_device("handheld-stick")
    table = constant_table(2.5, dev)
    r = Renderer(table, model="exact", tick_rate=10_000.0, audio_rate=48_000.0, burst_policy="add")
    img = I.to_image(table)
    assert I.settings(table)["normal_force_n"] == 2.5
    x = np.linspace(0.0, 0.008, 4001)          # 20 mm/s for 0.4 s: a stick-slip every 21 ms
    y = np.zeros_like(x)
    po, pa, (pclip, pev) = py_render(r, x, y)
    res, fout = _run_image(sd_vectors_image, image_payload(img, r, x, y), tmp_path)
    assert res.returncode == 0, res.stderr
    co, ca, (cclip, cev, _, _) = parse_outputs(fout.read_bytes(), len(x))
    assert pev > 10 and cev == pev
    assert_outputs_equal(co, po)
    np.testing.assert_array_equal(ca, pa)


# ------------------------------------------------------------------ decoded range (SD_ERR_IMAGE_RANGE)
def _u16_image(scale_offset):
    """A 1 x 8 uint16 table image (normal_force, grad_x) with one channel's scale/offset then set in the
    binary header only (what the C loader reads), resealed."""
    g = Grid(1, 8, 1e-3, 1e-3)
    nf = np.linspace(0.5, 2.0, 8)[None, :]
    chans = {"normal_force": nf, "grad_x": np.linspace(-0.1, 0.1, 8)[None, :]}
    table = FrictionTable.from_dense(g, chans, {n: choose_quantization(v, "uint16") for n, v in chans.items()})
    img = bytearray(I.to_image(table))
    for (name, field), value in scale_offset.items():
        slot = I.SLOTS.index(name)
        struct.pack_into("<d", img, 224 + 32 * slot + {"scale": 8, "offset": 16}[field], value)
    return table, _reseal(img)


@pytest.fixture(scope="module")
def sd_vectors_image_single(tmp_path_factory):
    out = tmp_path_factory.mktemp("c-image-single") / "sd_vectors"
    srcs = [str(CDIR / n) for n in (*LIB, "tool_vectors.c")]
    res = subprocess.run([_cc(), *CFLAGS, "-DSD_SINGLE", "-I", str(CDIR), *srcs, "-lm", "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    return out


def _load_code(exe, img, table, tmp_path):
    from shapedisplay.render import Renderer
    r = Renderer(table, model="jump")
    res, _ = _run_image(exe, image_payload(img, r, [0.0, 1e-4], [0.0, 0.0]), tmp_path)
    if res.returncode == 0:
        return 0
    assert res.returncode == 4, res.stderr
    return int(res.stderr.split("(")[1].split(")")[0])


@pytest.mark.parametrize("edit", [
    {("normal_force", "scale"): 1e307},                               # 65535 x 1e307 = inf
    {("normal_force", "offset"): 1.7976931348623157e308, ("normal_force", "scale"): 1e304},
    {("normal_force", "offset"): -1.7976931348623157e308, ("normal_force", "scale"): 1e304},   # offset - scale x top
    {("grad_x", "scale"): 1e307},
])
def test_c_loader_refuses_channels_decoding_beyond_the_reals(sd_vectors_image, sd_vectors_image_single, tmp_path,
                                                             edit):
    """offset +/- scale x (largest code of the type) must be finite (SD_ERR_IMAGE_RANGE, -18) in either build;
    every such value loaded before and played N, friction or skin stretch as inf or NaN. (The single-precision
    build refuses these scales and offsets already as beyond float range, SD_ERR_IMAGE_VALUE.)"""
    table, img = _u16_image(edit)
    assert _load_code(sd_vectors_image, img, table, tmp_path) == -18
    assert _load_code(sd_vectors_image_single, img, table, tmp_path) == -16


def test_single_build_refuses_values_beyond_float_range(sd_vectors_image, sd_vectors_image_single, tmp_path):
    """65535 x 1e35 = 6.6e39 is a double but not a float: the double build plays it, the single build refuses
    it; 65535 x 5e33 = 3.3e38 stays within float range and loads in both."""
    table, img = _u16_image({("normal_force", "scale"): 1e35})
    assert _load_code(sd_vectors_image, img, table, tmp_path) == 0
    assert _load_code(sd_vectors_image_single, img, table, tmp_path) == -18
    table, img = _u16_image({("normal_force", "scale"): 5e33})
    assert _load_code(sd_vectors_image_single, img, table, tmp_path) == 0


@pytest.mark.parametrize("scale, offset", [(1e307, 0.0), (1e304, 1.7976931348623157e308), (1e304, -1.7e308)])
def test_python_reader_refuses_what_the_c_loader_refuses(scale, offset):
    """The same rule in the Python reader (the table schema of table.py, which read_image and FrictionTable.load
    apply): offset +/- scale x the code type's largest code finite, else a TableError naming the channel."""
    from shapedisplay.table.model import Quantization
    g = Grid(1, 4, 1e-3, 1e-3)
    table = FrictionTable.from_codes(g, {"normal_force": np.array([[0, 1, 2, 65535]], np.uint16)},
                                     {"normal_force": Quantization("uint16", scale, offset)})
    with pytest.raises(TableError, match="normal_force.*overflow"):
        I.read_image(I.to_image(table))


@pytest.mark.parametrize("field, value", [(80, 7e30), (88, -1000.5), (64, 2e3)])
def test_c_loader_refuses_grids_beyond_a_kilometre(sd_vectors_image, sd_vectors_image_single, tmp_path, field,
                                                    value):
    """Grid origin and spacing within 1 km, as the Python reader's table schema requires (MAX_COORDINATE_M): an
    origin of 7e30 m (found by the fuzzer) was where a held cursor started, and the next tick's velocity was
    inf in the single-precision build."""
    table, img = _u16_image({})
    img = bytearray(img)
    struct.pack_into("<d", img, field, value)
    img = _reseal(img)
    assert _load_code(sd_vectors_image, img, table, tmp_path) == -18
    assert _load_code(sd_vectors_image_single, img, table, tmp_path) == -18
