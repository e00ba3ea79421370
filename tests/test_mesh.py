"""Meshes to height fields: exact answers on analytic shapes, a brute-force z-buffer, files, export."""
from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

trimesh = pytest.importorskip("trimesh")

from shapedisplay.author import mesh, raster  # noqa: E402
from shapedisplay.author.heightfield import HeightField  # noqa: E402

MM = 1e-3
ROOT = Path(__file__).resolve().parents[1]
KEYCAP = ROOT / "assets" / "meshes" / "keycap.stl"


def sample_xy(hf):
    """Sample positions (x, y) in the height field frame, each (rows, cols), metres."""
    return np.meshgrid(hf.x, hf.y)


def sphere_cap(R, hc, n_rings=48, n_sectors=192):
    """Closed spherical cap (mm): sphere radius R, cap height hc, flat base on z=0."""
    a = math.sqrt(2 * R * hc - hc * hc)
    theta_max = math.asin(a / R)
    verts = [[0.0, 0.0, hc]]
    for i in range(1, n_rings + 1):
        th = theta_max * i / n_rings
        phi = np.linspace(0, 2 * np.pi, n_sectors, endpoint=False)
        r = R * math.sin(th)
        z = R * math.cos(th) - (R - hc)
        verts += np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n_sectors, z)]).tolist()
    verts.append([0.0, 0.0, 0.0])
    verts = np.array(verts)
    faces = []
    j = np.arange(n_sectors)
    k = (j + 1) % n_sectors
    faces.append(np.column_stack([np.zeros(n_sectors, int), 1 + j, 1 + k]))
    for i in range(1, n_rings):
        a0, a1 = 1 + (i - 1) * n_sectors, 1 + i * n_sectors
        faces.append(np.column_stack([a0 + j, a1 + j, a1 + k]))
        faces.append(np.column_stack([a0 + j, a1 + k, a0 + k]))
    last = 1 + (n_rings - 1) * n_sectors
    faces.append(np.column_stack([np.full(n_sectors, len(verts) - 1), last + k, last + j]))
    return verts, np.vstack(faces)


def circumradius(tri):
    a = np.linalg.norm(tri[:, 1] - tri[:, 2], axis=1)
    b = np.linalg.norm(tri[:, 0] - tri[:, 2], axis=1)
    c = np.linalg.norm(tri[:, 0] - tri[:, 1], axis=1)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return a * b * c / (4 * area)


