"""Meshes as shape sources: 3D models to height fields and back.

A designer's keycap, knob or relief map arrives as a triangle mesh. This
module turns it into a :class:`~shapedisplay.author.heightfield.HeightField` by
looking at it from above and keeping the top surface, and writes a height
field back out as a mesh (STL/PLY) to 3D-print or inspect what will be
rendered.

Conventions
-----------
* **Files.** STL (ASCII and binary), OBJ, PLY, OFF, GLB and glTF are read with
  trimesh (optional extra: ``pip install 'shapedisplay[mesh]'``). A file that
  holds a scene of several meshes is merged: every mesh is moved into world
  coordinates by its scene-graph transform and the triangles are
  concatenated. Points, lines and other non-triangle geometry are ignored.
* **Units.** Coordinates are read in ``units`` ("mm" by default; "m" for
  glTF files, whose format defines metres; also "cm", "in") and converted
  to metres. A footprint under 1 mm or over 2 m
  looks implausible for a screen and raises :class:`ImplausibleSizeWarning`
  with the unit that would make it plausible.
* **View.** The mesh is rotated so that ``up`` points along +z and viewed
  from above; every sample keeps the highest surface over it (overhangs take
  the top, normals and winding are ignored, so inverted normals,
  non-watertight and non-manifold meshes work).  ``up`` is an axis name
  ``x|y|z|-x|-y|-z``, a 3-vector direction, or a (3, 3) rotation matrix
  applied to the vertices before viewing from +z. For an axis or direction
  the in-plane axes are: new x = world x made perpendicular to ``up`` (world
  y when ``up`` is along x), new y = up × new x. So ``up="z"`` is the
  identity and ``up="y"`` (glTF's convention) shows a Y-up model from above
  with x to the right and -z towards +y.
* **Origin.** Height-field coordinates are relative to the bounding-box
  minimum of the (rotated) mesh: the footprint starts at x = y = 0 and the
  lowest point of the mesh has height 0. ``meta["model_origin_m"]`` keeps
  that corner in the rotated model frame (metres). With ``margin`` the grid
  extends by whole samples beyond the footprint (x0 = y0 = -margin rounded
  up to a sample).
* **Sampling.** Sample (r, c) sits at (x0 + c*dx, y0 + r*dy). With
  ``resolution`` the spacing is fixed and the grid covers the footprint
  (the last sample may lie up to one spacing beyond it); with
  ``grid=(rows, cols)`` the first and last samples sit on the footprint's
  edges. Samples no triangle covers get ``background``.
* **Supersampling.** ``supersample=k`` rasterises k x k sub-samples spread
  evenly over each sample's cell (centred on the sample) and reduces them by
  their mean (``supersample_mode="mean"``: anti-aliased edges, a thin ridge
  keeps its area) or their maximum (``"max"``: a thin ridge keeps its full
  height). Uncovered sub-samples count as ``background``.
* **Vertical faces** (a button's side) cover no sample: they become a step
  between neighbouring samples, which gradient analysis reports as a wall.
* **Degenerate faces** (zero area in 3D) are dropped and counted in
  ``meta["degenerate_faces_dropped"]``.
"""
from __future__ import annotations

import json
import logging
import math
import os
import struct
import warnings
from pathlib import Path

import numpy as np

from shapedisplay.errors import FileFormatError, InputError, require, unknown_key
from shapedisplay.author.heightfield import HeightField, check_grid_size
from shapedisplay.author.meshfiles import MAX_COORDINATE, MAX_PLY_STRIPS, check_mesh_file, ply_elements

#: File suffixes read through trimesh.
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")

#: Length units accepted for mesh coordinates, metres per unit.
UNITS = {"mm": 1e-3, "cm": 1e-2, "m": 1.0, "in": 0.0254}

#: Footprints (longest side, metres) outside this range raise ImplausibleSizeWarning.
PLAUSIBLE_FOOTPRINT_M = (1e-3, 2.0)

#: Sub-sample reductions for supersampling.
SUPERSAMPLE_MODES = ("mean", "max")

#: Longest side of the grid when neither resolution nor grid is given.
DEFAULT_LONG_SIDE = 512

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


class ImplausibleSizeWarning(UserWarning):
    """The mesh footprint is implausibly small or large for a screen (unit confusion?)."""


# ---------------------------------------------------------------------------
# loading

