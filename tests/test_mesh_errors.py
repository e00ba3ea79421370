"""Bad mesh input: every case gives one clear error (or a documented repair)."""
from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")

from shapedisplay.author import mesh, meshfiles  # noqa: E402
from shapedisplay.errors import (  # noqa: E402
    FileFormatError, InputError, MissingDependencyError, ShapeDisplayError, UnitError,
)

MM = 1e-3


def one_line(exc_info) -> str:
    msg = str(exc_info.value)
    assert "\n" not in msg
    return msg


@pytest.fixture()
def box_stl(tmp_path):
    path = tmp_path / "box.stl"
    path.write_bytes(trimesh.creation.box(extents=(10, 10, 4)).export(file_type="stl"))
    return path


# ----------------------------------------------------------------- files
def test_missing_file(tmp_path):
    with pytest.raises(FileFormatError) as e:
        mesh.mesh_to_heightfield(tmp_path / "nope.stl")
    assert "nope.stl" in one_line(e) and "file not found" in one_line(e)


def test_unsupported_suffix(tmp_path):
    p = tmp_path / "model.fbx"
    p.write_bytes(b"x")
    with pytest.raises(FileFormatError, match=r"unsupported suffix '\.fbx'; readable: \.stl"):
        mesh.mesh_to_heightfield(p)


def test_empty_file(tmp_path):
    p = tmp_path / "empty.obj"
    p.write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty.obj': file is empty"):
        mesh.mesh_to_heightfield(p)


@pytest.mark.parametrize("cut", [10, 84, 100, -10])
def test_truncated_binary_stl(box_stl, cut):
    data = box_stl.read_bytes()
    box_stl.write_bytes(data[:cut])
    with pytest.raises(FileFormatError) as e:
        mesh.mesh_to_heightfield(box_stl)
    assert "box.stl" in one_line(e) and "truncated" in one_line(e)