# --------------------------------------------------------------- exact answers
def test_box_rasterises_to_its_exact_heights_and_step_locations():
    box = trimesh.creation.box(extents=(20, 10, 5))
    box.apply_translation([100, -40, 7])  # placement in the file must not matter
    hf = mesh.mesh_to_heightfield(box, resolution=0.5 * MM, margin=2 * MM)
    X, Y = sample_xy(hf)
    tol = raster.EDGE_TOLERANCE * hf.dx
    inside = (X >= -tol) & (X <= 20 * MM + tol) & (Y >= -tol) & (Y <= 10 * MM + tol)
    np.testing.assert_allclose(hf.heights, np.where(inside, 5 * MM, 0.0), rtol=0, atol=1e-15)
    # the walls sit between the last background and first top sample on every side
    mid = hf.heights[hf.rows // 2]
    jumps = np.flatnonzero(np.diff(mid) != 0)
    assert hf.x[jumps].tolist() == pytest.approx([-0.5 * MM, 20 * MM])
    assert hf.x0 == pytest.approx(-2 * MM) and hf.y0 == pytest.approx(-2 * MM)
    assert hf.meta["model_origin_m"] == pytest.approx([0.09, -0.045, 0.0045])
    assert hf.meta["footprint_m"] == pytest.approx([0.02, 0.01])


def test_sphere_cap_matches_analytic_heights_within_half_a_sample_of_slope():
    R, hc = 20.0, 5.0
    v, f = sphere_cap(R, hc)
    dx = 0.25 * MM
    hf = mesh.mesh_to_heightfield((v, f), resolution=dx)
    a = math.sqrt(2 * R * hc - hc * hc) * MM
    X, Y = sample_xy(hf)
    r = np.hypot(X - a, Y - a)  # footprint min corner is (-a, -a)
    Rm, hm = R * MM, hc * MM
    inside = r <= a
    exact = np.where(inside, np.sqrt(np.maximum(Rm**2 - r**2, 0)) - (Rm - hm), 0.0)
    slope = np.where(inside, r / np.sqrt(np.maximum(Rm**2 - r**2, 1e-30)), 0.0)
    # tessellation: a flat triangle through 3 points of the sphere deviates from it by at most
    # R - sqrt(R^2 - rho^2) (rho = circumradius) along the normal; vertically divide by cos of the
    # steepest normal on the cap, (R - hc) / R
    rho = circumradius(v[f] * MM).max()
    tess = (Rm - math.sqrt(Rm**2 - rho**2)) / ((Rm - hm) / Rm)
    err = np.abs(hf.heights - exact)
    assert np.all(err <= 0.5 * dx * slope + tess)      # the stated tolerance
    assert err.max() <= tess * (1 + 1e-9) + 1e-12       # point sampling adds no slope error
    # the apex lies within half a sample diagonal of a sample: drop <= r^2 / (2 (R - hc)) there
    assert hm - (dx**2 / 2) / (2 * (Rm - hm)) - tess <= hf.heights.max() <= hm


def test_cone_matches_analytic_heights_and_upside_down_is_flat():
    N, a, h = 256, 10.0, 6.0
    cone = trimesh.creation.cone(radius=a, height=h, sections=N)
    dx = 0.2 * MM
    hf = mesh.mesh_to_heightfield(cone, resolution=dx)
    X, Y = sample_xy(hf)
    r = np.hypot(X - a * MM, Y - a * MM)
    exact = np.where(r <= a * MM, h * MM * (1 - r / (a * MM)), 0.0)
    # facets through the apex and two rim points: error <= h (1/cos(pi/N) - 1)
    facet = h * MM * (1 / math.cos(math.pi / N) - 1)
    slope = h / a
    err = np.abs(hf.heights - exact)
    assert np.all(err <= 0.5 * dx * slope + facet)
    assert err.max() <= facet + 1e-12
    # seen from below (up = -z) the top surface is the flat base disc at height h
    under = mesh.mesh_to_heightfield(cone, resolution=dx, up="-z")
    covered = under.heights > 0
    np.testing.assert_allclose(under.heights[covered], h * MM, atol=1e-12)


def test_tilted_plane_is_exact_at_every_covered_sample():
    rng = np.random.default_rng(3)
    from scipy.spatial import Delaunay
    pts = np.vstack([rng.uniform(0, 30, size=(300, 2)), [[0, 0], [30, 0], [0, 30], [30, 30]]])
    z = 0.3 * pts[:, 0] - 0.2 * pts[:, 1] + 9                  # mm; lowest at (0, 30): 3 mm
    hf = mesh.mesh_to_heightfield((np.c_[pts, z], Delaunay(pts).simplices), resolution=0.5 * MM)
    X, Y = sample_xy(hf)
    np.testing.assert_allclose(hf.heights, 0.3 * X - 0.2 * Y + 6 * MM, rtol=0, atol=1e-15)


def test_overhang_keeps_the_highest_surface_and_normals_do_not_matter():
    base = trimesh.creation.box(extents=(20, 20, 2))            # z -1..1
    cap = trimesh.creation.box(extents=(6, 6, 1))
    cap.apply_translation([0, 0, 6])                            # floating plate z 5.5..6.5
    scene_mesh = trimesh.util.concatenate([base, cap])
    hf = mesh.mesh_to_heightfield(scene_mesh, resolution=1 * MM)
    X, Y = sample_xy(hf)
    on_cap = (np.abs(X - 10 * MM) <= 3 * MM + 1e-12) & (np.abs(Y - 10 * MM) <= 3 * MM + 1e-12)
    np.testing.assert_allclose(hf.heights, np.where(on_cap, 7.5 * MM, 2 * MM), atol=1e-15)
    inverted = (scene_mesh.vertices, scene_mesh.faces[:, ::-1])
    np.testing.assert_array_equal(mesh.mesh_to_heightfield(inverted, resolution=1 * MM).heights, hf.heights)


def test_open_and_non_manifold_meshes_still_give_the_top_surface():
    box = trimesh.creation.box(extents=(10, 10, 4))           # z -2..2
    ref = mesh.mesh_to_heightfield(box, resolution=0.5 * MM)
    no_bottom = box.faces[box.triangles_center[:, 2] > -1.9]  # open: not watertight
    assert not trimesh.Trimesh(box.vertices, no_bottom, process=False).is_watertight
    np.testing.assert_array_equal(
        mesh.mesh_to_heightfield((box.vertices, no_bottom), resolution=0.5 * MM).heights, ref.heights)
    # a vertical fin on a top edge (three faces share that edge) and a duplicated face
    v = np.vstack([box.vertices, [[5, -5, 2], [5, 5, 2], [5, 0, 10]]])
    n = len(box.vertices)
    faces = np.vstack([box.faces, box.faces[:1], [[n, n + 1, n + 2]]])
    assert not trimesh.Trimesh(v, faces, process=True).is_watertight
    np.testing.assert_array_equal(mesh.mesh_to_heightfield((v, faces), resolution=0.5 * MM).heights,
                                  ref.heights)


def brute_zbuffer(tri, rows, cols, band=1e-4):
    """Bounds on the max z-buffer of the triangles ``tri`` (m, 3, 3), grid units, from every (triangle, sample)
    pair: the plane through each triangle (from its normal, not barycentric weights) and the sample's
    signed distance to each edge, in samples. Returns ``(lo, hi)``, each (rows, cols): ``lo`` the highest
    triangle holding the sample or within 1e-9 samples of its edges (covered by the rasteriser's contract:
    edges count, up to :data:`raster.EDGE_TOLERANCE`), ``hi`` the highest within ``band`` samples of it
    (heights clamped to the triangle's own range); -inf where there is none. Only a sample between 1e-9 and
    ``band`` outside some triangle can have ``lo < hi``."""
    tri = np.asarray(tri, dtype=np.float64)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    tri, normal = tri[normal[:, 2] != 0], normal[normal[:, 2] != 0]       # vertical faces cover nothing
    orient = np.sign(normal[:, 2])[:, None]
    zmin, zmax = tri[:, :, 2].min(1)[:, None], tri[:, :, 2].max(1)[:, None]
    r, c = np.divmod(np.arange(rows * cols), cols)
    lo, hi = np.full(rows * cols, -np.inf), np.full(rows * cols, -np.inf)
    for s in range(0, rows * cols, 256):
        px, py = c[None, s:s + 256].astype(float), r[None, s:s + 256].astype(float)
        d = np.inf
        for i, j in ((0, 1), (1, 2), (2, 0)):
            p, q = tri[:, i, :2], tri[:, j, :2]
            e = q - p
            cross = e[:, :1] * (py - p[:, 1:]) - e[:, 1:] * (px - p[:, :1])
            d = np.minimum(d, orient * cross / np.hypot(e[:, :1], e[:, 1:]))
        a = tri[:, 0]
        z = a[:, 2:] - (normal[:, :1] * (px - a[:, :1]) + normal[:, 1:2] * (py - a[:, 1:2])) / normal[:, 2:]
        z = np.clip(z, zmin, zmax)
        lo[s:s + 256] = np.where(d >= -1e-9, z, -np.inf).max(0, initial=-np.inf)
        hi[s:s + 256] = np.where(d >= -band, z, -np.inf).max(0, initial=-np.inf)
    return lo.reshape(rows, cols), hi.reshape(rows, cols)


def assert_within(got, lo, hi, atol):
    """``got`` lies in [lo, hi] (to ``atol``): covered where ``lo`` is, uncovered where ``hi`` is not."""
    assert np.all(np.isfinite(got)[np.isfinite(lo)]) and np.all(np.isneginf(got)[np.isneginf(hi)])
    f = np.isfinite(got)
    assert np.all(got[f] >= lo[f] - atol) and np.all(got[f] <= hi[f] + atol)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 60),
       rows=st.integers(2, 40), cols=st.integers(2, 40))
