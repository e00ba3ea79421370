"""Meshes through the pipeline: heightmap command, compile, and agreement with analytic primitives."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")

from shapedisplay.author import mesh  # noqa: E402
from shapedisplay.author.compile import compile_heightfield  # noqa: E402
from shapedisplay.author.forces import MappingOptions  # noqa: E402
from shapedisplay.author.sources import load_source, raised_cosine_bump  # noqa: E402
from shapedisplay.cli.main import main  # noqa: E402

MM = 1e-3
ROOT = Path(__file__).resolve().parents[1]
KEYCAP = ROOT / "assets" / "meshes" / "keycap.stl"


def bump_mesh(A, rho, lo, hi, n):
    """Surface-only mesh (mm) of the raised-cosine bump A (1 + cos(pi r / rho)) / 2 centred on (10, 10).

    Vertices on an n x n grid spanning [lo, hi]^2: positions unrelated to the samples.
    """
    t = np.linspace(lo, hi, n)
    X, Y = np.meshgrid(t, t)
    r = np.hypot(X - 10, Y - 10)
    Z = np.where(r < rho, A * 0.5 * (1 + np.cos(np.pi * np.minimum(r, rho) / rho)), 0.0)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = np.vstack([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]), faces, (hi - lo) / (n - 1)


@pytest.fixture(scope="module")
def bump_pair():
    """The same raised-cosine bump as an analytic primitive and as a mesh, on the same samples."""
    A, rho, dx = 1.0, 5.0, 0.2                        # mm
    prim = raised_cosine_bump(A * MM, rho * MM, (20 * MM, 20 * MM), dx * MM)
    # the primitive's samples are cell centres 0.1 .. 19.9 mm; the mesh footprint spans exactly that
    lo, hi = prim.x0 / MM, prim.x0 / MM + (prim.cols - 1) * dx
    v, f, s = bump_mesh(A, rho, lo, hi, 283)
    hf = mesh.mesh_to_heightfield((v, f), resolution=dx * MM)
    # linear interpolation on right triangles with legs s: |error| <= M s^2 with
    # M = max second directional derivative = A/2 (pi/rho)^2
    tol = A * MM / 2 * (math.pi / (rho * MM)) ** 2 * (s * MM) ** 2
    return prim, hf, tol


def test_mesh_and_primitive_height_fields_agree(bump_pair):
    prim, hf, tol = bump_pair
    assert hf.shape == prim.shape and hf.dx == pytest.approx(prim.dx) and hf.dy == pytest.approx(prim.dy)
    # same samples: the mesh frame starts at its footprint corner, the primitive's at 0
    assert prim.x0 + hf.meta["model_origin_m"][0] == pytest.approx(prim.x0 * 2)
    err = np.abs(hf.heights - prim.heights)
    assert err.max() <= tol
    assert tol < 1.5e-6                               # stated: agreement within 1.5 um on a 1 mm bump


@pytest.mark.parametrize("mapping", [MappingOptions(), MappingOptions(slope_friction_gain=0.5)])
def test_mesh_and_primitive_compile_to_matching_tables(bump_pair, mapping):
    prim, hf, tol = bump_pair
    ta = compile_heightfield(prim, mapping=mapping)
    tb = compile_heightfield(hf, mapping=mapping)
    assert ta.table.channels == tb.table.channels
    for name in ta.table.channels:
        qa = ta.report["quantization"][name]["max_error"]
        qb = tb.report["quantization"][name]["max_error"]
        if name == "normal_force":
            bound = mapping.n_gain * tol
        else:   # central differences: height error 2 tol over 2 dx
            bound = tol / prim.dx
        diff = np.abs(ta.table.dense(name) - tb.table.dense(name))
        assert diff.max() <= bound + qa + qb + 1e-12, name


# ------------------------------------------------------------------ CLI
def test_heightmap_command_writes_every_format(tmp_path, capsys):
    for suffix in (".npy", ".npz", ".png", ".stl", ".ply"):
        out = tmp_path / f"keycap{suffix}"
        rc = main(["heightmap", str(KEYCAP), "-o", str(out), "--resolution", "0.5mm", "--margin", "1mm"])
        assert rc == 0 and out.is_file()
    text = capsys.readouterr().out
    assert "41 x 41 samples" in text and "5120 triangles from 1 mesh(es), 0 degenerate faces dropped" in text
    ref = mesh.mesh_to_heightfield(KEYCAP, resolution=0.5 * MM, margin=1 * MM)
    np.testing.assert_array_equal(np.load(tmp_path / "keycap.npy")[::-1], ref.heights)   # top view
    back = mesh.mesh_to_heightfield(tmp_path / "keycap.stl", resolution=0.5 * MM)
    np.testing.assert_allclose(back.heights, ref.heights + 1 * MM, atol=2e-8)
    # the PNG reads back through the image source with the size and range the command printed
    img = load_source(tmp_path / "keycap.png", size="20.5x20.5mm", height_range=(0.0, ref.heights.max()))
    np.testing.assert_allclose(img.heights, ref.heights, atol=ref.heights.max() / 65535)
    assert img.dx == pytest.approx(ref.dx)


def test_heightmap_command_options(tmp_path, capsys):
    out = tmp_path / "k.npy"
    rc = main(["heightmap", str(KEYCAP), "-o", str(out), "--samples", "61x31", "--up", "z",
               "--supersample", "3", "--supersample-mode", "max", "--background=-1mm"])
    assert rc == 0
    h = np.load(out)[::-1]                    # written as the top view
    assert h.shape == (31, 61)
    ref = mesh.mesh_to_heightfield(KEYCAP, grid=(31, 61), supersample=3, supersample_mode="max",
                                   background=-1 * MM)
    np.testing.assert_allclose(h, ref.heights, atol=1e-15)
    rc = main(["heightmap", str(KEYCAP), "-o", str(out), "--grid", "9x9", "--up", "0,0,1"])
    assert rc == 0


def test_heightmap_samples_are_cols_by_rows_and_grid_is_the_old_rows_by_cols(tmp_path, capsys):
    out = tmp_path / "k.npy"
    assert main(["heightmap", str(KEYCAP), "-o", str(out), "--samples", "40x12"]) == 0
    assert np.load(out).shape == (12, 40)                       # rows x cols of the array
    assert "40 x 12 samples (cols x rows)" in capsys.readouterr().out
    assert main(["heightmap", str(KEYCAP), "-o", str(out), "--grid", "12x40"]) == 0
    assert np.load(out).shape == (12, 40)
    assert "--grid is now --samples COLSxROWS" in capsys.readouterr().err
    for argv, pattern in ((["--samples", "40x12", "--grid", "12x40"], "not both"),
                          (["--samples", "40x12", "--resolution", "0.1mm"], "`--resolution` or `--samples`"),
                          (["--samples", "40"], "`--samples` must look like COLSxROWS"),
                          (["--samples", "1x12"], "at least 2x2")):
        assert main(["heightmap", str(KEYCAP), "-o", str(out), *argv]) == 2
        err = capsys.readouterr().err
        assert pattern in err and "Traceback" not in err, err


@pytest.mark.parametrize("argv, pattern", [
    (["--resolution", "0.0001mm"], "grid of 180001 x 180001"),
    (["--resolution", "0.1"], "`--resolution` needs a unit"),
    (["--units", "yd"], "unknown mesh units 'yd'"),
    (["--up", "q"], "`--up` must be one of x, y, z"),
    (["--up", "1,a,0"], "`--up` direction must be three numbers"),
    (["--size", "0x1mm"], "`--size` must be positive"),
    (["--height", "2:1mm"], "`--height` must run low:high"),
    (["--channel", "r"], "`--channel` applies to image sources, not to"),
])
def test_heightmap_command_errors_exit_2_without_output(tmp_path, capsys, argv, pattern):
    out = tmp_path / "map.npy"
    rc = main(["heightmap", str(KEYCAP), "-o", str(out)] + argv)
    err = capsys.readouterr().err
    assert rc == 2
    assert pattern in err and "Traceback" not in err
    assert err.count("error:") == 1
    assert list(tmp_path.iterdir()) == []


def test_heightmap_command_bad_files(tmp_path, capsys):
    bad = tmp_path / "cut.stl"
    bad.write_bytes(KEYCAP.read_bytes()[:1000])
    for src, pattern in ((bad, "binary STL is truncated"), (tmp_path / "none.obj", "no such file")):
        rc = main(["heightmap", str(src), "-o", str(tmp_path / "m.png")])
        assert rc == 2 and pattern in capsys.readouterr().err
    rc = main(["heightmap", str(KEYCAP), "-o", str(tmp_path / "m.bmp")])
    assert rc == 2 and "unsupported suffix '.bmp'" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.stl"]


@pytest.mark.parametrize("opt, value", [("--up", "y"), ("--units", "m"), ("--supersample", "2"),
                                        ("--supersample-mode", "max"), ("--background", "1mm"),
                                        ("--margin", "1mm")])
def test_heightmap_mesh_options_on_an_image_are_refused(tmp_path, capsys, opt, value):
    """Mesh options used to be silently ignored for image sources."""
    from shapedisplay.author.imageio import write_png
    write_png(tmp_path / "a.png", np.arange(12, dtype=np.uint8).reshape(3, 4))
    rc = main(["heightmap", str(tmp_path / "a.png"), "-o", str(tmp_path / "m.npy"), "--size", "4x3mm",
               "--height", "0:1mm", opt, value])
    err = capsys.readouterr().err
    assert rc == 2 and f"`{opt}` applies to meshes, not to '{tmp_path / 'a.png'}' (an image)" in err
    assert not (tmp_path / "m.npy").exists()


def test_heightmap_command_prints_the_unit_warning_before_the_error(tmp_path, capsys):
    rc = main(["heightmap", str(KEYCAP), "-o", str(tmp_path / "m.npy"), "--units", "m", "--resolution", "0.1mm"])
    err = capsys.readouterr().err
    assert rc == 2
    lines = err.strip().splitlines()
    assert "warning:" in lines[0] and "looks implausible" in lines[0] and "units='mm'" in lines[0]
    assert "error:" in lines[1] and "exceeds the limit" in lines[1]
    rc = main(["heightmap", str(KEYCAP), "-o", str(tmp_path / "m.npy"), "--units", "m", "--grid", "8x8"])
    assert rc == 0 and "warning:" in capsys.readouterr().err


def test_compile_command_prints_the_unit_warning_as_one_line(tmp_path, capsys):
    """compile used to let Python print the warning with a source line under it."""
    rc = main(["compile", str(KEYCAP), "-o", str(tmp_path / "k.npz"), "--units", "m", "-q"])
    err = capsys.readouterr().err
    assert rc == 0 and (tmp_path / "k.npz").is_file()
    assert err.startswith("shapedisplay compile: warning: mesh ") and "looks implausible" in err
    assert len(err.strip().splitlines()) == 1


def test_compile_command_takes_a_mesh(tmp_path, capsys):
    out = tmp_path / "keycap.npz"
    rc = main(["compile", str(KEYCAP), "-o", str(out), "--resolution", "0.5mm", "--up", "z", "--units", "mm"])
    assert rc == 0 and out.is_file()
    from shapedisplay.table.model import FrictionTable
    table = FrictionTable.load(out)
    ref = mesh.mesh_to_heightfield(KEYCAP, resolution=0.5 * MM)
    assert (table.grid.rows, table.grid.cols) == ref.shape
    n = table.dense("normal_force")
    m = MappingOptions()
    q = table.quant["normal_force"].max_error
    np.testing.assert_allclose(n, m.n_base + m.n_gain * ref.heights, atol=q + 1e-9)


def test_heightmap_command_exports_an_image_source_as_a_mesh(tmp_path, capsys):
    png = ROOT / "assets" / "maps" / "tent_profile.png"
    out = tmp_path / "tent.ply"
    rc = main(["heightmap", str(png), "-o", str(out), "--size", "60x4mm", "--height", "0:2mm", "--surface-only"])
    assert rc == 0, capsys.readouterr().err
    src = load_source(png, size="60x4mm", height_range="0:2mm")
    back = mesh.mesh_to_heightfield(out, resolution=src.dx)
    assert back.shape == src.shape
    np.testing.assert_allclose(back.heights, src.heights - src.heights.min(), atol=1e-8)
