"""Real material in: physical units of data, meshes at any size, strips, scene graphs, what is ignored."""
import json

import numpy as np
import pytest

from shapedisplay.author import mesh
from shapedisplay.table.model import FrictionTable
from shapedisplay.cli.main import main

trimesh = pytest.importorskip("trimesh")


def _compile(argv, capsys):
    code = main(["compile", *[str(a) for a in argv]])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


# ----------------------------------------------------------------- units
def test_metres_float64_and_nanometres_float32_give_the_same_table(tmp_path, capsys):
    """An AFM scan stored in metres or in nanometres: --height fits either onto the same relief."""
    rng = np.random.default_rng(11)
    y, x = np.mgrid[0:48, 0:64]
    nm = (286 + 250 * np.sin(x / 7.0) * np.cos(y / 9.0) + 30 * rng.standard_normal(x.shape)).astype(np.float32)
    np.save(tmp_path / "scan_nm.npy", nm)
    np.save(tmp_path / "scan_m.npy", nm.astype(np.float64) * 1e-9)
    common = ["--size", "64x48mm", "--height", "0:2mm", "--json"]
    rep_m = json.loads(_compile([tmp_path / "scan_m.npy", "-o", tmp_path / "m.npz", *common], capsys))
    rep_nm = json.loads(_compile([tmp_path / "scan_nm.npy", "-o", tmp_path / "nm.npz", *common, "--z-units", "nm"],
                                 capsys))
    a, b = FrictionTable.load(tmp_path / "m.npz"), FrictionTable.load(tmp_path / "nm.npz")
    assert a.channels == b.channels == ["normal_force"]
    assert a.quant == b.quant
    for name in a.channels:
        assert np.array_equal(a.codes[name], b.codes[name])
    # the report states the scale from the source unit to height and to force
    span_nm = float(nm.max()) - float(nm.min())
    sc = rep_nm["scale"]
    assert sc["source_unit"] == "nm" and sc["m_per_unit"] == pytest.approx(2e-3 / span_nm, rel=1e-6)
    assert sc["n_per_source_unit"] == pytest.approx(1000.0 * 2e-3 / span_nm, rel=1e-6)
    assert rep_m["scale"]["source_unit"] == "m"
    assert rep_m["scale"]["m_per_unit"] == pytest.approx(sc["m_per_unit"] * 1e9, rel=1e-6)
    text = _compile([tmp_path / "scan_nm.npy", "-o", tmp_path / "t.npz", "--size", "64x48mm", "--height", "0:2mm",
                     "--z-units", "nm"], capsys)
    assert "scale: 1 nm of data -> " in text and "of normal force (n_gain 1 N/mm)" in text
    assert f"data range {float(nm.min()):.6g}..{float(nm.max()):.6g} nm fitted onto 0..2 mm" in text


def test_float_data_without_height_keep_their_unit(tmp_path, capsys):
    np.save(tmp_path / "h.npy", np.array([[0.0, 250.0], [500.0, 1000.0]], dtype=np.float32))   # micrometres
    text = _compile([tmp_path / "h.npy", "-o", tmp_path / "t.npz", "--size", "2x2mm", "--z-units", "um"], capsys)
    assert "scale: 1 um of data -> 1 um of height -> 1 mN of normal force" in text
    n = FrictionTable.load(tmp_path / "t.npz").dense("normal_force")
    assert n.max() == pytest.approx(0.5 + 1.0, abs=0.01)          # 1 mm of height at 1 N/mm on 0.5 N


# ----------------------------------------------------------------- tall meshes
def _pyramid(tmp_path, height_mm=30.0):
    """A 20 x 20 mm square pyramid, `height_mm` tall (mm units), as a binary STL."""
    v = np.array([[0, 0, 0], [20, 0, 0], [20, 20, 0], [0, 20, 0], [10, 10, height_mm]], float)
    f = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]])
    p = tmp_path / "pyramid.stl"
    trimesh.Trimesh(v, f, process=False).export(p)
    return p


