"""Renderer over tables: offline vs online, channels, slope mapping, bursts, bad input."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapedisplay.devices import BurstParams, load_device
from shapedisplay.errors import InputError, ModelError, TableError
from shapedisplay.runtime.cursor import CursorPath, parse_stroke
from shapedisplay.runtime.models import simulate_pad
from shapedisplay.runtime.renderer import Renderer
from shapedisplay.table import FrictionTable, Grid, choose_quantization


def make_table(channels: dict, rows=1, cols=121, dx=0.5e-3, meta=None):
    g = Grid(rows, cols, dx, dx)
    chans = {n: np.broadcast_to(np.asarray(v, dtype=np.float64), (rows, cols)).copy() for n, v in channels.items()}
    quant = {n: choose_quantization(a, "float64") for n, a in chans.items()}
    return FrictionTable.from_dense(g, chans, quant, meta or {})


def ramp_table():
    xs = np.arange(121) * 0.5e-3
    return make_table({"normal_force": 0.5 + np.clip(100.0 * (xs - 0.02), 0.0, 2.0)})


def step_through(r, cp):
    """Play ``cp`` tick by tick through ``r.step`` from a reset; returns friction, lateral_x and audio arrays."""
    r.reset()
    F, LX, audio = [], [], []
    for x, y in zip(cp.x, cp.y):
        r.step(x, y)
        F.append(r.last["friction_force"])
        LX.append(r.last["lateral_x"])
        audio.extend(r.audio_block[:int(r.last["audio_samples"])])
    return np.array(F), np.array(LX), np.array(audio)


def quiet_device():
    d = load_device(None)
    return d.with_(burst=BurstParams(gain=0.3))


def test_constant_table_matches_pad_without_table():
    t = make_table({"normal_force": 2.0})
    r = Renderer(t, device=quiet_device(), model="exact", tick_rate=5000)
    res = r.render(parse_stroke("0,0 -> 60,0 @ 50 mm/s", 5000))
    ref = simulate_pad("exact", V=np.r_[0.0, np.full(res.t.size - 1, 0.05)], N=2.0, tick_rate=5000)
    assert np.max(np.abs(res.event_time - ref.event_time)) <= 1e-12
    assert np.allclose(res.event_amplitude, 0.3 * ref.event_amplitude)


def test_online_step_reproduces_offline_render():
    t = ramp_table()
    for model, policy in (("exact", "retrigger"), ("jump", "add"), ("karnopp", "max")):
        r = Renderer(t, device=quiet_device(), model=model, tick_rate=10_000, burst_policy=policy)
        cp = parse_stroke("0,0 <-> 60,0 @ 40 mm/s", 10_000)
        res = r.render(cp)
        F, _, audio = step_through(r, cp)
        assert np.max(np.abs(F - res.friction_force)) <= 1e-12
        assert len(audio) == res.audio.size
        assert np.max(np.abs(np.array(audio) - res.audio)) <= 1e-12
        assert r.event_count == res.event_time.size > 0
        assert r.clipped == res.clipped


def test_event_times_independent_of_tick_rate_on_a_table():
    t = make_table({"normal_force": 1.5})
    times = []
    for rate in (1000, 2000, 5000, 10_000):
        r = Renderer(t, device=quiet_device(), tick_rate=rate)
        times.append(r.render(parse_stroke("0,0 -> 40,0 @ 20mm/s", rate)).event_time)
    assert times[0].size > 50
    for et in times[1:]:
        # the cursor is at speed * t at every rate, so the events fall at the same absolute times
        assert et.size == times[0].size
        assert np.max(np.abs(et - times[0])) <= 1e-9


def test_higher_normal_force_gives_longer_stick_periods():
    t = ramp_table()
    res = Renderer(t, device=quiet_device(), tick_rate=10_000).render(parse_stroke("0,0 -> 60,0 @ 20 mm/s", 10_000))
    x_ev = np.interp(res.event_time, res.t, res.x)
    p = np.diff(res.event_time)
    low = p[x_ev[1:] < 0.018]
    high = p[x_ev[1:] > 0.042]
    assert low.size and high.size
    assert high.mean() > 3 * low.mean()
    assert np.all(np.abs(res.friction_force) <= 0.5 * res.normal_force * (1 + 1e-9) + 1e-12)


def test_slope_mapping_resists_uphill_only():
    kmu = 0.4
    t = make_table({"normal_force": 2.0, "grad_x": 0.5, "grad_y": 0.0}, rows=3,
                   meta={"mapping": {"slope_friction_gain": kmu}})
    r = Renderer(t, device=quiet_device(), tick_rate=2000)
    up = r.render(parse_stroke("0,0.5 -> 50,0.5 @ 20mm/s", 2000))
    down = r.render(parse_stroke("50,0.5 -> 0,0.5 @ 20mm/s", 2000))
    across = r.render(parse_stroke("10,0 -> 10,1 @ 1mm/s", 2000))
    mu_s = r.device.friction.mu_s
    assert np.allclose(up.mu_s[1:], mu_s + kmu * 0.5)
    assert np.allclose(down.mu_s[1:], mu_s)
    assert np.allclose(across.mu_s[1:], mu_s)
    assert np.abs(up.friction_force).max() > np.abs(down.friction_force).max()


def test_lateral_and_skin_stretch_channels():
    t = make_table({"normal_force": 1.2, "lateral_x": -0.3, "skin_stretch": 0.55e-3})
    r = Renderer(t, device=quiet_device(), model="karnopp", tick_rate=1000)
    res = r.render(parse_stroke("0,0 -> 30,0 @ 50mm/s", 1000))
    assert np.allclose(res.lateral_x, -0.3) and np.allclose(res.lateral_y, 0.0)
    mus_n = r.device.friction.mu_s * 1.2
    assert np.allclose(res.skin_stretch, 0.55e-3 * res.friction_force / mus_n)
    assert np.max(np.abs(res.skin_stretch)) <= 0.55e-3 * (1 + 1e-12)
    # the stretch climbs towards the target while stuck (the breakaway falls on the 8th tick's end) and
    # holds target * mu_k / mu_s while sliding
    assert np.max(np.abs(res.skin_stretch)) >= 0.55e-3 * (1 - 0.05 * 1e-3 * 1500.0 / mus_n) * (1 - 1e-12)
    assert np.isclose(res.skin_stretch[-1], 0.55e-3 * r.device.friction.mu_k / r.device.friction.mu_s)
    # without lateral channels the lateral outputs are zero
    res2 = Renderer(make_table({"normal_force": 1.0}), device=quiet_device()).render(
        parse_stroke("0,0 -> 10,0 @ 20mm/s", 10_000))
    assert not res2.lateral_x.any() and not res2.lateral_y.any()


def test_karnopp_restick_below_threshold_and_reversal():
    t = make_table({"normal_force": 1.0})
    dev = quiet_device().with_(extra={"karnopp": {"spring": "1.5 N/mm", "velocity_threshold": "12.5 mm/s"}})
    r = Renderer(t, device=dev, model="karnopp", tick_rate=1000)
    fast = r.render(parse_stroke("0,0 -> 20,0 @ 50mm/s", 1000))
    mus, muk = dev.friction.mu_s, dev.friction.mu_k
    assert fast.event_time.size == 1
    assert np.isclose(fast.friction_force[-1], muk * 1.0)       # sliding: mu_k N
    # breakaway after mu_s N / k_K of travel
    assert np.isclose(fast.event_time[0], mus * 1.0 / 1500.0 / 0.05, atol=1e-3)
    slow = r.render(parse_stroke("0,0 -> 5,0 @ 10mm/s", 1000))    # below v_T: stuck again after each slip
    assert slow.event_time.size > 1
    back = r.render(parse_stroke("0,0 <-> 20,0 @ 50mm/s", 1000))
    assert back.friction_force[-1] < 0 < back.friction_force[fast.t.size // 2]


def test_cursor_outside_table_holds_edge_value():
    t = ramp_table()
    r = Renderer(t, device=quiet_device(), tick_rate=1000)
    res = r.render(parse_stroke("-20,5 -> -10,5 @ 20mm/s", 1000))
    assert np.allclose(res.normal_force, 0.5)
    res = r.render(parse_stroke("70,0 -> 90,0 @ 20mm/s", 1000))
    assert np.allclose(res.normal_force, 2.5)


def test_cursor_teleport_many_cells_per_tick():
    t = ramp_table()
    r = Renderer(t, device=quiet_device(), tick_rate=100)
    cp = CursorPath(np.arange(6) / 100, np.array([0, 0.06, 0.0, 0.06, 0.03, 0.0]), np.zeros(6), 100.0, "jumps")
    for model in ("exact", "jump", "karnopp"):
        res = Renderer(t, device=quiet_device(), model=model, tick_rate=100).render(cp)
        assert np.all(np.isfinite(res.friction_force)) and np.all(np.isfinite(res.audio))
        assert np.all(np.abs(res.friction_force) <= 0.5 * res.normal_force * (1 + 1e-9) + 1e-12)


def test_euler_renderer_reports_divergence():
    t = make_table({"normal_force": 2.0})
    r = Renderer(t, device=quiet_device(), model="euler", tick_rate=1000)
    with pytest.raises(ModelError, match="diverged"):
        r.render(parse_stroke("0,0 -> 60,0 @ 50mm/s", 1000))
    r.reset()
    with pytest.raises(ModelError, match="diverged"):
        for i in range(1000):
            r.step(i * 5e-5, 0.0)


def test_max_stick_period_forces_bursts():
    t = make_table({"normal_force": 8.0})
    stroke = parse_stroke("0,0 -> 20,0 @ 5mm/s", 2000)
    free = Renderer(t, device=quiet_device(), tick_rate=2000).render(stroke)
    capped = Renderer(t, device=quiet_device(), tick_rate=2000, max_stick_period=0.05).render(stroke)
    assert capped.event_time.size > free.event_time.size
    stick_runs = np.diff(capped.event_time)
    assert np.all(stick_runs <= 0.05 + 1e-3)


def test_missing_channel_and_bad_options():
    t = make_table({"friction_scale": 1.0})
    with pytest.raises(TableError, match="normal_force"):
        Renderer(t)
    t = make_table({"normal_force": 1.0})
    with pytest.raises(InputError, match="tick_rate"):
        Renderer(t, tick_rate=50)
    with pytest.raises(InputError, match="tick_rate"):
        Renderer(t, tick_rate=250_000)
    with pytest.raises(InputError, match="burst policy"):
        Renderer(t, burst_policy="loudest")
    with pytest.raises(InputError, match="model"):
        Renderer(t, model="verlet")
    t = make_table({"normal_force": 1.0}, meta={"mapping": {"slope_friction_gain": 0.3}})
    with pytest.raises(TableError, match="grad_x"):
        Renderer(t)


@settings(max_examples=15, deadline=None)
@given(xs=st.lists(st.floats(-0.02, 0.08), min_size=3, max_size=40),
       model=st.sampled_from(["exact", "jump", "karnopp"]))
def test_random_cursor_paths_give_finite_bounded_output(xs, model):
    t = ramp_table()
    n = len(xs)
    cp = CursorPath(np.arange(n) / 1000.0, np.array(xs), np.zeros(n), 1000.0, "random")
    res = Renderer(t, device=quiet_device(), model=model, tick_rate=1000).render(cp)
    for a in (res.friction_force, res.audio, res.skin_stretch, res.event_amplitude):
        assert np.all(np.isfinite(a))
    assert np.all(np.abs(res.friction_force) <= 0.5 * res.normal_force * (1 + 1e-9) + 1e-12)
    assert np.abs(res.audio).max(initial=0) <= 1.0


def test_breakaway_and_kinetic_force_channels_replace_mu():
    t = make_table({"normal_force": 2.0, "breakaway_force": 1.4, "kinetic_force": 0.9})
    r = Renderer(t, device=quiet_device(), tick_rate=2000)
    res = r.render(parse_stroke("0,0 -> 40,0 @ 20mm/s", 2000))
    assert np.allclose(res.mu_s, 0.7)
    assert 1.38 < np.abs(res.friction_force).max() <= 1.4 * (1 + 1e-9)
    # breakaway amplitude B (mu_s N - c V)
    assert np.allclose(res.event_amplitude, 0.3 * (1.4 - r.device.pad.damping * 0.02))


def test_friction_scale_and_burst_gain_channels():
    t = make_table({"normal_force": 2.0, "friction_scale": 0.5, "burst_gain": 2.0})
    r = Renderer(t, device=quiet_device(), tick_rate=2000)
    res = r.render(parse_stroke("0,0 -> 40,0 @ 20mm/s", 2000))
    mus = 0.5 * r.device.friction.mu_s
    assert np.allclose(res.mu_s, mus)
    assert np.allclose(res.event_amplitude, 0.3 * 2.0 * (mus * 2.0 - r.device.pad.damping * 0.02))


def test_step_allocates_nothing_per_tick():
    import tracemalloc
    t = ramp_table()
    r = Renderer(t, device=quiet_device(), model="exact", tick_rate=10_000)
    xs = parse_stroke("0,0 <-> 60,0 @ 40 mm/s", 10_000).x.tolist()
    r.reset()
    step = r.step
    for i in range(200):
        step(xs[i], 0.0)
    tracemalloc.start()
    try:
        base, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        for i in range(200, 20_000):
            step(xs[i], 0.0)
        cur, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert r.event_count > 10
    assert cur - base <= 256 and peak - base < 2048   # bytes, over 19800 ticks


@settings(max_examples=10, deadline=None)
@given(pts=st.lists(st.tuples(st.floats(-0.01, 0.07), st.floats(-0.001, 0.005)), min_size=3, max_size=30),
       model=st.sampled_from(["exact", "jump", "karnopp"]), policy=st.sampled_from(["retrigger", "add", "max"]))
def test_online_equals_offline_on_random_2d_paths(pts, model, policy):
    kmu = 0.3
    xs = np.arange(121) * 0.5e-3
    N = 0.5 + np.clip(100.0 * (xs - 0.02), 0.0, 2.0)
    t = make_table({"normal_force": N, "grad_x": np.gradient(N), "grad_y": 0.1, "lateral_x": 0.2 * N},
                   rows=11, meta={"mapping": {"slope_friction_gain": kmu}})
    n = len(pts)
    cp = CursorPath(np.arange(n) / 2000.0, np.array([p[0] for p in pts]), np.array([p[1] for p in pts]),
                    2000.0, "random")
    r = Renderer(t, device=quiet_device(), model=model, tick_rate=2000, burst_policy=policy)
    res = r.render(cp)
    F, LX, _ = step_through(r, cp)
    assert np.allclose(F, res.friction_force, rtol=1e-9, atol=1e-12)
    assert np.allclose(LX, res.lateral_x, rtol=1e-9, atol=1e-12)
    assert r.event_count == res.event_time.size


def test_online_step_allocates_nothing_per_tick_in_compiled_code():
    """numba's own allocator: a compiled host loop over online_step allocates the same for 100 or 3000 ticks."""
    from numba import njit
    from numba.core.runtime import rtsys

    from shapedisplay.runtime.renderer import online_step

    @njit
    def host_loop(rec, blocks, data, bg, ev, audio, xs, i0, i1):
        acc = 0.0
        for i in range(i0, i1):
            acc += online_step(rec, blocks, data, bg, ev, audio, xs[i], 0.0)
        return acc

    r = Renderer(ramp_table(), device=quiet_device(), model="exact", tick_rate=10_000)
    from numba.core.runtime import _nrt_python      # counts of numba's allocator (NUMBA_NRT_STATS at run time)
    _nrt_python.memsys_enable_stats()
    xs = parse_stroke("0,0 <-> 60,0 @ 40 mm/s", 10_000).x
    args = (r.online_state, r._blocks, r._data, r._bg, r._ev, r._audio, xs)
    r.reset()
    host_loop(*args, 0, 10)                        # compile
    used = []
    for i0, i1 in ((10, 110), (110, 3110)):
        a = rtsys.get_allocation_stats().alloc
        host_loop(*args, i0, i1)
        used.append(rtsys.get_allocation_stats().alloc - a)
    assert r.event_count > 10
    assert used[0] == used[1] <= 8                 # the loop's array arguments, nothing per tick