def test_random_triangle_soups_match_a_brute_force_z_buffer(seed, n, rows, cols):
    rng = np.random.default_rng(seed)
    tri = rng.uniform(-5, 45, size=(n, 3, 3))
    got = raster.rasterize(tri, rows, cols)
    lo, hi = brute_zbuffer(tri, rows, cols)
    assert_within(got, lo, hi, atol=1e-9)
    assert np.isclose(lo, hi, rtol=0, atol=1e-9).mean() >= 0.9                     # the bracket pins down nearly every sample


def test_keycap_matches_a_brute_force_z_buffer():
    """The whole mesh path on the bundled keycap (float32 STL, 5120 triangles) against every
    (triangle, sample) pair: placement, grid and heights."""
    dx = 0.3 * MM
    hf = mesh.mesh_to_heightfield(KEYCAP, resolution=dx)
    assert hf.meta["degenerate_faces_dropped"] == 0 and hf.dx == hf.dy == dx
    km = trimesh.load(KEYCAP)
    v = np.asarray(km.vertices) * MM
    low = v.min(0)
    grid = np.column_stack([(v[:, 0] - low[0]) / dx, (v[:, 1] - low[1]) / dx, v[:, 2] - low[2]])
    lo, hi = brute_zbuffer(grid[km.faces], hf.rows, hf.cols)
    assert np.isfinite(lo).mean() > 0.9
    assert_within(np.where(np.isfinite(hi), hf.heights, -np.inf), lo, hi, atol=1e-12)
    np.testing.assert_array_equal(hf.heights[np.isneginf(hi)], 0.0)    # background
    assert np.isclose(lo, hi, rtol=0, atol=1e-12).all()


