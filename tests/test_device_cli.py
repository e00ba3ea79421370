"""`shapedisplay device ...` against `shapedisplay device emulate` running as its own process."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("serial")

from shapedisplay.cli.main import main
from test_device_render import tent_table


@pytest.fixture(scope="module")
def emulator(tmp_path_factory):
    d = tmp_path_factory.mktemp("emu")
    port_file = d / "port"
    proc = subprocess.Popen([sys.executable, "-m", "shapedisplay.cli.main", "device", "emulate", "--stop-after", "60",
                             "--memory", "64 KiB", "--port-file", str(port_file)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t_end = time.monotonic() + 60
    while not port_file.exists():
        if proc.poll() is not None or time.monotonic() > t_end:
            proc.kill()
            pytest.fail(f"emulator did not start: {proc.stderr.read()}")
        time.sleep(0.05)
    port = port_file.read_text().strip()
    yield proc, port, d
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()


@pytest.fixture(scope="module")
def table_path(tmp_path_factory):
    return str(tent_table().save(tmp_path_factory.mktemp("tab") / "tent.npz"))


def test_emulate_announces_port(emulator):
    proc, port, _ = emulator
    assert os.path.exists(port) and port.startswith("/dev/")


def test_info(emulator, capsys):
    _, port, _ = emulator
    assert main(["device", "info", port]) == 0
    out = capsys.readouterr().out
    assert "protocol 1..1" in out and "table memory 65536 bytes" in out and "models jump" in out
    assert main(["device", "info", port, "--json"]) == 0
    assert '"max_table_bytes": 65536' in capsys.readouterr().out


def test_upload_and_play(emulator, table_path, capsys, tmp_path):
    _, port, _ = emulator
    assert main(["device", "upload", table_path, port]) == 0
    assert "committed" in capsys.readouterr().out
    out_file = tmp_path / "played.npz"
    assert main(["device", "play", table_path, port, "--stroke", "5,0 -> 55,0 @ 200 mm/s", "-o", str(out_file)]) == 0
    out = capsys.readouterr().out
    assert "played 251 of 251 cursor samples" in out and "uploaded" not in out   # table already active
    with np.load(out_file) as z:
        assert z["drive"].size == 1 + 250 * 10 and np.count_nonzero(z["drive"]) > 100


def test_play_actuator_mode(emulator, table_path, capsys):
    _, port, _ = emulator
    assert main(["device", "play", table_path, port, "--stroke", "5,0 -> 25,0 @ 100 mm/s", "--mode", "actuator"]) == 0
    assert "played 200 of 200" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [
    (["device", "info", "/dev/no-such-port"], "cannot open"),
    (["device", "upload", "/no/such/table.npz", "PORT"], "no such file"),
    (["device", "play", "TABLE", "PORT", "--stroke", "0,0 -> 10,0"], "needs a speed"),
    (["device", "emulate", "--memory", "12 parsecs"], "--memory"),
    (["device", "emulate", "--tick-rate", "10 kHz", "--stream-rate", "3 kHz"], "multiple"),
    (["device", "info", "PORT", "--timeout", "0"], "--timeout"),
    (["device", "play", "TABLE", "PORT", "--stroke", "0,0 -> 10,0 @ 10 mm/s", "-o", "/no/such/dir/p.npz"],
     "does not exist"),
])
def test_bad_input_is_one_line_exit_2(emulator, table_path, capsys, argv, message):
    _, port, _ = emulator
    argv = [port if a == "PORT" else table_path if a == "TABLE" else a for a in argv]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    err = err.strip()
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err
    assert "played" not in out          # refused before anything was sent


def test_table_too_large_for_device(emulator, tmp_path, capsys):
    _, port, _ = emulator
    from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
    rng = np.random.default_rng(0)
    nf = rng.random((1, 20000))
    big = FrictionTable.from_dense(Grid(1, 20000, 1e-4, 1e-4), {"normal_force": nf},
                                   {"normal_force": choose_quantization(nf, "float64")})
    path = big.save(tmp_path / "big.npz")
    assert main(["device", "upload", str(path), port]) == 2
    err = capsys.readouterr().err
    assert "exceeds the device memory of 65536 bytes" in err and "nothing uploaded" in err


def _one_line_exit_2(capsys, argv, message):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err, err


def test_not_a_table_and_tampered_table_refused_before_upload(emulator, table_path, tmp_path, capsys):
    _, port, _ = emulator
    text = tmp_path / "notes.npz"
    text.write_text("not a table")
    _one_line_exit_2(capsys, ["device", "upload", str(text), port], "not a table")
    with np.load(table_path) as z:
        arrays = dict(z)
    arrays["normal_force"] = arrays["normal_force"].copy()
    arrays["normal_force"].flat[0] ^= 1                    # one stored code changed, header kept
    tampered = tmp_path / "tampered.npz"
    np.savez(tampered, **arrays)
    _one_line_exit_2(capsys, ["device", "play", str(tampered), port, "--stroke", "5,0 -> 15,0 @ 100 mm/s"],
                     "checksum mismatch")


def test_silent_port_times_out(tmp_path, capsys):
    master, slave = os.openpty()          # a serial port with nothing behind it
    try:
        t0 = time.monotonic()
        _one_line_exit_2(capsys, ["device", "info", os.ttyname(slave), "--timeout", "0.1", "--retries", "1"],
                         "did not answer HELLO")
        assert time.monotonic() - t0 < 10
    finally:
        os.close(master)
        os.close(slave)


def test_emulator_killed_mid_play_is_one_line_exit_2(table_path, tmp_path):
    port_file = tmp_path / "port"
    emu = subprocess.Popen([sys.executable, "-m", "shapedisplay.cli.main", "device", "emulate", "--stop-after", "60",
                            "--port-file", str(port_file)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        t_end = time.monotonic() + 60
        while not port_file.exists() and emu.poll() is None and time.monotonic() < t_end:
            time.sleep(0.05)
        host = subprocess.Popen([sys.executable, "-m", "shapedisplay.cli.main", "device", "play", table_path,
                                 port_file.read_text().strip(), "--stroke", "0,0 <-> 60,0 @ 20 mm/s x3"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "PYTHONUNBUFFERED": "1"})
        first = host.stdout.readline()     # "uploaded ... committed": streaming starts next (the stroke lasts 18 s)
        assert first.startswith("uploaded") and host.poll() is None, first
        emu.kill()
        out, err = host.communicate(timeout=30)
    finally:
        emu.kill()
        emu.wait()
    assert host.returncode == 2, (out, err)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and "disappeared" in err, err


def test_emulator_stops_on_sigterm(emulator):
    proc, port, _ = emulator
    proc.send_signal(signal.SIGTERM)
    proc.wait(10)
    assert proc.returncode == 0
    assert "device emulator on" in proc.stdout.read()
