"""A mesh and the same analytic shape, compiled and played: the renderer hears the same events."""
from __future__ import annotations

import math

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")

from shapedisplay.author import mesh  # noqa: E402
from shapedisplay.author.compile import compile_heightfield  # noqa: E402
from shapedisplay.author.forces import MappingOptions  # noqa: E402
from shapedisplay.render import Renderer, parse_stroke  # noqa: E402
from shapedisplay.author.sources import raised_cosine_bump  # noqa: E402
from test_mesh_pipeline import bump_mesh  # noqa: E402  (the same bump mesh as the pipeline tests)

MM = 1e-3


def test_stroke_over_mesh_and_primitive_gives_the_same_events():
    A, rho, dx = 1.0, 5.0, 0.2                                       # mm
    prim = raised_cosine_bump(A * MM, rho * MM, (20 * MM, 20 * MM), dx * MM)
    lo, hi = prim.x0 / MM, prim.x0 / MM + (prim.cols - 1) * dx
    v, f, s = bump_mesh(A, rho, lo, hi, 283)
    hf = mesh.mesh_to_heightfield((v, f), resolution=dx * MM)
    tol_h = A * MM / 2 * (math.pi / (rho * MM)) ** 2 * (s * MM) ** 2   # height agreement (see pipeline test)
    ca, cb = compile_heightfield(prim), compile_heightfield(hf)
    ra, rb = Renderer(ca.table), Renderer(cb.table)
    # the same physical stroke across the bump; the mesh frame starts at its footprint corner (0.1 mm)
    a = ra.render(parse_stroke("1,10 -> 19,10 @ 20 mm/s", ra.tick_rate))
    b = rb.render(parse_stroke("0.9,9.9 -> 18.9,9.9 @ 20 mm/s", rb.tick_rate))
    q = ca.report["quantization"]["normal_force"]["max_error"] + cb.report["quantization"]["normal_force"]["max_error"]
    dN = MappingOptions().n_gain * tol_h + q
    assert np.abs(a.normal_force - b.normal_force).max() <= dN
    # stated tolerance: same number of stick-slip events, onsets within 0.1 ms (a tenth of a
    # 1 kHz tick), burst amplitudes within 0.2 % of the largest
    assert a.event_time.size == b.event_time.size > 20
    assert np.abs(a.event_time - b.event_time).max() <= 1e-4
    peak = np.abs(a.event_amplitude).max()
    assert np.abs(a.event_amplitude - b.event_amplitude).max() <= 2e-3 * peak