def test_supersampling_keeps_a_thin_ridge_that_point_sampling_misses():
    plate = trimesh.creation.box(bounds=[[0, 0, -1], [10, 10, 0]])
    ridge = trimesh.creation.box(bounds=[[4.23, 0, 0], [4.33, 10, 1]])
    both = trimesh.util.concatenate([plate, ridge])
    plain = mesh.mesh_to_heightfield(both, resolution=0.5 * MM)
    assert plain.heights.max() == pytest.approx(1 * MM)        # ridge lost between samples
    # 5x5 sub-samples at offsets (-0.2, -0.1, 0, 0.1, 0.2) mm: only x = 4.3 mm (col 9) hits the ridge
    mean = mesh.mesh_to_heightfield(both, resolution=0.5 * MM, supersample=5)
    peak = mesh.mesh_to_heightfield(both, resolution=0.5 * MM, supersample=5, supersample_mode="max")
    inner = slice(1, -1)  # rows away from the plate's outer edge
    np.testing.assert_allclose(mean.heights[inner, 9], (4 * 1 + 2) / 5 * MM, atol=1e-15)
    np.testing.assert_allclose(peak.heights[inner, 9], 2 * MM, atol=1e-15)
    others = np.delete(mean.heights[inner, 1:-1], 8, axis=1)
    np.testing.assert_allclose(others, 1 * MM, atol=1e-15)


def test_background_value_and_grid_size_option():
    cone = trimesh.creation.cone(radius=5, height=3, sections=64)
    hf = mesh.mesh_to_heightfield(cone, grid=(21, 41), background=-1 * MM)
    assert hf.shape == (21, 41)
    assert hf.dx == pytest.approx(10 * MM / 40) and hf.dy == pytest.approx(10 * MM / 20)
    assert hf.heights[0, 0] == -1 * MM                             # corner outside the disc
    assert hf.heights.max() == pytest.approx(3 * MM)
    same = mesh.mesh_to_heightfield(cone, grid="21x41", background="-1 mm")
    np.testing.assert_array_equal(same.heights, hf.heights)
    default = mesh.mesh_to_heightfield(cone)
    assert max(default.shape) == mesh.DEFAULT_LONG_SIDE


@pytest.mark.parametrize("up, rotate", [
    ("y", [[1, 0, 0], [0, 0, 1], [0, -1, 0]]),     # model built Y-up: (x, y, z) -> (x, z, -y)
    ("x", [[0, 0, 1], [1, 0, 0], [0, 1, 0]]),      # z -> x, x -> y
    ("-y", [[1, 0, 0], [0, 0, -1], [0, 1, 0]]),    # (x, y, z) -> (x, -z, y)
])
def test_up_axis_recovers_the_z_up_view(up, rotate):
    cone = trimesh.creation.cone(radius=5, height=3, sections=64)
    box = trimesh.creation.box(extents=(2, 3, 1))
    box.apply_translation([7, 0, 0])
    shape = trimesh.util.concatenate([cone, box])
    ref = mesh.mesh_to_heightfield(shape, resolution=0.25 * MM)
    R = np.array(rotate, float)
    turned = (shape.vertices @ R.T, shape.faces)
    got = mesh.mesh_to_heightfield(turned, resolution=0.25 * MM, up=up)
    np.testing.assert_allclose(got.heights, ref.heights, atol=1e-12)
    by_vector = mesh.mesh_to_heightfield(turned, resolution=0.25 * MM, up=(R @ [0, 0, 1]).tolist())
    np.testing.assert_allclose(by_vector.heights, ref.heights, atol=1e-12)


