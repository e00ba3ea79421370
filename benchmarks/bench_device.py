"""Device link speed: upload throughput against line rate, cursor-to-actuator latency.

The emulator is paced to the line rate: it takes received bytes off the pty
no faster than baud/10 bytes per second (8N1, ten bit times per byte) and
writes its own frames at the same pace, so a pty behaves like a 921600-baud
UART. Printed figures are ratios against the line rate and the targets:

* upload throughput / line rate        (target >= 0.80)
* median cursor-to-actuator latency    (target <= 2 ms): time from the host
  writing a CURSOR frame to the host receiving the OUTPUT frame carrying the
  actuator samples rendered from it (a round trip, so it bounds the one-way
  latency from above).

Run: .venv/bin/python benchmarks/bench_device.py
"""
from __future__ import annotations

import os
import sys
import tempfile
import time

import numpy as np

from shapedisplay.link.emulator import DeviceEmulator, EmulatorConfig
from shapedisplay.link.host import DeviceLink
from shapedisplay.table.model import FrictionTable, Grid, choose_quantization

BAUD = 921_600
LINE_RATE = BAUD / 10.0     # bytes/s, 8N1


def table_image(cols: int, rows: int = 1, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, cols)
    nf = 0.5 + 2.0 * np.exp(-((x - 0.5) / 0.1) ** 2) + 0.05 * rng.random((rows, cols))
    grid = Grid(rows, cols, 0.25e-3, 0.25e-3)
    t = FrictionTable.from_dense(grid, {"normal_force": nf}, {"normal_force": choose_quantization(nf, "float32")},
                                 {"tick_rate_hz": 10000.0})
    with tempfile.TemporaryDirectory() as d:
        return t.save(os.path.join(d, "t.npz")).read_bytes()


def bench_upload(image: bytes, baud: int, repeats: int = 2) -> float:
    # renderer=False: the upload path alone (verification = CRC + table parse and checksum, no renderer set-up)
    emu = DeviceEmulator(EmulatorConfig(max_table_bytes=1 << 20, chunk_size=1024, upload_window=4, baud=baud,
                                        renderer=False))
    emu.start()
    try:
        with DeviceLink(emu.port, timeout=1.0) as link:
            best = 0.0
            for _ in range(repeats):
                rep = link.upload(image)
                best = max(best, rep.throughput_bytes_per_s)
            return best
    finally:
        emu.close()


def bench_latency(n: int, baud: int, model: str = "jump"):
    """Median latency with the emulator in its own process (as a device is), talking over a pty."""
    import subprocess
    image = tutorial_image()
    with tempfile.TemporaryDirectory() as d:
        port_file = os.path.join(d, "port")
        cmd = [sys.executable, "-m", "shapedisplay.cli.main", "device", "emulate", "--baud", str(baud),
               "--model", model, "--stop-after", "120", "--port-file", port_file]
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            t_end = time.monotonic() + 60
            while not os.path.exists(port_file):
                if time.monotonic() > t_end or proc.poll() is not None:
                    raise RuntimeError("emulator did not start")
                time.sleep(0.05)
            port = open(port_file).read().strip()
            with DeviceLink(port, timeout=2.0) as link:
                link.upload(image)
                # warm-up, then the measured stroke
                link.stream(np.linspace(0.0, 0.01, 100), paced=True, monitor=True)
                x = 0.005 + 0.03 * np.sin(np.linspace(0.0, 6.0, n)) ** 2
                rep = link.stream(x, paced=True, monitor=True)
            lat = rep.latencies_s[np.isfinite(rep.latencies_s)]
            return lat, rep
        finally:
            proc.terminate()
            proc.wait(10)


def tutorial_image() -> bytes:
    """A 60 mm tent profile table with the published Konyo pad (1-D, 0.25 mm grid)."""
    from shapedisplay.table.devices import load_device
    dev = load_device("handheld-stick")
    x = np.arange(241) * 0.25e-3
    n = np.interp(x, [0, 0.015, 0.030, 0.045, 0.060], [0.5, 0.5, 2.5, 0.5, 0.5])
    grid = Grid(1, x.size, 0.25e-3, 0.25e-3)
    t = FrictionTable.from_dense(grid, {"normal_force": n[None, :]},
                                 {"normal_force": choose_quantization(n, "uint16")},
                                 {"device": dev.to_json(), "tick_rate_hz": 10000.0})
    with tempfile.TemporaryDirectory() as d:
        return t.save(os.path.join(d, "t.npz")).read_bytes()


def main() -> int:
    image = table_image(60_000)
    print(f"table image: {len(image)} bytes; line rate at {BAUD} baud 8N1 = {LINE_RATE / 1e3:.2f} kB/s; "
          f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    fast = bench_upload(image, 0)
    paced = bench_upload(image, BAUD)
    print(f"upload, unpaced pty (memory speed): {fast / 1e3:9.1f} kB/s  = {fast / LINE_RATE:6.2f} x line rate")
    print(f"upload, pty paced to {BAUD} baud:  {paced / 1e3:9.1f} kB/s  = {paced / LINE_RATE:6.3f} x line rate "
          f"(target >= 0.80: {'OK' if paced / LINE_RATE >= 0.8 else 'MISSED'})")
    try:
        lat, rep = bench_latency(2000, BAUD)
    except ImportError as exc:
        print(f"latency: renderer unavailable ({exc})")
        return 0
    med = float(np.median(lat))
    lat0, _ = bench_latency(1000, 0)
    print(f"cursor->actuator latency through the pty, paced to {BAUD} baud, jump model, {lat.size} samples: "
          f"median {med * 1e3:.3f} ms, p95 {np.percentile(lat, 95) * 1e3:.3f} ms, max {lat.max() * 1e3:.3f} ms "
          f"= {med / 2e-3:.3f} x the 2 ms target ({'OK' if med <= 2e-3 else 'MISSED'})")
    print(f"  of which serialisation at line rate: 26 + 58 bytes = {84 / LINE_RATE * 1e3:.3f} ms; "
          f"unpaced pty median {np.median(lat0) * 1e3:.3f} ms")
    print(f"  underruns {rep.underruns}, overruns {rep.overruns}, rendered {rep.rendered}/{rep.sent}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
