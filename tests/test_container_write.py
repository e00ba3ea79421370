"""The table writer (container.write_npz): plain .npz through the standard library's zipfile and zlib."""
import io
import zipfile

import numpy as np
import pytest

from shapedisplay.table import container


def _arrays():
    rng = np.random.default_rng(9)
    y, x = np.mgrid[0:1500, 0:1700]
    return {"header": np.frombuffer(b'{"a": 1}', np.uint8),
            "smooth": np.rint(120 + 100 * np.sin(x / 80.0) * np.cos(y / 60.0)).astype(np.uint8),   # large, deflated
            "noisy": rng.integers(0, 65535, (1500, 1700), dtype=np.uint16),                         # large, stored
            "wide": rng.normal(0, 1, 3 * (1 << 20) // 8 + 77),                                      # float64
            "empty": np.zeros((0, 3), np.float32)}


@pytest.mark.parametrize("zip64_limit", [None, 1 << 20])
def test_write_npz_is_writestr_of_numpy_save_byte_for_byte(monkeypatch, zip64_limit):
    """Every entry is ZipFile.writestr of numpy.save's whole output with the method and zlib level that
    entry_compression chooses: small entries at level 6, large ones at level 1 or stored; zip64 records
    where writestr puts them (tried with a lower limit: the large entries then take them)."""
    if zip64_limit is not None:
        monkeypatch.setattr(zipfile, "ZIP64_LIMIT", zip64_limit)
        monkeypatch.setattr(container, "_ZIP64_LIMIT", zip64_limit)
    arrays = _arrays()
    expected = io.BytesIO()
    with zipfile.ZipFile(expected, "w", allowZip64=True) as zf:
        for name, a in arrays.items():
            npy = io.BytesIO()
            np.lib.format.write_array(npy, a, allow_pickle=False)
            method, level = container.entry_compression(a.reshape(-1).view(np.uint8))
            zf.writestr(zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0)), npy.getvalue(),
                        compress_type=method, compresslevel=level)
    got = io.BytesIO()
    container.write_npz(got, arrays)
    assert got.getvalue() == expected.getvalue()
    with zipfile.ZipFile(got) as z:
        methods = {i.filename: (i.compress_type, i.compress_size < 0.5 * i.file_size) for i in z.infolist()}
    assert methods["smooth.npy"] == (zipfile.ZIP_DEFLATED, True) and methods["noisy.npy"][0] == zipfile.ZIP_STORED
    assert container.entry_compression(arrays["smooth"].reshape(-1)) == (zipfile.ZIP_DEFLATED, container.LARGE_LEVEL)
    with np.load(io.BytesIO(got.getvalue())) as z:
        for name, a in arrays.items():
            assert z[name].dtype == a.dtype and np.array_equal(z[name], a)


def test_write_npz_rejects_object_arrays():
    with pytest.raises(ValueError, match="entry 'x': object arrays cannot be stored"):
        container.write_npz(io.BytesIO(), {"x": np.array([object()])})


def test_the_writer_needs_no_compression_package_beyond_the_standard_library():
    import inspect
    source = inspect.getsource(container)
    assert "isal" not in source and "._compress" not in source
