"""Size limits checked before allocating, and what the compiler writes: each hostile file is made here.

Each case: one line from the command (exit 2, no traceback, no numpy
warning), nothing written, and the cost bounded (time, traced memory).
"""
import os
import shutil
import struct
import subprocess
import sys
import time
import tracemalloc
import zlib

import numpy as np
import pytest

from shapedisplay.errors import InputError
from shapedisplay.author.heightfield import MAX_SIDE, check_grid_size
from shapedisplay.cli.main import main


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def one_error_line(err: str) -> str:
    """The whole stderr is one error line: no warning before it, no traceback."""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err and "RuntimeWarning" not in err and "overflow" not in err
    return lines[0]


def grey_png(path, cols: int, rows: int) -> int:
    """An 8-bit grey PNG of ``cols`` x ``rows`` pixels, all 128; the pixel data is deflated in blocks."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    row = b"\0" + b"\x80" * cols
    per_block = max(1, (1 << 21) // len(row))
    deflate, parts, left = zlib.compressobj(9), [], rows
    block = row * per_block
    while left >= per_block:
        parts.append(deflate.compress(block))
        left -= per_block
    parts.append(deflate.compress(row * left) + deflate.flush())
    ihdr = struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", b"".join(parts)) + chunk(b"IEND", b"")
    path.write_bytes(data)
    return len(data)


# ----------------------------------------------------------- 1. picture sides
def test_grid_side_limit_is_one_rule():
    check_grid_size(MAX_SIDE, 1, "profile")
    check_grid_size(1, MAX_SIDE, "profile")
    for rows, cols in ((MAX_SIDE + 1, 1), (1, MAX_SIDE + 1)):
        with pytest.raises(InputError, match=rf"side of {MAX_SIDE + 1} samples, beyond the limit of {MAX_SIDE} a "
                                             rf"side \(aspect ratio at most {MAX_SIDE}:1; "
                                             rf"shapedisplay.author.heightfield.MAX_SIDE\); crop it"):
            check_grid_size(rows, cols, "profile", "crop it")


def test_picture_of_1_x_100_million_pixels_is_refused_from_its_header(tmp_path, capsys):
    """194 KB of PNG, under Pillow's bomb limit: once 58 s and 7.5 GB, then MemoryError."""
    src, out = tmp_path / "tall.png", tmp_path / "t.npz"
    size = grey_png(src, 1, 100_000_000)
    assert size < 400_000
    tracemalloc.start()
    t0 = time.perf_counter()
    code, _, err = run(["compile", src, "-o", out, "--size", "60x4mm", "--height", "0:2mm"], capsys)
    elapsed = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    line = one_error_line(err)
    assert code == 2 and not out.exists()
    assert line == (f"shapedisplay compile: error: image '{src}': grid of 1 x 100000000 samples has a side of "
                    f"100000000 samples, beyond the limit of 65536 a side (aspect ratio at most 65536:1; "
                    f"shapedisplay.author.heightfield.MAX_SIDE); crop or resample the picture")
    assert peak < 50 * 2**20 and elapsed < 10


def test_picture_at_the_side_limit_compiles_with_its_row_stored_once(tmp_path, capsys):
    src, out = tmp_path / "tall.png", tmp_path / "t.npz"
    grey_png(src, 1, MAX_SIDE)
    t0 = time.perf_counter()
    code, _, err = run(["compile", src, "-o", out, "--size", "60x4mm", "--height", "0:2mm", "-q"], capsys)
    assert code == 0 and not err
    assert time.perf_counter() - t0 < 15          # one patch per row: 5 s before
    from shapedisplay.table.model import FrictionTable
    t = FrictionTable.load(out)
    assert t.patch_shapes == [(1, 1)] and len(t.blocks) == MAX_SIDE


# ----------------------------------------------------------- 5. durable writes
@pytest.mark.skipif(shutil.which("strace") is None or not sys.platform.startswith("linux"), reason="needs strace")
def test_compile_flushes_the_table_before_the_rename_and_the_folder_after(tmp_path):
    import re
    src, out, log = tmp_path / "map.png", tmp_path / "t.npz", tmp_path / "strace.txt"
    grey_png(src, 64, 48)
    cmd = ["strace", "-f", "-qq", "-o", str(log), "-e", "trace=openat,open,fsync,fdatasync,rename,renameat,renameat2",
           sys.executable, "-m", "shapedisplay", "compile", str(src), "-o", str(out), "--size", "60x40mm",
           "--height", "0:2mm", "-q"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    if done.returncode != 0 and "ptrace" in done.stderr:
        pytest.skip(f"strace cannot trace here: {done.stderr.strip()}")
    assert done.returncode == 0, done.stderr
    calls = log.read_text().splitlines()
    part = re.compile(r'open(?:at)?\(.*"(?P<name>[^"]*/\.t\.[^"/]*\.part\.npz)".*O_EXCL.*\) = (?P<fd>\d+)')  # mkstemp
    opened = [(i, m) for i, line in enumerate(calls) if (m := part.search(line))]
    assert opened, "\n".join(calls[-20:])
    at, m = opened[-1]
    fd, name = m["fd"], m["name"]
    renamed = next(i for i, line in enumerate(calls) if "rename" in line and f'"{name}"' in line and f'"{out}"' in line)
    assert any(re.search(rf"\b(fsync|fdatasync)\({fd}\)\s+= 0", line) for line in calls[at:renamed]), calls[at:renamed]
    folder = re.compile(rf'open(?:at)?\(.*"{re.escape(str(tmp_path))}/?".*O_DIRECTORY.*\) = (\d+)')
    after = calls[renamed:]
    dirs = [m.group(1) for line in after if (m := folder.search(line))]
    assert dirs and any(re.search(rf"\bfsync\({d}\)\s+= 0", line) for line in after for d in dirs), after
    assert out.stat().st_size > 0 and not [p for p in tmp_path.iterdir() if ".part" in p.name]
