"""glTF 2.0 (.glb) export with MPEG_haptic_material textures: schema, mesh, textures, preview, re-compile."""
import json
from pathlib import Path

import numpy as np
import pytest

from shapedisplay.table.devices import load_device
from shapedisplay.author.glb import EXTENSION, compile_haptic_glb, read_glb, read_haptic_glb
from shapedisplay.exchange.glb import export_glb
from shapedisplay.author.forces import MappingOptions
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
from shapedisplay.cli.main import main

SCHEMAS = Path(__file__).resolve().parent / "data" / "gltf_schema"
BASE = "https://schemas.invalid/gltf/"


def validator(root: str):
    """A jsonschema validator of ``root`` resolving the schemas' relative $refs among the vendored files."""
    jsonschema = pytest.importorskip("jsonschema")
    from referencing import Registry, Resource
    from referencing.jsonschema import DRAFT4, DRAFT7
    resources = []
    for p in SCHEMAS.glob("*.schema.json"):
        s = json.loads(p.read_text(encoding="utf-8"))
        spec = DRAFT7 if "draft-07" in s.get("$schema", "") else DRAFT4
        s["$id" if spec is DRAFT7 else "id"] = BASE + p.name
        resources.append((BASE + p.name, Resource(contents=s, specification=spec)))
    registry = Registry().with_resources(resources)
    schema = registry.contents(BASE + root)
    cls = jsonschema.validators.validator_for(schema)
    return cls(schema, registry=registry)


def bump_table(friction_varies=False):
    """A 2-D bump under the linear height mapping N = 0.5 N + 2 N/mm * h (h up to 1 mm)."""
    rows, cols, d = 24, 36, 0.5e-3
    yy, xx = np.mgrid[0:rows, 0:cols] * d
    h = 1e-3 * np.exp(-(((xx - 12e-3) / 3e-3) ** 2 + ((yy - 7e-3) / 2e-3) ** 2))
    mapping = MappingOptions(n_base=0.5, n_gain=2000.0)
    ch = {"normal_force": 0.5 + 2000.0 * h}
    if friction_varies:
        ch["friction_scale"] = 1.0 + 0.4 * (xx / xx.max())
    q = {n: choose_quantization(v, "float64") for n, v in ch.items()}
    meta = {"device": load_device(None).to_json(), "mapping": mapping.to_json()}
    return FrictionTable.from_dense(Grid(rows, cols, d, d, 2e-3, 1e-3), ch, q, meta), h


def test_extension_json_validates_against_the_khronos_schemas(tmp_path):
    t, _ = bump_table()
    doc, _ = read_glb(export_glb(t, tmp_path / "b.glb"))
    assert EXTENSION in doc["extensionsUsed"]
    root = doc["extensions"][EXTENSION]
    validator("glTF.MPEG_haptic_material.schema.json").validate(root)
    validator("MPEG_haptic_material.schema.json").validate(doc["meshes"][0]["extensions"][EXTENSION])
    mat = root["materials"][0]
    assert sorted(k for k in mat if k != "name") == ["friction", "stiffness", "vibration"]
    # the schema is not a rubber stamp: a texture without its type, or a bad type, fails
    bad = json.loads(json.dumps(root))
    del bad["materials"][0]["friction"][0]["type"]
    assert not validator("glTF.MPEG_haptic_material.schema.json").is_valid(bad)
    bad["materials"][0]["friction"][0]["type"] = "Highest"
    assert not validator("glTF.MPEG_haptic_material.schema.json").is_valid(bad)
    assert not validator("MPEG_haptic_material.schema.json").is_valid({"hapticMaterialIndex": -1})


