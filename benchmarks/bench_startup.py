"""Whole-process start-up where users wait: ``--help``, a warm ``play``, and the first ``play`` after an install.

Rows, each a whole process (``play`` of a 5 s stroke over the bundled phone
scene, exact model, 10 kHz):

* ``python -c "import shapedisplay"`` and ``shapedisplay --help``;
* a warm ``play``: the ordinary caches, filled by one untimed run;
* the first ``play`` after an install: every run gets a fresh, empty cache
  directory (``XDG_CACHE_HOME``), as after ``pip install``. The C engine is
  built by the install (``shapedisplay._engine``), so nothing is compiled at
  run time; the row shows that it stays so;
* ``compile`` of bundled assets, as ``make demo`` runs it: the phone scene,
  the tent profile picture and the keycap mesh (``--skip-compile`` leaves
  them out).

The baseline is ``python -c pass`` measured in the same run; every figure
is min/median/max over the runs, and its median is printed as a ratio
against the baseline median. The runs are interleaved (one of each command
per round), so a change of machine load hits every row alike.

Wall time is what a user waits; on a machine busy with other work it
grows with the load, so every row also gives the CPU time (user + system) of
the process, which on an idle machine is about its wall time. The load
average is printed with the table.

Child processes run without ``PYTHONDONTWRITEBYTECODE``: an installed package
has its bytecode compiled at install time (pip does it), so a user's command
does not recompile the package's modules on every start.

Usage: ``.venv/bin/python benchmarks/bench_startup.py [--runs N] [--cold-runs N] [--quick] [--skip-compile]``.
"""
import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "assets" / "scenes" / "phone.toml"
EXE = Path(sys.executable).parent / "shapedisplay"
STROKE = "62,2 -> 62,152 @ 30mm/s"  # 150 mm at 30 mm/s = 5 s
ASSETS = ROOT / "assets"
# (row label, compile arguments after the source; output added): the sources and options of `make demo`
COMPILES = {
    "compile phone scene": (ASSETS / "scenes" / "phone.toml", []),
    "compile tent profile PNG": (ASSETS / "maps" / "tent_profile.png",
                                 ["--size", "60x4mm", "--height", "0:2mm", "--mapping", "height", "--n-base", "0.5N",
                                  "--n-gain", "2N/mm"]),
    "compile keycap STL": (ASSETS / "meshes" / "keycap.stl", ["--resolution", "0.1mm", "--up", "z"]),
}


def child_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(extra)
    return env


def run_once(cmd, env) -> tuple[float, float]:
    """(wall, cpu) seconds of one run of ``cmd``; cpu = user + system time of the child process."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def row(name, runs, base) -> None:
    """Print wall min/median/max, its ratio to the baseline's wall median, and the same for the CPU time."""
    wall, cpu = [w for w, _ in runs], [c for _, c in runs]
    lo, med, hi = min(wall), statistics.median(wall), max(wall)
    cmed = statistics.median(cpu)
    unit, scale = ("s", 1.0) if med >= 1.0 else ("ms", 1e3)
    line = (f"{name:<44} wall min {lo * scale:7.1f}  median {med * scale:7.1f}  max {hi * scale:7.1f} {unit:<2}"
            f" ratio {med / base[0]:6.1f} | cpu median {cmed * scale:7.1f} {unit:<2} ratio {cmed / base[1]:6.1f}")
    print(line, flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7, help="timed runs of each warm command (at least 3)")
    ap.add_argument("--cold-runs", type=int, default=3, help="timed first plays from empty caches (at least 3)")
    ap.add_argument("--quick", action="store_true", help="3 runs of every row")
    ap.add_argument("--skip-compile", action="store_true", help="leave out the compile rows")
    args = ap.parse_args()
    runs, cold_runs = max(3, args.runs), max(3, args.cold_runs)
    if args.quick:
        runs = cold_runs = 3
    env = child_env()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        table = tmp / "phone.npz"
        subprocess.run([str(EXE), "compile", str(SCENE), "-o", str(table)], check=True, env=env,
                       stdout=subprocess.DEVNULL)

        play = [str(EXE), "play", str(table), "--stroke", STROKE, "--model", "exact", "--tick-rate", "10kHz",
                "-o", str(tmp / "out.wav")]

        warm = {
            "base": [sys.executable, "-c", "pass"],
            "import": [sys.executable, "-c", "import shapedisplay"],
            "help": [str(EXE), "--help"],
            "play": play,
        }
        if not args.skip_compile:
            for label, (src, opts) in COMPILES.items():
                warm[label] = [str(EXE), "compile", str(src), *opts, "-o", str(tmp / "compiled.npz")]
        for cmd in warm.values():
            run_once(cmd, env)                    # fills the ordinary caches (untimed)
        times = {k: [] for k in warm}
        for _ in range(runs):
            for k, cmd in warm.items():
                times[k].append(run_once(cmd, env))
        cold = {"first": [], "base": []}
        for i in range(cold_runs):
            cold["first"].append(run_once(play, child_env(XDG_CACHE_HOME=str(tmp / f"cache-{i}"))))
            cold["base"].append(run_once(warm["base"], env))
    print(f"whole process; warm rows {runs} runs, first-play rows {cold_runs} runs, each from empty caches; "
          f"ratio = median / baseline median (wall and CPU separately); load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} CPUs")
    allbase = times["base"] + cold["base"]
    base = (statistics.median(w for w, _ in allbase), statistics.median(c for _, c in allbase))
    row("baseline: python -c pass", allbase, base)
    row('python -c "import shapedisplay"', times["import"], base)
    row("shapedisplay --help", times["help"], base)
    row("play 5 s stroke, warm", times["play"], base)
    row("first play after install (empty caches)", cold["first"], base)
    for label in COMPILES:
        if label in times:
            row(label, times[label], base)
    return 0


if __name__ == "__main__":
    sys.exit(main())
