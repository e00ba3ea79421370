"""Friction-envelope table container: bit-exact round trips, verification, layout, lookups."""
import json
import zlib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

from shapedisplay.errors import FileFormatError, InputError, TableError
from shapedisplay.table.model import (CHANNELS, FORMAT_VERSION, FrictionTable, Grid, Quantization,
                                choose_quantization)


def _table(rows=4, cols=5, dtype="uint8"):
    g = Grid(rows, cols, 1e-3, 2e-3, 0.5e-3, 1e-3)
    n = 0.5 + np.arange(rows * cols, dtype=float).reshape(rows, cols) * 0.1
    q = choose_quantization(n, dtype)
    return FrictionTable.from_dense(g, {"normal_force": n}, {"normal_force": q}, {"source": {"x": 1}}), n


finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=40, deadline=None)
@given(values=hnp.arrays(np.float64, st.tuples(st.integers(1, 6), st.integers(2, 7)), elements=finite),
       dtype=st.sampled_from(["uint8", "uint16", "float32", "float64"]),
       names=st.sets(st.sampled_from(sorted(CHANNELS)), min_size=1, max_size=4))
def test_save_load_round_trip_is_bit_exact(tmp_path_factory, values, dtype, names):
    rows, cols = values.shape
    grid = Grid(rows, cols, 1e-4, 2e-4, 0.05e-3, 0.1e-3)
    chans = {n: values * (i + 1) for i, n in enumerate(sorted(names))}
    quant = {n: choose_quantization(v, dtype) for n, v in chans.items()}
    t = FrictionTable.from_dense(grid, chans, quant, {"mapping": {"n_base": 0.5}, "note": "x"})
    path = tmp_path_factory.mktemp("rt") / "t.npz"
    t.save(path)
    u = FrictionTable.load(path)
    assert u.grid == t.grid and u.channels == t.channels
    assert u.meta == t.meta and u.quant == t.quant and u.checksum == t.checksum
    for n in t.channels:
        assert u.codes[n].dtype == t.codes[n].dtype
        assert u.codes[n].tobytes() == t.codes[n].tobytes()
        assert np.array_equal(u.dense(n), t.dense(n))
        err = np.abs(t.dense(n) - chans[n]).max()
        assert err <= t.quant[n].max_error * (1 + 1e-12) + 1e-300


def test_quantization_error_bound_is_stated_truthfully():
    rng = np.random.default_rng(1)
    v = rng.uniform(0.5, 4.5, size=1000)
    for dt in ("uint8", "uint16"):
        q = choose_quantization(v, dt)
        assert np.abs(q.decode(q.encode(v)) - v).max() <= q.max_error
        assert q.max_error == pytest.approx((4.5 - 0.5) / np.iinfo(dt).max / 2, rel=1e-2)
    q = choose_quantization(v, "auto", max_error=0.01)
    assert q.dtype == "uint8"
    q = choose_quantization(v, "auto", max_error=1e-4)
    assert q.dtype == "uint16"


def test_readable_without_the_package(tmp_path):
    t, n = _table()
    t.save(tmp_path / "t.npz")
    with np.load(tmp_path / "t.npz") as z:
        header = json.loads(bytes(z["header"]).decode())
        codes = z["normal_force"]
    c = header["channels"]["normal_force"]
    values = (c["offset"] + c["scale"] * codes.astype(float)).reshape(header["grid"]["rows"], header["grid"]["cols"])
    assert np.abs(values - n).max() <= c["max_error"]
    assert header["format_version"] == FORMAT_VERSION


def _rewrite(path, out, header_edit=None, array_edit=None, fix_checksum=False):
    from shapedisplay.table.model import _checksum
    with np.load(path) as z:
        header = json.loads(bytes(z["header"]).decode())
        arrays = {k: z[k] for k in z.files if k != "header"}
    if header_edit:
        header_edit(header)
    if array_edit:
        array_edit(arrays)
    if fix_checksum:
        header["checksum"] = _checksum(header, arrays)
    np.savez(out, header=np.frombuffer(json.dumps(header).encode(), np.uint8), **arrays)


def test_wrong_version_rejected(tmp_path):
    t, _ = _table()
    t.save(tmp_path / "t.npz")
    _rewrite(tmp_path / "t.npz", tmp_path / "v.npz", lambda h: h.update(format_version=99), fix_checksum=True)
    with pytest.raises(TableError, match=r"format_version must be 1 \(got 99\)"):
        FrictionTable.load(tmp_path / "v.npz")