@pytest.mark.parametrize("model", ["stribeck", "tanh", "rk4"])
def test_online_step_equals_offline_for_the_other_models(model):
    t = ramp_table()
    rate = 100_000 if model == "rk4" else 10_000            # rk4 is stable on the Konyo pad above ~45 kHz
    r = Renderer(t, device=quiet_device(), model=model, tick_rate=rate)
    cp = parse_stroke("0,0 -> 60,0 @ 200 mm/s", rate)
    res = r.render(cp)
    F, _, _ = step_through(r, cp)
    assert np.max(np.abs(F - res.friction_force)) <= 1e-12
    assert r.event_count == res.event_time.size > (0 if model == "stribeck" else 10)


def test_renderer_source_names_the_kernels_it_compiles_in():
    """online_step is cached by numba keyed on renderer.py alone; renderer.py must change with its kernels.

    Every module whose cached kernels call into other files carries the sha256 of those files
    (written by `make generate`); pads.py reaches online_step through dispatch.py, dispatch.py views
    float64 arguments as the layouts of layouts.py, and its tick loops take arrays through borrow.py.
    """
    import hashlib
    import importlib
    from pathlib import Path

    from shapedisplay.runtime import codegen, renderer
    here = Path(renderer.__file__).parent
    assert set(codegen.KERNEL_DEPENDENCIES["renderer.py"]) >= {"dispatch.py", "lookup.py", "bursts.py"}
    assert codegen.KERNEL_DEPENDENCIES["dispatch.py"] == ("pads.py", "layouts.py", "borrow.py")
    for name, deps in codegen.KERNEL_DEPENDENCIES.items():
        mod = importlib.import_module(f"shapedisplay.runtime.{name[:-3]}")
        blob = b"".join((here / n).read_bytes() for n in deps)
        assert mod.KERNEL_SOURCES_SHA256 == hashlib.sha256(blob).hexdigest(), (
            f"{', '.join(deps)} changed: run `make generate` so that numba recompiles the cached kernels of {name}")

