"""Instrument height data (AFM/SPM text exports, Gwyddion .gsf): heights, size and units from the file.

The surface is three Gaussian bumps evaluated at the pixel centres of a
10 x 7.5 µm scan of 128 x 96 pixels (rows != cols catches a transposition);
each file form is written here byte by byte, as the instruments and Gwyddion
write it, and must come back as the same heights in metres, the same size,
and row 0 at the top (the largest y).
"""
import json
import os
import re
import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

from shapedisplay.author import instruments, sources
from shapedisplay.author.instruments import load_scan, read_gsf
from shapedisplay.cli.main import main
from shapedisplay.errors import FileFormatError, InputError

ROWS, COLS = 96, 128
W, H = 10e-6, 7.5e-6                                    # metres
#: (x, y) centre in metres, amplitude in nm, sigma in metres
BUMPS = [(3e-6, 5e-6, 120.0, 1e-6), (7e-6, 2e-6, 80.0, 1.5e-6), (5e-6, 6.6e-6, 40.0, 0.5e-6)]


def surface_nm(rows=ROWS, cols=COLS, w=W, h=H) -> np.ndarray:
    """Heights in nm in picture order: row 0 is the top edge, y = (rows - r - 0.5) h / rows."""
    x = (np.arange(cols) + 0.5) * w / cols
    y = (rows - np.arange(rows) - 0.5) * h / rows
    X, Y = np.meshgrid(x, y)
    return sum(a * np.exp(-((X - cx) ** 2 + (Y - cy) ** 2) / (2 * s * s)) for cx, cy, a, s in BUMPS)


def grid_text(z, sep="\t", fmt=repr) -> str:
    return "".join(sep.join(fmt(float(v)) for v in row) + "\n" for row in z)


def instrument_txt(path, z_nm=None, header=None, sep="\t", encoding="utf-8"):
    """An AFM text export: key : value header, a marker line, the grid in nm."""
    z = surface_nm() if z_nm is None else z_nm
    header = header if header is not None else (
        "Image Width : 128\nImage Height : 96\nReal Width : 10.00 μm\nReal Height : 7.50 μm\nZ Unit : nm\n"
        "\nStart of Data:\n")
    path.write_bytes((header + grid_text(z, sep)).encode(encoding))
    return path


def gwyddion_txt(path, z_m):
    """Gwyddion's ASCII export with its informational header: physical width/height, value units m."""
    path.write_text("# Channel: Height\n# Width: 10.000 µm\n# Height: 7.500 µm\n# Value units: m\n"
                    + grid_text(z_m), encoding="utf-8")
    return path


def gsf_bytes(values, fields) -> bytes:
    """A Gwyddion Simple Field file, as the format defines it, byte by byte."""
    rows, cols = np.shape(values)
    head = b"Gwyddion Simple Field 1.0\n" + b"".join(f"{k} = {v}\n".encode() for k, v in
                                                     [("XRes", cols), ("YRes", rows), *fields])
    pad = 4 - len(head) % 4                             # 1..4 NUL bytes: the data start on a multiple of 4
    return head + b"\0" * pad + np.asarray(values, dtype="<f4").tobytes()


GSF_FIELDS = [("XReal", "1e-05"), ("YReal", "7.5e-06"), ("XYUnits", "m"), ("ZUnits", "m")]


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_text_export_gives_the_file_heights_size_and_orientation(tmp_path):
    z = surface_nm()
    hf = sources.load_source(instrument_txt(tmp_path / "scan.txt", z))
    assert hf.shape == (ROWS, COLS)
    np.testing.assert_allclose(hf.heights, z[::-1] * 1e-9, rtol=1e-15, atol=0)   # nm -> m, row 0 = top
    assert hf.size_m == pytest.approx((W, H), rel=1e-12) and hf.dx == pytest.approx(W / COLS, rel=1e-12)
    # the tallest bump sits where BUMPS puts it, in physical x/y (y up): within a pixel (flipped: 2.5 um away)
    r, c = np.unravel_index(np.argmax(hf.heights), hf.shape)
    assert abs(hf.x[c] - 3e-6) <= hf.dx and abs(hf.y[r] - 5e-6) <= hf.dy
    assert np.array_equal(hf.heights[-1], z[0] * 1e-9)                       # the file's first row is the top
    assert hf.meta["kind"] == "scan" and hf.meta["file"] == str(tmp_path / "scan.txt")
    assert hf.meta["size_m"] == pytest.approx([W, H], rel=1e-12)
    assert hf.meta["scale"]["source_unit"] == "nm" and hf.meta["scale"]["m_per_unit"] == 1e-9