def test_truncated_ascii_stl(tmp_path):
    text = trimesh.creation.box(extents=(10, 10, 4)).export(file_type="stl_ascii")
    p = tmp_path / "ascii.stl"
    p.write_text(text[: len(text) // 2])
    with pytest.raises(FileFormatError, match="ASCII STL is truncated"):
        mesh.mesh_to_heightfield(p)


def test_ascii_stl_intact_reads(tmp_path):
    p = tmp_path / "ascii.stl"
    p.write_text(trimesh.creation.box(extents=(10, 10, 4)).export(file_type="stl_ascii"))
    hf = mesh.mesh_to_heightfield(p, resolution=1 * MM)
    assert hf.heights.max() == pytest.approx(4 * MM)


@pytest.mark.parametrize("name, data", [
    ("garbage.glb", b"glTF" + bytes(range(200))),
    ("garbage.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nend_header\n\x00\x01"),
])
def test_corrupt_files(tmp_path, name, data):
    p = tmp_path / name
    p.write_bytes(data)
    with pytest.raises(FileFormatError) as e:
        mesh.mesh_to_heightfield(p)
    assert name in one_line(e)


def test_file_without_triangles(tmp_path):
    p = tmp_path / "points.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(FileFormatError, match=r"points.obj': a point cloud \(3 points, no faces\); .*mesh the points"):
        mesh.mesh_to_heightfield(p)


def test_textured_ply_whose_texture_is_missing_compiles_without_a_traceback(tmp_path, capsys):
    """A scanner's PLY names its texture in a comment; the file is not there: the mesh compiles, the notes
    say textures are ignored, and trimesh's logged traceback never reaches the terminal."""
    p = tmp_path / "scan.ply"
    p.write_text("ply\nformat ascii 1.0\ncomment TextureFile missing_texture.png\nelement vertex 4\n"
                 "property float x\nproperty float y\nproperty float z\nelement face 2\n"
                 "property list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n"
                 "0 0 0\n10 0 1\n10 10 2\n0 10 1\n3 0 1 2 6 0 0 1 0 1 1\n3 0 2 3 6 0 0 1 1 0 1\n")
    from shapedisplay.cli.main import main
    assert main(["compile", str(p), "-o", str(tmp_path / "t.npz")]) == 0
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "Traceback" not in out
    assert "unable to load" not in err


def test_missing_trimesh_names_the_extra(box_stl, monkeypatch):
    monkeypatch.setitem(sys.modules, "trimesh", None)
    with pytest.raises(MissingDependencyError, match=r"Loading meshes needs trimesh: pip install 'shapedisplay\[mesh\]'"):
        mesh.mesh_to_heightfield(box_stl)


# ----------------------------------------------------------------- geometry
def test_empty_mesh_arrays():
    with pytest.raises(InputError, match="mesh is empty"):
        mesh.mesh_to_heightfield((np.zeros((0, 3)), np.zeros((0, 3), int)))


def test_nan_and_inf_vertices(tmp_path):
    box = trimesh.creation.box(extents=(10, 10, 4))
    v = box.vertices.copy()
    v[3] = [np.nan, 0, 0]
    v[5, 2] = np.inf
    with pytest.raises(InputError) as e:
        mesh.mesh_to_heightfield((v, box.faces))
    assert "2 NaN/inf vertices, first #3" in one_line(e)
    p = tmp_path / "nan.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n")
    with pytest.raises(InputError, match="nan.obj'.*NaN/inf"):
        mesh.mesh_to_heightfield(p)


def test_unused_nan_vertex_is_harmless():
    box = trimesh.creation.box(extents=(10, 10, 4))
    v = np.vstack([box.vertices, [[np.nan, np.nan, np.nan]]])
    hf = mesh.mesh_to_heightfield((v, box.faces), resolution=1 * MM)
    assert hf.heights.max() == pytest.approx(4 * MM)


def test_face_index_out_of_range():
    with pytest.raises(InputError, match=r"face indices must lie in 0\.\.2 \(got 0\.\.7\)"):
        mesh.mesh_to_heightfield((np.eye(3), [[0, 1, 7]]))


def test_degenerate_faces_are_dropped_and_counted():
    box = trimesh.creation.box(extents=(10, 10, 4))
    deg = [[0, 0, 1], [2, 2, 2], [0, 1, 1]]
    hf = mesh.mesh_to_heightfield((box.vertices, np.vstack([box.faces, deg])), resolution=1 * MM)
    ref = mesh.mesh_to_heightfield(box, resolution=1 * MM)
    assert hf.meta["degenerate_faces_dropped"] == 3 and ref.meta["degenerate_faces_dropped"] == 0
    np.testing.assert_array_equal(hf.heights, ref.heights)
    collinear = np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2.0]])
    with pytest.raises(InputError, match="all 1 faces are degenerate"):
        mesh.mesh_to_heightfield((collinear, [[0, 1, 2]]))


def test_zero_footprint_in_projection_plane():
    wall = np.array([[0, 0, 0], [10, 0, 0], [10, 0, 5], [0, 0, 5.0]])   # a sheet in the xz plane
    faces = [[0, 1, 2], [0, 2, 3]]
    with pytest.raises(InputError) as e:
        mesh.mesh_to_heightfield((wall, faces))
    assert "footprint seen along up=z has zero area" in one_line(e) and "choose another `up`" in one_line(e)
    hf = mesh.mesh_to_heightfield((wall, faces), up="-y", resolution=1 * MM)   # seen face-on it works
    assert hf.heights.max() == 0.0 and hf.shape == (6, 11)
    # two vertical sheets forming an L: non-zero bounding box, zero projected area
    L = np.array([[0, 0, 0], [10, 0, 0], [10, 0, 5], [0, 0, 5], [0, 10, 0], [0, 10, 5.0]])
    with pytest.raises(InputError, match="projected area 0"):
        mesh.mesh_to_heightfield((L, [[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 3]]))