_ALL_SLOTS = ("normal_force", "grad_x", "grad_y", "lateral_x", "lateral_y", "skin_stretch", "burst_gain")


@pytest.mark.parametrize("model, names, rows, kmu", [
    ("jump", ("normal_force", "lateral_x", "burst_gain"), -1, 0.0), ("jump", ("normal_force", "lateral_y"), -12, 0.0),
    ("exact", _ALL_SLOTS, 12, 0.3), ("jump", _ALL_SLOTS, 12, 0.3), ("karnopp", _ALL_SLOTS, 12, 0.3),
    ("jump", ("normal_force", "friction_scale", "kinetic_force"), 12, 0.0),
    ("jump", _ALL_SLOTS, 12, 0.0), ("exact", ("normal_force", "lateral_y", "burst_gain"), 12, 0.0),
    ("jump", ("normal_force", "lateral_x", "skin_stretch"), 1, 0.0), ("jump", ("lateral_x",), 1, 0.0),
    ("jump", ("normal_force", "grad_x"), 1, 0.3), ("jump", ("normal_force", "grad_x"), 1, 0.0),
    ("jump", ("normal_force",), -1, 0.0), ("jump", ("lateral_y",), -1, 0.0), ("jump", ("burst_gain", "grad_x"), -1, 0.0),
    ("jump", ("skin_stretch", "grad_y"), -1, 0.0)])
