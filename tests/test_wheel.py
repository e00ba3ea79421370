"""The package as users get it: a wheel installed into a fresh environment outside the checkout.

Builds the wheel from this checkout, checks it holds every subpackage and all
package data (bundled device profiles, the C runtime sources), installs it
without dependencies into a new virtual environment in a temporary folder
(the dependencies come from the test environment through a path entry, not
the checkout), and runs a smoke session there: compile with a bundled
device, play, export a C header, and, when a C compiler is present, build and
run the C runtime on that header and through the C engine.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "shapedisplay"

pytestmark = pytest.mark.slow


def _run(argv, cwd, env, timeout=600):
    res = subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, f"{argv}:\n{res.stdout}\n{res.stderr}"
    return res.stdout


def tracked_files() -> list[str]:
    """The checkout's files under shapedisplay/ and cli/ as git tracks them (a clean clone's tree)."""
    res = subprocess.run(["git", "ls-files", "-z", "shapedisplay", "cli", "pyproject.toml", "README.md"], cwd=ROOT,
                         capture_output=True, text=True)
    if res.returncode != 0:
        pytest.skip("the wheel test reads the file list from git")
    return [f for f in res.stdout.split("\0") if f and (ROOT / f).is_file() and not (ROOT / f).is_symlink()]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    # a copy of the tracked sources, so nothing is written into the checkout and no stale build/
    # folder or stray file can add to the wheel what a clean clone does not have
    src = tmp_path_factory.mktemp("src")
    for f in tracked_files():
        (src / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / f, src / f)
    # no isolation: the build uses this environment's setuptools and wheel (the test extra), offline
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", out, src],
         cwd=src, env=os.environ)
    (whl,) = out.glob("shapedisplay-*.whl")
    return whl


def test_wheel_holds_every_package_and_the_data_read_at_run_time(wheel):
    """Every tracked file of the package (modules, device profiles, C sources, web assets) is in the wheel."""
    names = set(zipfile.ZipFile(wheel).namelist())
    files = [f for f in tracked_files() if f.startswith("shapedisplay/") and not Path(f).name.startswith(".")]
    missing = sorted(f for f in files if f not in names)
    assert not missing, f"missing from the wheel: {missing}"
    assert any(f.startswith("shapedisplay/data/devices/") and f.endswith(".toml") for f in files)
    assert any(f.startswith("shapedisplay/runtime_c/") and f.endswith(".c") for f in files)
    cli = [f.replace("cli/", "shapedisplay_cli/", 1) for f in tracked_files() if f.startswith("cli/") and f.endswith(".py")]
    assert cli and not sorted(set(cli) - names)
    assert not any(n.startswith(("tests/", "cli/", "assets/")) for n in names)


def test_installed_wheel_compiles_plays_exports_and_runs_c(wheel, tmp_path):
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=tmp_path, env=os.environ)
    py = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env.update(XDG_CACHE_HOME=str(tmp_path / "cache"), HOME=str(tmp_path))
    _run([sys.executable, "-m", "pip", "--python", py, "install", "--no-deps", "--no-index", "-q", wheel],
         cwd=tmp_path, env=env)
    # the dependencies (numpy, numba, ...) from the test environment, but not its editable shapedisplay:
    # a plain path entry does not run that environment's .pth files
    site = Path(_run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp_path, env).strip())
    (site / "test-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    where = _run([py, "-c", "import shapedisplay, shapedisplay_cli; print(shapedisplay.__file__); "
                            "print(shapedisplay_cli.__file__)"], tmp_path, env).split()
    assert all(Path(w).is_relative_to(venv) for w in where), where     # the wheel, not the checkout
    sd = venv / "bin" / "shapedisplay"
    shutil.copy(ROOT / "assets" / "maps" / "tent_profile.png", tmp_path / "tent.png")

    out = _run([sd, "compile", "tent.png", "-o", "t.npz", "--size", "60x4mm", "--height", "0:2mm",
                "--device", "handheld-stick", "--json"], tmp_path, env)
    assert json.loads(out)["device"] == "handheld-stick"
    out = _run([sd, "play", "t.npz", "--stroke", "5:55mm @ 50mm/s", "--model", "jump", "--tick-rate", "2kHz",
                "-o", "o.wav", "--json"], tmp_path, env)
    auto = json.loads(out)
    assert auto["events"] > 0 and (tmp_path / "o.wav").stat().st_size > 44
    _run([sd, "export", "t.npz", "--format", "c", "-o", "table.h", "--name", "sd_table"], tmp_path, env)
    assert "sd_table" in (tmp_path / "table.h").read_text()

    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        pytest.skip("no C compiler: the C runtime part of the smoke test needs one")
    # with a C compiler, play went through the C runtime built from the installed sources (its offline loop
    # ships in the wheel too); the numba kernels write the same file
    assert auto["engine"] == "c"
    out = _run([sd, "play", "t.npz", "--stroke", "5:55mm @ 50mm/s", "--model", "jump", "--tick-rate", "2kHz",
                "-o", "o-py.wav", "--json", "--engine", "python"], tmp_path, env)
    assert json.loads(out)["engine"] == "python"
    assert (tmp_path / "o-py.wav").read_bytes() == (tmp_path / "o.wav").read_bytes()
    runtime_c = Path(_run([py, "-c", "from shapedisplay.link.c_engine import RUNTIME_C; print(RUNTIME_C)"],
                          tmp_path, env).strip())
    assert runtime_c.is_relative_to(venv)
    lib = [runtime_c / n for n in ("sd_render.c", "sd_pad.c", "sd_exact.c", "sd_image.c")]
    _run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-I", runtime_c, "-I", tmp_path,
          "-DSD_TABLE_HEADER=\"table.h\"", runtime_c / "tool_play_header.c", *lib, "-lm", "-o", "play"],
         tmp_path, env)
    n = 400
    x = np.linspace(5e-3, 55e-3, n)
    with open(tmp_path / "in.bin", "wb") as f:
        np.array([n], np.int64).tofile(f)
        x.tofile(f)
        np.full(n, 2e-3).tofile(f)
    _run([tmp_path / "play", "48000", "in.bin", "out.bin"], tmp_path, env)
    drive = np.fromfile(tmp_path / "out.bin", dtype=np.float64, count=n)
    assert drive.shape == (n,) and np.all(np.isfinite(drive)) and np.any(drive != 0)
    # the C engine (ctypes), built from the installed sources, plays as the Python renderer does
    out = _run([py, "-c", """
import numpy as np
from shapedisplay.link.c_engine import CRenderer
from shapedisplay.link.engine import render_stream
from shapedisplay.runtime import Renderer
from shapedisplay.table import FrictionTable
t = FrictionTable.load("t.npz")
x = np.float32(np.linspace(5e-3, 55e-3, 300)).astype(float)
c = render_stream(CRenderer(t, model="jump", tick_rate=2000.0), x, None, 2)
p = render_stream(Renderer(t, model="jump", tick_rate=2000.0), x, None, 2)
print(int(np.array_equal(c, p)), int(np.count_nonzero(p)))
"""], tmp_path, env)
    same, nonzero = map(int, out.split())
    assert same == 1 and nonzero > 0