def test_huge_grid_refused_before_allocation():
    box = trimesh.creation.box(extents=(10, 10, 4))
    with pytest.raises(InputError) as e:
        mesh.mesh_to_heightfield(box, resolution=1e-9)
    assert "grid of 10000001 x 10000001" in one_line(e) and "exceeds the limit" in one_line(e)
    with pytest.raises(InputError, match="with supersample=16: grid of"):
        mesh.mesh_to_heightfield(box, grid=(8000, 8000), supersample=16)


@pytest.mark.parametrize("scale, units, hint", [(1e-3, "mm", "units='m'"), (1e3, "mm", "units='")])
def test_implausible_footprint_warns_with_the_likely_unit(scale, units, hint):
    box = trimesh.creation.box(extents=(18 * scale, 18 * scale, 8 * scale))
    with pytest.warns(mesh.ImplausibleSizeWarning, match=f"looks implausible for a screen.*{hint}"):
        mesh.mesh_to_heightfield(box, grid=(20, 20), units=units)


def test_plausible_footprint_does_not_warn():
    box = trimesh.creation.box(extents=(0.018, 0.018, 0.008))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hf = mesh.mesh_to_heightfield(box, grid=(20, 20), units="m")
    assert hf.meta["footprint_m"] == pytest.approx([0.018, 0.018])


@pytest.mark.parametrize("units, factor", [("mm", 1e-3), ("cm", 1e-2), ("m", 1.0), ("in", 0.0254)])
def test_units_scale_lengths_and_heights(units, factor):
    box = trimesh.creation.box(extents=(2, 1, 0.5))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mesh.ImplausibleSizeWarning)
        hf = mesh.mesh_to_heightfield(box, grid=(11, 21), units=units)
    assert hf.dx == pytest.approx(2 * factor / 20)
    assert hf.heights.max() == pytest.approx(0.5 * factor)


# ----------------------------------------------------------------- parameters
@pytest.mark.parametrize("kwargs, pattern", [
    ({"units": "furlong"}, "unknown mesh units 'furlong'"),
    ({"resolution": 1e-3, "grid": (5, 5)}, "either `resolution` or `grid`, not both"),
    ({"resolution": -1e-3}, "`resolution` must be a finite length > 0"),
    ({"resolution": "0.1"}, "`resolution` needs a unit"),
    ({"resolution": "0.1 N"}, "`resolution` must be a length"),
    ({"grid": "1x5"}, "`grid` must be at least 2x2"),
    ({"grid": "512"}, "`grid` must look like 'ROWSxCOLS'"),
    ({"supersample": 0}, "`supersample` must be an integer from 1 to 16"),
    ({"supersample": 2.5}, "`supersample` must be an integer"),
    ({"supersample_mode": "median"}, "unknown supersample mode 'median'"),
    ({"up": "w"}, "`up` must be one of x, y, z"),
    ({"up": [0, 0, 0]}, "`up` must be an axis name, a non-zero finite 3-vector"),
    ({"up": np.diag([1.0, 1.0, -1.0])}, "must be a proper rotation"),
    ({"background": float("nan")}, "`background` must be a finite height"),
    ({"margin": "-1 mm"}, "`margin` must be a finite length >= 0"),
])
def test_bad_parameters_name_themselves(kwargs, pattern):
    box = trimesh.creation.box(extents=(10, 10, 4))
    with pytest.raises(ShapeDisplayError, match=pattern) as e:
        mesh.mesh_to_heightfield(box, **kwargs)
    one_line(e)


def test_unit_error_is_an_input_error():
    with pytest.raises(UnitError):
        mesh.mesh_to_heightfield(trimesh.creation.box(), resolution="3")


def test_bad_output_suffix_for_mesh_export(tmp_path):
    hf = mesh.mesh_to_heightfield(trimesh.creation.box(extents=(10, 10, 4)), resolution=1 * MM)
    with pytest.raises(FileFormatError, match=r"suffix must be \.stl or \.ply \(got '\.obj'\)"):
        mesh.save_heightfield_mesh(hf, tmp_path / "x.obj")
    with pytest.raises(FileFormatError, match="directory .* does not exist"):
        mesh.save_heightfield_mesh(hf, tmp_path / "missing" / "x.stl")
    assert list(tmp_path.iterdir()) == []


