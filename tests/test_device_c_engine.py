"""The emulated device takes the binary table image (export --format bin) as firmware does: upload, play, CLI."""
import numpy as np
import pytest

pytest.importorskip("serial")

from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig
from shapedisplay.link.engine import render_stream
from shapedisplay.link.host import DeviceLink
from shapedisplay.render import Renderer
from test_device_render import f32, tent_table


def test_emulator_takes_a_binary_table_image(tmp_path):
    """An upload may be the binary table image (export --format bin): same samples as the .npz."""
    from shapedisplay.render.image import to_image
    table = tent_table()
    emu = DeviceEmulator(EmulatorConfig(model="jump"))
    emu.start()
    try:
        with DeviceLink(emu.port, timeout=2.0) as link:
            link.upload(to_image(table))
            x = np.linspace(0.003, 0.057, 300)
            rep = link.stream(x, paced=False, monitor=True)
            assert rep.rendered == 300 and rep.missing_outputs == 0
        host = render_stream(Renderer(table, model="jump", tick_rate=10_000.0), f32(x), None, 10)
        assert np.count_nonzero(host) > 300                      # bursts were played
        np.testing.assert_array_equal(rep.outputs, f32(host))
    finally:
        emu.close()


def test_cli_emulate_plays_an_uploaded_image(tmp_path, capsys):
    import os
    import subprocess
    import sys
    import time
    from shapedisplay.cli.main import main
    port_file = tmp_path / "port"
    proc = subprocess.Popen([sys.executable, "-m", "shapedisplay.cli.main", "device", "emulate",
                             "--stop-after", "60", "--port-file", str(port_file)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    try:
        t_end = time.monotonic() + 90
        while not port_file.exists():
            assert proc.poll() is None and time.monotonic() < t_end, proc.stderr.read() if proc.poll() else "slow"
            time.sleep(0.05)
        from shapedisplay.render.image import export_image
        table = str(export_image(tent_table(), tmp_path / "t.sdt"))      # the binary image, uploaded as is
        out = tmp_path / "played.npz"
        assert main(["device", "play", table, port_file.read_text().strip(), "--stroke",
                     "5,0 -> 45,0 @ 100 mm/s", "-o", str(out)]) == 0
        with np.load(out) as z:
            drive = z["drive"]
        assert drive.size == 1 + 400 * 10 and np.count_nonzero(drive) > 1000
    finally:
        proc.terminate()
        proc.wait(10)
