"""Renderer over tables: offline vs online, the lookup, channels, slope mapping, bursts, event ring, bad input."""
from __future__ import annotations


import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from shapedisplay.table.devices import BurstParams, load_device
from shapedisplay.errors import InputError, ModelError, TableError
from shapedisplay.render.cursor import CursorPath, parse_stroke
from shapedisplay.render.models import simulate_pad
from shapedisplay.render.renderer import Renderer
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization


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


@pytest.mark.parametrize("model, policy", [("exact", "retrigger"), ("jump", "add"), ("karnopp", "max"),
                                           ("stribeck", "retrigger")])
def test_online_step_reproduces_offline_render(model, policy):
    """A path rendered offline (one call) is the same path stepped tick by tick: every output, every audio
    sample and every count, on a 2-D table with slope friction and a lateral channel, a stroke with reversals."""
    kmu = 0.3
    xs = np.arange(121) * 0.5e-3
    N = 0.5 + np.clip(100.0 * (xs - 0.02), 0.0, 2.0)
    t = make_table({"normal_force": N, "grad_x": np.gradient(N), "grad_y": 0.1, "lateral_x": 0.2 * N},
                   rows=11, meta={"mapping": {"slope_friction_gain": kmu}})
    r = Renderer(t, device=quiet_device(), model=model, tick_rate=10_000, burst_policy=policy)
    cp = parse_stroke("0,0 <-> 60,4 @ 40 mm/s", 10_000)
    res = r.render(cp)
    r.reset()
    rows, audio = [], []
    for x, y in zip(cp.x, cp.y):
        r.step(x, y)
        rows.append(r.last.copy())
        audio.append(r.audio_block[:r.audio_samples].copy())
    rows = np.array(rows)
    for name in ("friction_force", "normal_force", "lateral_x", "skin_stretch", "mu_s", "vx", "vy"):
        assert rows[name].tobytes() == getattr(res, name).tobytes(), name
    assert np.array_equal(rows["state"].astype(np.int8), res.state)
    assert np.concatenate(audio).tobytes() == res.audio.tobytes()
    assert r.event_count == res.event_time.size > 0
    assert r.clipped == res.clipped and r.events_dropped == res.events_dropped == 0


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


def bilinear(table, name, x, y):
    """Bilinear interpolation of a channel of ``table`` at (x, y) (m), the edge held outside: numpy, from the
    dense samples, sample (r, c) at (x0 + c dx, y0 + r dy)."""
    g, a = table.grid, table.dense(name)
    fc = np.clip((np.asarray(x) - g.x0) / g.dx, 0.0, g.cols - 1)
    fr = np.clip((np.asarray(y) - g.y0) / g.dy, 0.0, g.rows - 1)
    c0 = np.minimum(np.floor(fc).astype(int), max(g.cols - 2, 0))
    r0 = np.minimum(np.floor(fr).astype(int), max(g.rows - 2, 0))
    c1, r1 = np.minimum(c0 + 1, g.cols - 1), np.minimum(r0 + 1, g.rows - 1)
    wc, wr = fc - c0, fr - r0
    return ((1 - wr) * ((1 - wc) * a[r0, c0] + wc * a[r0, c1]) + wr * ((1 - wc) * a[r1, c0] + wc * a[r1, c1]))