def _polygon_obj(path, n: int) -> None:
    """An OBJ of one face: a circle of ``n`` vertices (a fan of n - 2 slivers once triangulated)."""
    a = 2 * np.pi * np.arange(n) / n
    v = np.column_stack([30 + 20 * np.cos(a), 30 + 20 * np.sin(a), 1 + 0.5 * np.sin(5 * a)])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
    path.write_text("\n".join(lines) + "\nf " + " ".join(map(str, range(1, n + 1))) + "\n")


def test_obj_face_of_80000_vertices_is_refused_before_triangulating(tmp_path, capsys):
    """One face line of 80,000 vertices took 47.5 s (its fan rasterised sliver by sliver)."""
    import time

    from shapedisplay.cli.main import main
    path = tmp_path / "polygon.obj"
    _polygon_obj(path, 80_000)
    t0 = time.perf_counter()
    code = main(["compile", str(path), "-o", str(tmp_path / "t.npz")])
    elapsed = time.perf_counter() - t0
    out, err = capsys.readouterr()
    assert code == 2 and not out and not (tmp_path / "t.npz").exists()
    assert err == (f"shapedisplay compile: error: mesh '{path}': face on line 80001 has 80000 vertices, beyond the "
                   f"limit of {meshfiles.MAX_FACE_VERTICES} a face (shapedisplay.author.meshfiles.MAX_FACE_VERTICES); triangulate "
                   f"the polygon in a modelling program first\n")
    assert elapsed < 5


def test_obj_face_at_the_vertex_limit_still_reads(tmp_path):
    path = tmp_path / "polygon.obj"
    _polygon_obj(path, meshfiles.MAX_FACE_VERTICES)
    verts, faces, _ = mesh.load_mesh(path)
    assert len(verts) == meshfiles.MAX_FACE_VERTICES and len(faces) == meshfiles.MAX_FACE_VERTICES - 2
    path.write_text("f " + " ".join(["1"] * (meshfiles.MAX_FACE_VERTICES + 1)) + "\n")   # the first line too
    with pytest.raises(FileFormatError, match=r"face on line 1 has 4097 vertices"):
        mesh.load_mesh(path)


def test_size_scales_a_footprint_far_from_the_origin(tmp_path):
    """Coordinates near 3e38 mm scaled to 60 mm: the corner added back lost the footprint (ZeroDivisionError)."""
    s = 3e38
    v = np.array([[-s, -s, 0], [s, -s, 0], [-s, s, s], [s, s, s]])
    hf = mesh.mesh_to_heightfield((v, [[0, 1, 2], [1, 3, 2]]), size="60mm")
    assert hf.size_m[0] == pytest.approx(60 * MM, rel=0.01) and np.isfinite(hf.heights).all()
    assert hf.heights.max() == pytest.approx(30 * MM, rel=0.01)


def _ring(n: int) -> np.ndarray:
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([10 + 5 * np.cos(a), 10 + 5 * np.sin(a), np.ones(n)])


def _polygon_off(path, n: int) -> None:
    with open(path, "w") as f:
        f.write(f"OFF\n{n} 1 0\n")
        np.savetxt(f, _ring(n), fmt="%.5f")
        f.write(f"{n} " + " ".join(map(str, range(n))) + "\n")