def test_up_as_rotation_matrix():
    cone = trimesh.creation.cone(radius=5, height=3, sections=64)
    rot = mesh.up_rotation("y")
    a = mesh.mesh_to_heightfield(cone, resolution=0.5 * MM, up="y")
    b = mesh.mesh_to_heightfield(cone, resolution=0.5 * MM, up=rot)
    np.testing.assert_array_equal(a.heights, b.heights)
    for name in ("x", "y", "z", "-x", "-y", "-z"):
        m = mesh.up_rotation(name)
        np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(m) == pytest.approx(1.0)


# --------------------------------------------------------------- files and scenes
@pytest.mark.parametrize("fmt", ["stl", "stl_ascii", "obj", "ply", "off", "glb"])
def test_every_format_gives_the_same_height_field(tmp_path, fmt):
    cone = trimesh.creation.cone(radius=5, height=3, sections=48)
    ref = mesh.mesh_to_heightfield(cone, resolution=0.25 * MM)
    suffix = "stl" if fmt == "stl_ascii" else fmt
    path = tmp_path / f"shape.{suffix}"
    data = cone.export(file_type=fmt)
    path.write_bytes(data.encode() if isinstance(data, str) else data)
    hf = mesh.mesh_to_heightfield(path, resolution=0.25 * MM, units=("mm" if path.suffix in (".glb", ".gltf") else None))
    # STL stores float32 coordinates: allow their rounding times the slope
    np.testing.assert_allclose(hf.heights, ref.heights, atol=1e-8)
    assert hf.shape == ref.shape


