"""PLY triangle strips as scanners and plyfile write them: every layout reads, the surface is the one the
strips describe, and a broken strip file is one line and exit 2."""
from __future__ import annotations

import numpy as np
import pytest

from shapedisplay.author import meshfiles
from shapedisplay.cli.main import main
from shapedisplay.author.mesh import load_mesh, mesh_to_heightfield, strip_triangles
from shapedisplay.errors import FileFormatError

plyfile = pytest.importorskip("plyfile")
trimesh = pytest.importorskip("trimesh")

N_X, N_Y = 17, 11       # grid vertices along x and y (rows != columns catches a transposition)


def _grid():
    """A bump on a 16 x 10 mm grid: vertex (j, i) at x = i mm, y = j mm."""
    x, y = np.meshgrid(np.arange(N_X, dtype=float), np.arange(N_Y, dtype=float))
    z = 2.0 * np.exp(-((x - 8.0) ** 2 + (y - 5.0) ** 2) / 8.0)
    return np.column_stack([x.ravel(), y.ravel(), z.ravel()])


def _vid(j, i):
    return j * N_X + i


def _row_strip(j):
    """One strip across row pair (j, j+1), counter-clockwise seen from +z."""
    s = []
    for i in range(N_X):
        s += [_vid(j + 1, i), _vid(j, i)]
    return s


def _faces():
    """The triangles the strips describe, listed as faces."""
    return np.concatenate([strip_triangles([_row_strip(j)], N_X * N_Y) for j in range(N_Y - 1)])


def _write_strips(path, strips, text):
    v = _grid()
    vert = np.empty(len(v), dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("red", "u1")])
    vert["x"], vert["y"], vert["z"], vert["red"] = v[:, 0], v[:, 1], v[:, 2], 200
    st = np.empty(len(strips), dtype=[("vertex_indices", "O")])
    st["vertex_indices"] = [np.asarray(s, dtype="i4") for s in strips]
    plyfile.PlyData([plyfile.PlyElement.describe(vert, "vertex"),
                     plyfile.PlyElement.describe(st, "tristrips", len_types={"vertex_indices": "i4"})],
                    text=text).write(str(path))
    return path


def _one_strip():
    """All rows in one strip, -1 between them (the layout of the Stanford scans)."""
    s = []
    for j in range(N_Y - 1):
        s += _row_strip(j) + [-1]
    return [s[:-1]]


LAYOUTS = {
    "one-strip": _one_strip,
    "strip-per-row": lambda: [_row_strip(j) for j in range(N_Y - 1)],
    "uneven": lambda: [_row_strip(0) + [-1] + _row_strip(1)] + [_row_strip(j) for j in range(2, N_Y - 1)],
}


def test_strip_triangles_closed_form():
    # a, b, c, d, e: (a b c), (c b d) flipped, (c d e); -1 restarts; repeated vertices drop the triangle
    t = strip_triangles([[0, 1, 2, 3, 4, -1, 5, 6, 7, 7, 8]], 9)
    assert t.tolist() == [[0, 1, 2], [2, 1, 3], [2, 3, 4], [5, 6, 7]]
    assert strip_triangles([[0, 1]], 2).shape == (0, 3)


def test_strips_of_every_layout_and_encoding_read_as_the_faces(tmp_path):
    ref_path = tmp_path / "faces.ply"
    trimesh.Trimesh(_grid(), _faces(), process=False).export(str(ref_path))
    ref = mesh_to_heightfield(ref_path, resolution="0.25mm", units="mm")
    assert np.ptp(ref.heights) > 1.5e-3                 # the bump is there (2 mm)
    for name, strips in LAYOUTS.items():
        for text in (False, True):
            p = _write_strips(tmp_path / f"{name}-{'ascii' if text else 'binary'}.ply", strips(), text)
            v, f, info = load_mesh(p)
            assert sorted(map(tuple, f.tolist())) == sorted(map(tuple, _faces().tolist())), (name, text)
            assert info["notes"] == ["vertex colours of 1 mesh ignored"]
            hf = mesh_to_heightfield(p, resolution="0.25mm", units="mm")
            np.testing.assert_array_equal(hf.heights, ref.heights)


def test_strips_cli_compile(tmp_path, capsys):
    p = _write_strips(tmp_path / "scan.ply", _one_strip(), text=False)
    out = tmp_path / "t.npz"
    assert main(["compile", str(p), "-o", str(out), "--resolution", "0.25mm", "--units", "mm"]) == 0, \
        capsys.readouterr().err
    assert out.exists()


@pytest.mark.parametrize("case", ["index", "no-list", "no-vertex", "garbage", "records"])
def test_broken_strip_files_are_one_line(tmp_path, capsys, monkeypatch, case):
    p = tmp_path / f"{case}.ply"
    if case == "index":
        _write_strips(p, [[0, 1, 2, 99999]], text=False)
        expect = "vertex index 99999"
    elif case == "no-list":
        p.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement tristrips 1\nproperty int n\nend_header\n0 0 0\n1 0 0\n0 1 0\n3\n")
        expect = "no list property vertex_indices"
    elif case == "no-vertex":
        p.write_text("ply\nformat ascii 1.0\nelement tristrips 1\nproperty list uchar int vertex_indices\n"
                     "end_header\n3 0 1 2\n")
        expect = "without an element 'vertex'"
    elif case == "garbage":
        p.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                      b"property float z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n"
                      + b"\x00" * 36 + b"\xff\xff\xff\x7f")
        expect = "cannot read PLY file"
    else:
        monkeypatch.setattr(meshfiles, "MAX_PLY_STRIPS", 3)
        monkeypatch.setattr("shapedisplay.author.mesh.MAX_PLY_STRIPS", 3)
        _write_strips(p, [_row_strip(j) for j in range(N_Y - 1)], text=True)
        expect = "exceed the limit of 3"
    with pytest.raises(FileFormatError, match=expect):
        load_mesh(p)
    rc = main(["compile", str(p), "-o", str(tmp_path / "t.npz"), "--resolution", "1mm"])
    stderr = capsys.readouterr().err
    assert rc == 2
    assert len(stderr.strip().splitlines()) == 1 and "Traceback" not in stderr, stderr
    assert str(p) in stderr and expect in stderr
    assert not (tmp_path / "t.npz").exists()