def test_checksum_mismatch_rejected(tmp_path):
    t, _ = _table()
    t.save(tmp_path / "t.npz")

    def flip(arrays):
        a = arrays["normal_force"].copy()
        a[3] ^= 1
        arrays["normal_force"] = a
    _rewrite(tmp_path / "t.npz", tmp_path / "c.npz", array_edit=flip)
    with pytest.raises(TableError, match="checksum mismatch"):
        FrictionTable.load(tmp_path / "c.npz")
    _rewrite(tmp_path / "t.npz", tmp_path / "m.npz", lambda h: h["grid"].update(dx_m=5.0))
    with pytest.raises(TableError, match="checksum mismatch"):
        FrictionTable.load(tmp_path / "m.npz")


def _set_channel(h, **kw):
    h["channels"]["normal_force"].update(kw)


def _rename_channel(h):
    h["channels"]["normal_forse"] = h["channels"].pop("normal_force")


@pytest.mark.parametrize("edit, array_edit, match", [
    (lambda h: h.clear() or h.update(format="shapedisplay-friction-table", format_version=1), None,
     r"header 'grid' must be an object \(got None\)"),
    (_rename_channel, None, r"unknown channel 'normal_forse' \(did you mean 'normal_force'\?\)"),
    (lambda h: _set_channel(h, dtype="int7"), None, r"channel 'normal_force': dtype must be one of .* \(got 'int7'\)"),
    (lambda h: _set_channel(h, scale=None), None, r"must be finite numbers \(got scale=None\)"),
    (lambda h: _set_channel(h, offset=float("nan")), None, r"entry 'header': numbers must be finite \(got NaN\)"),
    (None, lambda a: a.update(normal_force=a["normal_force"].astype(np.float64)),
     r"entry 'normal_force': dtype must be one of \['u1'\] little-endian \(got '<f8'\)"),
    (None, lambda a: a.pop("normal_force"), r"channel 'normal_force' has no array in the file"),
    (lambda h: h.update(blocks=[[0, 0]]), None, r"each block \[row0, col0, patch\] must be 3 non-negative integers"),
    (lambda h: h.update(blocks=[[0, 0, 7]]), None, r"block at \(0, 0\) names patch 7"),
    (lambda h: h.update(patches=[[4]]), None, r"each patch shape must be 2 non-negative integers \(got \[4\]\)"),
    (lambda h: h.update(channels=["normal_force"]), None, r"'channels' must be an object \(got \['normal_force'\]\)"),
    (lambda h: h["grid"].update(rows=10 ** 9, cols=10 ** 9), None, r"grid of 1000000000 x 1000000000 samples exceeds"),
    (lambda h: h["grid"].update(dx_m=-1.0), None, r"header 'grid.dx_m' must be within 0..1000 \(got -1.0\)"),
    (lambda h: h["grid"].update(rows="four"), None, r"header 'grid.rows' must be an integer >= 1 \(got 'four'\)"),
    (lambda h: h.update(device="handheld"), None, r"'device' must be an object \(got 'handheld'\)"),
])
def test_malformed_header_with_valid_checksum_is_one_clear_error(tmp_path, edit, array_edit, match):
    """A foreign writer can recompute the checksum; the structure is still checked."""
    t, _ = _table()
    t.save(tmp_path / "t.npz")
    _rewrite(tmp_path / "t.npz", tmp_path / "bad.npz", edit, array_edit, fix_checksum=True)
    with pytest.raises(TableError, match=match) as info:
        FrictionTable.load(tmp_path / "bad.npz")
    assert str(info.value).startswith(f"table '{tmp_path / 'bad.npz'}'") and "\n" not in str(info.value)


def test_header_that_is_not_an_object(tmp_path):
    np.savez(tmp_path / "l.npz", header=np.frombuffer(b"[1, 2]", np.uint8))
    with pytest.raises(TableError, match=r"header must be a JSON object \(got list\)"):
        FrictionTable.load(tmp_path / "l.npz")