@pytest.mark.parametrize("fmt", ["glb", "gltf"])
def test_scene_meshes_are_merged_in_world_coordinates(tmp_path, fmt):
    a = trimesh.creation.box(extents=(4, 4, 2))
    b = trimesh.creation.box(extents=(4, 4, 6))
    scene = trimesh.Scene()
    scene.add_geometry(a, node_name="a", transform=trimesh.transformations.translation_matrix([0, 0, 1]))
    scene.add_geometry(b, node_name="b", transform=trimesh.transformations.translation_matrix([10, 0, 3]))
    if fmt == "glb":
        path = tmp_path / "scene.glb"
        path.write_bytes(scene.export(file_type="glb"))
    else:
        for name, data in scene.export(file_type="gltf").items():
            (tmp_path / name).write_bytes(data)
        path = tmp_path / "model.gltf"
    hf = mesh.mesh_to_heightfield(path, resolution=0.5 * MM, units="mm")
    assert hf.meta["meshes"] == 2
    assert hf.meta["footprint_m"] == pytest.approx([14 * MM, 4 * MM])
    X, _ = sample_xy(hf)
    row = hf.heights[hf.rows // 2]
    x = hf.x
    assert np.all(row[x <= 4 * MM] == pytest.approx(2 * MM))
    assert np.all(row[(x > 4 * MM + 1e-9) & (x < 10 * MM - 1e-9)] == 0)
    assert np.all(row[x >= 10 * MM] == pytest.approx(6 * MM))


# --------------------------------------------------------------- export round trip
@pytest.mark.parametrize("suffix", [".stl", ".ply"])
def test_export_then_rasterise_round_trips(tmp_path, suffix):
    hf = mesh.mesh_to_heightfield(KEYCAP, resolution=0.5 * MM, margin=1 * MM)
    path = tmp_path / f"out{suffix}"
    mesh.save_heightfield_mesh(hf, path)                       # closed solid, 1 mm base
    back = mesh.mesh_to_heightfield(path, resolution=0.5 * MM)
    assert back.shape == hf.shape
    # heights are measured from the lowest point, which is now the 1 mm base below min(h)
    np.testing.assert_allclose(back.heights, hf.heights - hf.heights.min() + 1 * MM, atol=2e-8)
    surface = tmp_path / f"surface{suffix}"
    mesh.save_heightfield_mesh(hf, surface, solid=False)
    back2 = mesh.mesh_to_heightfield(surface, resolution=0.5 * MM)
    np.testing.assert_allclose(back2.heights, hf.heights - hf.heights.min(), atol=2e-8)


def test_exported_solid_is_watertight_with_outward_normals(tmp_path):
    hf = HeightField(np.random.default_rng(0).uniform(0, 1e-3, (7, 9)), 1e-3, 2e-3)
    v, f = mesh.heightfield_to_mesh(hf)
    tm = trimesh.Trimesh(v, f, process=True)
    assert tm.is_watertight and tm.is_winding_consistent
    assert tm.volume > 0
    # volume = integral of (h - zb) over the grid with linear triangles
    h = hf.heights
    zb = h.min() - 1e-3
    cell = (h[:-1, :-1] + h[:-1, 1:] + h[1:, 1:]) / 3 + (h[:-1, :-1] + h[1:, 1:] + h[1:, :-1]) / 3
    expected = (cell.sum() / 2 - zb * (h.shape[0] - 1) * (h.shape[1] - 1)) * hf.dx * hf.dy
    assert tm.volume == pytest.approx(expected, rel=1e-9)


def test_save_heightmap_png_npy_npz(tmp_path):
    hf = mesh.mesh_to_heightfield(KEYCAP, resolution=0.5 * MM)
    mesh.save_heightmap(hf, tmp_path / "h.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "h.npy")[::-1], hf.heights)     # top view: row 0 = far edge
    mesh.save_heightmap(hf, tmp_path / "h.npz")
    with np.load(tmp_path / "h.npz") as z:
        np.testing.assert_array_equal(z["heights"], hf.heights)
        assert float(z["dx"]) == hf.dx
    mesh.save_heightmap(hf, tmp_path / "h.png")
    from shapedisplay.author.imageio import read_picture
    gray = read_picture(tmp_path / "h.png").values[::-1]
    assert gray.dtype == np.uint16 and gray.shape == hf.shape
    lo, hi = hf.heights.min(), hf.heights.max()
    np.testing.assert_allclose(lo + gray / 65535 * (hi - lo), hf.heights, atol=(hi - lo) / 65535)
    data = (tmp_path / "h.png").read_bytes()
    size = f"{hf.cols * hf.dx!r}x{hf.rows * hf.dy!r}".encode()
    assert b"tEXtheight_max_m\0" + repr(float(hi)).encode() in data and b"tEXtsize_m\0" + size in data
    desc = mesh.save_heightmap(hf, tmp_path / "h.stl")
    n_top = 2 * (hf.rows - 1) * (hf.cols - 1)
    assert desc.startswith("closed solid of") and f"({n_top} on top" in desc
    assert mesh.save_heightmap(hf, tmp_path / "s.stl", solid=False) == f"top surface of {n_top} triangles (open mesh)"
    with pytest.raises(mesh.FileFormatError, match="unsupported suffix '.txt'"):
        mesh.save_heightmap(hf, tmp_path / "h.txt")


# --------------------------------------------------------------- the keycap asset
def test_keycap_asset_is_reproducible_and_matches_its_formula(tmp_path):
    import importlib.util
    spec = importlib.util.spec_from_file_location("make_keycap", KEYCAP.with_name("make_keycap.py"))
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    out = tmp_path / "keycap.stl"
    gen.main([str(out)])
    assert out.read_bytes() == KEYCAP.read_bytes()
    v, f = gen.keycap()
    assert 2000 <= len(f) <= 10000
    assert trimesh.Trimesh(v, f).is_watertight
    dx = 0.25 * MM
    hf = mesh.mesh_to_heightfield(KEYCAP, resolution=dx)
    X, Y = sample_xy(hf)
    x, y = X / MM - 9, Y / MM - 9                               # keycap centred on 0 in its file
    centre = (np.abs(x) < 5) & (np.abs(y) < 5)
    exact = gen.dish(x, y) * MM
    R = gen.DISH_R * MM
    top = f[np.all(v[f][:, :, 2] > gen.HEIGHT - gen.DISH_DEPTH - 1e-9, axis=1)]
    rho = circumradius(v[top] * MM).max()
    tess = (R - math.sqrt(R**2 - rho**2)) / math.sqrt(1 - (5 * math.sqrt(2) * MM / R) ** 2)
    assert np.abs(hf.heights[centre] - exact[centre]).max() <= tess + 1e-9  # float32 file
    assert hf.heights[hf.rows // 2, hf.cols // 2] == pytest.approx(7.2 * MM, abs=1e-8)


def test_box_sides_are_reported_as_walls_by_gradient_analysis():
    from shapedisplay.author.gradients import detect_walls, gradient
    box = trimesh.creation.box(extents=(20, 10, 5))
    hf = mesh.mesh_to_heightfield(box, resolution=0.5 * MM, margin=2 * MM)
    gx, gy = gradient(hf, "central")
    report = detect_walls(hf, gx, gy, max_slope=1.0)
    X, Y = sample_xy(hf)
    tol = 1e-9
    inside = (X >= -tol) & (X <= 20 * MM + tol) & (Y >= -tol) & (Y <= 10 * MM + tol)
    # central differences see the 5 mm step on both samples next to each side
    expected = np.zeros_like(inside)
    expected[:, 1:-1] |= inside[:, 2:] != inside[:, :-2]
    expected[1:-1, :] |= inside[2:, :] != inside[:-2, :]
    np.testing.assert_array_equal(report.mask, expected)
    assert report.regions == 1
    assert report.boxes_mm == [[-0.5, 20.5, -0.5, 10.5]]
    assert report.steepest == pytest.approx(math.hypot(5, 5))   # 5 mm over 2 x 0.5 mm, both axes at corners


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_v=st.integers(3, 30), n_f=st.integers(1, 40),
       scale=st.sampled_from([1e-3, 1.0, 50.0, 1e4]), k=st.integers(1, 3),
       up=st.sampled_from(["z", "-z", "x", "y"]))
def test_finite_meshes_give_finite_bounded_heights_or_a_clear_error(seed, n_v, n_f, scale, k, up):
    from shapedisplay.errors import ShapeDisplayError
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n_v, 3)) * scale
    f = rng.integers(0, n_v, size=(n_f, 3))
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mesh.ImplausibleSizeWarning)
        try:
            hf = mesh.mesh_to_heightfield((v, f), grid=(17, 23), supersample=k, up=up,
                                          background=-1 * MM)
        except ShapeDisplayError as exc:
            assert "\n" not in str(exc)
            return
    h = hf.heights
    assert np.isfinite(h).all()
    top = hf.meta["height_range_m"][1]
    assert h.min() >= -1 * MM - 1e-12 and h.max() <= top * (1 + 1e-9) + 1e-15