@pytest.mark.parametrize("rows, sparse, kmu", [(1, False, 0.0), (12, False, 0.0), (12, True, 0.3), (1, True, 0.3)])
def test_lookup_is_bilinear_interpolation_at_the_middle_of_each_tick(rows, sparse, kmu):
    """Every tick's channels are the table's bilinear interpolation at the midpoint of the tick's motion (tick 0:
    its position), the edge value held outside; N clamped at 0; mu_s = device mu_s times friction_scale (clamped
    at 0) plus K_mu max(0, grad . v_hat): a numpy reference on the dense samples, dense and sparse tables, one row and 2-D."""
    rng = np.random.default_rng(7)
    cols = 20
    names = ("normal_force", "friction_scale", "lateral_x", "lateral_y", "grad_x", "grad_y")
    meta = {"mapping": {"slope_friction_gain": kmu}}
    grid = Grid(rows, cols, 1e-3, 1e-3, 0.5e-3, 0.2e-3)
    if sparse:
        patch = {n: rng.uniform(-0.3, 2.0, (min(5, rows), 7)) for n in names}
        t = FrictionTable.from_patches(grid, [((0 if rows == 1 else 1, 2), patch), ((0 if rows == 1 else 6, 11), patch)],
                                       {n: choose_quantization(v, "uint16") for n, v in patch.items()},
                                       {n: 0.4 for n in names}, meta)
    else:
        dense = {n: rng.uniform(-0.3, 2.0, (rows, cols)) for n in names}
        t = FrictionTable.from_dense(grid, dense, {n: choose_quantization(v, "uint16") for n, v in dense.items()}, meta)
    n = 2500
    r = Renderer(t, device=quiet_device(), model="jump", tick_rate=10_000)
    mu_s = r.device.friction.mu_s
    for cp in (CursorPath(np.arange(n) / 10_000.0, rng.uniform(-0.005, 0.03, n), rng.uniform(-0.005, 0.02, n),
                          10_000.0, "random"),
               CursorPath(np.arange(n) / 10_000.0, 0.01 + np.cumsum(rng.choice([-2e-5, 0.0, 3e-5], n)),
                          np.full(n, 0.0041), 10_000.0, "along x")):
        xm, ym = cp.x.copy(), cp.y.copy()
        xm[1:], ym[1:] = 0.5 * (cp.x[1:] + cp.x[:-1]), 0.5 * (cp.y[1:] + cp.y[:-1])
        res = r.render(cp)
        want = {name: bilinear(t, name, xm, ym) for name in names}
        scale = 1e-12 * 2.0
        assert np.max(np.abs(res.normal_force - np.maximum(want["normal_force"], 0.0))) <= scale
        assert np.max(np.abs(res.lateral_x - want["lateral_x"])) <= scale
        assert np.max(np.abs(res.lateral_y - want["lateral_y"])) <= scale
        dx, dy = np.diff(cp.x, prepend=cp.x[0]), np.diff(cp.y, prepend=cp.y[0])
        dist = np.hypot(dx, dy)
        with np.errstate(invalid="ignore", divide="ignore"):
            slope = np.where(dist > 0, (want["grad_x"] * dx + want["grad_y"] * dy) / dist, 0.0)
        mus = np.maximum(mu_s * want["friction_scale"], 0.0) + kmu * np.maximum(slope, 0.0)
        assert np.max(np.abs(res.mu_s - mus)) <= 1e-9, cp.source
        assert np.allclose(res.vx, dx * 10_000.0, rtol=1e-9, atol=1e-12)
        assert (np.abs(res.lateral_x) > 0).all() and res.event_time.size > 0


def test_off_grid_paths_are_resampled_onto_the_tick_grid():
    """A path whose sample times are not t0 + k / tick_rate (another rate, a recording, float32 rows) is played
    as its resampling onto the renderer's grid, which the result's t, x, y are."""
    n = 500
    raw = CursorPath(np.arange(n) / 7_000.0, np.linspace(0.0, 0.02, n), np.linspace(0.01, 0.0, n), None, "raw")
    f32 = CursorPath(np.arange(n, dtype=np.float32) / np.float32(10_000), np.linspace(0, 0.02, n, dtype=np.float32),
                     np.zeros(n, np.float32), 10_000.0, "float32")
    drift = CursorPath(np.arange(n) * (1.0 / 10_000.0), np.linspace(0.0, 0.02, n), np.zeros(n), 10_000.0, "force")
    assert not np.array_equal(drift.t, np.arange(n) / 10_000.0)      # k * (1 / rate) is not k / rate everywhere
    for model in ("exact", "jump"):
        r = Renderer(ramp_table(), device=quiet_device(), model=model, tick_rate=10_000)
        for cp in (raw, f32, drift):
            res = r.render(cp)
            assert np.array_equal(res.t, res.t[0] + np.arange(res.t.size) / 10_000.0), cp.source
            assert res.t.dtype == res.x.dtype == np.float64
            grid = cp.resample(10_000.0)
            want = r.render(CursorPath(grid.t, grid.x, grid.y, 10_000.0, "grid"))
            for name in ("t", "x", "y", "friction_force"):
                assert getattr(res, name).tobytes() == getattr(want, name).tobytes(), (cp.source, name)
            assert np.allclose(np.interp(res.t, np.asarray(cp.t, np.float64), np.asarray(cp.x, np.float64)), res.x,
                               atol=1e-9)
        on_grid = parse_stroke("0,0.5 <-> 40,0.5 @ 30 mm/s", 10_000)
        res = r.render(on_grid)
        assert res.t.tobytes() == on_grid.t.tobytes() and res.x.tobytes() == on_grid.x.tobytes()