def test_a_mesh_taller_than_the_force_range_is_fitted_by_default(tmp_path, capsys):
    src = _pyramid(tmp_path)
    rep = json.loads(_compile([src, "-o", tmp_path / "fit.npz", "--resolution", "0.5mm", "--json"], capsys))
    c = rep["clamped"]["normal_force"]
    assert c["above"] == 0 and c["below"] == 0                       # nothing clamped
    assert any("heights scaled x" in n and "would clamp" in n for n in rep["source_notes"])
    assert "to fit the device's" in rep["scale"]["rule"]
    lo, hi = 0.0, 10.0                                               # the default device's force range
    n = FrictionTable.load(tmp_path / "fit.npz").dense("normal_force")
    assert n.max() == pytest.approx(hi, abs=0.05) and n.min() >= lo
    # relief scale stated: 30 mm of model -> (10 - 0.5) / 30 mm of height
    assert rep["scale"]["m_per_unit"] == pytest.approx(1e-3 * 9.5 / 30.0, rel=1e-3)
    text = _compile([src, "-o", tmp_path / "fit2.npz", "--resolution", "0.5mm"], capsys)
    assert "note: relief 0..30 mm would clamp" in text and "clamped normal_force" not in text


def test_an_explicit_gain_or_height_keeps_the_users_scale(tmp_path, capsys):
    src = _pyramid(tmp_path)
    rep = json.loads(_compile([src, "-o", tmp_path / "g.npz", "--resolution", "0.5mm", "--n-gain", "1N/mm",
                               "--json"], capsys))
    assert rep["clamped"]["normal_force"]["above"] > 0                 # the user's gain, clamped and reported
    assert not any("scaled" in n for n in rep["source_notes"])
    rep = json.loads(_compile([src, "-o", tmp_path / "h.npz", "--resolution", "0.5mm", "--height", "0:4mm",
                               "--json"], capsys))
    assert rep["clamped"]["normal_force"]["above"] == 0
    n = FrictionTable.load(tmp_path / "h.npz").dense("normal_force")
    assert n.max() == pytest.approx(0.5 + 4.0, abs=0.03)


def test_mesh_size_scales_the_footprint_or_the_whole_model(tmp_path):
    src = _pyramid(tmp_path, 10.0)
    a = mesh.mesh_to_heightfield(src, resolution="0.5mm", size="40x10mm")      # stretch, heights kept
    assert a.meta["footprint_m"] == pytest.approx([0.04, 0.01]) and a.heights.max() == pytest.approx(0.01, rel=0.02)
    b = mesh.mesh_to_heightfield(src, resolution="0.5mm", size="60mm")         # uniform x3
    assert b.meta["footprint_m"] == pytest.approx([0.06, 0.06]) and b.heights.max() == pytest.approx(0.03, rel=0.02)
    c = mesh.mesh_to_heightfield(src, resolution="0.5mm", height_range="1:3mm")
    assert c.heights.max() == pytest.approx(3e-3, rel=1e-3) and c.heights.min() == pytest.approx(1e-3)


# ----------------------------------------------------------------- mesh files
def test_ply_triangle_strips_are_read(tmp_path):
    # a 3 x 2 vertex grid as one strip, the same as four triangles
    verts = "0 0 0\n0 1 0\n1 0 1\n1 1 1\n2 0 0\n2 1 0\n"
    (tmp_path / "strip.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
        "element tristrips 1\nproperty list int int vertex_indices\nend_header\n" + verts + "9 0 1 2 3 -1 2 3 4 5\n")
    (tmp_path / "faces.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 4\nproperty list uchar int vertex_indices\nend_header\n" + verts
        + "3 0 1 2\n3 2 1 3\n3 2 3 4\n3 4 3 5\n")
    a = mesh.mesh_to_heightfield(tmp_path / "strip.ply", resolution=0.05)
    b = mesh.mesh_to_heightfield(tmp_path / "faces.ply", resolution=0.05)
    assert a.meta["triangles"] == 4
    np.testing.assert_array_equal(a.heights, b.heights)