def test_samples_just_outside_a_steep_sliver_do_not_overshoot():
    # nearly vertical face (projected width 1e-7 samples, 5 high); samples lie 9e-7 samples beyond
    # its top edge, inside the edge tolerance: extrapolation would give 50, clamping keeps <= 5
    tri = np.array([[[0, -1e-6, 0], [4, -1e-6, 0], [2, -1e-6 + 1e-7, 5]]])
    h = raster.rasterize(tri, 2, 5)
    assert np.all(h[0] <= 5.0) and np.all(h[0] >= 0.0)
    assert np.all(np.isneginf(h[1]))


@pytest.mark.parametrize("name, text", [
    ("quad.obj", "v 0 0 0\nv 10 0 0\nv 10 10 2\nv 0 10 2\nf 1 2 3 4\n"),
    ("quad.off", "OFF\n4 1 0\n0 0 0\n10 0 0\n10 10 2\n0 10 2\n4 0 1 2 3\n"),
])
def test_polygon_faces_are_triangulated(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    hf = mesh.mesh_to_heightfield(p, resolution=1 * MM)
    assert hf.meta["triangles"] == 2
    _, Y = sample_xy(hf)
    np.testing.assert_allclose(hf.heights, 0.2 * Y, atol=1e-15)      # the ramp z = 0.2 y


@pytest.mark.parametrize("suffix, expected", [(".glb", "m"), (".gltf", "m"), (".stl", "mm"), (".PLY", "mm")])
def test_gltf_files_default_to_metres_as_their_format_defines(suffix, expected, tmp_path):
    assert mesh.default_units(tmp_path / f"part{suffix}") == expected
    assert mesh.default_units((np.zeros((3, 3)), np.array([[0, 1, 2]]))) == "mm"


def test_a_gltf_part_in_metres_keeps_its_size(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(0.020, 0.010, 0.002))       # metres, as glTF defines
    box.export(tmp_path / "part.glb")
    hf = mesh.mesh_to_heightfield(tmp_path / "part.glb", resolution="0.5mm")
    assert hf.meta["units"] == "m"
    assert hf.meta["footprint_m"] == pytest.approx([0.020, 0.010])
