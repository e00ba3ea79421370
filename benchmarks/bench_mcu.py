"""Instructions per renderer tick on a Cortex-M4F (QEMU mps2-an386, -icount), with RAM and flash.

Builds the bare-metal harness (`make -C runtime-c m4`), plays a 2-D table with six channels
(normal force, friction scale, burst gain, grad x/y, lateral x; two widgets, 0.5 mm samples)
along a diagonal stroke, and counts the instructions of every `sd_renderer_step` call with
SysTick under QEMU's instruction counting (-icount shift=6: 1.6 counts per instruction; the
measurement's own cost subtracted). One line per configuration:

    instructions per tick: mean M max X (model, policy, tick rate, audio rate)

Budget of the target: a 168 MHz core at 10 kHz ticks has 16 800 cycles per tick; the aim is
half of it. Instructions are not cycles (a Cortex-M4 takes 1-3 cycles per instruction, more
for divisions and flash wait states), so read these as a lower bound of the cycles.
Needs arm-none-eabi-gcc, newlib and qemu-system-arm (scripts/install-system-deps.sh --with-toolchains).
"""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from runtime_vectors import build_m4, case_setup, image_payload, m4_instructions, run_m4  # noqa: E402

# (model, policy, tick rate, audio rate, stroke seconds: shorter where a tick costs millions)
CONFIGS = [
    ("jump", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("exact", "retrigger", 10_000.0, 48_000.0, 0.25),
    ("jump", "add", 10_000.0, 48_000.0, 0.05),
    ("jump", "max", 10_000.0, 48_000.0, 0.05),
    ("jump", "retrigger", 1_000.0, 48_000.0, 0.25),
]


def main() -> int:
    missing = [t for t in ("arm-none-eabi-gcc", "qemu-system-arm") if shutil.which(t) is None]
    if missing:
        print(f"bench_mcu: needs {missing} (scripts/install-system-deps.sh --with-toolchains)")
        return 2
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for label, defs in (("default", ()), ("small-RAM", ("-DSD_EVENT_RING=128", "-DSD_AUDIO_BLOCK_MAX=16"))):
            elf, (text, data, bss) = build_m4(tmp / label, defs)
            print(f"{label} build: flash (text) {text} B, data {data} B (the harness's 1 MB input buffer and "
                  f"64k-sample audio log are in bss: {bss} B total)")
        elf, _ = build_m4(tmp / "run")
        for model, policy, tick, audio, seconds in CONFIGS:
            table, r, x, y, img = case_setup("uint16", "diagonal", policy, tick, audio, model, seconds=seconds)
            ins = m4_instructions(run_m4(elf, "bench", image_payload(img, r, x, y), tmp, icount=True))
            print(f"instructions per tick: mean {ins.mean():.0f} max {ins.max():.0f} "
                  f"({model}, {policy}, {tick / 1000:g} kHz tick, {audio / 1000:g} kHz audio)"
                  f"  median {np.median(ins):.0f}, {ins.size} ticks, mean = {ins.mean() / 16800:.2f} x the 16.8k "
                  f"budget")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