def test_fused_lookup_equals_table_sample_and_prepare_inputs_bit_for_bit(model, names, rows, kmu):
    """The offline render's lookup gives the inputs of FrictionTable.sample + prepare_inputs exactly, on sparse
    blocks with a background, cursor outside too: in one pass (tables whose friction coefficients vary: slope
    term, friction_scale, kinetic_force) and in passes over whole rows (every other table, 2-D and one-row,
    normal_force missing, negative N and gain clamped; ``rows < 0``: a dense table of ``-rows`` rows, one block;
    a dense one-row table with one channel for the per-tick rows takes a loop of its own)."""
    from shapedisplay.runtime.layouts import NSLOT, SLOTS
    from shapedisplay.runtime.renderer import INPUT_ROWS, prepare_inputs
    rng = np.random.default_rng(7)
    cols = 20
    if rows < 0:
        rows = -rows
        dense = {n: rng.uniform(-0.3, 2.0, (rows, cols)) for n in names}
        t = FrictionTable.from_dense(Grid(rows, cols, 1e-3, 1e-3, 0.5e-3, 0.2e-3), dense,
                                     {n: choose_quantization(v, "uint16") for n, v in dense.items()},
                                     {"mapping": {"slope_friction_gain": kmu, "n_base": 1.5}})
        assert len(t.blocks) == 1
    else:
        patch = {n: rng.uniform(-0.3, 2.0, (min(5, rows), 7)) for n in names}
        quant = {n: choose_quantization(v, "uint16") for n, v in patch.items()}
        t = FrictionTable.from_patches(Grid(rows, cols, 1e-3, 1e-3, 0.5e-3, 0.2e-3),
                                       [((0 if rows == 1 else 1, 2), patch), ((0 if rows == 1 else 6, 11), patch)],
                                       quant, {n: 0.4 for n in names},
                                       {"mapping": {"slope_friction_gain": kmu, "n_base": 1.5}})
        assert len(t.blocks) == 2
    n = 2500
    r = Renderer(t, device=quiet_device(), model=model, tick_rate=10_000)
    # a random path, and one along x (one y for every tick, which takes a path of its own) that stops and turns
    along = np.cumsum(rng.choice([-2e-5, 0.0, 3e-5], n))
    for cp in (CursorPath(np.arange(n) / 10_000.0, rng.uniform(-0.005, 0.03, n), rng.uniform(-0.005, 0.02, n),
                          10_000.0, "random"),
               CursorPath(np.arange(n) / 10_000.0, 0.01 + along, np.full(n, 0.0041), 10_000.0, "along x"),
               CursorPath(np.arange(n) / 10_000.0, along * 1e-152, np.full(n, 0.0041), 10_000.0, "slow along x"),
               # along x through signed zeros: -0 - +0 = -0 gives vx = -0, and V must still be +0
               CursorPath(np.arange(n) / 10_000.0, rng.choice([0.0, -0.0, 0.0, -0.0, 2e-6, -3e-6], n),
                          np.full(n, -0.0), 10_000.0, "zeros")):
        got = dict(zip(INPUT_ROWS, r._inputs(cp)))
        xm, ym = cp.x.copy(), cp.y.copy()
        xm[1:] = 0.5 * (cp.x[1:] + cp.x[:-1])
        ym[1:] = 0.5 * (cp.y[1:] + cp.y[:-1])
        vals = np.zeros((NSLOT, n))
        for i, name in enumerate(SLOTS):
            if name in t.channels:
                vals[i] = t.sample(name, xm, ym)
        arrs = np.empty((7, n))
        prepare_inputs(cp.t, cp.x, cp.y, vals, r._config, r._slot_channel, *arrs)
        for name, want in zip(("V", "vx", "vy", "normal_force", "mu_s", "mu_k", "gain"), arrs):
            assert got[name].tobytes() == want.tobytes(), name
        for name, slot in (("lateral_x", "lateral_x"), ("lateral_y", "lateral_y"), ("skin_target", "skin_stretch")):
            assert got[name].tobytes() == vals[SLOTS.index(slot)].tobytes(), name
        res = r.render(cp)
        assert res.lateral_x.tobytes() == got["lateral_x"].tobytes()
        assert res.event_time.size > 0 or cp.source in ("slow along x", "zeros")
        if cp.source == "zeros":
            assert (np.signbit(got["vx"]) & (got["vx"] == 0)).any() and not np.signbit(got["V"][got["V"] == 0]).any()
        assert "along x" not in cp.source or ((got["V"] < 0).any() and (got["V"] == 0).any() and (got["V"] > 0).any())