def test_trimesh_loads_the_surface_in_the_table_orientation(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    t, h = bump_table()
    scene = trimesh.load(export_glb(t, tmp_path / "b.glb"))
    (mesh,) = scene.geometry.values()
    g = t.grid
    assert len(mesh.vertices) == g.rows * g.cols and len(mesh.faces) == 2 * (g.rows - 1) * (g.cols - 1)
    np.testing.assert_allclose(mesh.bounds[0][:2], [g.x0, g.y0], atol=1e-7)
    np.testing.assert_allclose(mesh.bounds[1][:2], [g.x0 + (g.cols - 1) * g.dx, g.y0 + (g.rows - 1) * g.dy],
                               atol=1e-7)
    # the summit (x 12 mm + x0, y 7 mm + y0) is the highest vertex, height 1 mm (float32)
    top = mesh.vertices[np.argmax(mesh.vertices[:, 2])]
    np.testing.assert_allclose(top, [g.x0 + 12e-3, g.y0 + 7e-3, h.max()], atol=1e-7)
    # faces point up (+z) on flat ground: the top view
    assert np.median(mesh.face_normals[:, 2]) > 0.99


def test_textures_round_trip_within_their_scale_and_are_the_top_view(tmp_path):
    t, _ = bump_table(friction_varies=True)
    p = export_glb(t, tmp_path / "b.glb")
    got = read_haptic_glb(p)
    dev = load_device(None)
    exact = {"stiffness": t.dense("normal_force"), "friction": dev.friction.mu_s * t.dense("friction_scale"),
             "vibration": np.full(t.dense("normal_force").shape, dev.burst.gain)}
    for name, v in exact.items():
        sc = got["scales"][name]
        assert np.max(np.abs(got["channels"][name] - v)) <= sc["max_error"] + 1e-12, name
        assert sc["bits"] == 16 and sc["rule"] == "value = offset + scale * texel"
    assert got["scales"]["stiffness"]["unit"] == "N" and got["scales"]["friction"]["unit"] == "1"
    # raw texture: image row 0 is the largest y; the summit sits at image row rows-1-14, column 24
    from PIL import Image
    import io
    doc, binary = read_glb(p)
    view = doc["bufferViews"][doc["images"][0]["bufferView"]]
    img = np.array(Image.open(io.BytesIO(binary[view["byteOffset"]:view["byteOffset"] + view["byteLength"]])))
    assert img.dtype == np.uint16 and img.max() == 65535
    assert np.unravel_index(np.argmax(img), img.shape) == (24 - 1 - 14, 24)
    # TEXCOORD_0 of vertex (r, c) lands on texel (rows-1-r, c)'s centre
    acc = doc["accessors"][1]
    bv = doc["bufferViews"][acc["bufferView"]]
    uv = np.frombuffer(binary[bv["byteOffset"]:bv["byteOffset"] + bv["byteLength"]], "<f4").reshape(-1, 2)
    r, c = 14, 24
    u, v = uv[r * 36 + c]
    assert (int(u * 36), int(v * 24)) == (c, 24 - 1 - r)


def test_preview_renders_the_glb_off_screen(tmp_path):
    pytest.importorskip("pyvista")
    from shapedisplay import viewer
    from shapedisplay.author.mesh import mesh_to_heightfield
    t, h = bump_table()
    hf = mesh_to_heightfield(export_glb(t, tmp_path / "b.glb"), resolution=0.5e-3, units="m")
    assert hf.heights.max() == pytest.approx(h.max(), rel=0.02)
    pv = viewer.render(viewer.model_from_heightfield(hf), "height", size=(320, 240), view="top",
                       annotations=False, scalar_bar=False)
    img = pv.screenshot() if hasattr(pv, "screenshot") else pv
    img = np.asarray(img)
    assert img.shape[:2] == (240, 320) and img.std() > 5     # a drawn surface, not a blank frame


def test_compile_glb_uses_the_haptic_textures(tmp_path, capsys):
    t, _ = bump_table(friction_varies=True)
    p = export_glb(t, tmp_path / "b.glb")
    res = compile_haptic_glb(p)
    got = res.table
    assert "friction_scale" in got.channels and "from the friction texture" in res.report["glb_textures"]
    n_err = got.quant["normal_force"].max_error + read_haptic_glb(p)["scales"]["stiffness"]["max_error"]
    assert np.max(np.abs(got.dense("normal_force") - t.dense("normal_force"))) <= n_err + 1e-12
    fs_err = got.quant["friction_scale"].max_error + 0.5 / 65535 * 0.4 * 1.0001
    assert np.max(np.abs(got.dense("friction_scale") - t.dense("friction_scale"))) <= fs_err
    # the CLI takes the same path; geometry options are refused for a textured glb
    assert main(["compile", str(p), "-o", str(tmp_path / "c.npz"), "-q"]) == 0
    back = FrictionTable.load(tmp_path / "c.npz")
    assert back.channels == got.channels
    code = main(["compile", str(p), "-o", str(tmp_path / "d.npz"), "--resolution", "1mm"])
    assert code == 2 and "haptic textures set the grid" in capsys.readouterr().err


def test_damaged_glb_is_one_clear_error(tmp_path):
    from shapedisplay.errors import FileFormatError
    t, _ = bump_table()
    data = bytearray(export_glb(t, tmp_path / "b.glb").read_bytes())
    (tmp_path / "short.glb").write_bytes(bytes(data[:100]))
    with pytest.raises(FileFormatError, match="declared length"):
        read_haptic_glb(tmp_path / "short.glb")
    data[12:16] = (10 ** 9).to_bytes(4, "little")                     # JSON chunk length past the end
    (tmp_path / "long.glb").write_bytes(bytes(data))
    with pytest.raises(FileFormatError, match="runs past the end"):
        read_haptic_glb(tmp_path / "long.glb")
