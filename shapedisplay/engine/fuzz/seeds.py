"""Seed corpus of fuzz_engine.c: each table image given, wrapped in the harness's control block.

    python seeds.py OUT_DIR IMAGE.sdt...

The images come from `shapedisplay export TABLE --format bin` (the Makefile's fuzz-seeds rule
makes them from the scenes in assets/); per image a few runs: the models with a C tick in
turn, each burst policy, a stroke across the table (cursor mode 0) and one with jumps over
+-1 km (mode 1). The images' meta sections (the table's JSON header, which the C loader
does not read) are cut off, so that each run spends its time on what the engine reads.
Standard library only.
"""
import math
import struct
import sys
import zlib
from pathlib import Path

TICKS = 200


def stroke(mode: int, press: bool = False) -> bytes:
    """TICKS (x, y) int16 pairs: a diagonal sweep with a circle on it (mode 0, in table units:
    +-32767 spans the table and half its size around it) or jumps of up to 1 km (mode 1); with ``press``
    each pair is followed by a press byte (0.02 N per unit): pressed firmly every other 40 ticks."""
    out = bytearray()
    for k in range(TICKS):
        if mode == 0:
            u = -0.8 + 1.6 * k / TICKS
            x, y = u + 0.1 * math.cos(0.3 * k), u + 0.1 * math.sin(0.3 * k)
        else:
            x, y = math.sin(1.7 * k) ** 3, math.cos(2.3 * k) ** 5
        out += struct.pack("<hh", int(32767 * max(-1.0, min(1.0, x))), int(32767 * max(-1.0, min(1.0, y))))
        if press:
            out.append(150 if (k // 40) % 2 else 0)
    return bytes(out)


def without_meta(data: bytes) -> bytes:
    """The image with an empty meta section (the last before the CRC; a version 2 image's reaction section
    comes before it and stays), size field and CRC made right."""
    (meta_off,) = struct.unpack_from("<I", data, 556)
    body = bytearray(data[:meta_off + (-meta_off) % 4])
    struct.pack_into("<I", body, 60, 0)
    struct.pack_into("<I", body, 8, len(body) + 4)
    return bytes(body) + struct.pack("<I", zlib.crc32(bytes(body)) & 0xFFFFFFFF)


def main(out_dir: str, images: list[str]) -> None:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # (flags, model, policy, cursor mode); flags 4: a press per tick (reactive widgets)
    runs = [(0, 0, 0, 0), (0, 1, 1, 0), (0, 2, 2, 0), (2, 0, 0, 1), (4, 1, 0, 0)]
    for image in images:
        data = without_meta(Path(image).read_bytes())
        for flags, model, policy, mode in runs:
            head = struct.pack("<BBBBHHII", flags, model, policy, mode, TICKS, 0, len(data), 0)
            (out / f"{Path(image).stem}-m{model}-p{policy}-c{mode}-f{flags}").write_bytes(
                head + data + stroke(mode, press=bool(flags & 4)))


if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2:])