def load_mesh(path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Read a mesh file and merge its scene into one triangle list.

    Parameters
    ----------
    path : str or os.PathLike
        ``.stl .obj .ply .off .glb .gltf``.

    Returns
    -------
    vertices : ndarray of shape (n, 3), float64, file units
    faces : ndarray of shape (m, 3), int64
        Indices into ``vertices``.
    info : dict
        ``{"meshes": number of meshes merged, "format": suffix}``.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise FileFormatError(
            f"mesh '{path}': unsupported suffix '{suffix}'; readable: {', '.join(MESH_SUFFIXES)}"
        )
    check_mesh_file(path, suffix)
    if suffix == ".ply" and "tristrips" in ply_elements(path):
        return _load_ply_strips(path)
    trimesh = require("trimesh", "mesh", "Loading meshes")
    log = logging.getLogger("trimesh")       # it logs a traceback for a texture file it cannot find:
    level = log.level                        # textures are not read here (the notes say they are ignored)
    try:
        log.setLevel(logging.CRITICAL)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = trimesh.load(str(path), file_type=suffix[1:], process=False, force="scene")
            geoms = scene.dump()
    except Exception as exc:  # trimesh raises many kinds for corrupt files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"mesh '{path}': cannot read {suffix[1:].upper()} file ({msg})") from None
    finally:
        log.setLevel(level)
    verts, faces, offset, count = [], [], 0, 0
    ignored: dict = {}
    for g in geoms:
        f = getattr(g, "faces", None)
        v = getattr(g, "vertices", None)
        if f is None or v is None or len(f) == 0:
            kind = type(g).__name__
            name = {"PointCloud": "point clouds", "Path3D": "lines/curves", "Path2D": "2-D paths"}.get(kind, kind)
            ignored[name] = ignored.get(name, 0) + 1
            continue
        f = np.asarray(f, dtype=np.int64)
        if f.ndim != 2 or f.shape[1] != 3:
            continue
        for what in _visual_notes(g):
            ignored[what] = ignored.get(what, 0) + 1
        verts.append(np.asarray(v, dtype=np.float64))
        faces.append(f + offset)
        offset += len(v)
        count += 1
    if not faces:
        points = sum(len(getattr(g, "vertices", ())) for g in geoms if type(g).__name__ == "PointCloud")
        if points:
            raise FileFormatError(f"mesh '{path}': a point cloud ({points} points, no faces); shapedisplay needs a "
                                  f"surface: mesh the points first (e.g. Poisson reconstruction in a mesh editor)")
        raise FileFormatError(f"mesh '{path}': no triangles found (empty mesh or unreadable content)")
    notes = [f"{what} of {n} mesh{'es' if n > 1 else ''} ignored" if what in _VISUALS else f"{n} {what} ignored"
             for what, n in ignored.items()]
    return np.concatenate(verts), np.concatenate(faces), {"meshes": count, "format": suffix[1:], "notes": notes}


def _load_ply_strips(path: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """A PLY file whose faces are triangle strips (``element tristrips``), read with plyfile.

    plyfile reads every layout the format allows (ASCII or binary, one strip
    with -1 restarts or one record per strip, strips of different lengths),
    which trimesh's reader does not; anything else in the file (faces,
    colours) is read too or named in the notes.
    """
    plyfile = require("plyfile", "mesh", "Reading PLY triangle strips")
    try:
        ply = plyfile.PlyData.read(str(path))
    except Exception as exc:  # plyfile raises PlyParseError, ValueError, ... for corrupt files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"mesh '{path}': cannot read PLY file ({msg})") from None
    names = [e.name for e in ply.elements]
    if "vertex" not in names:
        raise FileFormatError(f"mesh '{path}': PLY element 'tristrips' without an element 'vertex'")
    vert = ply["vertex"].data
    if vert.dtype.names is None or not all(k in vert.dtype.names for k in "xyz"):
        raise FileFormatError(f"mesh '{path}': PLY element 'vertex' has no x, y, z properties "
                              f"(has {', '.join(vert.dtype.names or ())})")
    v = np.column_stack([np.asarray(vert[k], dtype=np.float64) for k in "xyz"])
    faces = [strip_triangles(_element_lists(ply["tristrips"].data, path, "tristrips"), len(v), path)]
    if "face" in names:
        for poly in _element_lists(ply["face"].data, path, "face"):
            if len(poly) >= 3:           # a fan, as trimesh splits polygons
                faces.append(np.column_stack([np.full(len(poly) - 2, poly[0]), poly[1:-1], poly[2:]]))
    f = np.concatenate(faces).astype(np.int64).reshape(-1, 3)
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise FileFormatError(f"mesh '{path}': PLY face index {int(f.max() if f.max() >= len(v) else f.min())} "
                              f"outside the {len(v)} vertices")
    if len(f) == 0:
        raise FileFormatError(f"mesh '{path}': no triangles found (empty mesh or unreadable content)")
    notes = ["vertex colours of 1 mesh ignored"] if any(k in vert.dtype.names for k in ("red", "r", "diffuse_red")) \
        else []
    return v, f, {"meshes": 1, "format": "ply", "notes": notes}


def _element_lists(data, path: Path, element: str) -> list:
    """The index lists of a PLY element (its one list property), as int64 arrays."""
    names = data.dtype.names or ()
    key = "vertex_indices" if "vertex_indices" in names else ("vertex_index" if "vertex_index" in names else None)
    if key is None or len(data) > MAX_PLY_STRIPS:
        why = (f"{len(data)} records exceed the limit of {MAX_PLY_STRIPS} (shapedisplay.author.meshfiles."
               f"MAX_PLY_STRIPS)") if key else f"no list property vertex_indices (has {', '.join(names)})"
        raise FileFormatError(f"mesh '{path}': PLY element '{element}': {why}")
    try:
        return [np.asarray(r, dtype=np.int64).ravel() for r in data[key]]
    except (TypeError, ValueError, OverflowError):
        raise FileFormatError(f"mesh '{path}': PLY element '{element}': property {key} is not a list of "
                              f"vertex indices") from None


def strip_triangles(strips, n_vertices: int, path="strips") -> np.ndarray:
    """Triangles of triangle strips: each strip's index list, -1 restarting a strip.

    Triangle ``i`` of a run is ``(r[i], r[i+1], r[i+2])`` for even ``i`` and
    ``(r[i+1], r[i], r[i+2])`` for odd ``i`` (alternate triangles flip
    winding so that all face the same way); triangles that repeat a vertex
    (strips repeat vertices to turn corners) are dropped.
    """
    out = [np.empty((0, 3), np.int64)]
    for s in strips:
        s = np.asarray(s, dtype=np.int64).ravel()
        if s.size < 3:
            continue
        if s.min() < -1 or s.max() >= n_vertices:
            bad = int(s.min() if s.min() < -1 else s.max())
            raise FileFormatError(f"mesh '{path}': PLY element 'tristrips': vertex index {bad} outside "
                                  f"0..{n_vertices - 1} (-1 restarts a strip)")
        idx = np.arange(s.size)
        start = np.maximum.accumulate(np.where(s < 0, idx + 1, 0))   # first index of each run
        pos = idx - start                                           # position within the run
        a, b, c, p = s[:-2], s[1:-1], s[2:], pos[2:]
        ok = (a >= 0) & (b >= 0) & (c >= 0) & (p >= 2)
        odd = (p - 2) % 2 == 1
        tri = np.column_stack([np.where(odd, b, a), np.where(odd, a, b), c])[ok]
        keep = (tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])
        out.append(tri[keep])
    return np.concatenate(out)


_VISUALS = ("textures", "vertex colours", "face colours")


def _visual_notes(g) -> list:
    """What a geometry carries that a height field cannot: textures and colours."""
    vis = getattr(g, "visual", None)
    kind = getattr(vis, "kind", None)
    if kind == "texture":
        mat = getattr(vis, "material", None)
        has_image = any(getattr(mat, k, None) is not None for k in ("image", "baseColorTexture"))
        return ["textures"] if has_image else []
    defined = getattr(vis, "defined", None)
    if kind == "vertex" and defined:
        return ["vertex colours"]
    if kind == "face" and defined:
        return ["face colours"]
    return []




# ---------------------------------------------------------------------------
# parameters

def up_rotation(up="z") -> np.ndarray:
    """Rotation matrix that turns ``up`` into +z (see the module docstring).

    Parameters
    ----------
    up : str, array of shape (3,), or array of shape (3, 3)
        Axis name ``x|y|z|-x|-y|-z``, a direction, or a rotation matrix.

    Returns
    -------
    ndarray of shape (3, 3), float64
        Rows are the new x, y, z axes in world coordinates.
    """
    if isinstance(up, str):
        name = up.strip().lower()
        sign = -1.0 if name.startswith("-") else 1.0
        key = name.lstrip("+-")
        if key not in _AXES:
            raise InputError(f"`up` must be one of x, y, z, -x, -y, -z, a direction or a 3x3 rotation (got {up!r})")
        d = sign * np.array(_AXES[key])
    else:
        arr = np.asarray(up, dtype=np.float64)
        if arr.shape == (3, 3):
            if not np.all(np.isfinite(arr)) or not np.allclose(arr @ arr.T, np.eye(3), atol=1e-6) \
                    or np.linalg.det(arr) < 0:
                raise InputError(f"`up` as a 3x3 matrix must be a proper rotation (orthonormal, det +1) (got {arr.tolist()})")
            return arr
        if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.linalg.norm(arr) == 0:
            raise InputError(f"`up` must be an axis name, a non-zero finite 3-vector or a 3x3 rotation (got {up!r})")
        d = arr / np.linalg.norm(arr)
    ref = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    ex = ref - d * (ref @ d)
    ex /= np.linalg.norm(ex)
    ey = np.cross(d, ex)
    return np.vstack([ex, ey, d])


def _length(value, name: str, allow_zero: bool = False) -> float:
    from shapedisplay.units import parse_quantity
    if isinstance(value, str):
        v = parse_quantity(value, "m", name)
    else:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(f"`{name}` must be a length in metres or a string such as '0.1 mm' (got {value!r})") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        rule = ">= 0" if allow_zero else "> 0"
        raise InputError(f"`{name}` must be a finite length {rule} (got {value!r})")
    return v


def _grid(value) -> tuple[int, int]:
    if isinstance(value, str):
        parts = value.lower().replace(" ", "").split("x")
        if len(parts) != 2:
            raise InputError(f"`grid` must look like 'ROWSxCOLS', e.g. '512x512' (got {value!r})")
        value = parts
    try:
        rows, cols = (int(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"`grid` must be two integers (rows, cols) (got {value!r})") from None
    if rows < 2 or cols < 2:
        raise InputError(f"`grid` must be at least 2x2 samples (got rows={rows}, cols={cols})")
    return rows, cols


def _mesh_size(value):
    """``size``: one length (uniform scale) or (width, height), metres."""
    from shapedisplay.units import parse_pair
    if isinstance(value, str) and "x" not in value or isinstance(value, (int, float)):
        return _length(value, "size")
    if isinstance(value, str):
        w, h = parse_pair(value, "x", "m", "size")
    else:
        try:
            w, h = (_length(v, "size") for v in value)
        except (TypeError, ValueError):
            raise InputError(f"`size` must be a length or (width, height) (got {value!r})") from None
    if not (w > 0 and h > 0):
        raise InputError(f"`size` must be positive (got width={w} m, height={h} m)")
    return float(w), float(h)


def _background(value) -> float:
    from shapedisplay.units import parse_quantity
    if isinstance(value, str):
        return parse_quantity(value, "m", "background")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"`background` must be a finite height in metres (got {value!r})")
    return v


# ---------------------------------------------------------------------------
# mesh -> height field

#: File suffixes whose format defines its length unit (glTF 2.0: metres).
FORMAT_UNITS = {".glb": "m", ".gltf": "m"}


def default_units(path) -> str:
    """The coordinate unit assumed when none is given: the one the format defines, else millimetres."""
    if isinstance(path, (str, os.PathLike)):
        return FORMAT_UNITS.get(Path(os.fspath(path)).suffix.lower(), "mm")
    return "mm"


def mesh_to_heightfield(path, resolution=None, grid=None, up="z", units=None, background=0.0,
                        supersample=1, *, supersample_mode="mean", margin=0.0, size=None,
                        height_range=None) -> HeightField:
    """Project the top surface of a mesh onto a regular height field.

    Parameters
    ----------
    path : str, os.PathLike, trimesh.Trimesh / Scene, or (vertices, faces)
        A mesh file (``.stl .obj .ply .off .glb .gltf``), a trimesh object, or
        arrays ``vertices`` (n, 3) float in ``units`` and ``faces`` (m, 3) int.
    resolution : float (metres) or str such as ``"0.1 mm"``, optional
        Sample spacing along x and y. Exclusive with ``grid``.
    grid : (rows, cols) or str ``"ROWSxCOLS"``, optional
        Grid size; the spacing then follows from the footprint. If neither is
        given, the longer side gets 512 samples.
    up : str, (3,) or (3, 3)
        View direction, see :func:`up_rotation`.
    units : {"mm", "cm", "m", "in"}, optional
        Unit of the mesh coordinates; by default :func:`default_units` (metres
        for ``.glb``/``.gltf``, whose format defines them, millimetres otherwise).
    background : float (metres) or str
        Height of samples the mesh does not cover.
    supersample : int >= 1
        k: average (or max) of k x k sub-samples per sample.
    supersample_mode : {"mean", "max"}
        Reduction of sub-samples.
    margin : float (metres) or str
        Background border added around the footprint.
    size : float, (width, height) (metres) or str, optional
        Scale the model: one length scales it uniformly (x, y and heights)
        so that the longer side of its footprint has that length; a pair
        stretches the footprint to exactly width x height (heights kept).
    height_range : (low, high) metres or str "0:2mm", optional
        Fit the relief: the lowest point of the model goes to ``low``, the
        highest to ``high`` (background heights follow the same map).

    Returns
    -------
    HeightField
        heights (rows, cols) float64 metres above the mesh's lowest point;
        ``meta`` holds ``triangles``, ``degenerate_faces_dropped``,
        ``meshes``, ``units``, ``up``, ``model_origin_m``, ``footprint_m``,
        ``supersample``, ``supersample_mode``, ``covered_fraction``, ``scale``
        (file units -> metres of height), ``notes`` (what was ignored: textures,
        colours, points and lines).

    Raises
    ------
    FileFormatError
        Missing, unreadable, truncated or empty file.
    InputError
        Bad parameter, non-finite vertices, zero-area footprint, grid too large.
    MissingDependencyError
        trimesh is needed for files and is not installed.
    """
    from shapedisplay.author import raster

    # --- check parameters before touching the file
    units = default_units(path) if units is None else units
    units = units.strip().lower() if isinstance(units, str) else units
    if units not in UNITS:
        raise unknown_key("mesh units", units, UNITS)
    if resolution is not None and grid is not None:
        raise InputError(f"give either `resolution` or `grid`, not both (got resolution={resolution!r}, grid={grid!r})")
    res = _length(resolution, "resolution") if resolution is not None else None
    shape = _grid(grid) if grid is not None else None
    bg = _background(background)
    mrg = _length(margin, "margin", allow_zero=True)
    if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 16:
        raise InputError(f"`supersample` must be an integer from 1 to 16 (got {supersample!r})")
    k = int(supersample)
    if supersample_mode not in SUPERSAMPLE_MODES:
        raise unknown_key("supersample mode", supersample_mode, SUPERSAMPLE_MODES)
    rot = up_rotation(up)
    if size is not None:
        size = _mesh_size(size)
    hr = None
    if height_range is not None:
        from shapedisplay.author.heightfield import height_range as parse_height_range
        hr = parse_height_range(height_range)

    verts, faces, info, name = _mesh_arrays(path)
    where = f"mesh '{name}'"

    # --- check the mesh
    if faces.size == 0 or verts.size == 0:
        raise InputError(f"{where}: mesh is empty ({len(verts)} vertices, {len(faces)} faces)")
    if faces.ndim != 2 or faces.shape[1] != 3 or verts.ndim != 2 or verts.shape[1] != 3:
        raise InputError(f"{where}: need vertices (n, 3) and triangle faces (m, 3) (got {verts.shape}, {faces.shape})")
    if faces.min() < 0 or faces.max() >= len(verts):
        raise InputError(f"{where}: face indices must lie in 0..{len(verts) - 1} (got {faces.min()}..{faces.max()})")
    used = np.zeros(len(verts), dtype=bool)
    used[faces.ravel()] = True
    bad = used & ~np.all(np.isfinite(verts), axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{where}: vertices must be finite: {int(bad.sum())} NaN/inf vertices, first #{i} = {verts[i].tolist()}"
        )
    bad = used & np.any(np.abs(verts) > MAX_COORDINATE, axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{where}: vertex coordinates must be within +-{MAX_COORDINATE:g} (file units; "
            f"shapedisplay.author.meshfiles.MAX_COORDINATE): {int(bad.sum())} vertices beyond, first #{i} = {verts[i].tolist()}"
        )

    # coordinates as contiguous columns (fast gathers and reductions), metres, rotated
    scale = UNITS[units]
    px, py, pz = np.ascontiguousarray(verts.T) * scale
    if not np.array_equal(rot, np.eye(3)):
        px, py, pz = rot @ np.vstack([px, py, pz])
    f0, f1, f2 = np.ascontiguousarray(faces.T)
    e1x, e1y, e1z = px[f1] - px[f0], py[f1] - py[f0], pz[f1] - pz[f0]
    e2x, e2y, e2z = px[f2] - px[f0], py[f2] - py[f0], pz[f2] - pz[f0]
    nz = e1x * e2y - e1y * e2x                      # twice the projected (signed) area
    area2sq = (e1y * e2z - e1z * e2y) ** 2 + (e1z * e2x - e1x * e2z) ** 2 + nz ** 2
    lo = np.array([px[used].min(), py[used].min(), pz[used].min()])
    hi = np.array([px[used].max(), py[used].max(), pz[used].max()])
    diag = float(np.linalg.norm(hi - lo))
    degenerate = area2sq <= (1e-9 * diag) ** 4      # |cross| <= (1e-9 * bounding-box diagonal)^2
    n_deg = int(np.count_nonzero(degenerate))
    if n_deg == len(faces):
        raise InputError(f"{where}: all {len(faces)} faces are degenerate (zero area); nothing to rasterise")
    if n_deg:
        keep = ~degenerate
        faces, nz = faces[keep], nz[keep]
        used = np.zeros(len(verts), dtype=bool)
        used[faces.ravel()] = True
        lo = np.array([px[used].min(), py[used].min(), pz[used].min()])
        hi = np.array([px[used].max(), py[used].max(), pz[used].max()])
    width, height = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    file_width, file_height = width, height
    proj = float(np.abs(nz).sum()) / 2
    tiny = 1e-9 * max(diag, 1e-300)
    if width <= tiny or height <= tiny or proj <= (1e-9 * diag) ** 2:
        raise InputError(
            f"{where}: footprint seen along up={_up_text(up)} has zero area "
            f"({width * 1e3:.6g} x {height * 1e3:.6g} mm, projected area {proj * 1e6:.3g} mm^2); choose another `up`"
        )
    zscale = 1.0
    origin = lo                                     # the footprint's corner, file coordinates in metres
    if size is None:
        _warn_size(where, width, height, units)
    else:   # scale about the footprint's corner
        if isinstance(size, float):
            sx = sy = zscale = size / max(width, height)
        else:
            sx, sy = size[0] / width, size[1] / height
        # positions from the corner: adding the corner back would lose a scaled footprint far smaller than
        # the corner's coordinates (1e38 mm scaled to 60 mm: width 0)
        px, py, pz = (px - lo[0]) * sx, (py - lo[1]) * sy, (pz - lo[2]) * zscale
        hi = (hi - lo) * np.array([sx, sy, zscale])
        lo = np.zeros(3)
        width, height = float(hi[0]), float(hi[1])

    # --- grid
    if shape is not None:
        rows_f, cols_f = shape
        dx, dy = width / (cols_f - 1), height / (rows_f - 1)
    else:
        if res is None:
            res = max(width, height) / (DEFAULT_LONG_SIDE - 1)
        dx = dy = res
        cols_f = int(math.ceil(width / dx - raster.EDGE_TOLERANCE)) + 1
        rows_f = int(math.ceil(height / dy - raster.EDGE_TOLERANCE)) + 1
    mc = int(math.ceil(mrg / dx - 1e-9)) if mrg > 0 else 0
    mr = int(math.ceil(mrg / dy - 1e-9)) if mrg > 0 else 0
    rows, cols = rows_f + 2 * mr, cols_f + 2 * mc
    check_grid_size(rows, cols, f"{where} height field", "give a coarser `resolution` or a smaller `size`")
    check_grid_size(rows * k, cols * k, f"{where} with supersample={k}", "give a smaller `supersample`")
    x0, y0 = -mc * dx, -mr * dy

    # --- rasterise in sub-sample grid units
    sdx, sdy = dx / k, dy / k
    ox = lo[0] + x0 - dx / 2 * (1 - 1 / k)
    oy = lo[1] + y0 - dy / 2 * (1 - 1 / k)
    g = np.empty((len(px), 3))
    g[:, 0] = (px - ox) / sdx
    g[:, 1] = (py - oy) / sdy
    g[:, 2] = pz - lo[2]
    zbuf = raster.rasterize_mesh(g, faces, rows * k, cols * k)
    covered = np.isfinite(zbuf)
    zbuf[~covered] = bg
    if k > 1:
        blocks = zbuf.reshape(rows, k, cols, k)
        heights = blocks.mean(axis=(1, 3)) if supersample_mode == "mean" else blocks.max(axis=(1, 3))
    else:
        heights = zbuf
    relief = float(hi[2] - lo[2])
    m_per_unit = UNITS[units] * zscale
    offset = 0.0
    scale_rule = f"model in {units}" + (f", scaled x{zscale:.6g}" if zscale != 1.0 else "") \
        + (f", footprint stretched to {width * 1e3:.6g} x {height * 1e3:.6g} mm" if isinstance(size, tuple) else "")
    if hr is not None:
        a = (hr[1] - hr[0]) / relief if relief > 0 else 0.0
        heights *= a
        heights += hr[0]
        bg = hr[0] + a * bg
        m_per_unit *= a
        offset = hr[0]
        scale_rule += (f", relief {relief * 1e3:.6g} mm fitted onto {hr[0] * 1e3:.6g}..{hr[1] * 1e3:.6g} mm"
                       if relief > 0 else f", flat model placed at {hr[0] * 1e3:.6g} mm")
    from shapedisplay.author.heightfield import height_scale
    meta = {
        "kind": "mesh",
        "triangles": int(len(faces)) + n_deg,
        "degenerate_faces_dropped": n_deg,
        "meshes": info.get("meshes", 1),
        "units": units,
        "up": _up_text(up),
        "model_origin_m": [float(v) for v in origin],
        "footprint_m": [width, height],
        "height_range_m": [0.0, relief] if hr is None else list(hr),
        "file_footprint_m": [file_width, file_height],
        "scale": height_scale(units, m_per_unit, offset, scale_rule, "model height"),
        "notes": list(info.get("notes", [])),
        "supersample": k,
        "supersample_mode": supersample_mode,
        "background_m": bg,
        "covered_fraction": float(covered.mean()),
    }
    return HeightField(heights, dx, dy, x0, y0, source=f"mesh {name}", meta=meta)


def _up_text(up) -> str:
    return up if isinstance(up, str) else json.dumps(np.asarray(up, dtype=float).tolist())


def _mesh_arrays(src):
    """Return (vertices, faces, info, name) from a path, a trimesh object or arrays."""
    if isinstance(src, (str, os.PathLike)):
        v, f, info = load_mesh(src)
        return v, f, info, str(src)
    if isinstance(src, tuple) and len(src) == 2:
        v = np.asarray(src[0], dtype=np.float64)
        f = np.asarray(src[1])
        if f.size and not np.issubdtype(f.dtype, np.integer):
            raise InputError(f"mesh '<arrays>': faces must be integers (got dtype {f.dtype})")
        return v, f.astype(np.int64).reshape(-1, 3) if f.size else f.reshape(0, 3).astype(np.int64), \
            {"meshes": 1}, "<arrays>"
    if hasattr(src, "dump") and hasattr(src, "geometry"):  # trimesh.Scene
        geoms = [g for g in src.dump() if getattr(g, "faces", None) is not None and len(g.faces)]
        if not geoms:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64), {"meshes": 0}, "<scene>"
        vs, fs, off = [], [], 0
        for g in geoms:
            vs.append(np.asarray(g.vertices, dtype=np.float64))
            fs.append(np.asarray(g.faces, dtype=np.int64) + off)
            off += len(g.vertices)
        return np.concatenate(vs), np.concatenate(fs), {"meshes": len(geoms)}, "<scene>"
    if hasattr(src, "vertices") and hasattr(src, "faces"):  # trimesh.Trimesh
        return (np.asarray(src.vertices, dtype=np.float64), np.asarray(src.faces, dtype=np.int64),
                {"meshes": 1}, "<trimesh>")
    raise InputError(f"mesh source must be a file path, a trimesh object or (vertices, faces) (got {type(src).__name__})")


def _warn_size(where: str, width: float, height: float, units: str) -> None:
    lo, hi = PLAUSIBLE_FOOTPRINT_M
    side = max(width, height)
    if lo <= side <= hi:
        return
    raw = side / UNITS[units]
    fits = [u for u, s in UNITS.items() if lo <= raw * s <= hi and u != units]
    hint = (f"; if the file is in {', '.join(fits)}, give its unit: --units {fits[0]} (units='{fits[0]}' in Python)"
            if fits else "")
    warnings.warn(
        f"{where}: footprint {width * 1e3:.4g} x {height * 1e3:.4g} mm looks implausible for a screen "
        f"(expected {lo * 1e3:g} mm to {hi:g} m) with units='{units}'{hint}",
        ImplausibleSizeWarning, stacklevel=3,
    )


# ---------------------------------------------------------------------------
# height field -> mesh

def heightfield_to_mesh(hf: HeightField, solid: bool = True, base_thickness: float = 1e-3):
    """Triangulate a height field, optionally as a closed solid for printing.

    Parameters
    ----------
    hf : HeightField
    solid : bool
        If True, add vertical side walls and a flat bottom at
        ``min(heights) - base_thickness`` so the mesh is watertight.
    base_thickness : float, metres
        Thickness below the lowest sample (``solid`` only); > 0.

    Returns
    -------
    vertices : ndarray of shape (n, 3), float64, metres
        Top vertex of sample (r, c) is ``vertices[r * cols + c] = (x, y, h)``.
    faces : ndarray of shape (m, 3), int64
        Counter-clockwise seen from outside (normals point out / up).
    """
    if hf.rows < 2:
        raise InputError(f"`hf`: a 1-D profile ({hf.cols} x {hf.rows} samples) has no surface to triangulate; need >= 2 rows")
    rows, cols = hf.rows, hf.cols
    xx, yy = np.meshgrid(hf.x, hf.y)
    top = np.column_stack([xx.ravel(), yy.ravel(), hf.heights.ravel()])
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    faces = [np.column_stack([a, b, d]), np.column_stack([a, d, c])]
    verts = [top]
    if solid:
        t = float(base_thickness)
        if not math.isfinite(t) or t <= 0:
            raise InputError(f"`base_thickness` must be a finite length > 0 (got {base_thickness!r})")
        zb = float(hf.heights.min()) - t
        # boundary loop counter-clockwise seen from +z
        ring = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])
        n0 = rows * cols
        bottom = top[ring].copy()
        bottom[:, 2] = zb
        verts.append(bottom)
        nr = len(ring)
        nxt = np.roll(np.arange(nr), -1)
        # wall quad: top i -> top i+1 -> bottom i+1 -> bottom i (outward for a CCW ring)
        faces.append(np.column_stack([ring, n0 + np.arange(nr), n0 + nxt]))
        faces.append(np.column_stack([ring, n0 + nxt, ring[nxt]]))
        # bottom: fan around the centre, facing down
        centre = n0 + nr
        verts.append([[hf.x0 + (cols - 1) * hf.dx / 2, hf.y0 + (rows - 1) * hf.dy / 2, zb]])
        faces.append(np.column_stack([np.full(nr, centre), n0 + nxt, n0 + np.arange(nr)]))
    return np.vstack(verts).astype(np.float64), np.vstack(faces).astype(np.int64)


