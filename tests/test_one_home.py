"""One home for each piece of shared knowledge.

* The rounded rectangle and its edge rises live in ``author/shapes.py``; the
  primitives (``sources.rounded_button``: edge "ramp"/"cosine"/"step") and the
  scene widgets (edge "linear"/"cosine"/"tent") both spell them, and both
  spellings name the same functions.
* The header schema of ``device`` is derived from the dataclasses of
  ``table/devices.py``; the one of ``mapping`` (whose dataclass lives on the
  authoring side, which the table side does not import) is held to
  ``MappingOptions`` here.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field, fields, is_dataclass

import numpy as np
import pytest

from shapedisplay.author import shapes, sources
from shapedisplay.author.forces import MappingOptions
from shapedisplay.author.scene import check_scene
from shapedisplay.author.scene import widgets
from shapedisplay.errors import InputError, TableError
from shapedisplay.table import devices, model
from shapedisplay.table.devices import BurstParams, DeviceProfile, FrictionParams, PadParams, header_kinds

RISES = {shapes.linear_rise, shapes.cosine_rise, shapes.step_rise}


# ----------------------------------------------------------------- edge rises and the rounded rectangle
def test_both_spellings_name_the_one_set_of_rises():
    assert sources.EDGE_PROFILES == tuple(shapes.PRIMITIVE_EDGES) == ("ramp", "cosine", "step")
    assert widgets.EDGES == tuple(shapes.WIDGET_EDGES) == ("linear", "cosine", "tent")
    assert set(shapes.PRIMITIVE_EDGES.values()) | set(shapes.WIDGET_EDGES.values()) <= RISES
    # the same shape under either spelling is the same function, not a copy
    assert shapes.PRIMITIVE_EDGES["ramp"] is shapes.WIDGET_EDGES["linear"] is shapes.WIDGET_EDGES["tent"]
    assert shapes.PRIMITIVE_EDGES["cosine"] is shapes.WIDGET_EDGES["cosine"]
    for kind in widgets.EDGES:
        assert widgets.edge_profile(0.3, kind) == shapes.WIDGET_EDGES[kind](0.3)


def test_rises_values():
    t = np.array([-1.0, 0.0, 0.25, 0.5, 1.0, 2.0])
    assert shapes.linear_rise(t).tolist() == [0.0, 0.0, 0.25, 0.5, 1.0, 1.0]
    assert shapes.step_rise(t).tolist() == [0.0, 0.0, 1.0, 1.0, 1.0, 1.0]
    np.testing.assert_allclose(shapes.cosine_rise(t), [0, 0, (1 - np.sqrt(0.5)) / 2, 0.5, 1, 1], rtol=0, atol=1e-16)


def test_rounded_rect_distance():
    x = np.array([[0.0, 3.0, 5.0, 6.0]])
    y = np.zeros((1, 1))
    d = shapes.rounded_rect_distance(x, y, 5.0, 2.0, 1.0)
    assert d.tolist() == [[-2.0, -2.0, 0.0, 1.0]]
    # at a corner the outline is the arc: distance to the arc's centre minus the radius
    assert shapes.rounded_rect_distance(5.0, 2.0, 5.0, 2.0, 1.0) == pytest.approx(np.hypot(1, 1) - 1)
    # a radius beyond the smaller half side is taken as that (a stadium)
    assert shapes.rounded_rect_distance(5.0, 0.0, 5.0, 2.0, 9.0) == shapes.rounded_rect_distance(5.0, 0.0, 5.0, 2.0, 2.0)
    u, v = np.linspace(0, 10, 11)[None, :], np.linspace(0, 4, 5)[:, None]
    assert np.array_equal(widgets.inside_distance(u, v, 10.0, 4.0, 1.5, False),
                          -shapes.rounded_rect_distance(u - 5.0, v - 2.0, 5.0, 2.0, 1.5))


@pytest.mark.parametrize("primitive_edge, widget_edge", [("ramp", "linear"), ("cosine", "cosine")])
@pytest.mark.parametrize("corner", [0.0, 1.5e-3, 3e-3])
def test_primitive_button_is_the_widget_button(primitive_edge, widget_edge, corner):
    """sources.rounded_button and the scene's button widget give the same heights at the same points."""
    w, d, h, ramp, cx, cy = 10e-3, 6e-3, 1e-3, 1.3e-3, 9.7e-3, 6.1e-3
    hf = sources.rounded_button(w, d, h, (20e-3, 14e-3), 0.1e-3, center=(cx, cy), corner_radius=corner,
                                edge=primitive_edge, edge_width=ramp)
    u, v = hf.x[None, :] - (cx - w / 2), hf.y[:, None] - (cy - d / 2)
    p = {"height": h, "edge": widget_edge, "ramp": ramp, "corner_radius": corner}
    got = widgets.WIDGET_TYPES["button"].heights(p, u, v, w, d, False)
    assert np.abs(hf.heights).max() == pytest.approx(h)
    np.testing.assert_allclose(hf.heights, got, rtol=0, atol=1e-15)