def test_gwyddion_ascii_export(tmp_path):
    z = surface_nm() * 1e-9
    hf = load_scan(gwyddion_txt(tmp_path / "g.txt", z))
    assert np.array_equal(hf.heights, z[::-1])
    assert hf.size_m == pytest.approx((W, H), rel=1e-12)
    assert "Gwyddion ASCII export, 'Height'" in hf.source and hf.meta["z_unit"] == "m"


# Each header spelling real exports use, with the grid in the unit the header states.
SPELLINGS = {
    "hash and equals, units in brackets": (
        "# Width (px) = 128\n# Height (px) = 96\n# X Length [nm] = 10000\n# Y Length [nm] = 7500\n"
        "# Z Units = um\n", 1e-3, " "),
    "semicolon comments, XY unit line, Angstrom, commas": (
        "; XRes: 128\n; YRes: 96\n; XReal: 1e-5\n; YReal: 7.5e-6\n; XY Unit: m\n; Height Unit: Angstrom\n"
        "# Data:\n", 10.0, ", "),
    "samples per line, lines, micro sign, tab": (
        "Samples per line = 128\nLines = 96\nX Scan Size = 10 µm\nY Scan Size = 7.5 µm\nValue Units = nm\n",
        1.0, "\t"),
    "Lateral Unit and pixels both ways": (
        "Pixels: 128 x 96\nX Range: 10\nY Range: 7.5\nLateral Units: um\nZ Unit: Å\n[Data]\n", 10.0, ";"),
    "Nanoscope-style ~m": (
        "XRes = 128\nYRes = 96\nXReal = 10 ~m\nYReal = 7.5 ~m\nZUnit = nm\n\n", 1.0, " "),
    "Gwyddion export in German": (
        "# Kanal: Topografie\n# Breite: 10.000 µm\n# Höhe: 7.500 µm\n# Value units: nm\n", 1.0, " "),
    "Gwyddion export in French": (
        "# Canal: Topographie\n# Largeur: 10.000 µm\n# Hauteur: 7500 nm\n# Value units: nm\n", 1.0, " "),
}


@pytest.mark.parametrize("name", SPELLINGS)
def test_header_spellings_give_the_same_field(tmp_path, name):
    header, per_nm, sep = SPELLINGS[name]
    z = surface_nm()
    hf = load_scan(instrument_txt(tmp_path / "s.txt", z * per_nm, header, sep))
    np.testing.assert_allclose(hf.heights, z[::-1] * 1e-9, rtol=1e-14, atol=0)
    assert hf.size_m == pytest.approx((W, H), rel=1e-12)


def test_decimal_commas_latin1_and_one_value_a_line(tmp_path):
    z = surface_nm()
    comma = "".join(";".join(repr(float(v)).replace(".", ",") for v in row) + "\n" for row in z)
    (tmp_path / "c.txt").write_bytes(("XRes=128\nYRes=96\nXReal=10 µm\nYReal=7.5 µm\nZ Unit=nm\n\n" + comma)
                                     .encode("latin-1"))                  # µ as the single byte 0xB5
    one = "".join(repr(float(v)) + "\n" for v in z.ravel())
    (tmp_path / "o.txt").write_text("Image Width: 128\nImage Height: 96\nScan Size: 10 µm\nZ Unit: nm\n" + one)
    a, b = load_scan(tmp_path / "c.txt"), load_scan(tmp_path / "o.txt")
    assert np.array_equal(a.heights, b.heights) and np.array_equal(a.heights, z[::-1] * 1e-9)
    assert a.size_m == pytest.approx((W, H)) and b.size_m == pytest.approx((W, W))   # Scan Size: a square


@pytest.mark.parametrize("title", ["", "a", "ab", "abc", "Topography (forward)"])
def test_gsf_read_byte_exact_with_every_padding(tmp_path, title):
    z = (surface_nm() * 1e-9).astype(np.float32)
    fields = GSF_FIELDS + ([("Title", title)] if title else [])
    (tmp_path / "s.gsf").write_bytes(gsf_bytes(z, fields))
    hf = load_scan(tmp_path / "s.gsf")
    assert np.array_equal(hf.heights, z[::-1].astype(np.float64))            # row 0 of the file = top
    assert hf.size_m == pytest.approx((W, H), rel=1e-12) and hf.meta["scale"]["m_per_unit"] == 1.0
    assert (f"Title {title!r}" in hf.source) == bool(title)


