"""The studio reads only under its source's folder: every file a scene or an SVG mockup names.

Each path-bearing key the scene reader knows (``scene.spec.path_keys()``) and
each SVG attribute that becomes one is tried with a file outside the folder,
named three ways (an absolute path, a ``../`` path, a symlink inside the folder
pointing outside): the studio's compile is refused with one line naming the
key and the path, and no table is kept. The same file inside the folder
compiles. The command line (``compile_scene`` without ``confine``) still reads
files anywhere.
"""
from __future__ import annotations

import builtins
import os
import shutil

import numpy as np
import pytest

from shapedisplay.table.devices import BUNDLED_DEVICES
from shapedisplay.errors import InputError
from shapedisplay.author.scene import WIDGET_TYPES, compile_scene
from shapedisplay.author.scene.spec import PATH_KEYS, path_keys, widget_file_keys
from shapedisplay.author.scene.svg import _ROOT_KEYS
from shapedisplay.studio.session import Session

HEAD = '[canvas]\nsize = "20x20 mm"\nresolution = "1 mm"\n'
BOX = 'position = "0,0 mm"\nsize = "10x10 mm"\n'
BUTTON = '[[widget]]\nid = "b"\ntype = "button"\n' + BOX + 'height = "1 mm"\n'
#: The keys a widget of each type with a file needs besides the file, and the file it reads.
WIDGET_BODY = {"image": 'height = "0:1 mm"\n', "mesh": "", "data": 'channel = "friction_scale"\n'}
FILE_NAME = {"image": "bump.png", "mesh": "bump.stl", "data": "field.npy", "device": "dev.toml"}

STL = """solid bump
facet normal 0 0 1
outer loop
vertex 0 0 0
vertex 10 0 1
vertex 0 10 1
endloop
endfacet
facet normal 0 0 1
outer loop
vertex 10 0 1
vertex 10 10 0
vertex 0 10 1
endloop
endfacet
endsolid bump
"""


def write_file(kind: str, folder) -> str:
    """Write a valid file of ``kind`` (image, mesh, data, device) in ``folder``; its name."""
    from PIL import Image
    name = FILE_NAME[kind]
    p = folder / name
    if kind == "image":
        Image.fromarray(np.arange(64, dtype=np.uint8).reshape(8, 8) * 4).save(p)
    elif kind == "mesh":
        p.write_text(STL)
    elif kind == "data":
        np.save(p, np.linspace(0.0, 1.0, 16).reshape(4, 4))
    else:
        shutil.copy(BUNDLED_DEVICES / "handheld-stick.toml", p)
    return name


def scene_text(key: str, ref: str) -> str:
    """A scene whose path-bearing ``key`` (as path_keys() writes it; ``widget.TYPE.KEY`` for a widget) is ``ref``."""
    parts = key.split(".")
    if key == "device.profile":
        return HEAD + f'[device]\nprofile = "{ref}"\n' + BUTTON
    if parts[0] == "defaults":
        if len(parts) == 2:                 # [defaults] file: every type with that key takes it
            wtype = "image"
            return HEAD + f'[defaults]\n{parts[1]} = "{ref}"\n' + _widget(wtype)
        wtype = parts[1]
        return HEAD + f'[defaults.{wtype}]\n{parts[2]} = "{ref}"\n' + _widget(wtype)
    _, wtype, k = parts
    return HEAD + _widget(wtype) + f'{k} = "{ref}"\n'


def _widget(wtype: str) -> str:
    return f'[[widget]]\nid = "w"\ntype = "{wtype}"\n' + BOX + WIDGET_BODY[wtype]


def kind_of(key: str) -> str:
    if key == "device.profile":
        return "device"
    parts = key.split(".")
    return "image" if key == "defaults.file" else parts[1]


def cases() -> list:
    """Every path-bearing key of the scene reader; widget keys once per widget type that has them."""
    keys = [k for k in path_keys() if not k.startswith("widget.")]
    keys += [f"widget.{t}.{k}" for t in sorted(WIDGET_TYPES) for k in widget_file_keys(t)]
    return keys


def test_every_path_key_has_a_case():
    """A new path-bearing key (a widget type with a file, a [device]-like table) needs a case here."""
    assert {f"{sec}.{key}" for sec, key in PATH_KEYS} <= set(cases())
    for key in cases():
        assert kind_of(key) in FILE_NAME, key
    assert {"device.profile", "defaults.file", "defaults.image.file", "widget.image.file",
            "widget.mesh.file", "widget.data.file"} <= set(cases())