@settings(max_examples=300, deadline=None)
@given(m=st.floats(1.0, 2.0, exclude_max=True), e=st.integers(-500, 499), sign=st.sampled_from([-1.0, 1.0]))
def test_square_root_of_a_square_is_the_magnitude(m, e, sign):
    """What the lookup of a path along x relies on (speed |vx| for sqrt(vx vx), where vx vx is a normal number):
    in binary floating point the rounded square root of the rounded square is the magnitude."""
    x = sign * math.ldexp(m, e)
    assert math.sqrt(x * x) == abs(x)
    assert np.sqrt(np.array([x]) * x)[0] == abs(x)


@pytest.mark.parametrize("target", [0.0, -0.0, 2.5e-4, -1e-3])
def test_skin_stretch_of_one_target_equals_the_row_form(target):
    """skin_stretch_uniform (one target on every tick; no division for a zero one) gives skin_stretch_of's values
    bit for bit: signed zeros from a zero target, NaN and infinite forces, limits of zero, negative and NaN."""
    from shapedisplay.runtime.renderer import skin_stretch_of, skin_stretch_uniform
    rng = np.random.default_rng(3)
    n = 4000
    f = rng.normal(0.0, 1.0, n)
    f[:6] = [0.0, -0.0, np.nan, np.inf, -np.inf, 1e-320]
    mus = rng.uniform(-0.2, 1.0, n)
    N = rng.uniform(0.0, 2.0, n)
    N[6:9] = [0.0, np.nan, np.inf]
    want, got = np.empty(n), np.empty(n)
    skin_stretch_of(np.full(n, target), f, mus, N, want)
    skin_stretch_uniform(target, f, mus, N, got)
    assert got.tobytes() == want.tobytes()


def _render_with_run_kernel(r, cp):
    """What Renderer.render computes, with the model run by run_kernel (all six per-tick rows) instead of the
    render's own tick loop: the reference it must equal bit for bit."""
    from shapedisplay.runtime.bursts import render_bursts
    from shapedisplay.runtime.models import run_kernel
    from shapedisplay.runtime.renderer import skin_stretch_of
    V, vx, vy, N, mus, muk, gain, lx, ly, target = r._inputs(cp)
    S, f, st, *_, et, ea = run_kernel(r.model, cp.t, V, N, mus, muk, gain)
    ss = np.empty_like(f)
    skin_stretch_of(target, f, mus, N, ss)
    b = r.device.burst
    audio, clipped = render_bursts(et, ea, cp.t[0], cp.duration, r.audio_rate, b.carrier_hz, b.rise_s, b.decay_s,
                                   r.burst_policy)
    return dict(t=cp.t, x=cp.x, y=cp.y, vx=vx, vy=vy, normal_force=N, friction_force=f, state=st.astype(np.int8),
                lateral_x=lx, lateral_y=ly, skin_stretch=ss, event_time=et, event_amplitude=ea, audio=audio,
                clipped=clipped, mu_s=mus)