def test_gsf_paddings_cover_one_to_four_bytes(tmp_path):
    z = np.arange(6, dtype=np.float32).reshape(2, 3)
    pads = set()
    for t in ("a", "ab", "abc", "abcd"):
        data = gsf_bytes(z, [("Title", t)])
        pads.add(len(data) - 4 * z.size - data.index(b"\0"))
        (tmp_path / f"{t}.gsf").write_bytes(data)
        assert np.array_equal(read_gsf(tmp_path / f"{t}.gsf").values, z)
    assert pads == {1, 2, 3, 4}


@settings(max_examples=30, deadline=None)
@given(values=hnp.arrays(np.float32, hnp.array_shapes(min_dims=2, max_dims=2, min_side=2, max_side=9),
                         elements=st.floats(-1e3, 1e3, width=32)),
       title=st.text(st.characters(blacklist_characters="\0\n=", blacklist_categories=("Cs",)), max_size=9))
def test_gsf_values_round_trip_bit_exact(tmp_path_factory, values, title):
    p = tmp_path_factory.mktemp("g") / "r.gsf"
    p.write_bytes(gsf_bytes(values, [("ZUnits", "nm"), ("Title", title.strip() or "t")]))
    scan = read_gsf(p)
    assert scan.values.dtype == np.float32 and np.array_equal(scan.values, values) and scan.z_unit == "nm"


@pytest.mark.parametrize("form", ["txt", "gwyddion", "gsf"])
def test_cli_compile_takes_size_and_heights_from_the_file(tmp_path, capsys, form):
    z_nm = surface_nm()
    if form == "txt":
        src = instrument_txt(tmp_path / "scan.txt", z_nm)
    elif form == "gwyddion":
        src = gwyddion_txt(tmp_path / "gwy.txt", z_nm * 1e-9)
    else:
        z_nm = (z_nm * 1e-9).astype(np.float32).astype(np.float64) * 1e9
        src = tmp_path / "scan.gsf"
        src.write_bytes(gsf_bytes(z_nm * 1e-9, GSF_FIELDS))
    t = tmp_path / "t.npz"
    code, out, err = run(["compile", src, "-o", t, "--quantize", "float64"], capsys)
    assert code == 0 and t.is_file(), err
    unit = "nm" if form == "txt" else "m"
    assert f"scale: 1 {unit} of data -> 1 {unit} of height" in out and "10 x 7.5 um" in out
    code, out, _ = run(["inspect", t, "--json"], capsys)
    s = json.loads(out)
    g = s["meta"]["report"]["grid"]
    assert g == s["grid"] and (g["cols"], g["rows"]) == (COLS, ROWS)
    assert (g["cols"] * g["dx_m"], g["rows"] * g["dy_m"]) == pytest.approx((W, H), rel=1e-12)
    assert "10 x 7.5 um" in s["meta"]["source"]["description"]
    n = s["channels"]["normal_force"]
    n_gain = s["meta"]["mapping"]["n_gain"]
    assert (n["max"] - n["min"]) / n_gain == pytest.approx((z_nm.max() - z_nm.min()) * 1e-9, rel=1e-9)


def test_equal_options_are_accepted_and_height_fits(tmp_path, capsys):
    src = instrument_txt(tmp_path / "scan.txt")
    base = load_scan(src)
    for opts in ({"size": "10x7.5um"}, {"size": (W, H)}, {"resolution": "78.125nm"}, {"z_units": "nm"},
                 {"z_units": "nm", "size": "0.01x0.0075mm"}):
        assert np.array_equal(load_scan(src, **opts).heights, base.heights), opts
    res = load_scan(src, height_range="0:2mm")
    assert res.heights.min() == 0.0 and res.heights.max() == pytest.approx(2e-3, rel=1e-12)
    assert res.size_m == pytest.approx((W, H)) and "fitted onto 0..2 mm" in res.meta["scale"]["rule"]
    code, out, err = run(["compile", src, "-o", tmp_path / "t.npz", "--size", "10x7.5um", "--z-units", "nm",
                          "--height", "0:1mm", "--n-gain", "2N/mm"], capsys)
    assert code == 0, err
    assert "scale: 1 nm of data -> 8.317 um of height -> 16.63 mN of normal force" in out