def test_gltf_scene_graph_transforms_and_several_bodies(tmp_path):
    box = trimesh.creation.box((10.0, 6.0, 2.0))
    cyl = trimesh.creation.cylinder(radius=3.0, height=4.0, sections=24)
    scene = trimesh.Scene()
    t_parent = trimesh.transformations.translation_matrix((20.0, 10.0, 0.0)) @ \
        trimesh.transformations.rotation_matrix(np.pi / 2, (0, 0, 1))
    scene.add_geometry(box, node_name="plate", geom_name="plate", transform=t_parent)
    t_child = trimesh.transformations.translation_matrix((0.0, 8.0, 2.0)) @ \
        trimesh.transformations.scale_matrix(0.5)
    scene.add_geometry(cyl, node_name="knob", geom_name="knob", parent_node_name="plate", transform=t_child)
    scene.export(tmp_path / "s.glb")
    # the same bodies placed by hand in world coordinates
    world = trimesh.util.concatenate([box.copy().apply_transform(t_parent),
                                      cyl.copy().apply_transform(t_parent @ t_child)])
    a = mesh.mesh_to_heightfield(tmp_path / "s.glb", resolution="0.25mm", units="mm")
    b = mesh.mesh_to_heightfield((world.vertices, world.faces), resolution="0.25mm")
    assert a.meta["meshes"] == 2
    assert a.shape == b.shape
    np.testing.assert_allclose(a.heights, b.heights, atol=1e-9)
    assert a.meta["footprint_m"] == pytest.approx(b.meta["footprint_m"])
    assert a.meta["footprint_m"][1] == pytest.approx(10e-3)          # the plate turned 90 degrees: 6 x 10 mm


def test_ignored_colours_and_textures_are_named_in_the_report(tmp_path, capsys):
    from PIL import Image
    box = trimesh.creation.box((10.0, 10.0, 2.0))
    box.visual.vertex_colors = np.tile([255, 0, 0, 255], (len(box.vertices), 1))
    box.export(tmp_path / "coloured.ply")
    rep = json.loads(_compile([tmp_path / "coloured.ply", "-o", tmp_path / "c.npz", "--json"], capsys))
    assert "vertex colours of 1 mesh ignored" in rep["source_notes"]
    quad = trimesh.Trimesh([[0, 0, 0], [10, 0, 0], [10, 10, 1], [0, 10, 1]], [[0, 1, 2], [0, 2, 3]], process=False)
    tex = Image.fromarray(np.zeros((4, 4, 3), np.uint8))
    quad.visual = trimesh.visual.TextureVisuals(uv=[[0, 0], [1, 0], [1, 1], [0, 1]], image=tex)
    quad.export(tmp_path / "textured.glb")
    text = _compile([tmp_path / "textured.glb", "-o", tmp_path / "t.npz"], capsys)
    assert "note: textures of 1 mesh ignored" in text
    plain = trimesh.creation.box((10.0, 10.0, 2.0))
    plain.export(tmp_path / "plain.stl")
    rep = json.loads(_compile([tmp_path / "plain.stl", "-o", tmp_path / "p.npz", "--json"], capsys))
    assert rep["source_notes"] == []


def test_mesh_options_on_preview_and_heightmap_take_negative_axes(tmp_path, capsys):
    """A Y-up model seen with --up -y / --up y: the same options on every command."""
    tray = trimesh.creation.box((60.0, 4.0, 30.0))        # lying along x-z, 4 mm thick along y
    tray.export(tmp_path / "tray.glb")
    assert main(["heightmap", str(tmp_path / "tray.glb"), "-o", str(tmp_path / "t.npy"), "--up", "y",
                 "--units", "mm", "--resolution", "1mm"]) == 0
    assert main(["heightmap", str(tmp_path / "tray.glb"), "-o", str(tmp_path / "u.npy"), "--up", "-y",
                 "--size", "30x15mm", "--height", "0:1mm", "--resolution", "1mm"]) == 0
    out = capsys.readouterr().out
    assert "31 x 16 samples" in out or "16 x 31 samples" in out
    assert np.load(tmp_path / "u.npy").max() == pytest.approx(1e-3)
    from shapedisplay.author.sources import source_options
    assert source_options(tmp_path / "tray.glb", up="-y", units="m", size="60mm", flags={"size": "--extent"}) == {
        "up": "-y", "units": "m", "size": pytest.approx(0.06)}