@pytest.mark.parametrize("model, names, rows, kmu, policy, gain", [
    ("jump", ("normal_force",), -1, 0.0, "retrigger", 0.3), ("exact", ("normal_force", "lateral_x"), -1, 0.0, "add", 0.3),
    ("jump", ("normal_force", "lateral_y", "skin_stretch"), -12, 0.0, "max", 3.0),
    ("exact", ("normal_force", "friction_scale", "grad_x", "grad_y"), 12, 0.3, "retrigger", 3.0),
    ("karnopp", ("normal_force", "burst_gain"), 12, 0.0, "add", 0.3),
    ("stribeck", ("normal_force", "kinetic_force"), 1, 0.0, "retrigger", 0.3),
    ("tanh", ("normal_force", "breakaway_force"), 12, 0.0, "max", 0.3),
    ("karnopp", ("normal_force",), 1, 0.0, "max", 0.3), ("jump", ("lateral_x",), 1, 0.0, "retrigger", 0.3),
    ("jump", ("normal_force", "grad_x"), 1, 0.3, "add", 3.0)])
def test_render_tick_loop_equals_run_kernel_bit_for_bit(model, names, rows, kmu, policy, gain):
    """render() runs the model through dispatch.render_ticks (friction and phase stored, nothing else): every
    output equals the render built on run_kernel bit for bit, on dense and sparse, one-row and 2-D tables (every
    lookup path), five models, three burst policies, clipping on and off, a random walk with reversals, a stroke
    and a path that barely moves."""
    rng = np.random.default_rng(11)
    cols = 40
    meta = {"mapping": {"slope_friction_gain": kmu, "n_base": 1.5}}
    if rows < 0:
        rows = -rows
        dense = {n: rng.uniform(-0.3, 2.0, (rows, cols)) for n in names}
        t = FrictionTable.from_dense(Grid(rows, cols, 1e-3, 1e-3, 0.5e-3, 0.2e-3), dense,
                                     {n: choose_quantization(v, "uint16") for n, v in dense.items()}, meta)
    else:
        patch = {n: rng.uniform(0.2, 2.0, (min(5, rows), 9)) for n in names}
        quant = {n: choose_quantization(v, "uint16") for n, v in patch.items()}
        t = FrictionTable.from_patches(Grid(rows, cols, 1e-3, 1e-3, 0.5e-3, 0.2e-3),
                                       [((0 if rows == 1 else 1, 2), patch), ((0 if rows == 1 else 6, 21), patch)],
                                       quant, {n: 0.4 for n in names}, meta)
    dev = load_device(None).with_(burst=BurstParams(gain=gain))
    n = 3001
    walk = CursorPath(np.arange(n) / 10_000.0, 0.01 + np.cumsum(rng.normal(0, 2e-5, n)),
                      0.004 + np.cumsum(rng.normal(0, 1e-5, n)), 10_000.0, "walk")
    r = Renderer(t, device=dev, model=model, tick_rate=10_000, burst_policy=policy)
    clipped = 0
    for cp in (walk, parse_stroke("2,1 <-> 30,3 @ 60 mm/s", 10_000), parse_stroke("5,1 -> 5.0001,1 @ 1 mm/s", 10_000)):
        got = r.render(cp)
        want = _render_with_run_kernel(r, cp)
        for name, w in want.items():
            g = getattr(got, name)
            if name == "clipped":
                assert g == w
            else:
                assert g.dtype == w.dtype and g.shape == w.shape and g.tobytes() == w.tobytes(), name
        clipped += got.clipped
    assert (clipped > 0) == (gain > 1.0)


@pytest.mark.parametrize("model", ["exact", "jump", "karnopp", "stribeck", "euler", "rk4", "tanh"])
def test_render_ticks_equals_run_ticks_state_events_and_rows(model):
    """dispatch.render_ticks against dispatch.run_ticks on the same inputs (stick, slip, reversals; 20 kHz so the
    explicit baselines stay stable): the same friction rows, the phase as astype(int8), the same events and the
    same final state field by field, the work terms of a last tick taken on the stuck fast path included, and of
    one ending in a slip (the only tick whose work terms the exact model's render form computes); and the
    same again with mu_s, mu_k (and a constant gain) given as one-element rows, one value for every tick."""
    from shapedisplay.runtime.dispatch import render_ticks, run_ticks
    from shapedisplay.runtime.models import get_model
    dev = load_device(None)
    m = get_model(model, dev)
    rng = np.random.default_rng(3)
    # a path whose last tick ends in a slip: a steady stroke cut after its last slipping tick
    steady = np.full(1500, 0.05)
    _, rows0, _ = _run_ticks_reference(m, m.new_state(), np.arange(1500) / 20_000.0, steady, np.full(1500, 1.5),
                                       np.full(1500, dev.friction.mu_s), np.full(1500, dev.friction.mu_k),
                                       np.ones(1500))
    last_slip = int(np.flatnonzero(rows0[1])[-1]) + 1 if rows0[1].any() else 1500
    for n, V, N in ((4000, 0.04 * np.sin(np.arange(4000) / 300.0), None), (2000, np.full(2000, 1e-4), None),
                    (3, np.array([0.0, 0.01, 0.02]), None), (last_slip, steady[:last_slip], np.full(last_slip, 1.5))):
        t = np.arange(n) / 20_000.0
        N = 1.0 + 0.5 * rng.random(n) if N is None else N
        mus = np.full(n, dev.friction.mu_s)
        muk = np.full(n, dev.friction.mu_k)
        for gain in (np.ones(n), 0.5 + rng.random(n)):
            S1 = m.new_state()
            rows = np.empty((6, n))
            ev1 = np.zeros((2, n))
            n1 = run_ticks(m.model_id, S1, m.param_block, t, V, N, mus, muk, gain, *rows, ev1[0], ev1[1])
            one = (gain[:1] if (gain == 1.0).all() else gain)
            for args in ((mus, muk, gain), (mus[:1], muk[:1], one)):
                S2 = m.new_state()
                ev2 = np.zeros((2, n))
                f = np.empty(n)
                ph = np.empty(n, np.int8)
                n2 = render_ticks(m.model_id, S2, m.param_block, t, V, N, *args, f, ph, ev2[0], ev2[1])
                assert n1 == n2 and ev1.tobytes() == ev2.tobytes()
                assert f.tobytes() == rows[0].tobytes() and ph.tobytes() == rows[1].astype(np.int8).tobytes()
                assert S1.tobytes() == S2.tobytes(), [(k, S1[k], S2[k]) for k in S1.dtype.names if S1[k] != S2[k]]
            if model == "exact" and n == last_slip:
                assert rows[1][-1] == 1.0 and rows[5][-1] > 0.0      # ended in a slip, damper work computed