CONTRADICTIONS = {
    "size": (["--size", "20x20mm"], "`--size` 20 x 20 mm contradicts '{src}' (Real Width 10.00 μm x "
                                    "Real Height 7.50 μm)"),
    "resolution": (["--resolution", "0.1um"], "`--resolution` 100 nm contradicts '{src}' (Real Width 10.00 μm x "
                                              "Real Height 7.50 μm: 78.125 nm a pixel over 128 x 96 pixels)"),
    "z units": (["--z-units", "um"], "`--z-units` um contradicts '{src}' (Z Unit nm)"),
    "channel": (["--channel", "r"], "`--channel` applies to colour pictures, not to scan '{src}'"),
    "mesh option": (["--up", "y"], "`--up` applies to meshes, not to '{src}' (an instrument scan)"),
    "both size and resolution": (["--size", "10x7.5um", "--resolution", "78.125nm"],
                                 "give `--size` or `--resolution`, not both (got 10 x 7.5 um and 78.125 nm)"),
}


@pytest.mark.parametrize("case", CONTRADICTIONS)
def test_options_that_contradict_the_file_are_refused_naming_both(tmp_path, capsys, case):
    src = instrument_txt(tmp_path / "scan.txt")
    argv, needle = CONTRADICTIONS[case]
    code, out, err = run(["compile", src, "-o", tmp_path / "t.npz", *argv], capsys)
    assert code == 2 and needle.format(src=src) in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "t.npz").exists()


def test_what_the_file_does_not_state_the_options_give(tmp_path):
    z = surface_nm()
    bare = instrument_txt(tmp_path / "bare.txt", z, "XRes: 128\nYRes: 96\n")
    with pytest.raises(InputError, match=r"does not state its physical size .* give `size`"):
        load_scan(bare, z_units="nm")
    with pytest.raises(InputError, match=r"does not state the unit of its heights .* give `z_units`"):
        load_scan(bare, size="10x7.5um")
    hf = load_scan(bare, size="10x7.5um", z_units="nm")
    assert np.array_equal(hf.heights, z[::-1] * 1e-9) and hf.size_m == pytest.approx((W, H))
    assert load_scan(bare, resolution="0.1mm", height_range="0:1mm").size_m == pytest.approx((12.8e-3, 9.6e-3))
    p = tmp_path / "nosize.gsf"
    p.write_bytes(gsf_bytes(z.astype(np.float32), [("ZUnits", "m")]))      # XReal defaults to 1: not a size
    with pytest.raises(InputError, match=r"does not state its physical size \(no XReal and YReal lines\)"):
        load_scan(p)
    p.write_bytes(gsf_bytes(z.astype(np.float32), [("XReal", "1e-5"), ("YReal", "7.5e-6"), ("ZUnits", "m")]))
    with pytest.raises(InputError, match=r"does not state its physical size \(no XYUnits line\)"):
        load_scan(p)
    assert load_scan(p, size="10x7.5um").size_m == pytest.approx((W, H))


def test_source_kind_options_and_suggestions():
    from shapedisplay.author.sources import source_kind, source_options
    assert [source_kind(p) for p in ("a.txt", "b.GSF", "c.png")] == ["scan", "scan", "image"]
    assert source_options("a.txt") == {}                     # the file states its size: none needed
    assert source_options("a.gsf", size="10x10um", z_units="nm") == {"size": pytest.approx((1e-5, 1e-5)),
                                                                      "z_units": "nm"}
    with pytest.raises(InputError, match=r"did you mean '\.txt'"):
        source_kind("scan.tx")
    with pytest.raises(InputError, match=r"did you mean '\.gsf'"):
        source_kind("scan.gfs")


# ----------------------------------------------------------------- hostile and broken files
def _gsf(tmp_path, data: bytes):
    p = tmp_path / "bad.gsf"
    p.write_bytes(data)
    return p


def _txt(tmp_path, data):
    p = tmp_path / "bad.txt"
    p.write_bytes(data if isinstance(data, bytes) else data.encode())
    return p


GOOD_HEADER = "Image Width: 4\nImage Height: 3\nReal Width: 4 um\nReal Height: 3 um\nZ Unit: nm\n"
GRID = "1 2 3 4\n5 6 7 8\n9 10 11 12\n"
Z = np.arange(12, dtype=np.float32).reshape(3, 4)