def test_truncated_and_foreign_files(tmp_path):
    t, _ = _table()
    t.save(tmp_path / "t.npz")
    data = (tmp_path / "t.npz").read_bytes()
    (tmp_path / "trunc.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(TableError, match="unreadable or truncated"):
        FrictionTable.load(tmp_path / "trunc.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(TableError, match="no 'header' entry"):
        FrictionTable.load(tmp_path / "other.npz")
    with pytest.raises(TableError, match="no such file"):
        FrictionTable.load(tmp_path / "missing.npz")
    (tmp_path / "t.json").write_text('{"format": "shapedisplay-friction-table"}')
    with pytest.raises(TableError, match=r"not a table \(.npz zip archive\); it starts with b'\{\"fo'"):
        FrictionTable.load(tmp_path / "t.json")     # numpy would try to unpickle it and talk of allow_pickle
    with pytest.raises(TableError, match="is a directory, not a table file"):
        FrictionTable.load(tmp_path)


def test_save_is_atomic(tmp_path, monkeypatch):
    t, _ = _table()
    target = tmp_path / "t.npz"

    def boom(fh, arrays):
        fh.write(b"partial")
        raise RuntimeError("disk full")
    monkeypatch.setattr("shapedisplay.table.model.write_npz", boom)
    with pytest.raises(RuntimeError):
        t.save(target)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(FileFormatError, match="does not exist"):
        t.save(tmp_path / "nodir" / "t.npz")


def test_write_failures_are_one_clear_error_without_partial_files(tmp_path, monkeypatch):
    import os
    t, _ = _table()
    (tmp_path / "sub").mkdir()
    for target in (tmp_path / "sub", ""):
        with pytest.raises(FileFormatError, match="is a directory or empty; give a file name"):
            t.save(target)

    def full(src, dst):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(os, "replace", full)
    with pytest.raises(FileFormatError, match=r"output '.*t.npz': cannot write \(No space left on device\)"):
        t.save(tmp_path / "t.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub"]


def test_identical_patches_stored_once_and_sampled():
    grid = Grid(10, 30, 1e-3, 1e-3)
    patch = {"normal_force": np.full((4, 5), 2.0)}
    placed = [((1, 1), patch), ((1, 10), patch), ((5, 20), {"normal_force": np.full((4, 5), 3.0)})]
    q = {"normal_force": Quantization("uint8", 0.02, 0.0, 0.01)}
    t = FrictionTable.from_patches(grid, placed, q, {"normal_force": 0.5})
    assert len(t.patch_shapes) == 2 and len(t.blocks) == 3
    assert t.stored_bytes == 2 * 4 * 5
    d = t.dense("normal_force")
    assert d[0, 0] == 0.5 and d[2, 12] == 2.0 and d[6, 21] == 3.0
    with pytest.raises(TableError, match="overlaps"):
        FrictionTable.from_patches(grid, [((0, 0), patch), ((2, 2), patch)], q, {})


def test_bilinear_sampling_is_exact_on_linear_fields():
    grid = Grid(5, 7, 1e-3, 2e-3, 1e-3, 0.0)
    r, c = np.mgrid[0:5, 0:7]
    x, y = grid.x0 + c * grid.dx, grid.y0 + r * grid.dy
    f = 1.0 + 200.0 * x + 50.0 * y
    t = FrictionTable.from_dense(grid, {"normal_force": f}, {"normal_force": Quantization("float64")})
    px, py = np.array([1.3e-3, 4.77e-3, 6.9e-3]), np.array([0.5e-3, 3.3e-3, 7.9e-3])
    assert np.allclose(t.sample("normal_force", px, py), 1.0 + 200.0 * px + 50.0 * py, rtol=0, atol=1e-12)
    # outside: edge value held
    assert t.sample("normal_force", -1.0, -1.0) == pytest.approx(f[0, 0])
    assert t.sample("normal_force", 1.0, 1.0) == pytest.approx(f[-1, -1])


def test_one_d_table_ignores_y():
    grid = Grid(1, 4, 1e-3, 1e-3)
    t = FrictionTable.from_dense(grid, {"normal_force": np.array([[1.0, 2.0, 3.0, 4.0]])},
                                 {"normal_force": Quantization("float64")})
    assert t.is_1d
    assert t.sample("normal_force", 1.5e-3, 123.0) == pytest.approx(2.5)


def test_unknown_channel_suggests():
    with pytest.raises(InputError, match=r"unknown channel 'normal_forse' \(did you mean 'normal_force'\?\)"):
        FrictionTable.from_dense(Grid(1, 2, 1e-3, 1e-3), {"normal_forse": np.zeros((1, 2))},
                                 {"normal_forse": Quantization("float64")})
    t, _ = _table()
    with pytest.raises(TableError, match="lacks channel"):
        t.require("lateral_x")


def test_from_codes_matches_from_dense():
    t, n = _table(6, 9, "uint16")
    q = t.quant["normal_force"]
    u = FrictionTable.from_codes(t.grid, {"normal_force": q.encode(n)}, {"normal_force": q}, None, t.meta)
    assert u.checksum == t.checksum
    with pytest.raises(InputError, match="must be uint16 of shape"):
        FrictionTable.from_codes(t.grid, {"normal_force": q.encode(n)[:2]}, {"normal_force": q})


def test_sizes_reported():
    t, _ = _table(4, 5)
    assert t.stored_bytes == 20
    assert t.dense_bytes == 4 * 5 * len(CHANNELS) * 4
    s = t.summary()
    assert s["stored_bytes"] == 20 and s["dense_bytes"] == t.dense_bytes


def test_non_finite_channel_values_are_refused():
    """NaN used to give a NaN offset and error bound, and a table that decoded to NaN everywhere."""
    g = Grid(2, 3, 1e-3, 1e-3)
    v = np.array([[0.5, np.nan, 1.0], [1.0, 2.0, 3.0]])
    for dtype in ("uint8", "float32", "auto"):
        with pytest.raises(InputError, match=r"channel values must be finite to be quantized \(got range nan..nan\)"):
            choose_quantization(v, dtype, max_error=0.01)
    q = Quantization("float32", 1.0, 0.0, 1e-7)
    with pytest.raises(InputError, match=r"patch at row 0, col 0: channel 'normal_force' must be finite \(1 NaN/inf"):
        FrictionTable.from_dense(g, {"normal_force": np.where(np.isnan(v), np.inf, v)}, {"normal_force": q})


def test_from_bytes_reads_the_same_table_as_load(tmp_path):
    grid = Grid(2, 3, 1e-3, 1e-3)
    vals = np.array([[0.5, 1.0, 1.5], [2.0, 2.5, 3.0]])
    t = FrictionTable.from_dense(grid, {"normal_force": vals}, {"normal_force": choose_quantization(vals, "uint16")})
    path = t.save(tmp_path / "t.npz")
    u = FrictionTable.from_bytes(path.read_bytes())
    assert u.checksum == FrictionTable.load(path).checksum
    np.testing.assert_array_equal(u.dense("normal_force"), t.dense("normal_force"))
    with pytest.raises(TableError, match="uploaded table: unreadable or truncated"):
        FrictionTable.from_bytes(path.read_bytes()[:50])


def test_large_table_written_fast_reads_as_the_numpy_written_file(tmp_path):
    """The writer stores incompressible large channels and deflates the rest at level 1: the same
    table, channel for channel, as numpy's savez_compressed of the same entries; numpy reads it too."""
    import io
    import zipfile

    rows, cols = 1200, 1000                                # 1.2 MB per uint8 channel: above SMALL_ENTRY
    y, x = np.mgrid[0:rows, 0:cols]
    smooth = 0.5 + np.sin(x / 90.0) * np.cos(y / 70.0) + 1.0
    noisy = np.random.default_rng(3).uniform(-1.0, 1.0, (rows, cols))
    chans = {"normal_force": smooth, "lateral_x": noisy, "lateral_y": noisy[::-1].copy()}
    quant = {n: choose_quantization(v, "uint8") for n, v in chans.items()}
    quant["lateral_y"] = choose_quantization(noisy, "uint16")
    t = FrictionTable.from_dense(Grid(rows, cols, 1e-4, 1e-4), chans, quant, {"source": {"x": 1}})
    data = t.to_bytes()
    assert data == t.to_bytes() == t.save(tmp_path / "t.npz").read_bytes()       # byte-stable
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        methods = {i.filename: i.compress_type for i in z.infolist()}
    assert methods == {"header.npy": zipfile.ZIP_DEFLATED, "normal_force.npy": zipfile.ZIP_DEFLATED,
                       "lateral_x.npy": zipfile.ZIP_STORED, "lateral_y.npy": zipfile.ZIP_STORED}
    legacy = io.BytesIO()
    np.savez_compressed(legacy, **t._arrays())
    old, new = FrictionTable.from_bytes(legacy.getvalue()), FrictionTable.from_bytes(data)
    assert old.checksum == new.checksum and old.quant == new.quant and old.meta == new.meta
    with np.load(io.BytesIO(data)) as z, np.load(io.BytesIO(legacy.getvalue())) as zl:
        assert sorted(z.files) == sorted(zl.files)
        for name in z.files:
            assert z[name].dtype == zl[name].dtype and np.array_equal(z[name], zl[name])
    for name in chans:
        assert np.array_equal(new.codes[name], old.codes[name])
        assert np.array_equal(new.dense(name), t.dense(name))


def test_negative_zero_channel_keeps_its_checksum(tmp_path):
    # A channel of -0.0 values: its offset must not carry the sign into the header.
    grid = Grid(1, 2, 1e-4, 2e-4, 0.05e-3, 0.1e-3)
    values = np.array([[-0.0, -0.0]])
    t = FrictionTable.from_dense(grid, {"normal_force": values},
                                 {"normal_force": choose_quantization(values, "uint8")}, {})
    t.save(tmp_path / "t.npz")
    u = FrictionTable.load(tmp_path / "t.npz")
    assert u.checksum == t.checksum and u.quant == t.quant


def _writestr_npz(arrays) -> bytes:
    """The .npz that ZipFile.writestr of numpy.save's whole output gives, compressed as write_npz chooses."""
    import io
    import zipfile

    from shapedisplay.table.container import entry_compression
    expected = io.BytesIO()
    with zipfile.ZipFile(expected, "w", allowZip64=True) as zf:
        for name, a in arrays.items():
            npy = io.BytesIO()
            np.lib.format.write_array(npy, a, allow_pickle=False)
            method, level = entry_compression(a.reshape(-1).view(np.uint8))
            zf.writestr(zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0)), npy.getbuffer(),
                        compress_type=method, compresslevel=level)
    return expected.getvalue()


