"""One orientation everywhere: x to the right, y up; a height picture is the top view.

An asymmetric glyph (an "F": no mirror or rotation maps it onto itself) goes
through picture -> mesh -> picture and mesh -> picture -> mesh, through the
compiler and through the preview's top view, and must come out the same way
round every time.
"""
import numpy as np
import pytest

from shapedisplay.author import mesh, sources
from shapedisplay.author.imageio import read_picture, write_png
from shapedisplay.cli.main import main

ROWS, COLS = 30, 20          # picture rows (top to bottom), columns (left to right); 1 mm pixels


def glyph() -> np.ndarray:
    """An "F" in picture order: stem on the left, top bar at the top."""
    g = np.zeros((ROWS, COLS), np.uint16)
    g[3:27, 3:7] = 65535       # stem
    g[3:7, 3:17] = 65535       # top bar
    g[13:16, 3:13] = 65535     # middle bar
    return g


def _agree(a, b) -> float:
    return float(((a > 0.5) == (b > 0.5)).mean())


def test_picture_is_the_top_view_in_the_compiled_table(tmp_path):
    from shapedisplay.author.compile import compile_heightfield
    write_png(tmp_path / "F.png", glyph())
    t = compile_heightfield(sources.load_image(tmp_path / "F.png", "20x30mm", "0:1mm")).table
    n = lambda x_mm, y_mm: float(t.sample("normal_force", x_mm * 1e-3, y_mm * 1e-3))   # noqa: E731
    # the top bar is near the top edge of the picture: large y; the stem on the left: small x
    assert n(12, 25) > n(12, 5) + 0.9          # top bar present, nothing at the same x near the bottom
    assert n(4.5, 5) > n(15.5, 5) + 0.9        # the stem reaches the bottom on the left, not on the right


def test_picture_mesh_picture_round_trip(tmp_path, capsys):
    write_png(tmp_path / "F.png", glyph())
    assert main(["heightmap", str(tmp_path / "F.png"), "-o", str(tmp_path / "F.stl"), "--size", "20x30mm",
                 "--height", "0:1mm", "--surface-only"]) == 0
    # the mesh seen from above: the top bar at large y (mesh coordinates are mm, z up)
    v, f, _ = mesh.load_mesh(tmp_path / "F.stl")
    high = v[v[:, 2] > 0.5]
    assert high[:, 1].max() > 25 and high[high[:, 1] > 25][:, 0].max() > 15     # bar reaches x = 16 mm up top
    assert high[high[:, 1] < 5][:, 0].max() < 7.5                              # only the stem at the bottom
    assert main(["heightmap", str(tmp_path / "F.stl"), "-o", str(tmp_path / "back.png"), "--resolution", "1mm"]) == 0
    back = read_picture(tmp_path / "back.png").values
    assert back.shape == (ROWS, COLS)
    assert np.array_equal(back, glyph())                 # the same picture, the same way round
    capsys.readouterr()


def test_mesh_picture_mesh_round_trip(tmp_path, capsys):
    hf = sources.load_image(_write(tmp_path), "20x30mm", "0:1mm")
    mesh.save_heightfield_mesh(hf, tmp_path / "F.ply", solid=False)
    ref = mesh.mesh_to_heightfield(tmp_path / "F.ply", resolution="1mm")
    assert main(["heightmap", str(tmp_path / "F.ply"), "-o", str(tmp_path / "F.png"), "--resolution", "1mm"]) == 0
    pic = read_picture(tmp_path / "F.png").values
    assert _agree(pic / 65535, glyph() / 65535) == 1.0    # the picture of the mesh is the glyph, top row first
    assert main(["heightmap", str(tmp_path / "F.png"), "-o", str(tmp_path / "back.ply"), "--size", "20x30mm",
                 "--height", "0:1mm", "--surface-only"]) == 0
    back = mesh.mesh_to_heightfield(tmp_path / "back.ply", resolution="1mm")
    assert back.shape == ref.shape
    np.testing.assert_allclose(back.heights, ref.heights, atol=1e-9)
    capsys.readouterr()


def test_npy_arrays_are_pictures_too(tmp_path, capsys):
    np.save(tmp_path / "F.npy", glyph() / 65535 * 1e-3)
    hf = sources.load_image(tmp_path / "F.npy", "20x30mm", None)
    assert hf.heights[-5, 12] == pytest.approx(1e-3) and hf.heights[4, 12] == 0.0    # top bar at large y
    assert main(["heightmap", str(tmp_path / "F.npy"), "-o", str(tmp_path / "out.npy"), "--size", "20x30mm"]) == 0
    assert np.array_equal(np.load(tmp_path / "out.npy"), glyph() / 65535 * 1e-3)
    capsys.readouterr()


def test_preview_top_view_shows_the_picture_as_an_image_viewer_does(tmp_path):
    pytest.importorskip("pyvista")
    from PIL import Image

    from shapedisplay import viewer
    from shapedisplay.errors import ShapeDisplayError
    try:
        viewer.check_offscreen()
    except ShapeDisplayError as exc:
        pytest.skip(f"no off-screen OpenGL: {exc}")
    hf = sources.load_image(_write(tmp_path), "20x30mm", "0:1mm")
    p = viewer.render(viewer.model_from_heightfield(hf), "height", size=(400, 600), view="top", cmap="gray",
                      lighting=False, scalar_bar=False, annotations=False)
    img = p.screenshot()[..., 0].astype(float)
    p.close()
    dark = img < 60                                      # the flat ground around the glyph is black
    rows, cols = np.nonzero(dark)
    crop = img[rows.min():rows.max() + 1, cols.min():cols.max() + 1]
    small = np.asarray(Image.fromarray(crop.astype(np.uint8)).resize((COLS, ROWS), Image.BILINEAR)) / 255
    g = glyph() / 65535
    same = _agree(small, g)
    assert same > 0.93
    assert same > _agree(small, g[::-1]) + 0.08 and same > _agree(small, g[:, ::-1]) + 0.08   # not mirrored


def _write(tmp_path):
    write_png(tmp_path / "F.png", glyph())
    return tmp_path / "F.png"