HOSTILE = {
    "truncated gsf": (lambda p: _gsf(p, gsf_bytes(Z, GSF_FIELDS)[:-3]), r"4 x XRes 4 x YRes 3 = \d+ \(truncated\)"),
    "gsf XRes lies": (lambda p: _gsf(p, gsf_bytes(Z, GSF_FIELDS).replace(b"XRes = 4", b"XRes = 5")),
                      "the file holds"),
    "gsf with bytes after the data": (lambda p: _gsf(p, gsf_bytes(Z, GSF_FIELDS) + b"\0\0\0\0"),
                                      "bytes after the data"),
    "huge gsf": (lambda p: _gsf(p, gsf_bytes(Z, GSF_FIELDS).replace(b"XRes = 4\nYRes = 3",
                                                                    b"XRes = 99999\nYRes = 99999")),
                 "exceeds the limit of .* samples"),
    "gsf wrong magic": (lambda p: _gsf(p, b"Gwyddion Simple Field 2.0\n" + bytes(64)), "not a Gwyddion Simple Field"),
    "gsf without NUL padding": (lambda p: _gsf(p, b"Gwyddion Simple Field 1.0\nXRes = 2\nYRes = 1\n"),
                                "ends before the NUL bytes"),
    "gsf bad padding": (lambda p: _gsf(p, b"Gwyddion Simple Field 1.0\nXRes = 2\nYRes = 1\n\0\x01" + bytes(8)),
                        r"must be closed by \d NUL bytes"),
    "gsf without YRes": (lambda p: _gsf(p, gsf_bytes(Z, []).replace(b"YRes = 3", b"YRez = 3")),
                         "lacks the mandatory 'YRes = N' line"),
    "gsf NaN": (lambda p: _gsf(p, gsf_bytes(np.where(Z == 6, np.nan, Z), GSF_FIELDS)),
                r"row 2 \(from the top\), column 3 holds nan"),
    "gsf current channel": (lambda p: _gsf(p, gsf_bytes(Z, GSF_FIELDS[:3] + [("ZUnits", "A")])),
                            "'A' is an ampere in Gwyddion's SI units"),
    "gsf binary garbage": (lambda p: _gsf(p, bytes(range(256)) * 64), "not a Gwyddion Simple Field"),
    "NaN cell": (lambda p: _txt(p, GOOD_HEADER + "1 2 3 4\n5 6 nan 8\n9 10 11 12\n"),
                 r"grid row 2 \(line 7\), column 3 holds nan"),
    "inf cell": (lambda p: _txt(p, GOOD_HEADER + "1 2 3 4\n5 6 7 8\n9 10 11 1e999\n"),
                 r"grid row 3 \(line 8\), column 4 holds inf"),
    "text cell": (lambda p: _txt(p, GOOD_HEADER + "1 2 3 4\n5 six 7 8\n9 10 11 12\n"),
                  r"grid row 2 \(line 7\), column 2: 'six' is not a number"),
    "ragged row": (lambda p: _txt(p, GOOD_HEADER + "1 2 3 4\n5 6 7\n9 10 11 12\n"),
                   r"grid row 2 \(line 7\) holds 3 values, row 1 holds 4; .*ragged"),
    "header says more rows": (lambda p: _txt(p, GOOD_HEADER.replace("Height: 3\n", "Height: 4\n") + GRID),
                              r"the header says 4 rows \(Image Width 4, Image Height 4\), the grid has 3 lines"),
    "header says other columns": (lambda p: _txt(p, GOOD_HEADER.replace("Width: 4\n", "Width: 5\n") + GRID),
                                  r"the header says 5 columns \(Image Width 5, Image Height 3\)"),
    "two column counts": (lambda p: _txt(p, "XRes: 5\n" + GOOD_HEADER + GRID),
                          "two values for the columns: 'XRes 5' and 'Image Width 4'"),
    "huge header dims": (lambda p: _txt(p, GOOD_HEADER.replace("Width: 4\n", "Width: 99999\n")
                                         .replace("Height: 3\n", "Height: 99999\n") + GRID),
                         "exceeds the limit of .* samples"),
    "binary garbage": (lambda p: _txt(p, bytes(range(256)) * 64), "NUL bytes: a binary file"),
    "million-line header": (lambda p: _txt(p, "Comment: x\n" * 1_000_000 + GRID),
                            "no grid of numbers within the first 200 lines"),
    "endless header line": (lambda p: _txt(p, "Note: " + "x" * 100_000 + "\n" + GRID),
                            "line 1 is longer than 4096 bytes and is not a row of numbers"),
    "no grid": (lambda p: _txt(p, GOOD_HEADER), "no grid of numbers after the header"),
    "voltage channel": (lambda p: _txt(p, GOOD_HEADER.replace("Z Unit: nm", "Z Unit: V") + GRID),
                        "unit 'V' is not a length"),
    "length without unit": (lambda p: _txt(p, GOOD_HEADER.replace("4 um", "4") + GRID),
                            "'Real Width 4' has no unit and the header has no XY Unit line"),
    "xyz point list": (lambda p: _txt(p, "".join(f"{x} {y} {x * y % 3}\n" for x in range(4) for y in range(5))),
                       r"20 lines of 3 numbers .*a list of points \(x y z a line\), not a grid"),
    "x z profile": (lambda p: _txt(p, "".join(f"{0.7 * i + 0.01 * (i % 3)} {np.sin(i)}\n" for i in range(40))),
                    r"40 lines of 2 numbers .*\(x z a line\)"),
    "sonar gsf": (lambda p: _bytes(p / "sonar.gsf", b"\x00\x00\x00\x0c\x00\x00\x00\x01GSF-v03.08\x00\x00" * 4),
                  "a Generic Sensor Format \\(sonar bathymetry\\) file"),
}