def test_friction_limits_by_hand():
    """Breakaway and kinetic force at rest: N clamped at 0, mu times friction_scale, or the stored forces where
    present; kinetic never above breakaway."""
    from shapedisplay.render.renderer import friction_limits
    n = np.array([-1.0, 0.0, 0.5, 2.0])
    bk, kn = friction_limits({"normal_force": n, "friction_scale": np.array([1.0, 2.0, 0.5, 3.0])}, 0.5, 0.3)
    np.testing.assert_allclose(bk, [0.0, 0.0, 0.5 * 0.5 * 0.5, 0.5 * 3.0 * 2.0], rtol=1e-15, atol=0)
    np.testing.assert_allclose(kn, [0.0, 0.0, 0.3 * 0.5 * 0.5, 0.3 * 3.0 * 2.0], rtol=1e-15, atol=0)
    bk, kn = friction_limits({"normal_force": n, "breakaway_force": np.array([0.3, 0.3, 0.4, 1.0]),
                              "kinetic_force": np.array([0.1, 0.1, 0.6, 0.5])}, 0.5, 0.3)
    np.testing.assert_allclose(bk, [0.0, 0.0, 0.4, 1.0], rtol=1e-15, atol=0)
    np.testing.assert_allclose(kn, [0.0, 0.0, 0.4, 0.5], rtol=1e-15, atol=0)    # 0.6 > 0.4: limited to it
    bk, kn = friction_limits({"normal_force": np.full((3, 4), 2.0)}, 0.6, 0.4)
    assert bk.shape == kn.shape == (3, 4) and np.allclose(bk, 1.2) and np.allclose(kn, 0.8)
    with pytest.raises(InputError, match="normal_force"):
        friction_limits({"friction_scale": np.ones(3)}, 0.5, 0.3)