def _streamed_arrays():
    from shapedisplay.table.container import _CHUNK
    rng = np.random.default_rng(9)
    y, x = np.mgrid[0:1500, 0:1700]
    return {"header": np.frombuffer(b'{"a": 1}', np.uint8),
            "smooth": np.rint(120 + 100 * np.sin(x / 80.0) * np.cos(y / 60.0)).astype(np.uint8),   # large, deflated
            "noisy": rng.integers(0, 65535, (1500, 1700), dtype=np.uint16),                         # stored
            "wide": rng.normal(0, 1, 3 * _CHUNK // 8 + 77),                                         # float64
            "empty": np.zeros((0, 3), np.float32)}


def test_streamed_npz_matches_writestr_of_the_whole_npy():
    """write_npz streams each array into its zip entry a chunk at a time: every entry's name, method,
    CRC, sizes and content are those of ZipFile.writestr of numpy.save's whole output; small and stored
    entries byte for byte, the large deflated one through ISA-L's deflate (a plain deflate stream that
    zlib inflates to the same bytes)."""
    import io
    import zipfile

    from shapedisplay.table.container import write_npz
    arrays = _streamed_arrays()
    expected = _writestr_npz(arrays)
    got = io.BytesIO()
    write_npz(got, arrays)
    with zipfile.ZipFile(got) as z, zipfile.ZipFile(io.BytesIO(expected)) as ze:
        infos, want = z.infolist(), ze.infolist()
        assert [i.filename for i in infos] == [i.filename for i in want]
        for i, w in zip(infos, want):
            assert (i.compress_type, i.CRC, i.file_size, i.date_time) == (w.compress_type, w.CRC, w.file_size,
                                                                          w.date_time)
            assert z.read(i) == ze.read(w)
            if i.filename != "smooth.npy":
                assert i.compress_size == w.compress_size
        methods = {i.filename: i.compress_type for i in infos}
        assert methods["smooth.npy"] == zipfile.ZIP_DEFLATED and methods["noisy.npy"] == zipfile.ZIP_STORED
        raw = got.getvalue()
        smooth = z.getinfo("smooth.npy")
        start = smooth.header_offset + 30 + len(smooth.filename.encode()) + len(smooth.extra)
        stream = raw[start:start + smooth.compress_size]
        assert zlib.decompress(stream, -15) == ze.read("smooth.npy")      # plain deflate
        assert smooth.compress_size < 0.5 * smooth.file_size
    with np.load(io.BytesIO(got.getvalue())) as z:
        for name, a in arrays.items():
            assert z[name].dtype == a.dtype and np.array_equal(z[name], a)


def test_streamed_npz_is_byte_for_byte_writestr():
    """Large entries are deflated by zlib level 1: the whole file is byte for byte what ZipFile.writestr of
    numpy.save's whole output gives."""
    import io

    from shapedisplay.table import container
    arrays = _streamed_arrays()
    got = io.BytesIO()
    container.write_npz(got, arrays)
    assert got.getvalue() == _writestr_npz(arrays)