def _bytes(path, data):
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("case", HOSTILE)
def test_broken_and_hostile_files_are_one_line_exit_2(tmp_path, capsys, case):
    make, needle = HOSTILE[case]
    src = make(tmp_path)
    tracemalloc.start()
    try:
        code, out, err = run(["compile", src, "-o", tmp_path / "t.npz"], capsys)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert f"scan '{src}'" in err and re.search(needle, err), err
    assert not (tmp_path / "t.npz").exists()
    assert peak < 64 * 2 ** 20 + 4 * os.path.getsize(src), f"{peak / 2**20:.1f} MiB"   # nothing the size of the lie


def test_rows_longer_than_a_header_line_are_read(tmp_path):
    z = np.random.default_rng(1).random((3, 1000))          # rows of ~20 kB, beyond MAX_LINE_BYTES
    p = _txt(tmp_path, "XRes: 1000\nYRes: 3\nScan Size: 1 mm x 3 um\nZ Unit: um\n" + grid_text(z, " "))
    hf = load_scan(p)
    assert np.array_equal(hf.heights, z[::-1] * 1e-6) and hf.size_m == pytest.approx((1e-3, 3e-6))


def test_library_errors_are_shape_display_errors(tmp_path):
    p = _gsf(tmp_path, gsf_bytes(Z, GSF_FIELDS)[:-1])
    with pytest.raises(FileFormatError, match="truncated"):
        read_gsf(p)
    with pytest.raises(FileFormatError, match="no such file"):
        load_scan(tmp_path / "missing.gsf")
    with pytest.raises(InputError, match="exceeds the limit of"):
        instruments.read_text_export(_txt(tmp_path, GOOD_HEADER.replace("Height: 3", "Height: 99999")
                                          .replace("Width: 4", "Width: 99999") + GRID))


def test_a_relief_no_finger_feels_is_said_with_the_option_that_fits_it(tmp_path, capsys):
    """A 10 um scan of 20 nm relief keeps its units (1 N/mm: 20 uN of relief) and says so, naming --height."""
    src = tmp_path / "scan.txt"
    z = surface_nm() * (20.0 / np.ptp(surface_nm()))
    src.write_text("Image Width: 128\nImage Height: 96\nReal Width: 10 um\nReal Height: 7.5 um\nZ Unit: nm\n\n"
                   + "\n".join(" ".join(f"{v:.6g}" for v in row) for row in z) + "\n")
    code, out, err = run(["compile", src, "-o", tmp_path / "t.npz"], capsys)
    assert code == 0
    assert "warning: the relief is 2e-05 N of normal force" in err and "`--height` LO:HI" in err
    code, out, err = run(["compile", src, "-o", tmp_path / "t.npz", "--height", "0:1mm"], capsys)
    assert code == 0 and "warning" not in err
