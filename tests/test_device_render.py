"""The emulated device renders with the same Renderer as the host: identical samples over a real pty."""
import numpy as np
import pytest

pytest.importorskip("serial")

from shapedisplay.link import protocol as P
from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig
from shapedisplay.link.engine import force_to_position, render_stream, step_period
from shapedisplay.link.host import DeviceLink, DeviceRefused
from shapedisplay.table.devices import load_device
from shapedisplay.render import Renderer
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization


def tent_table(device="handheld-stick"):
    """Published tent profile: N1 = 0.5 N, N2 = 2.5 N over 15..45 mm, 0.25 mm grid."""
    dev = load_device(device)
    x = np.arange(241) * 0.25e-3
    n = np.interp(x, [0, 0.015, 0.030, 0.045, 0.060], [0.5, 0.5, 2.5, 0.5, 0.5])
    return FrictionTable.from_dense(Grid(1, x.size, 0.25e-3, 0.25e-3), {"normal_force": n[None, :]},
                                    {"normal_force": choose_quantization(n, "uint16")},
                                    {"device": dev.to_json()})


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    table = tent_table()
    path = table.save(tmp_path_factory.mktemp("dev") / "tent.npz")
    emu = DeviceEmulator(EmulatorConfig(model="jump"))
    emu.start()
    link = DeviceLink(emu.port, timeout=2.0)
    link.connect()
    link.upload(path.read_bytes())
    yield table, emu, link
    link.close()
    emu.close()


def f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def test_device_output_equals_host_renderer(setup):
    table, emu, link = setup
    x = np.linspace(0.002, 0.058, 400)          # a 56 mm stroke over 0.4 s: 140 mm/s
    rep = link.stream(x, paced=False, monitor=True)
    assert rep.rendered == 400 and rep.overruns == 0 and rep.missing_outputs == 0, rep.problems()
    host = render_stream(Renderer(table, model="jump", tick_rate=10_000.0), f32(x), np.zeros(400), 10)
    assert rep.outputs.size == host.size == 1 + 399 * 10
    np.testing.assert_array_equal(rep.outputs, f32(host))     # OUTPUT carries float32
    assert np.count_nonzero(host) > 1000                       # bursts were played


def test_step_period_matches_offline_tick_grid():
    """Interpolated device ticks are the renderer's ticks on the 10 kHz grid: the same events as ``step``."""
    table = tent_table()
    r = Renderer(table, model="jump", tick_rate=10_000.0)
    x = np.linspace(0.0, 0.06, 301)
    out = render_stream(r, x, None, 10)
    n_events = r.event_count
    r.reset()
    xs = np.interp(np.arange(3001) / 10.0, np.arange(301), x)
    ref = np.array([r.step(v, 0.0) for v in xs])
    assert r.event_count == n_events > 10
    np.testing.assert_allclose(out, ref, atol=1e-9)


def test_force_input_integrates_alpha(setup):
    table, emu, link = setup
    forces = np.full(200, 0.25)                 # 0.25 N on an 80 mm/(N s) stick: 20 mm/s
    rep = link.stream(forces, input="force", paced=False, monitor=True)
    assert rep.rendered == 200
    alpha = load_device("handheld-stick").cursor_gain
    pos, v, xs = None, None, []
    for f in f32(forces):
        pos, v = force_to_position(pos, v, f, 0.0, alpha, 1e-3)
        xs.append(pos[0])
    assert xs[-1] == pytest.approx(alpha * 0.25 * 0.199, rel=1e-12)
    r = Renderer(table, model="jump", tick_rate=10_000.0)
    np.testing.assert_array_equal(rep.outputs, f32(render_stream(r, np.array(xs), None, 10)))


def test_force_input_refused_without_cursor_gain(tmp_path):
    table = tent_table("desktop-rig")
    dev = table.meta["device"]
    dev["cursor_gain"] = 0.0
    table = FrictionTable.from_dense(table.grid, {"normal_force": table.dense("normal_force")},
                                     table.quant, {"device": dev})
    emu = DeviceEmulator(EmulatorConfig())
    emu.start()
    try:
        with DeviceLink(emu.port, timeout=2.0) as link:
            link.upload(table.save(tmp_path / "t.npz").read_bytes())
            with pytest.raises(DeviceRefused, match="cursor gain"):
                link.start(input="force")
            assert link.status().state == P.State.IDLE
    finally:
        emu.close()


def test_actuator_mode_plays_host_rendered_blocks(setup):
    table, emu, link = setup
    x = np.linspace(0.01, 0.05, 120)
    host = render_stream(Renderer(table, model="jump", tick_rate=10_000.0), x, None, 10)
    blocks = host[1:].reshape(-1, 10)                  # tick 0 carries no burst
    rep = link.stream(blocks, mode="actuator", paced=False, monitor=True)
    assert rep.rendered == blocks.shape[0] and rep.clipped == 0
    np.testing.assert_array_equal(rep.outputs, f32(blocks.ravel()))


def test_step_period_first_sample_is_tick_zero():
    r = Renderer(tent_table(), model="jump", tick_rate=10_000.0)
    buf = np.empty(10)
    assert step_period(r, None, 0.01, 0.0, 10, buf) == 1 and buf[0] == 0.0
    assert step_period(r, (0.01, 0.0), 0.011, 0.0, 10, buf) == 10
    assert r.last["x"] == 0.011       # the last tick sits exactly on the new sample