def make_ref(how: str, kind: str, tmp_path):
    """(scene folder, value to write) naming a file outside the folder ``how``; inside for "inside"."""
    folder, outside = tmp_path / "scene", tmp_path / "outside"
    folder.mkdir()
    outside.mkdir()
    name = write_file(kind, outside)
    if how == "absolute":
        return folder, str(outside / name)
    if how == "dotdot":
        return folder, f"../outside/{name}"
    if how == "symlink":
        os.symlink(outside / name, folder / ("link-" + name))
        return folder, "link-" + name
    shutil.copy(outside / name, folder / name)
    return folder, name


def studio_compile(source, device=None) -> Session:
    s = Session(source, device=device, out_dir=source.parent / "out")
    s.compile()
    return s


def assert_refused(s: Session, key: str, ref: str):
    assert s.error is not None, f"{key} = {ref!r} was read"
    msg = s.error.message
    assert "\n" not in msg and "outside the scene's folder" in msg, msg
    assert key in msg and repr(ref) in msg, msg
    assert s.current is None


@pytest.mark.parametrize("how", ["absolute", "dotdot", "symlink"])
@pytest.mark.parametrize("key", cases())
def test_scene_key_outside_the_folder_is_refused(tmp_path, key, how):
    folder, ref = make_ref(how, kind_of(key), tmp_path)
    src = folder / "s.toml"
    src.write_text(scene_text(key, ref))
    named = key if not key.startswith("widget.") else f"widget[0].{key.split('.')[2]}"
    assert_refused(studio_compile(src), named, ref)
    if how == "absolute":                    # the command line reads it (a user's own command)
        assert compile_scene(src).table is not None


@pytest.mark.parametrize("key", cases())
def test_scene_key_inside_the_folder_compiles(tmp_path, key):
    folder, ref = make_ref("inside", kind_of(key), tmp_path)
    src = folder / "s.toml"
    src.write_text(scene_text(key, ref))
    s = studio_compile(src)
    assert s.error is None and s.current is not None
    assert s.current.table.checksum == compile_scene(src).table.checksum


# --------------------------------------------------------------- SVG mockups
def svg_cases() -> list:
    """(attribute, element) of every SVG attribute that becomes a path-bearing key."""
    out = [(f"data-{name.replace('_', '-')}", "svg") for name, target in sorted(_ROOT_KEYS.items())
           if target in PATH_KEYS]
    out += [(f"data-{k.replace('_', '-')}", t) for t in sorted(WIDGET_TYPES) for k in widget_file_keys(t)]
    return out


def svg_text(attr: str, element: str, ref: str) -> str:
    root = f' {attr}="{ref}"' if element == "svg" else ""
    if element == "svg":
        widget = '<rect data-widget="button" data-height="1 mm" x="0" y="0" width="10" height="10"/>'
    else:
        extra = " ".join(f'data-{k.replace("_", "-")}={v.split("=", 1)[1].strip()}'
                         for k, v in (line.split(" ", 1) for line in WIDGET_BODY[element].splitlines()))
        widget = (f'<rect id="{element}-w" data-widget="{element}" {attr}="{ref}" {extra} '
                  'x="0" y="0" width="10" height="10"/>')
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="20mm" height="20mm" viewBox="0 0 20 20" '
            f'data-resolution="1 mm"{root}>{widget}</svg>')


def test_svg_cases_cover_the_device_and_every_widget_file():
    attrs = {a for a, _ in svg_cases()}
    assert {"data-device", "data-profile", "data-file"} <= attrs
    assert {e for _, e in svg_cases()} >= {"svg", "image", "mesh", "data"}


@pytest.mark.parametrize("how", ["absolute", "dotdot", "symlink", "inside"])
@pytest.mark.parametrize("attr,element", svg_cases())
def test_svg_attribute_outside_the_folder_is_refused(tmp_path, attr, element, how):
    pytest.importorskip("svgelements")
    folder, ref = make_ref(how, "device" if element == "svg" else element, tmp_path)
    src = folder / "mock.svg"
    src.write_text(svg_text(attr, element, ref))
    s = studio_compile(src)
    if how == "inside":
        assert s.error is None and s.current is not None, s.error
        return
    assert_refused(s, attr, ref)
    assert ("device.profile" if element == "svg" else "widget[0].file") in s.error.message


