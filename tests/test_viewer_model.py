"""The preview's numpy model: built without VTK, and its forces come from the layers that own them."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from shapedisplay.render.renderer import friction_limits

ROOT = os.path.join(os.path.dirname(__file__), os.pardir)
SCENES = os.path.join(ROOT, "assets", "scenes")


def test_model_of_scene_and_table_loads_no_vtk(tmp_path):
    """The model half of the viewer runs without pyvista/VTK ever being imported."""
    code = f"""
import sys
from shapedisplay import viewer
from shapedisplay.author.scene import compile_scene
m = viewer.load_model({os.path.join(SCENES, 'phone.toml')!r})
res = compile_scene({os.path.join(SCENES, 'phone.toml')!r})
res.table.save({str(tmp_path / 't.npz')!r})
t = viewer.load_model({str(tmp_path / 't.npz')!r})
assert "breakaway_force" in m.fields and "normal_force" in t.fields
print(sorted(k for k in sys.modules if k.split('.')[0] in ('pyvista', 'vtk', 'vtkmodules')))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_friction_limits_follow_the_renderers_rule():
    """mu_s N and mu_k N at rest: N clamped at 0, times friction_scale, stored forces win, mu_k <= mu_s."""
    n = np.array([2.0, -1.0, 1.0, 4.0])
    fs = np.array([1.5, 1.0, -2.0, 1.0])
    bk, kn = friction_limits({"normal_force": n, "friction_scale": fs}, 0.5, 0.3)
    np.testing.assert_array_equal(bk, [0.5 * 1.5 * 2.0, 0.0, 0.0, 0.5 * 4.0])
    np.testing.assert_array_equal(kn, [0.3 * 1.5 * 2.0, 0.0, 0.0, 0.3 * 4.0])
    # a stored breakaway force is used as mu_s N; a kinetic force above it is limited to it
    bk, kn = friction_limits({"normal_force": n[:1], "breakaway_force": np.array([0.7]),
                              "kinetic_force": np.array([0.9])}, 0.5, 0.3)
    assert bk[0] == pytest.approx(0.7, rel=1e-15) and kn[0] == pytest.approx(0.7, rel=1e-15)
    # shape is kept, 2-D in and out
    bk, _ = friction_limits({"normal_force": np.ones((3, 4))}, 0.6, 0.4)
    assert bk.shape == (3, 4) and np.all(bk == 0.6)


def test_friction_limits_equal_what_the_renderer_plays(tmp_path):
    """A slow stroke on a table with friction_scale: the renderer's mu_s N equals the preview's at each tick."""
    from shapedisplay.table.devices import load_device
    from shapedisplay.render.cursor import CursorPath
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.table.model import FrictionTable, Grid, choose_quantization

    g = Grid(1, 50, 1e-3, 1e-3)
    x = np.arange(50) * 1e-3
    chans = {"normal_force": (1.0 + x * 40.0)[None, :], "friction_scale": (0.9 + x * 10.0)[None, :]}
    q = {k: choose_quantization(v, "float64") for k, v in chans.items()}
    table = FrictionTable.from_patches(g, [((0, 0), chans)], q, {k: 1.0 for k in chans}, {})
    dev = load_device(None)
    r = Renderer(table, dev)
    t = np.arange(200) / r.tick_rate
    cp = CursorPath(t, np.linspace(5e-3, 40e-3, t.size), np.zeros(t.size))
    res = r.render(cp)
    xm = np.concatenate([[cp.x[0]], 0.5 * (cp.x[1:] + cp.x[:-1])])
    here = {k: table.sample(k, xm, np.zeros_like(xm)) for k in chans}
    bk, _ = friction_limits(here, dev.friction.mu_s, dev.friction.mu_k)
    np.testing.assert_allclose(res.mu_s * res.normal_force, bk, rtol=1e-12)