def save_mesh(vertices, faces, path, units: str = "mm") -> None:
    """Write a triangle mesh as binary STL or binary little-endian PLY, atomically.

    Parameters
    ----------
    vertices : ndarray of shape (n, 3), metres
    faces : ndarray of shape (m, 3), int
    path : str or os.PathLike
        ``.stl`` or ``.ply``.
    units : {"mm", "cm", "m", "in"}
        Unit written into the file (STL and PLY carry none; mm is customary).
    """
    from shapedisplay.atomic import atomic_path

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".stl", ".ply"):
        raise FileFormatError(f"mesh output '{path}': suffix must be .stl or .ply (got '{suffix}')")
    if units not in UNITS:
        raise unknown_key("mesh units", units, UNITS)
    v = np.asarray(vertices, dtype=np.float64) / UNITS[units]
    f = np.asarray(faces, dtype=np.int64)
    if suffix == ".stl":
        tri = v[f]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
        rec = np.zeros(len(f), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
        rec["n"], rec["v"] = n, tri
        header = f"shapedisplay height field mesh, units {units}".encode().ljust(80, b" ")[:80]
        data = header + struct.pack("<I", len(f)) + rec.tobytes()
    else:
        head = (f"ply\nformat binary_little_endian 1.0\ncomment shapedisplay height field mesh, units {units}\n"
                f"element vertex {len(v)}\nproperty float x\nproperty float y\nproperty float z\n"
                f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
        rec = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", 3)])
        rec["n"], rec["i"] = 3, f
        data = head + v.astype("<f4").tobytes() + rec.tobytes()
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def save_heightfield_mesh(hf: HeightField, path, units: str = "mm", solid: bool = True,
                          base_thickness: float = 1e-3) -> int:
    """Export a height field as a mesh (``.stl`` binary or ``.ply``), atomically.

    Coordinates are written in ``units`` (mm by default, so that reading the
    file back with :func:`mesh_to_heightfield` and its default ``units="mm"``
    round-trips). See :func:`heightfield_to_mesh` for ``solid`` and
    ``base_thickness``; reading a solid back gives heights shifted by
    ``base_thickness - min(heights)`` (heights are measured from the mesh's
    lowest point). Returns the number of triangles written.
    """
    v, f = heightfield_to_mesh(hf, solid=solid, base_thickness=base_thickness)
    save_mesh(v, f, path, units=units)
    return len(f)


# ---------------------------------------------------------------------------
# height field -> image / array files

#: Height-map output suffixes handled by :func:`save_heightmap`.
HEIGHTMAP_SUFFIXES = (".npy", ".npz", ".png", ".stl", ".ply")


def save_heightmap(hf: HeightField, path, **mesh_options) -> str:
    """Write a height field to ``path``; the suffix picks the format. Atomic.

    ``.npy``
        heights (rows, cols) float64 metres in picture order: the top view,
        row 0 the far edge (largest y), as :func:`shapedisplay.author.sources.load_image`
        reads ``.npy`` arrays.
    ``.npz``
        ``heights`` in height-field order (row 0 at ``y0``, the smallest y;
        sample (r, c) at ``(x0 + c dx, y0 + r dy)``), ``dx``, ``dy``, ``x0``,
        ``y0`` (metres) and ``meta`` (JSON text).
    ``.png``
        16-bit grayscale top view (row 0 the far edge, x to the right, y up);
        black = lowest, white = highest sample. tEXt chunks record
        ``height_min_m``, ``height_max_m``, ``dx_m``, ``dy_m`` and ``size_m`` =
        cols*dx x rows*dy, the ``size`` that reads the image back at the same
        spacing.
    ``.stl`` / ``.ply``
        :func:`save_heightfield_mesh` with ``mesh_options``.

    Returns
    -------
    str
        One-line description of what was written.
    """
    from shapedisplay.atomic import atomic_path
    from shapedisplay.author.heightfield import picture_from_grid
    from shapedisplay.author.imageio import encode_png

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in HEIGHTMAP_SUFFIXES:
        raise FileFormatError(
            f"height-map output '{path}': unsupported suffix '{suffix}'; use one of {', '.join(HEIGHTMAP_SUFFIXES)}"
        )
    h = hf.heights
    if suffix in (".stl", ".ply"):
        n_faces = save_heightfield_mesh(hf, path, **mesh_options)
        n_top = 2 * (hf.rows - 1) * (hf.cols - 1)
        if n_faces == n_top:
            return f"top surface of {n_top} triangles (open mesh)"
        return f"closed solid of {n_faces} triangles ({n_top} on top, side walls and a flat base)"
    with atomic_path(path) as tmp:
        if suffix == ".npy":
            with open(tmp, "wb") as fh:
                np.save(fh, np.ascontiguousarray(picture_from_grid(h)))
            desc = "heights in metres (float64), top view (row 0 = far edge)"
        elif suffix == ".npz":
            with open(tmp, "wb") as fh:
                np.savez(fh, heights=h, dx=hf.dx, dy=hf.dy, x0=hf.x0, y0=hf.y0,
                         meta=np.array(json.dumps(hf.meta, default=str)))
            desc = "heights in metres with grid"
        else:
            lo, hi = float(h.min()), float(h.max())
            span = hi - lo
            gray = np.zeros(h.shape, np.uint16) if span == 0 else np.round((h - lo) / span * 65535).astype(np.uint16)
            w, ht = hf.size_m
            text = {"height_min_m": repr(lo), "height_max_m": repr(hi), "dx_m": repr(hf.dx), "dy_m": repr(hf.dy),
                    "size_m": f"{hf.cols * hf.dx!r}x{hf.rows * hf.dy!r}",
                    "Software": "shapedisplay"}
            tmp.write_bytes(encode_png(np.ascontiguousarray(picture_from_grid(gray)), text=text))
            desc = (f"16-bit PNG; read it back with --size {w * 1e3:.6g}x{ht * 1e3:.6g}mm "
                    f"--height {lo * 1e3:.6g}:{hi * 1e3:.6g}mm")
    return desc
