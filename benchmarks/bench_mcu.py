"""Instructions per renderer tick on a Cortex-M4F (QEMU mps2-an386, -icount), with RAM and flash.

Builds the bare-metal harness (`make -C engine m4`: the single-precision build, sd_real = float, as the
M4F's FPU; and M4_PRECISION=double for comparison), plays a 2-D table with six channels
(normal force, friction scale, burst gain, grad x/y, lateral x; two widgets, 0.5 mm samples)
along a diagonal stroke, and counts the instructions of every `sd_renderer_step` call with
SysTick under QEMU's instruction counting (-icount shift=6: 1.6 counts per instruction; the
measurement's own cost subtracted). One line per configuration:

    instructions per tick: mean M max X (model, policy, tick rate, audio rate)

and one with reactions active (the bundled reactive scene played with a press per tick:
runtime_vectors.REACT_BENCH):

    reactions active: instructions per tick mean M median D max X (...)

karnopp and stribeck take pad parameters the binary table image does not carry, so they are played
the way firmware binds a table: the table exported as a C header (`export_c(table, "sd_table.h",
name="sd_table")`), `sd_table_bind()` then `sd_table_use_model()` (the parameters the package derives
for each model from the table's device), the same stroke compiled into a small harness
(HEADER_BENCH_C) that counts every `sd_renderer_step` the same way; jump is played that way too,
to show that both routes count alike. One line per model:

    header route: instructions per tick mean M median D max X (model, ...)

Budget of the target: a 168 MHz core at 10 kHz ticks has 16 800 cycles per tick; the aim is
half of it. Instructions are not cycles (a Cortex-M4 takes 1-3 cycles per instruction, more
for divisions and flash wait states), so read these as a lower bound of the cycles.
Needs arm-none-eabi-gcc, newlib and qemu-system-arm (scripts/install-system-deps.sh --with-toolchains).

Instruction counts under -icount are deterministic: one run per line.

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

from bench_c_runtime import CDIR, library_sources  # noqa: E402
from runtime_vectors import (ICOUNT_SHIFT, QEMU_M4, REACT_BENCH, build_m4, case_setup, image_payload,  # noqa: E402
                             m4_instructions, react_payload, react_setup, run_m4)
from shapedisplay.exchange.export import export_c  # noqa: E402

# (model, policy, tick rate, audio rate, stroke seconds: shorter where a tick costs millions)
CONFIGS = [
    ("jump", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("exact", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("jump", "add", 10_000.0, 48_000.0, 0.05),
    ("jump", "max", 10_000.0, 48_000.0, 0.05),
    ("jump", "retrigger", 1_000.0, 48_000.0, 0.25),
]
# the models played from the C header export (model, policy, tick rate, audio rate, stroke seconds)
HEADER_CONFIGS = [
    ("jump", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("karnopp", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("stribeck", "retrigger", 10_000.0, 48_000.0, 0.25),
]
BUDGET = 16_800           # cycles of a 10 kHz tick at 168 MHz

# The header route: the table and the model's pad parameters from sd_table.h, the stroke compiled in (as
# sd_real, converted outside the count), SysTick counts of every sd_renderer_step, then the count of an
# empty measurement, written to the file named by the first semihosting argument after the program's.
HEADER_BENCH_C = r"""
#include <string.h>
#include "sd_runtime.h"
#include "m4/m4.h"
#include "sd_table.h"
#define N %(n)d
static const sd_real XS[N] = {%(xs)s};
static const sd_real YS[N] = {%(ys)s};
static uint32_t counts[N + 1];
static sd_renderer_t R;
static int32_t blocks[SD_TABLE_N_BLOCKS][5];
int main(void)
{
    static char cmd[256];
    char *out = cmd;
    sd_table_t T;
    sd_config_t C;
    int32_t fd;
    long i;
    sd_table_bind(&T, &C, blocks);
    if (sd_table_use_model(&C, %(model)s) != 0) return 5;
    C.policy = %(policy)d;
    C.tick_rate = (sd_real)%(tick)r;
    C.audio_rate = (sd_real)%(audio)r;
    if (sd_renderer_init(&R, &T, &C) != SD_OK) return 3;
    if (m4_cmdline(cmd, sizeof cmd) != 0) return 2;
    while (*out && *out != ' ') out++;          /* argv[1]: the output file */
    while (*out == ' ') out++;
    for (i = 0; i < N; i++) {
        m4_count_start();
        sd_renderer_step(&R, XS[i], YS[i]);
        counts[i] = m4_count_read();
    }
    m4_count_start();
    counts[N] = m4_count_read();
    fd = m4_open(out, 1);
    if (fd < 0) return 2;
    m4_write(fd, counts, 4 * (N + 1));
    m4_close(fd);
    return 0;
}
"""


def header_instructions(tmp: Path, table, model: str, r, x, y) -> np.ndarray:
    """Instructions per sd_renderer_step on the M4F (single precision), the table and ``model``'s pad
    parameters bound from the C header export; ``r`` gives the policy and rates, ``x``, ``y`` the stroke (m)."""
    import subprocess
    tmp.mkdir(parents=True, exist_ok=True)
    export_c(table, tmp / "sd_table.h", name="sd_table")
    src = tmp / "bench_header.c"
    src.write_text(HEADER_BENCH_C % dict(n=len(x), xs=", ".join(f"(sd_real){v!r}" for v in map(float, x)),
                                         ys=", ".join(f"(sd_real){v!r}" for v in map(float, y)),
                                         model=f"SD_MODEL_{model.upper()}", policy=int(r.config["policy"]),
                                         tick=float(r.tick_rate), audio=float(r.audio_rate)))
    elf = tmp / "bench_header.elf"
    cmd = ["arm-none-eabi-gcc", "-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard",
           "--specs=nano.specs", "-nostartfiles", "-std=c99", "-O2", "-ffp-contract=off", "-DSD_SINGLE",
           "-I", str(CDIR), "-I", str(tmp), "-T", str(CDIR / "m4" / "mps2.ld"), str(CDIR / "m4" / "startup.c"),
           str(src), *library_sources(), "-lm", "-o", str(elf)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if res.returncode != 0:
        raise RuntimeError(f"building the header harness failed:\n{res.stderr[-2000:]}")
    fout = tmp / "counts.bin"
    res = subprocess.run([*QEMU_M4, "-icount", f"shift={ICOUNT_SHIFT}", "-semihosting-config",
                          f"enable=on,target=native,arg=bench,arg={fout}", "-kernel", str(elf)],
                         capture_output=True, text=True, timeout=600)
    if res.returncode != 0:
        why = " (the header carries no parameters for this model)" if res.returncode == 5 else ""
        raise RuntimeError(f"the header harness exited with {res.returncode}{why}: {res.stderr[-500:]}")
    return m4_instructions(fout.read_bytes())


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
    small = ("-DSD_EVENT_RING=128", "-DSD_AUDIO_BLOCK_MAX=16", "-DSD_MAX_REACTIVE=8", "-DSD_REACT_QUEUE=16")
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
                  f"  median {np.median(ins):.0f}, {ins.size} ticks, mean = {ins.mean() / BUDGET:.2f} x the 16.8k "
                  f"budget, single precision")
        # reactions active (docs/reactive.md): the bundled reactive scene with a press per tick -- a button pressed,
        # a toggle flipped, a slider's thumb dragged across its detents, an object dragged, a list scrolling
        table, r, x, y, press, img = react_setup("bench", REACT_BENCH, "jump", 10_000.0, 48_000.0)
        ins = m4_instructions(run_m4(builds["single"], "react-bench", react_payload(img, r, x, y, press), tmp_run,
                                     icount=True))
        print(f"reactions active: instructions per tick mean {ins.mean():.0f} median {np.median(ins):.0f} "
              f"max {ins.max():.0f} (jump, retrigger, 10 kHz tick, 48 kHz audio, assets/scenes/reactive.toml)  "
              f"{ins.size} ticks, mean = {ins.mean() / BUDGET:.2f} x the 16.8k budget, single precision")
        # karnopp and stribeck (and jump, to compare the routes) bound from the C header export
        for model, policy, tick, audio, seconds in HEADER_CONFIGS:
            table, r, x, y, img = case_setup("uint16", "diagonal", policy, tick, audio, model, seconds=seconds)
            ins = header_instructions(tmp / f"header-{model}", table, model, r, x, y)
            print(f"header route: instructions per tick mean {ins.mean():.0f} median {np.median(ins):.0f} "
                  f"max {ins.max():.0f} ({model}, {policy}, {tick / 1000:g} kHz tick, {audio / 1000:g} kHz audio)"
                  f"  {ins.size} ticks, mean = {ins.mean() / BUDGET:.2f} x, worst tick = {ins.max() / BUDGET:.2f} x "
                  f"the 16.8k budget, single precision")
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
