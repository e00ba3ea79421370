"""Start-up cost: ``import shapedisplay`` and ``shapedisplay --help``.

Budget (issue 2): ``import shapedisplay`` loads no trimesh / pyvista /
pyserial / matplotlib; ``shapedisplay --help`` returns within 0.3 s. The
baseline is a bare ``python -c pass`` measured in the same run; ratios are
printed against it. Usage: ``.venv/bin/python benchmarks/bench_import.py``.
"""
import statistics
import subprocess
import sys
import time
from pathlib import Path

HEAVY = ("trimesh", "pyvista", "vtk", "serial", "matplotlib", "scipy")
FORBIDDEN = ("trimesh", "pyvista", "vtk", "serial", "matplotlib")
BUDGET_HELP_S = 0.3
EXE = Path(sys.executable).parent / "shapedisplay"


def timed(cmd, k=7):
    times = []
    for _ in range(k):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def loaded(code):
    probe = code + f"; import sys; print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True).stdout
    return [m for m in out.strip().split(",") if m]


def main() -> int:
    base = timed([sys.executable, "-c", "pass"])
    t_import = timed([sys.executable, "-c", "import shapedisplay"])
    t_help = timed([str(EXE), "--help"])
    t_chelp = timed([str(EXE), "compile", "--help"])
    print(f"python -c pass (baseline)       {base * 1e3:7.1f} ms")
    print(f"import shapedisplay             {t_import * 1e3:7.1f} ms   ratio {t_import / base:.2f}")
    print(f"shapedisplay --help             {t_help * 1e3:7.1f} ms   ratio {t_help / base:.2f}   "
          f"budget {BUDGET_HELP_S * 1e3:.0f} ms")
    print(f"shapedisplay compile --help     {t_chelp * 1e3:7.1f} ms   ratio {t_chelp / base:.2f}")
    ok = t_help <= BUDGET_HELP_S
    for what, code in (("import shapedisplay", "import shapedisplay"),
                       ("CLI parser", "import shapedisplay.cli.main as m; m.build_parser()"),
                       ("authoring modules", "import shapedisplay.author.sources, shapedisplay.author.compile, shapedisplay.exchange.export")):
        mods = loaded(code)
        bad = [m for m in mods if m in FORBIDDEN]
        ok &= not bad
        print(f"{what:<22} loads heavy modules: {mods or 'none'}{'   FORBIDDEN: ' + str(bad) if bad else ''}")
    print("within budget" if ok else "OVER BUDGET")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