def test_events_dropped_when_the_event_ring_overflows():
    """A flood of bursts (Karnopp on a touch of 0.3 mN at 192 kHz: thousands within one burst's 35 ms) overflows
    the engine's event ring: the render says how many bursts left the audio, keeps every event, and stepping
    the path counts the same; a path with fewer than half the ring sounding at once drops none."""
    from shapedisplay.render.native import renderer_layout
    ring = renderer_layout()["event_ring"]
    window = 0.005 + 0.030
    for N, floods in ((3e-4, True), (1e-3, False)):
        r = Renderer(make_table({"normal_force": N}), device=quiet_device(), model="karnopp", tick_rate=192_000)
        cp = parse_stroke("0,0 -> 0.5,0 @ 5mm/s", 192_000)
        res = r.render(cp)
        et = res.event_time
        live = np.searchsorted(et, et + window) - np.arange(et.size)       # bursts sounding at each event
        assert (live.max() > ring // 2) == floods and et.size > 1000
        assert (res.events_dropped > 0) == floods
        assert res.summary()["events_dropped"] == res.events_dropped < et.size
        r.reset()
        for x, y in zip(cp.x, cp.y):
            r.step(x, y)
        assert r.event_count == et.size and r.events_dropped == res.events_dropped
        if not floods:
            b = r.device.burst
            from shapedisplay.render.bursts import render_bursts
            audio, _ = render_bursts(et, res.event_amplitude, res.t[0], res.duration, r.audio_rate, b.carrier_hz,
                                     b.rise_s, b.decay_s, r.burst_policy)
            assert np.max(np.abs(audio - res.audio)) <= 1e-12


@pytest.mark.parametrize("model, policy", [("exact", "add"), ("jump", "max"), ("karnopp", "retrigger"),
                                           ("tanh", "retrigger")])
def test_render_is_its_model_over_its_inputs_and_the_bursts_of_its_events(model, policy):
    """What render plays is the model run alone (run_kernel) over the per-tick inputs (model_inputs), and its
    audio is the bursts of its events (render_bursts): the pieces the reports and the docs use compose."""
    from shapedisplay.render.bursts import render_bursts
    from shapedisplay.render.models import run_kernel
    r = Renderer(ramp_table(), device=quiet_device(), model=model, tick_rate=10_000, burst_policy=policy)
    cp = parse_stroke("0,0 <-> 60,0 @ 40 mm/s", 10_000)
    res = r.render(cp)
    t, V, N, mus, muk, gain = r.model_inputs(cp)
    assert np.array_equal(N, res.normal_force) and np.array_equal(mus, res.mu_s)
    assert np.allclose(np.abs(V[1:]), np.hypot(res.vx, res.vy)[1:], rtol=1e-12)
    _, f, phase, _, _, et, ea = run_kernel(r.model, t, V, N, mus, muk, gain)
    assert np.max(np.abs(f - res.friction_force)) <= 1e-12 and np.array_equal(phase.astype(np.int8), res.state)
    assert np.max(np.abs(et - res.event_time)) <= 1e-12 and np.allclose(ea, res.event_amplitude, rtol=1e-12)
    b = r.device.burst
    audio, clipped = render_bursts(res.event_time, res.event_amplitude, res.t[0], res.duration, r.audio_rate,
                                   b.carrier_hz, b.rise_s, b.decay_s, policy)
    assert res.event_time.size > 0 and clipped == res.clipped
    assert np.max(np.abs(audio - res.audio)) <= 1e-12


@pytest.mark.parametrize("model", ["exact", "jump", "karnopp", "stribeck", "tanh"])
def test_run_kernel_carries_its_state_and_keeps_every_event(model):
    """run_kernel over a run cut in two, the second half from the first's final state, gives the whole run's
    rows and events; a light touch at 100 Hz slips many times per tick (more events than its first buffer)."""
    from shapedisplay.render.models import get_model, run_kernel
    dev = load_device(None)
    m = get_model(model, dev)
    mus, muk, one = np.array([dev.friction.mu_s]), np.array([dev.friction.mu_k]), np.ones(1)
    for rate, n, N, V in ((20_000.0, 4000, None, 0.04 * np.sin(np.arange(4000) / 300.0)),
                          (100.0, 3000, np.full(3000, 0.02), np.full(3000, 0.05))):
        t = np.arange(n) / rate
        N = 1.0 + 0.5 * np.random.default_rng(5).random(n) if N is None else N
        S, f, ph, x, v, et, ea = run_kernel(m, t, V, N, mus, muk, one)
        h = n // 2
        S1, *a, et1, ea1 = run_kernel(m, t[:h + 1], V[:h + 1], N[:h + 1], mus, muk, one)
        S2, *b, et2, ea2 = run_kernel(m, t[h:], V[h:], N[h:], mus, muk, one, state=S1)
        for whole, first, second in zip((f, ph, x, v), a, b):
            assert np.array_equal(whole, np.r_[first, second[1:]])
        assert np.array_equal(et, np.r_[et1, et2]) and np.array_equal(ea, np.r_[ea1, ea2])
        assert S.tobytes() == S2.tobytes()
        assert et.size > 0 and np.all(np.diff(et) >= 0)
        if rate == 100.0 and model in ("exact", "jump"):
            assert et.size > n // 8 + 1024                  # grew past run_kernel's first event buffer


def test_a_pad_beyond_the_h_omega_limit_is_refused_by_name():
    """A pad ringing far faster than the tick (h * omega_n > H_OMEGA_MAX) is refused in one line, not played for minutes."""
    import dataclasses

    from shapedisplay.errors import ModelError
    from shapedisplay.table.devices import H_OMEGA_MAX, PadParams
    table = FrictionTable.from_dense(Grid(1, 8, 1e-3, 1e-3), {"normal_force": np.ones((1, 8))},
                                     {"normal_force": choose_quantization(np.ones((1, 8)), "float64")})
    dev = load_device(None).with_(tick_rate_hz=20_000.0)
    m = dev.pad.mass
    stiff = dataclasses.replace(dev, pad=PadParams(m, m * (1.001 * H_OMEGA_MAX * 10_000.0) ** 2, dev.pad.damping))
    Renderer(table, device=stiff)                          # resolved at the device's 20 kHz: h * omega_n = 500
    Renderer(table, device=stiff, tick_rate=10_010.0)      # just within the limit
    with pytest.raises(ModelError, match=r"h \* omega_n = .* = 1001, beyond the limit of 1000 \(raise the tick rate"):
        Renderer(table, device=stiff, tick_rate=10_000.0)


def test_a_device_profile_beyond_the_h_omega_limit_is_refused_at_load(tmp_path):
    from shapedisplay.errors import ModelError
    from shapedisplay.table.devices import H_OMEGA_MAX
    stiff = 1e-6 * (1.01 * H_OMEGA_MAX * 1000.0) ** 2          # N/m at 1 kHz
    p = tmp_path / "stiff.toml"
    p.write_text(f'[device]\nname = "stiff"\ntick_rate = "1 kHz"\n[pad]\nmass = 1e-6\nstiffness = {stiff:.6g}\n')
    with pytest.raises(ModelError, match=r"device pad: h \* omega_n = .* = 1010, beyond the limit of 1000"):
        load_device(p)
