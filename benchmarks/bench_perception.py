"""Whole-process time of the legibility check: ``shapedisplay check SCENE --perception`` on the phone scene.

The target is one second for the whole process (docs/perception.md), so the
studio can run the check on every save. Rows, each a whole process, timed
over ``--runs`` rounds (at least 5), interleaved (one of each command per
round, so a change of machine load hits every row alike):

* baseline: plain ``shapedisplay check assets/scenes/phone.toml`` (parse and
  validate, no rendering), measured in the same run;
* ``check --perception`` (text) and ``check --perception --json``.

Every row gives wall time min/median/max, the median's ratio to the
baseline's, and the CPU time (user + system) of the process: on a machine
busy with other work the wall time grows with the load, the CPU time far
less. The load average is printed with the table.

Usage: ``.venv/bin/python benchmarks/bench_perception.py [--runs N]``.
"""
import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "assets" / "scenes" / "phone.toml"
EXE = Path(sys.executable).parent / "shapedisplay"
TARGET_S = 1.0


def run_once(cmd) -> tuple[float, float]:
    """(wall, cpu) seconds of one run of ``cmd``; cpu = user + system time of the child process."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def row(name, runs, base) -> float:
    wall, cpu = [w for w, _ in runs], [c for _, c in runs]
    lo, med, hi = min(wall), statistics.median(wall), max(wall)
    cmed = statistics.median(cpu)
    print(f"{name:<40} wall min {lo * 1e3:7.1f}  median {med * 1e3:7.1f}  max {hi * 1e3:7.1f} ms"
          f"  ratio {med / base[0]:5.2f} | cpu median {cmed * 1e3:7.1f} ms  ratio {cmed / base[1]:5.2f}", flush=True)
    return med


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7, help="timed runs of each command (at least 5)")
    args = ap.parse_args()
    runs = max(5, args.runs)
    cmds = {
        "baseline: check (no --perception)": [str(EXE), "check", str(SCENE)],
        "check --perception": [str(EXE), "check", str(SCENE), "--perception"],
        "check --perception --json": [str(EXE), "check", str(SCENE), "--perception", "--json"],
    }
    for cmd in cmds.values():
        run_once(cmd)                         # fills the ordinary caches (untimed)
    times = {k: [] for k in cmds}
    for _ in range(runs):
        for k, cmd in cmds.items():
            times[k].append(run_once(cmd))
    print(f"whole process, {runs} runs each; ratio = median / baseline median (wall and CPU separately); "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; target {TARGET_S:g} s")
    names = list(cmds)
    base = (statistics.median(w for w, _ in times[names[0]]), statistics.median(c for _, c in times[names[0]]))
    meds = [row(k, times[k], base) for k in names]
    worst = max(meds[1:])
    print(f"check --perception: median {worst:.3f} s, {'within' if worst <= TARGET_S else 'OVER'} the {TARGET_S:g} s "
          f"target")
    return 0


if __name__ == "__main__":
    sys.exit(main())