# --------------------------------------------------------------- the studio's own options and names
def test_device_option_outside_the_folder_is_refused(tmp_path):
    folder, ref = make_ref("absolute", "device", tmp_path)
    (folder / "k.toml").write_text(HEAD + BUTTON)
    with pytest.raises(InputError, match="outside the source's folder"):
        Session(folder / "k.toml", device=ref)
    link = folder / "dev.toml"
    os.symlink(ref, link)
    with pytest.raises(InputError, match="outside the source's folder"):
        Session(folder / "k.toml", device=str(link))


def test_a_device_name_is_only_ever_a_bundled_profile(tmp_path, monkeypatch):
    """A file in the current directory named like a bundled profile is not read for that name."""
    folder = tmp_path / "scene"
    folder.mkdir()
    (folder / "s.toml").write_text(HEAD + '[device]\nprofile = "handheld-stick"\n' + BUTTON)
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    (cwd / "handheld-stick").write_text("not a profile [")
    (cwd / "nosuch").write_text("not a profile [")
    monkeypatch.chdir(cwd)
    s = studio_compile(folder / "s.toml")
    assert s.error is None and s.current is not None
    s = studio_compile(folder / "s.toml", device="handheld-stick")
    assert s.error is None and s.current is not None
    (folder / "s.toml").write_text(HEAD + '[device]\nprofile = "nosuch"\n' + BUTTON)
    s = studio_compile(folder / "s.toml")
    assert s.error is not None and "unknown device 'nosuch'" in s.error.message


def test_a_mesh_reads_no_material_outside_the_folder(tmp_path, monkeypatch):
    """An OBJ inside the folder whose ``mtllib`` points outside: nothing outside is opened."""
    pytest.importorskip("trimesh")
    folder, outside = tmp_path / "scene", tmp_path / "outside"
    folder.mkdir()
    outside.mkdir()
    (outside / "m.mtl").write_text("newmtl m\nKd 1 0 0\nmap_Kd tex.png\n")
    write_file("image", outside)
    (folder / "m.obj").write_text("mtllib ../outside/m.mtl\nusemtl m\nv 0 0 0\nv 10 0 1\nv 0 10 1\nv 10 10 0\n"
                                  "f 1 2 3\nf 2 4 3\n")
    (folder / "s.toml").write_text(HEAD + _widget("mesh") + 'file = "m.obj"\n')
    opened = []
    real_open = builtins.open

    def spy(file, *args, **kwargs):
        opened.append(os.path.realpath(os.fspath(file)) if isinstance(file, (str, os.PathLike)) else file)
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", spy)
    s = studio_compile(folder / "s.toml")
    monkeypatch.undo()
    assert s.error is None and s.current is not None
    assert not [p for p in opened if isinstance(p, str) and p.startswith(str(outside.resolve()))]


def test_a_mesh_that_may_name_files_needs_a_trimesh_that_keeps_them_in_its_folder(tmp_path, monkeypatch):
    """trimesh 4 reads an OBJ's ``../`` material anywhere: the studio refuses such a mesh with it."""
    trimesh = pytest.importorskip("trimesh")
    folder = tmp_path / "scene"
    folder.mkdir()
    (folder / "m.obj").write_text("v 0 0 0\nv 10 0 1\nv 0 10 1\nf 1 2 3\n")
    (folder / "s.toml").write_text(HEAD + _widget("mesh") + 'file = "m.obj"\n')
    monkeypatch.setattr(trimesh, "__version__", "4.6.0")
    s = studio_compile(folder / "s.toml")
    assert s.error is not None and "trimesh>=5" in s.error.message and "`widget[0].file`" in s.error.message
    s = studio_compile(folder / "m.obj")
    assert s.error is not None and "trimesh>=5" in s.error.message
    write_file("mesh", folder)                  # an STL names no other file: read with any trimesh
    (folder / "s.toml").write_text(HEAD + _widget("mesh") + 'file = "bump.stl"\n')
    assert studio_compile(folder / "s.toml").error is None
    assert compile_scene(folder / "s.toml").table is not None
    monkeypatch.undo()
    assert studio_compile(folder / "m.obj").error is None
