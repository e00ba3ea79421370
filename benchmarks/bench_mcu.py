"""Instructions per renderer tick on a Cortex-M4F (QEMU mps2-an386, -icount), with RAM and flash.

Builds the bare-metal harness (`make -C runtime-c m4`: the single-precision build, sd_real = float, as the
M4F's FPU; and M4_PRECISION=double for comparison), plays a 2-D table with six channels
(normal force, friction scale, burst gain, grad x/y, lateral x; two widgets, 0.5 mm samples)
along a diagonal stroke, and counts the instructions of every `sd_renderer_step` call with
SysTick under QEMU's instruction counting (-icount shift=6: 1.6 counts per instruction; the
measurement's own cost subtracted). One line per configuration:

    instructions per tick: mean M max X (model, policy, tick rate, audio rate)

Budget of the target: a 168 MHz core at 10 kHz ticks has 16 800 cycles per tick; the aim is
half of it. Instructions are not cycles (a Cortex-M4 takes 1-3 cycles per instruction, more
for divisions and flash wait states), so read these as a lower bound of the cycles.
Needs arm-none-eabi-gcc, newlib and qemu-system-arm (scripts/install-system-deps.sh --with-toolchains).

Run: ``.venv/bin/python benchmarks/bench_mcu.py [--quick]``.
"""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_c_runtime import library_sources  # noqa: E402
from runtime_vectors import build_m4, case_setup, image_payload, m4_instructions, run_m4  # noqa: E402

# (model, policy, tick rate, audio rate, stroke seconds: shorter where a tick costs millions)
CONFIGS = [
    ("jump", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("exact", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("jump", "add", 10_000.0, 48_000.0, 0.05),
    ("jump", "max", 10_000.0, 48_000.0, 0.05),
    ("jump", "retrigger", 1_000.0, 48_000.0, 0.25),
]


def runtime_footprint(src: Path, precision: str, defs=()) -> tuple[int, int]:
    """Flash (text + rodata) of the runtime's own object files, and sizeof(sd_renderer_t), for one build."""
    import re
    import subprocess
    flags = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard", "-std=c99", "-O2",
             "-ffp-contract=off", *(["-DSD_SINGLE"] if precision == "single" else []), *defs]
    text = 0
    for path in library_sources():
        name = Path(path).name
        obj = src / (name + f".{precision}.o")
        subprocess.run(["arm-none-eabi-gcc", *flags, "-c", str(src / name), "-o", str(obj)], check=True)
        out = subprocess.run(["arm-none-eabi-size", str(obj)], capture_output=True, text=True, check=True).stdout
        text += int(out.splitlines()[-1].split()[0])
    probe = src / f"probe_{precision}.c"
    probe.write_text('#include "sd_runtime.h"\nchar sd_size_probe[sizeof(sd_renderer_t)];\n')
    obj = src / f"probe_{precision}.o"
    subprocess.run(["arm-none-eabi-gcc", *flags, "-fno-common", "-c", str(probe), "-o", str(obj)], check=True)
    out = subprocess.run(["arm-none-eabi-nm", "-S", str(obj)], capture_output=True, text=True, check=True).stdout
    size = int(re.search(r"^\S+ (\S+) \w sd_size_probe", out, re.M).group(1), 16)
    return text, size


def main() -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="single precision only, the jump and exact lines")
    quick = ap.parse_args().quick
    missing = [t for t in ("arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]
    if missing:
        print(f"bench_mcu: needs {missing} (scripts/install-system-deps.sh --with-toolchains)")
        return 2
    small = ("-DSD_EVENT_RING=128", "-DSD_AUDIO_BLOCK_MAX=16")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        precisions = ("single",) if quick else ("single", "double")
        for precision in precisions:
            for label, defs in (("default", ()), ("small-RAM", small)):
                elf, (text, data, bss) = build_m4(tmp / f"{precision}-{label}", defs, precision)
                code, ram = runtime_footprint(elf.parent.parent, precision, defs)
                print(f"{precision} precision, {label} build: runtime code {code} B flash, sd_renderer_t {ram} B RAM; "
                      f"whole harness with libm: flash (text) {text} B, data {data} B")
        builds = {p: build_m4(tmp / f"run-{p}", (), p)[0] for p in precisions}
        tmp_run = tmp / "io"
        tmp_run.mkdir()
        # the single-precision build (the M4F's) first: one line per configuration
        for model, policy, tick, audio, seconds in CONFIGS[:2] if quick else CONFIGS:
            table, r, x, y, img = case_setup("uint16", "diagonal", policy, tick, audio, model, seconds=seconds)
            ins = m4_instructions(run_m4(builds["single"], "bench", image_payload(img, r, x, y), tmp_run, icount=True))
            print(f"instructions per tick: mean {ins.mean():.0f} max {ins.max():.0f} "
                  f"({model}, {policy}, {tick / 1000:g} kHz tick, {audio / 1000:g} kHz audio)"
                  f"  median {np.median(ins):.0f}, {ins.size} ticks, mean = {ins.mean() / 16800:.2f} x the 16.8k "
                  f"budget, single precision")
        # the double build, for comparison (the M4F emulates double arithmetic in software)
        for model, policy, tick, audio, seconds in () if quick else CONFIGS[:2]:
            table, r, x, y, img = case_setup("uint16", "diagonal", policy, tick, audio, model, seconds=seconds)
            d_ins = m4_instructions(run_m4(builds["double"], "bench", image_payload(img, r, x, y), tmp_run,
                                           icount=True))
            s_ins = m4_instructions(run_m4(builds["single"], "bench", image_payload(img, r, x, y), tmp_run,
                                           icount=True))
            print(f"double build, same stroke: mean {d_ins.mean():.0f} max {d_ins.max():.0f} ({model}, {policy}, "
                  f"{tick / 1000:g} kHz tick, {audio / 1000:g} kHz audio): single precision is "
                  f"{d_ins.mean() / s_ins.mean():.1f}x fewer instructions on average, {d_ins.max() / s_ins.max():.1f}x "
                  f"at the worst tick")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
