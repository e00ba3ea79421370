"""Whole-process start-up: ``shapedisplay --help`` and a warm ``play`` of a 5 s stroke.

Targets: ``shapedisplay --help`` <= 0.1 s and a warm ``play`` of a 5 s stroke
<= 0.3 s, each measured as a whole process. The baseline is
``python -c "import shapedisplay"`` measured in the same run; every figure is
min/median/max over the runs and its median is printed as a ratio against the
baseline median.

The table is compiled from the bundled phone scene into a temporary directory;
one untimed ``play`` fills the kernel cache first, so the timed runs are warm.

Usage: ``.venv/bin/python benchmarks/bench_startup.py [--runs N]``.
"""
import argparse
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
TARGET_HELP_S = 0.1
TARGET_PLAY_S = 0.3


def timed(cmd, runs, cwd=None):
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return times


def row(name, times, base_median, target=None):
    lo, med, hi = min(times), statistics.median(times), max(times)
    line = (f"{name:<38} min {lo * 1e3:7.1f}  median {med * 1e3:7.1f}  max {hi * 1e3:7.1f} ms"
            f"   ratio {med / base_median:5.2f}")
    if target is not None:
        line += f"   target {target * 1e3:.0f} ms {'met' if med <= target else 'NOT met'}"
    print(line)
    return med


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7, help="timed runs per command (at least 5)")
    args = ap.parse_args()
    runs = max(5, args.runs)
    with tempfile.TemporaryDirectory() as tmp:
        table = Path(tmp) / "phone.npz"
        subprocess.run([str(EXE), "compile", str(SCENE), "-o", str(table)], check=True,
                       stdout=subprocess.DEVNULL)
        play = [str(EXE), "play", str(table), "--stroke", STROKE, "-o", str(Path(tmp) / "out.wav")]
        subprocess.run(play, check=True, stdout=subprocess.DEVNULL)  # fills the kernel cache (untimed)
        base = timed([sys.executable, "-c", "import shapedisplay"], runs)
        t_help = timed([str(EXE), "--help"], runs)
        t_play = timed(play, runs)
    print(f"{runs} runs each, whole process; ratio = median / baseline median")
    base_med = row('python -c "import shapedisplay"', base, statistics.median(base))
    row("shapedisplay --help", t_help, base_med, TARGET_HELP_S)
    row("shapedisplay play (5 s stroke, warm)", t_play, base_med, TARGET_PLAY_S)
    return 0


if __name__ == "__main__":
    sys.exit(main())