def _run_ticks_reference(m, init, t, V, N, mus, muk, gain):
    """dispatch.run_ticks from a copy of ``init`` with room for every event: (state, rows, events)."""
    from shapedisplay.runtime.dispatch import run_ticks
    n = t.size
    S = init.copy()
    rows = np.empty((6, n))
    ev = np.zeros((2, 64 * n + 64))
    n_ev = run_ticks(m.model_id, S, m.param_block, t, V, N, mus, muk, gain, *rows, ev[0], ev[1])
    assert n_ev <= ev.shape[1]
    return S, rows, ev[:, :n_ev]


def _assert_run_kernel_equals(m, init, args):
    """run_kernel (default block, and a caller's ``out``) gives run_ticks' rows, events and state bit for bit."""
    from shapedisplay.runtime.models import run_kernel
    S, rows, ev = _run_ticks_reference(m, init, *args)
    before = init.tobytes()
    for out in (None, np.empty((6, args[0].size))):
        got = run_kernel(m, *args, state=init[0], out=out)
        assert init.tobytes() == before
        assert got[0].tobytes() == S[0].tobytes(), [(k, got[0][k], S[0][k]) for k in S.dtype.names]
        assert all(a.shape == b.shape and a.tobytes() == b.tobytes() for a, b in zip(got[1:7], rows))
        assert got[7].tobytes() == ev[0].tobytes() and got[8].tobytes() == ev[1].tobytes()
        assert out is None or np.shares_memory(got[1], out)
    return ev.shape[1]


@pytest.mark.parametrize("model", ["exact", "jump", "karnopp", "stribeck", "euler", "rk4", "tanh"])
def test_run_block_equals_run_ticks_and_grows_its_event_buffer(model):
    """dispatch.run_block (the one call run_kernel makes: rows, events and final state written into one
    block) and dispatch.run_block_grow (the paths that block cannot hold) against dispatch.run_ticks on the
    same inputs: the same rows, events and final state bit for bit, from a fresh state and from a state
    reached mid-run; run_block_grow started with an event buffer of one slot grows it, runs again from the
    initial state and gives the same answer; the initial state is left as it was. run_kernel returns exactly
    these arrays, also on the paths run_block does not take: fewer ticks than the state has words, more
    events than ticks, a caller's output block."""
    from shapedisplay.runtime.dispatch import STATE_WORDS, run_block, run_block_grow, run_ticks
    from shapedisplay.runtime.layouts import PAD_STATE
    from shapedisplay.runtime.models import get_model
    dev = load_device(None)
    m = get_model(model, dev)
    n = 4000
    t = np.arange(n) / 20_000.0
    V = 0.04 * np.sin(np.arange(n) / 300.0)
    N = 1.0 + 0.5 * np.random.default_rng(5).random(n)
    mus, muk, gain = np.full(n, dev.friction.mu_s), np.full(n, dev.friction.mu_k), np.ones(n)
    half = n // 2
    S_mid = m.new_state()
    run_ticks(m.model_id, S_mid, m.param_block, t[:half], V[:half], N[:half], mus[:half], muk[:half],
              gain[:half], *np.empty((6, half)), *np.empty((2, n)))
    prm = m.param_block.view(np.float64)
    for init in (m.new_state(), S_mid):      # (euler has diverged by mid-run: no events after it)
        before = init.tobytes()
        S1, rows, ev = _run_ticks_reference(m, init, t, V, N, mus, muk, gain)
        n1 = ev.shape[1]
        assert n1 > 1 or init is S_mid          # more events than the first buffer of one slot holds
        block = np.full((9, n), np.nan)
        n_ev, truncated = run_block(m.model_id, init.view(np.float64), prm, t, V, N, mus, muk, gain, block)
        assert init.tobytes() == before
        assert n_ev == n1 and truncated == S1[0]["truncated"] == 0
        assert block[:6].tobytes() == rows.tobytes() and block[6:8, :n1].tobytes() == ev.tobytes()
        assert block[8, :STATE_WORDS].view(PAD_STATE).tobytes() == S1.tobytes()
        for cap in (1, n1, n + 1024):
            block = np.empty((6, n))
            S2, ev2, truncated = run_block_grow(m.model_id, init.view(np.float64), prm, t, V, N, mus, muk, gain,
                                                block, cap)
            assert init.tobytes() == before
            assert S2.tobytes() == S1.tobytes() and truncated == S1[0]["truncated"] == 0
            assert ev2.shape == (2, n1) and ev2.tobytes() == ev.tobytes()
            assert block.tobytes() == rows.tobytes()
        _assert_run_kernel_equals(m, init, (t, V, N, mus, muk, gain))
        short = STATE_WORDS - 1
        _assert_run_kernel_equals(m, init, (t[:short], V[:short], N[:short], mus[:short], muk[:short], gain[:short]))
    # a slow tick rate and a light touch: many slips per tick, more events than ticks (exact, jump)
    n = 40
    t = np.arange(n) / 100.0
    many = _assert_run_kernel_equals(m, m.new_state(), (t, np.full(n, 0.05), np.full(n, 0.02), mus[:n], muk[:n],
                                                        gain[:n]))
    assert many > n or model not in ("exact", "jump")