def test_step_edge_is_a_wall_at_the_outline():
    hf = sources.rounded_button("10mm", "6mm", "1mm", "20x14mm", "0.1mm", edge="step", edge_width="2mm")
    inside = -shapes.rounded_rect_distance(hf.x[None, :] - 10e-3, hf.y[:, None] - 7e-3, 5e-3, 3e-3, 0.0) > 0
    assert np.array_equal(hf.heights, np.where(inside, 1e-3, 0.0))


def test_unknown_edges_list_the_names_of_their_spelling(tmp_path):
    with pytest.raises(InputError, match=r"unknown edge profile 'linear'.*valid: cosine, ramp, step"):
        sources.rounded_button("10mm", "6mm", "1mm", "20x20mm", "0.1mm", edge="linear")
    with pytest.raises(InputError, match=r"unknown edge profile 'tent'.*valid: cosine, ramp, step"):
        shapes.edge_rise("tent", shapes.PRIMITIVE_EDGES)
    assert shapes.edge_rise("tent") is shapes.linear_rise
    p = tmp_path / "s.toml"
    p.write_text('[canvas]\nsize = "40x20 mm"\nresolution = "0.5 mm"\n[[widget]]\nid = "b"\ntype = "button"\n'
                 'position = "5,5 mm"\nsize = "10x8 mm"\nedge = "ramp"\n')
    with pytest.raises(InputError, match=r"`widget\[0\]\.edge` must be one of linear, cosine, tent \(got 'ramp'\)"):
        check_scene(p)


def test_widget_edge_choices_are_spellings_of_the_rises():
    """Every edge or profile name a widget type accepts is a key of WIDGET_EDGES (its heights look it up there)."""
    import inspect
    import re
    src = inspect.getsource(widgets)
    for names in re.findall(r'choice\(raw\.get\("(?:edge|profile)", "\w+"\), \(([^)]*)\)', src):
        for name in re.findall(r'"(\w+)"', names):
            assert name in shapes.WIDGET_EDGES, name


# ----------------------------------------------------------------- header schema from the dataclasses
def _leaves(cls, prefix=()):
    """(path, kind) of every leaf field of dataclass ``cls``, nested dataclasses walked."""
    for f in fields(cls):
        kind = header_kinds(cls)[f.name]
        if isinstance(kind, dict):
            yield from _leaves(devices.field_types(cls)[f.name], prefix + (f.name,))
        else:
            yield prefix + (f.name,), kind


def _wrong(kind):
    return {"str": 1, "bool": 1, "number": "1", "number?": "1", "object": [1], "names": [1]}.get(kind, ["a"])


def test_device_schema_is_every_field_of_the_dataclasses():
    def names(cls):
        return {f.name: names(devices.field_types(cls)[f.name]) if is_dataclass(devices.field_types(cls)[f.name])
                else None for f in fields(cls)}

    def shape(kinds):
        return {k: shape(v) if isinstance(v, dict) else None for k, v in kinds.items()}

    assert shape(header_kinds(DeviceProfile)) == names(DeviceProfile)
    assert header_kinds(DeviceProfile)["pad"] == {f.name: "number" for f in fields(PadParams)}
    assert header_kinds(DeviceProfile)["outputs"] == "names"
    assert header_kinds(DeviceProfile)["normal_force_range"] == 2


