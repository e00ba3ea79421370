"""The package as users get it: a wheel installed into a fresh environment outside the checkout.

Builds the wheel from this checkout (its C runtime and C kernels compiled into
the extension modules ``shapedisplay._engine`` and ``shapedisplay._kernels_c``
by ``setup.py``), checks it holds them, every subpackage and all package data
(bundled device profiles, the C runtime sources), installs it without
dependencies into a new virtual environment in a temporary folder (the
dependencies come from the test environment through a path entry, not the
checkout), and runs a session there as a user without a C compiler would:
no compiler on the ``PATH``, ``CC`` unset, an empty home and cache folder.
Compile, play with every model, the quick accuracy report, a study, a C
header export and the studio's page all work, and nothing is compiled or
cached at run time.
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
    """The checkout's files under shapedisplay/ as git tracks them (a clean clone's tree)."""
    res = subprocess.run(["git", "ls-files", "-z", "shapedisplay", "pyproject.toml", "setup.py",
                          "README.md"], cwd=ROOT,
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
    assert any(f.startswith("shapedisplay/table/data/devices/") and f.endswith(".toml") for f in files)
    assert any(f.startswith("shapedisplay/engine/") and f.endswith(".c") for f in files)
    assert any(f.startswith("shapedisplay/cli/") and f.endswith(".py") for f in files)
    assert not any(n.startswith(("tests/", "cli/", "assets/")) for n in names)
    # the C runtime and kernels, compiled at build time for this platform
    for module in ("_engine", "_kernels_c"):
        assert [n for n in names if n.startswith(f"shapedisplay/{module}.") and n.endswith((".so", ".pyd"))], module


#: C compilers a user might have; the session's PATH holds none of them.
COMPILERS = ("cc", "gcc", "clang", "c99", "tcc", "icc", "icx", "zig")
#: Models played from the wheel; all four are meant to play through the compiled C runtime.
MODELS = ("exact", "jump", "karnopp", "stribeck")


def _no_compiler_env(tmp_path: Path, venv: Path) -> dict:
    """An environment without a C compiler: PATH is a folder of links to the venv's python and shapedisplay
    (and a few basic tools), CC/CFLAGS unset, HOME and XDG_CACHE_HOME fresh and empty."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "shapedisplay").symlink_to(venv / "bin" / "shapedisplay")   # its first line names the venv's python
    for name in ("python", "python3"):      # a link would not find the venv's pyvenv.cfg: a script that runs it
        (bin_dir / name).write_text(f'#!/bin/sh\nexec "{venv / "bin" / "python"}" "$@"\n')
        (bin_dir / name).chmod(0o755)
    for tool in ("sh", "env", "ls", "cat", "uname"):
        found = shutil.which(tool)
        if found:
            (bin_dir / tool).symlink_to(found)
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME", "CC", "CXX", "CFLAGS", "LDSHARED", "NUMBA_CACHE_DIR")}
    env.update(PATH=str(bin_dir), HOME=str(home), XDG_CACHE_HOME=str(home / ".cache"),
               MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
    assert all(shutil.which(c, path=env["PATH"]) is None for c in COMPILERS)
    return env


def _files_compiled_at_run_time(*folders: Path) -> list[str]:
    """Shared libraries, objects or a shapedisplay cache under ``folders`` (what a build at run time leaves)."""
    found = []
    for folder in folders:
        for p in folder.rglob("*"):
            if p.suffix in (".so", ".dylib", ".dll", ".o", ".pyd") or p.name == "shapedisplay":
                found.append(str(p.relative_to(folder)))
    return found


def _studio_page(sd: Path, source: Path, cwd: Path, env: dict, timeout: float = 120.0) -> bytes:
    """The studio's page: ``shapedisplay studio SOURCE --no-browser --port 0`` in the background, the page
    fetched with the token it prints, the studio stopped."""
    import re
    import threading
    import time
    import urllib.error
    import urllib.request
    proc = subprocess.Popen([str(sd), "studio", str(source), "--no-browser", "--port", "0"], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()
    try:
        end = time.monotonic() + timeout
        url = None
        while url is None:
            assert proc.poll() is None and time.monotonic() < end, f"the studio printed no URL: {lines}"
            m = re.search(r"http://127\.0\.0\.1:\d+/\?token=\S+", "".join(lines))
            url = m.group(0) if m else None
            time.sleep(0.1)
        while True:            # the page is answered after the first compile
            try:
                with urllib.request.urlopen(url, timeout=30) as r:
                    if r.status == 200:
                        return r.read()
            except (urllib.error.URLError, OSError):
                pass
            assert proc.poll() is None and time.monotonic() < end, f"the studio served no page: {lines}"
            time.sleep(0.2)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_installed_wheel_runs_without_a_c_compiler_and_compiles_nothing(wheel, tmp_path):
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=tmp_path, env=os.environ)
    py = venv / "bin" / "python"
    _run([sys.executable, "-m", "pip", "--python", py, "install", "--no-deps", "--no-index", "-q", wheel],
         cwd=tmp_path, env=os.environ)
    # the dependencies (numpy, numba, ...) from the test environment, but not its editable shapedisplay:
    # a plain path entry does not run that environment's .pth files
    site = Path(_run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp_path,
                     os.environ).strip())
    (site / "test-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    env = _no_compiler_env(tmp_path, venv)
    home = Path(env["HOME"])
    where = _run(["python", "-c", "import shapedisplay, shapedisplay.cli; print(shapedisplay.__file__); "
                                  "print(shapedisplay.cli.__file__); from shapedisplay.render import native; "
                                  "from shapedisplay.author import kernels as _kernels; print(native.library_path()); "
                                  "print(_kernels.c_kernels()._name)"], tmp_path, env).split()
    assert all(Path(w).is_relative_to(venv) for w in where), where     # the wheel, not the checkout
    sd = shutil.which("shapedisplay", path=env["PATH"])
    assert sd is not None
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(ROOT / "assets" / "maps" / "tent_profile.png", work / "tent.png")
    shutil.copy(ROOT / "assets" / "scenes" / "phone.toml", work / "phone.toml")

    out = _run([sd, "compile", "tent.png", "-o", "t.npz", "--size", "60x4mm", "--height", "0:2mm",
                "--device", "handheld-stick", "--json"], work, env)
    assert json.loads(out)["device"] == "handheld-stick"
    for model in MODELS:
        out = _run([sd, "play", "t.npz", "--stroke", "5:55mm @ 50mm/s", "--model", model, "--tick-rate", "2kHz",
                    "-o", f"{model}.wav", "--trace-out", f"{model}-trace.npz", "--json"], work, env)
        res = json.loads(out)
        assert res["events"] > 0 and (work / f"{model}.wav").stat().st_size > 44, model
        assert (work / f"{model}-trace.npz").stat().st_size > 0, model
    _run([sd, "report", "accuracy", "--quick", "--no-progress", "-o", "report"], work, env)
    assert any((work / "report").iterdir())
    out = _run([sd, "study", "bump", "--json"], work, env)
    assert json.loads(out)
    _run([sd, "export", "t.npz", "--format", "c", "-o", "table.h", "--name", "sd_table"], work, env)
    assert "sd_table" in (work / "table.h").read_text()
    page = _studio_page(Path(sd), work / "phone.toml", work, env)
    assert b"shapedisplay studio" in page

    # nothing was compiled at run time: no library, object file or shapedisplay cache in the home and cache
    # folders (other tools may keep their caches there, matplotlib its font list)
    assert _files_compiled_at_run_time(home, Path(env["XDG_CACHE_HOME"])) == []

    # numba and llvmlite: what a `pip install` of the wheel pulls in is its metadata's requirements (the
    # environment's own `pip list` shows the test environment's packages, reached through the path entry)
    required = json.loads(_run(["python", "-c", "import importlib.metadata as m, json; "
                                                "print(json.dumps(m.requires('shapedisplay') or []))"], work, env))
    names = {r.split(";")[0].split("[")[0].split("<")[0].split(">")[0].split("=")[0].strip().lower() for r in required}
    assert not names & {"numba", "llvmlite"}, sorted(names)
    # and nothing the package runs imports them, whatever the environment holds
    loaded = _run(["python", "-c", "import sys, shapedisplay.render as r, shapedisplay.reports.accuracy, "
                                   "shapedisplay.reports.presets, shapedisplay.author.compile, shapedisplay.author.mesh, shapedisplay.author.raster; "
                                   "r.Renderer; r.simulate_pad('stribeck', duration=0.01); "
                                   "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numba', 'llvmlite')))"],
                  work, env)
    assert loaded.strip() == "[]", loaded