def test_render_returns_the_paths_own_rows_as_read_only_views():
    """t, x, y of a render are the cursor path's rows (not copies), read-only: of the path itself on the tick grid,
    of the resampled path otherwise, and float64 rows of the same values for a path that held another type."""
    on_grid = parse_stroke("0,0.5 <-> 40,0.5 @ 30 mm/s", 10_000)
    n = 500
    raw = CursorPath(np.arange(n) / 7_000.0, np.linspace(0.0, 0.02, n), np.linspace(0.01, 0.0, n), None, "raw")
    f32 = CursorPath(np.arange(n, dtype=np.float32) / np.float32(10_000), np.linspace(0, 0.02, n, dtype=np.float32),
                     np.zeros(n, np.float32), 10_000.0, "float32")
    for model in ("exact", "jump"):
        r = Renderer(ramp_table(), device=quiet_device(), model=model, tick_rate=10_000)
        res = r.render(on_grid)
        for name in ("t", "x", "y"):
            got, src = getattr(res, name), getattr(on_grid, name)
            assert np.shares_memory(got, src) and not got.flags.writeable and got.tobytes() == src.tobytes(), name
        res = r.render(raw)
        grid = raw.resample(10_000)
        for name in ("t", "x", "y"):
            got = getattr(res, name)
            assert not got.flags.writeable and got.tobytes() == getattr(grid, name).tobytes(), name
            assert not np.shares_memory(got, getattr(raw, name)), name
        res = r.render(f32)
        for name in ("t", "x", "y"):
            got = getattr(res, name)
            assert got.dtype == np.float64 and not got.flags.writeable, name
            assert got.tobytes() == getattr(f32, name).astype(np.float64).tobytes(), name


def test_rows_of_one_value_are_read_only_views_with_the_values_of_every_row():
    """The render returns a row that holds one value on every tick (mu_s of a table whose friction does not vary,
    the lateral rows of a table without them, vy on a path along x) as a read-only view of that value, with
    the bytes of the row written out (Renderer._inputs with every row); the other rows, and every row of a
    table whose friction varies, are written out. The model gets V, which on a path along x without a -0 in vx is
    vx itself (not written out)."""
    from shapedisplay.runtime.renderer import INPUT_ROWS, lookup_inputs
    along = parse_stroke("0,0.5 <-> 40,0.5 @ 30 mm/s", 10_000)
    diag = parse_stroke("0,0 -> 40,1 @ 30 mm/s", 10_000)
    xs = np.arange(121) * 0.5e-3
    plain = ramp_table()
    lateral = make_table({"normal_force": 0.5 + np.clip(100.0 * (xs - 0.02), 0.0, 2.0), "lateral_x": 0.1 * xs})
    varying = make_table({"normal_force": 1.0 + 0.0 * xs, "friction_scale": 1.0 + 5.0 * xs})
    # along x through signed zeros: vx is -0 on some ticks, where V must be +0 (V is not vx there)
    n = 3000
    zeros = CursorPath(np.arange(n) / 10_000.0, np.random.default_rng(5).choice([0.0, -0.0, 2e-6, -3e-6], n),
                       np.full(n, -0.0), 10_000.0, "zeros")
    for table, cp, views in ((plain, along, {"vy", "mu_s", "lateral_x", "lateral_y"}),
                             (plain, zeros, {"vy", "mu_s", "lateral_x", "lateral_y"}),
                             (plain, diag, {"mu_s", "lateral_x", "lateral_y"}),
                             (lateral, along, {"vy", "mu_s", "lateral_y"}), (varying, along, set())):
        for model in ("exact", "jump"):
            r = Renderer(table, device=quiet_device(), model=model, tick_rate=10_000)
            res = r.render(cp)
            want = dict(zip(INPUT_ROWS, r._inputs(cp)))
            for name in ("vx", "vy", "normal_force", "mu_s", "lateral_x", "lateral_y"):
                got = getattr(res, name)
                assert got.shape == cp.t.shape and got.tobytes() == want[name].tobytes(), name
                assert (got.strides == (0,) and not got.flags.writeable) == (name in views), name
            # the V the render hands the model: vx itself where the lookup says so (bit 0), else its own row
            k, n = len(INPUT_ROWS), cp.t.size
            block = np.full((k + 6, n), np.nan)
            ones = lookup_inputs(cp.t, cp.x, cp.y, r._blocks, r._data, r._bg, r._grid, r._config, r._slot_channel,
                                 block[:k], block[k + 2:].view(np.int64), False)
            assert bool(ones & 1) == (cp is along and table is not varying)
            assert (block[1] if ones & 1 else block[0]).tobytes() == want["V"].tobytes()
            # the other outputs as the rows written out give them (the model and skin stretch read the one value)
            ref = Renderer(table, device=quiet_device(), model=model, tick_rate=10_000)
            t, V, N, mus, muk, gain = ref.model_inputs(cp)
            from shapedisplay.runtime.models import run_kernel
            _, f, *_ = run_kernel(ref.model, t, V, N, mus, muk, gain)
            assert res.friction_force.tobytes() == f.tobytes()