@pytest.mark.parametrize("path, kind", list(_leaves(DeviceProfile)), ids=lambda v: ".".join(v) if isinstance(v, tuple) else v)
def test_every_device_field_is_checked_in_a_header(path, kind):
    d = json.loads(json.dumps(DeviceProfile().to_json()))
    model.check_meta({"device": d})
    sec = d
    for key in path[:-1]:
        sec = sec[key]
    sec[path[-1]] = _wrong(kind)
    with pytest.raises(TableError, match=rf"header 'device\.{'.'.join(path)}' must be"):
        model.check_meta({"device": d})


@dataclass(frozen=True)
class Knob:
    travel_m: float = 1e-3


@dataclass(frozen=True)
class Wider(DeviceProfile):
    """A profile with fields added: a section, a string, a 3-number tuple, an optional number."""

    knob: Knob = field(default_factory=Knob)
    mode: str = "a"
    limits: tuple = (0.0, 1.0, 2.0)
    dither: float | None = None


@dataclass(frozen=True)
class Odd:
    values: list = field(default_factory=list)


def test_a_field_added_to_a_dataclass_is_in_the_schema_with_no_other_edit():
    kinds = header_kinds(Wider)
    assert kinds["knob"] == {"travel_m": "number"} and kinds["mode"] == "str"
    assert kinds["limits"] == 3 and kinds["dither"] == "number?"
    assert {k: v for k, v in kinds.items() if k in header_kinds(DeviceProfile)} == header_kinds(DeviceProfile)
    wide = Wider(knob=Knob(2e-3), limits=(1.0, 2.0, 3.0), dither=0.5)
    assert Wider.from_json(json.loads(json.dumps(wide.to_json()))) == wide     # to_json/from_json follow too

    with pytest.raises(TypeError, match="Odd.values: a table header has no form"):
        header_kinds(Odd)


def test_device_json_round_trips_every_bundled_profile():
    for name in devices.bundled_devices():
        p = devices.load_device(name)
        d = json.loads(json.dumps(p.to_json()))
        assert set(d) == {f.name for f in fields(DeviceProfile)}
        assert DeviceProfile.from_json(d) == p
        model.check_meta({"device": d})


def test_device_toml_keys_cover_every_field():
    """A field of the profile is settable from a device file: its TOML key tables name every one."""
    sections = {f.name for f in fields(DeviceProfile) if is_dataclass(devices.field_types(DeviceProfile)[f.name])}
    assert {a for a, _, _ in devices._DEVICE_KEYS.values()} == {f.name for f in fields(DeviceProfile)} - sections - {"extra"}
    assert set(devices._PAD_KEYS) == {f.name for f in fields(PadParams)}
    assert set(devices._FRICTION_KEYS) == {f.name for f in fields(FrictionParams)}
    assert {a for a, _ in devices._BURST_KEYS.values()} == {f.name for f in fields(BurstParams)}
    assert sections | {"device"} <= set(devices._SECTIONS)


def test_mapping_schema_is_the_mapping_dataclass():
    """The table side keeps the mapping's kinds (it imports no authoring module); they are MappingOptions' fields."""
    assert {**header_kinds(MappingOptions), "spec": "str"} == model.MAPPING_KINDS
    assert set(MappingOptions().to_json()) == set(model.MAPPING_KINDS)


@pytest.mark.parametrize("key", sorted(model.MAPPING_KINDS))
def test_every_mapping_field_is_checked_in_a_header(key):
    m = MappingOptions.parse("height+slope+lateral+stretch+perceptual", n_gain="2 N/mm").to_json()
    model.check_meta({"mapping": json.loads(json.dumps(m))})
    m[key] = _wrong(model.MAPPING_KINDS[key])
    with pytest.raises(TableError, match=rf"header 'mapping\.{key}' must be"):
        model.check_meta({"mapping": m})


def test_mapping_rules_beyond_the_kinds():
    with pytest.raises(TableError, match=r"'mapping\.perceptual_exponent' must be a number > 0"):
        model.check_meta({"mapping": {"perceptual_exponent": -1.0}})
    model.check_meta({"mapping": {"perceptual_exponent": None, "added_by_a_newer_writer": 1}})