def _polygon_ply(path, n: int, binary: bool, extra_triangles: int = 0) -> None:
    """One n-gon (and some triangles after it) in an ASCII or binary little-endian PLY."""
    head = (f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\nelement vertex {n}\n"
            f"property float x\nproperty float y\nproperty float z\nelement face {1 + extra_triangles}\n"
            f"property list uchar int vertex_indices\nend_header\n" if n < 256 else
            f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\nelement vertex {n}\n"
            f"property float x\nproperty float y\nproperty float z\nelement face {1 + extra_triangles}\n"
            f"property list uint int vertex_indices\nend_header\n")
    v = _ring(n)
    ctype = "<u1" if n < 256 else "<u4"
    with open(path, "wb") as f:
        f.write(head.encode())
        if binary:
            f.write(v.astype("<f4").tobytes())
            f.write(np.array([n], ctype).tobytes() + np.arange(n, dtype="<i4").tobytes())
            for _ in range(extra_triangles):
                f.write(np.array([3], ctype).tobytes() + np.arange(3, dtype="<i4").tobytes())
        else:
            np.savetxt(f, v, fmt="%.5f")
            f.write((f"{n} " + " ".join(map(str, range(n))) + "\n").encode())
            f.write(b"3 0 1 2\n" * extra_triangles)


@pytest.mark.parametrize("kind", ["off", "ply-ascii", "ply-binary"])
def test_off_and_ply_polygons_beyond_the_vertex_limit_are_refused_before_triangulating(tmp_path, capsys, kind):
    """An 800,000-vertex OFF face took 17 s and 480 MB to compile; OFF and PLY polygons now meet the OBJ rule."""
    import time

    from shapedisplay.cli.main import main
    n = 80_000
    path = tmp_path / ("polygon." + kind.split("-")[0])
    if kind == "off":
        _polygon_off(path, n)
    else:
        _polygon_ply(path, n, binary=kind == "ply-binary", extra_triangles=5)
    t0 = time.perf_counter()
    code = main(["compile", str(path), "-o", str(tmp_path / "t.npz")])
    elapsed = time.perf_counter() - t0
    out, err = capsys.readouterr()
    assert code == 2 and not out and not (tmp_path / "t.npz").exists()
    where = "#0" if kind == "ply-binary" else f"on line {n + (3 if kind == 'off' else 10)}"
    assert err == (f"shapedisplay compile: error: mesh '{path}': face {where} has {n} vertices, beyond the limit of "
                   f"{meshfiles.MAX_FACE_VERTICES} a face (shapedisplay.author.meshfiles.MAX_FACE_VERTICES); "
                   f"triangulate the polygon in a modelling program first\n")
    assert elapsed < 5


@pytest.mark.parametrize("binary", [False, True])
def test_ply_polygons_at_the_limit_and_mixed_sizes_still_read(tmp_path, binary):
    m = meshfiles.MAX_FACE_VERTICES
    path = tmp_path / "ok.ply"
    extra = 0 if binary else 3          # (trimesh reads a binary PLY of mixed uint-counted lists as truncated)
    _polygon_ply(path, m, binary=binary, extra_triangles=extra)
    verts, faces, _ = mesh.load_mesh(path)
    assert len(verts) == m and len(faces) == (m - 2) + extra
    if not binary:                      # (trimesh reads binary PLY faces of mixed sizes as truncated)
        path = tmp_path / "small.ply"
        _polygon_ply(path, 6, binary=binary, extra_triangles=2)      # a hexagon and triangles: mixed sizes
        verts, faces, _ = mesh.load_mesh(path)
        assert len(faces) == 4 + 2


def test_binary_ply_with_a_big_polygon_after_triangles_is_refused(tmp_path):
    """Mixed polygon sizes are walked record by record: a big one after small ones is found."""
    n = meshfiles.MAX_FACE_VERTICES + 1
    path = tmp_path / "late.ply"
    v = _ring(n)
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face 3\nproperty list ushort int vertex_indices\nend_header\n")
    tri = np.array([3], "<u2").tobytes() + np.arange(3, dtype="<i4").tobytes()
    big = np.array([n], "<u2").tobytes() + np.arange(n, dtype="<i4").tobytes()
    path.write_bytes(head.encode() + v.astype("<f4").tobytes() + tri + tri + big)
    with pytest.raises(FileFormatError, match=r"face #2 has 4097 vertices"):
        mesh.load_mesh(path)
