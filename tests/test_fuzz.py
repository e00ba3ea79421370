"""Fuzzing in the suite: 10,000 table mutations and 2,000 malformed command lines, scenes, strokes and traces.

Everything runs in-process (a small sample goes through the real command).
Each case must end in one of two ways: accepted, and then everything about
it is finite and it plays and exports; or refused with ShapeDisplayError
(exit 2 and one line from the command). Anything else fails the test with
the case that caused it. Memory is measured per case with tracemalloc and
bounded by ``CASE_MEMORY_BOUND``; no file changes except a command's
intended output.
"""
from __future__ import annotations

import copy
import io
import json
import math
import os
import random
import struct
import subprocess
import sys
import time
import tracemalloc
import zipfile
import zlib
from pathlib import Path

import numpy as np
import pytest

from hostile import documented_checksum, npy_bytes, npz_bytes, small_table, table_bytes, zip_of
from shapedisplay.errors import ShapeDisplayError
from shapedisplay.table.model import FrictionTable

ROOT = Path(__file__).resolve().parent.parent
SEED = 20261123
#: Most memory (tracemalloc peak) reading or refusing one case may use. The table is 60 samples;
#: a bomb that got through the caps would show up here as hundreds of MB. (What an accepted
#: table costs to play and export afterwards is not the reader's and is not counted.)
CASE_MEMORY_BOUND = 16 << 20
N_FLIPS, N_TRUNC, N_ZIP, N_HEADER, N_IMAGE = 3000, 1000, 2000, 3000, 1000
HOSTILE_VALUES = [float("nan"), float("inf"), -float("inf"), -1, 0, -0.0, 1e308, -1e308, 10 ** 30, 2 ** 64,
                  "x", "", True, False, None, [], {}, [1, 2], [[[[[[]]]]]], {"a": 1}, 1e-320, 0.5, 7]


class Tally:
    def __init__(self):
        self.tried = self.rejected = self.accepted = 0
        self.peak = 0
        self.peak_case = ""
        self.kinds: dict[str, list[int]] = {}

    def line(self, what: str) -> str:
        return (f"{what}: {self.tried} tried, {self.rejected} rejected with ShapeDisplayError, {self.accepted} "
                f"accepted (each checked: finite values, and a table plays and exports); worst case peak {self.peak / 2**20:.2f} MB "
                f"({self.peak_case})")


def _run_case(tally: Tally, kind: str, label: str, read, accept, allowance=lambda result: 0):
    """Run one case under tracemalloc; only ShapeDisplayError may escape ``read``."""
    tally.tried += 1
    k = tally.kinds.setdefault(kind, [0, 0])
    k[0] += 1
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    result = None
    try:
        result = read()
    except ShapeDisplayError as exc:
        assert "\n" not in str(exc), (label, str(exc))
        tally.rejected += 1
    except Exception as exc:  # noqa: BLE001 - this is what the test looks for
        raise AssertionError(f"{label}: {type(exc).__name__}: {exc}") from exc
    peak = tracemalloc.get_traced_memory()[1] - base       # what reading (or refusing) cost
    if peak > tally.peak:
        tally.peak, tally.peak_case = peak, label
    bound = CASE_MEMORY_BOUND + (allowance(result) if result is not None else 0)
    assert peak < bound, (label, peak, bound)
    if result is not None:
        tally.accepted += 1
        k[1] += 1
        accept(result, label)


# ------------------------------------------------------------------ what an accepted table must do
def _check_accepted_table(t: FrictionTable, label: str) -> None:
    from shapedisplay.render.renderer import Renderer
    for name in t.channels:
        assert np.isfinite(t.dense(name)).all(), (label, name)
    text = json.dumps(t.to_json(), allow_nan=False)          # export --format json must not fail later
    assert text and json.dumps(t.summary(), allow_nan=False)
    try:
        r = Renderer(t, model="jump")
    except ShapeDisplayError:
        return                                               # a clear refusal is fine
    g = t.grid
    xs = g.x0 + np.linspace(0, max(g.cols - 1, 1) * g.dx, 40)
    for x in xs:
        r.step(float(x), g.y0)
        assert all(math.isfinite(v) for v in r.outputs().values()), label


# ------------------------------------------------------------------ mutators
def _flip(rng, data: bytes) -> bytes:
    b = bytearray(data)
    for _ in range(rng.choice((1, 1, 1, 2, 4))):
        i = rng.randrange(len(b))
        b[i] ^= rng.randrange(1, 256)
    return bytes(b)


def _truncate(rng, data: bytes) -> bytes:
    if rng.random() < 0.2:
        return data + bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64)))
    return data[:rng.randrange(len(data))]


def _records(data: bytes, sig: bytes):
    pos = data.find(sig)
    while pos >= 0:
        yield pos
        pos = data.find(sig, pos + 4)


# central directory record fields: (offset, struct format)
_CD_FIELDS = [(4, "<H"), (6, "<H"), (8, "<H"), (10, "<H"), (16, "<I"), (20, "<I"), (24, "<I"), (28, "<H"),
              (30, "<H"), (32, "<H"), (38, "<I"), (42, "<I")]
_LH_FIELDS = [(4, "<H"), (6, "<H"), (8, "<H"), (14, "<I"), (18, "<I"), (22, "<I"), (26, "<H"), (28, "<H")]
_EOCD_FIELDS = [(4, "<H"), (6, "<H"), (8, "<H"), (10, "<H"), (12, "<I"), (16, "<I"), (20, "<H")]


def _zip_edit(rng, data: bytes, arrays: dict, header_npy: bytes) -> bytes:
    choice = rng.randrange(10)
    if choice < 7:
        sig, fields = [(b"PK\x01\x02", _CD_FIELDS), (b"PK\x03\x04", _LH_FIELDS),
                       (b"PK\x05\x06", _EOCD_FIELDS)][min(choice // 3, 2)]
        spots = list(_records(data, sig))
        if not spots:
            return data
        at = rng.choice(spots)
        off, fmt = rng.choice(fields)
        size = struct.calcsize(fmt)
        if at + off + size > len(data):
            return data
        (old,) = struct.unpack_from(fmt, data, at + off)
        top = (1 << (8 * size)) - 1
        new = rng.choice([0, 1, top, old + 1, max(old - 1, 0), rng.randrange(top + 1), 99, 8, 12, 14,
                          0x1, 0x8, 0x41])
        b = bytearray(data)
        struct.pack_into(fmt, b, at + off, min(new, top))
        return bytes(b)
    entries = [("header.npy", header_npy)] + [(f"{n}.npy", npy_bytes(a)) for n, a in arrays.items()]
    if choice == 7:        # duplicate or extra entry
        extra = rng.choice([entries[rng.randrange(len(entries))], ("evil.npy", npy_bytes(np.zeros(3))),
                            ("../x.npy", b"x"), ("normal_force", b"")])
        entries.insert(rng.randrange(len(entries) + 1), extra)
    elif choice == 8:      # an entry missing or renamed
        i = rng.randrange(len(entries))
        if rng.random() < 0.5:
            del entries[i]
        else:
            entries[i] = (rng.choice(["NORMAL_FORCE.npy", "header", "h.npy", "grad_x.npy", "x" * 300 + ".npy"]),
                          entries[i][1])
    else:                  # an entry's .npy header edited
        i = rng.randrange(len(entries))
        name, raw = entries[i]
        hl = int.from_bytes(raw[8:10], "little")
        text = raw[10:10 + hl]
        pos = rng.randrange(len(text))
        text = text[:pos] + bytes([rng.choice(b"(),:'<>|01234567fiuU {}[]\x00")]) + text[pos + 1:]
        entries[i] = (name, raw[:10] + text + raw[10 + hl:])
    method = rng.choice([zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED])
    return zip_of(entries, method)


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, prefix + (i,))


def _header_edit(rng, header: dict, arrays: dict) -> bytes:
    h = copy.deepcopy(header)
    arrays = {n: np.array(a) for n, a in arrays.items()}
    kind = rng.randrange(10)
    if kind < 7:
        paths = [p for p in _paths(h) if p and p[0] != "checksum"]
        path = rng.choice(paths)
        parent = h
        for key in path[:-1]:
            parent = parent[key]
        last = path[-1]
        if kind == 0 and isinstance(parent, dict):
            del parent[last]
        elif kind == 1 and isinstance(parent, dict):
            parent[rng.choice(["extra", "_", "\u00e9", "x" * 50])] = rng.choice(HOSTILE_VALUES)
        else:
            parent[last] = copy.deepcopy(rng.choice(HOSTILE_VALUES))
    elif kind == 7:        # non-finite values in a float channel
        name = rng.choice([n for n, a in arrays.items() if a.dtype.kind == "f"] or list(arrays))
        a = arrays[name].astype(np.float32) if arrays[name].dtype.kind != "f" else arrays[name]
        a[rng.randrange(a.size)] = rng.choice([np.nan, np.inf, -np.inf, 3e38])
        arrays[name] = a
    elif kind == 8:        # dtype or shape of an array
        name = rng.choice(list(arrays))
        a = arrays[name]
        arrays[name] = rng.choice([a.astype(np.float64), a.astype(np.uint16), a.astype(np.int8), a[:-1],
                                   np.concatenate([a, a]), a.reshape(1, -1), a.astype(">f4"), a[:0]])
    else:                  # grid, patches and blocks with hostile sizes
        h["grid"][rng.choice(["rows", "cols"])] = rng.choice([0, -1, 2 ** 31, 2 ** 64, 16384, 1])
        if rng.random() < 0.5:
            h["patches"] = [[rng.choice([0, 1, 6, 10, 2 ** 40]), rng.choice([0, 10, 2 ** 40])]]
    h.pop("checksum", None)
    try:
        h["checksum"] = documented_checksum(h, arrays)
        return npz_bytes(h, arrays)
    except (ValueError, TypeError, OverflowError):  # a value JSON cannot write: fall back to raw text
        text = json.dumps(h, default=str)
        return npz_bytes(h, arrays, header_text=text)


def _image_edit(rng, image: bytes) -> bytes:
    b = bytearray(image)
    kind = rng.randrange(4)
    if kind == 0:                     # one field of the fixed header set to a hostile value
        off = 8 * rng.randrange(1, 560 // 8)
        struct.pack_into("<Q", b, off, rng.choice([0, 1, 2 ** 63, 2 ** 64 - 1, 2 ** 31, 0x7FF8000000000000,
                                                    0x7FF0000000000000]))
    elif kind == 1:
        for _ in range(rng.choice((1, 2, 8))):
            i = rng.randrange(len(b) - 4)
            b[i] ^= rng.randrange(1, 256)
    elif kind == 2:
        cut = rng.randrange(16, len(b) - 4)
        b = b[:cut] + b[-4:]
        struct.pack_into("<I", b, 12, len(b))
    else:                             # the meta JSON replaced by something hostile of the same length
        pos = image.find(b'{"blocks"')
        if pos > 0:
            junk = rng.choice([b"[" * 64, b"NaN", b'{"a": 1e999}', b"\xff\xfe", b"{}"])
            b[pos:pos + len(junk)] = junk
    struct.pack_into("<I", b, len(b) - 4, zlib.crc32(bytes(b[:-4])) & 0xFFFFFFFF)   # CRC by the documented rule
    return bytes(b)


# ------------------------------------------------------------------ the 10,000 table mutations
#: Most the fuzz process's resident set may grow over the 10,000 table mutations, MB (a single
#: bomb getting through the caps would inflate hundreds of MB).
TABLE_FUZZ_RSS_GROWTH_BOUND_MB = 64


def run_table_fuzz(seed: int = SEED) -> dict:
    """The 10,000 table mutations, in this process; returns the counts (raises on any other exception).

    Peak memory is measured as the growth of this process's peak resident set
    over the run (tracemalloc on every case would triple the run time).
    """
    import resource

    from shapedisplay.render.image import read_image, to_image
    rng = random.Random(seed)
    table = small_table()
    good = table_bytes(table)
    header = copy.deepcopy(table.header())
    header["checksum"] = documented_checksum(header, table.codes)
    plain = npz_bytes(header, table.codes)
    header_npy = npy_bytes(np.frombuffer(json.dumps(header, sort_keys=True).encode(), np.uint8))
    image = to_image(table)
    assert read_image(image).checksum == table.checksum
    _check_accepted_table(FrictionTable.from_bytes(good), "the unmutated table")   # imports happen here
    same = table.checksum
    counts = {"tried": 0, "rejected": 0, "accepted": 0, "accepted_changed": 0, "by_kind": {}}
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    plan = ([("flip", lambda: _flip(rng, rng.choice((good, plain))))] * N_FLIPS
            + [("truncate", lambda: _truncate(rng, rng.choice((good, plain))))] * N_TRUNC
            + [("zip", lambda: _zip_edit(rng, rng.choice((good, plain)), table.codes, header_npy))] * N_ZIP
            + [("header", lambda: _header_edit(rng, header, table.codes))] * N_HEADER
            + [("image", lambda: _image_edit(rng, image))] * N_IMAGE)
    for i, (kind, make) in enumerate(plan):
        data = make()
        read = read_image if kind == "image" else FrictionTable.from_bytes
        k = counts["by_kind"].setdefault(kind, {"tried": 0, "accepted": 0})
        counts["tried"] += 1
        k["tried"] += 1
        try:
            t = read(data)
        except ShapeDisplayError as exc:
            assert "\n" not in str(exc), (kind, i, str(exc))
            counts["rejected"] += 1
            continue
        except Exception as exc:  # noqa: BLE001 - this is what the fuzz looks for
            raise AssertionError(f"{kind} #{i} (seed {seed}): {type(exc).__name__}: {exc}") from exc
        counts["accepted"] += 1
        k["accepted"] += 1
        if t.checksum != same:        # an edit the checksum rule covered: check it plays and exports
            counts["accepted_changed"] += 1
            _check_accepted_table(t, f"{kind} #{i} (seed {seed})")
    counts["seconds"] = time.perf_counter() - t0
    counts["rss_growth_mb"] = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024
    return counts


def test_ten_thousand_table_mutations():
    """Run in one fresh process (all cases in it) so its peak resident set measures the fuzz alone."""
    code = ("import json, sys; sys.path.insert(0, %r); import test_fuzz; "
            "print(json.dumps(test_fuzz.run_table_fuzz()))") % str(Path(__file__).parent)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-4000:]
    c = json.loads(out.stdout.strip().splitlines()[-1])
    assert c["tried"] == 10_000 == N_FLIPS + N_TRUNC + N_ZIP + N_HEADER + N_IMAGE
    assert c["rejected"] + c["accepted"] == c["tried"]
    for kind, k in c["by_kind"].items():          # every kind is mostly refused: the fuzz is not the good path
        assert k["accepted"] < k["tried"] / 2, (kind, k)
    assert c["rss_growth_mb"] < TABLE_FUZZ_RSS_GROWTH_BOUND_MB, c
    print(f"\ntable mutations: {c['tried']} tried, {c['rejected']} rejected with ShapeDisplayError, "
          f"{c['accepted']} accepted ({c['accepted_changed']} with changed content, each finite, played and "
          f"exported); peak RSS growth {c['rss_growth_mb']:.1f} MB; {c['seconds']:.1f} s; by kind {c['by_kind']}")


def test_mutants_read_from_files_change_no_file(tmp_path):
    """A sample read through the path-based loader: the folder is byte-identical afterwards."""
    rng = random.Random(SEED + 1)
    good = table_bytes(small_table())
    for i in range(200):
        p = tmp_path / f"m{i}.npz"
        p.write_bytes(_flip(rng, good) if i % 2 else _truncate(rng, good))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    for p in sorted(tmp_path.iterdir()):
        try:
            FrictionTable.load(p)
        except ShapeDisplayError:
            pass
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_mutants_through_the_real_command(tmp_path):
    """A small sample through the installed command: exit 2 (or 0), one line, no traceback."""
    rng = random.Random(SEED + 2)
    good = table_bytes(small_table())
    cases = [_flip(rng, good), _truncate(rng, good), _zip_edit(rng, good, small_table().codes, b""),
             b"PK\x03\x04" + b"\0" * 30]
    for i, data in enumerate(cases):
        p = tmp_path / f"m{i}.npz"
        p.write_bytes(data)
        out = subprocess.run([sys.executable, "-m", "shapedisplay.cli.main", "inspect", str(p)],
                             capture_output=True, text=True, timeout=120)
        assert out.returncode in (0, 2), out
        if out.returncode == 2:
            assert len(out.stderr.strip().splitlines()) == 1 and "Traceback" not in out.stderr, out.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == [f"m{i}.npz" for i in range(len(cases))]


# ------------------------------------------------------------------ 2,000 malformed inputs
N_STROKES, N_TRACES, N_SCENES, N_COMMANDS = 600, 400, 500, 500
_NUMS = ["0", "1", "-1", "60", "1e308", "-1e308", "nan", "inf", "1e-300", "2.5", "", "x", "1e3", "0x10",
         "99999999999999999999", "-0", "1,", ",", "1e"]
_SPEEDS = ["20 mm/s", "20mm/s", "1e9 m/s", "0 mm/s", "-5 mm/s", "nan mm/s", "20 Hz", "20", "1e-300 mm/s",
           "inf m/s", "20 kg", "mm/s", ""]


def _stroke(rng) -> str:
    n = rng.randrange(1, 5)
    pts = [f"{rng.choice(_NUMS)},{rng.choice(_NUMS)}" for _ in range(n)]
    joins = [rng.choice([" -> ", "->", " <-> ", " - ", ":"]) for _ in range(n - 1)]
    path = pts[0] + "".join(j + p for j, p in zip(joins, pts[1:]))
    if rng.random() < 0.2:
        path = f"{rng.choice(_NUMS)}:{rng.choice(_NUMS)}mm"
    text = f"{path} @ {rng.choice(_SPEEDS)}"
    if rng.random() < 0.3:
        text += f" x{rng.choice(['3', '0', '30000000', '1000000000', '9' * 30, '-1', 'q'])}"
    if rng.random() < 0.05:
        text = rng.choice(["", "@", "@@", "->@", "0,0 -> 1,1 @ 1mm/s @ 2mm/s", "\x00", "0,0->" * 5000 + "1,1 @ 1mm/s"])
    return text


def _trace_csv(rng) -> str:
    rows = []
    if rng.random() < 0.3:
        rows.append(rng.choice(["t,x,y", "t,x_m,y_m", "time", "# comment", "t,fx,fy"]))
    t = 0.0
    for _ in range(rng.randrange(0, 12)):
        t += rng.choice([1e-3, 1e-3, 0.0, -1e-3, 1e300, 1e-12])
        cols = [repr(t)] + [rng.choice(["0", "1", "5", "-3", "1e308", "nan", "inf", "", "a", "1e6"])
                            for _ in range(rng.choice((1, 2, 2, 2, 3)))]
        rows.append(",".join(cols))
    return "\n".join(rows) + rng.choice(["\n", "", "\n\n", "\x00"])


#: Memory an accepted cursor path may take beyond the case bound, per tick (t, x, y and the
#: temporaries of sampling: the size the path declares, refused beyond MAX_TICKS).
BYTES_PER_TICK = 64


def _ticks_allowance(cp) -> int:
    return BYTES_PER_TICK * cp.t.size


def _check_cursor(cp, label):
    assert np.isfinite(cp.t).all() and np.isfinite(cp.x).all() and np.isfinite(cp.y).all(), label
    assert cp.t.size <= 10_000_000


def test_two_thousand_malformed_strokes_traces_scenes_and_command_lines(tmp_path, capsys):
    from shapedisplay.render.cursor import load_force_csv, load_trace_csv, parse_stroke
    from shapedisplay.author.scene import check_scene, load_scene
    from shapedisplay.render.sinks import read_trace
    from shapedisplay.cli.main import main
    rng = random.Random(SEED + 3)
    tally = Tally()
    t0 = time.perf_counter()
    tracemalloc.start()
    try:
        for i in range(N_STROKES):
            s = _stroke(rng)
            _run_case(tally, "stroke", f"stroke {s[:80]!r}", lambda: parse_stroke(s, 10_000), _check_cursor,
                      _ticks_allowance)
        csv = tmp_path / "rec.csv"
        trace_npz = _trace_npz_bytes(tmp_path)
        npz = tmp_path / "trace_in.npz"
        for i in range(N_TRACES // 2):                       # .npz traces, as play --trace-out writes them
            npz.write_bytes(_trace_mutant(rng, trace_npz))
            _run_case(tally, "trace-npz", f"trace npz #{i}", lambda: read_trace(npz), _check_trace_dict,
                      lambda d: 16 * BYTES_PER_TICK * d["t"].size)
        for i in range(N_TRACES // 2, N_TRACES):
            csv.write_text(_trace_csv(rng), encoding="utf-8", errors="surrogateescape")
            if i % 2:
                _run_case(tally, "trace", f"trace #{i}", lambda: load_trace_csv(csv, 10_000), _check_cursor,
                          _ticks_allowance)
            else:
                _run_case(tally, "force", f"force #{i}", lambda: load_force_csv(csv, 0.08, 10_000),
                          _check_cursor, _ticks_allowance)
        base_scene = (ROOT / "assets" / "scenes" / "keypad.toml").read_text()
        scene_path = tmp_path / "s.toml"
        for i in range(N_SCENES):
            scene_path.write_text(_mutate_toml(rng, base_scene))
            _run_case(tally, "scene", f"scene #{i}", lambda: check_scene(load_scene(scene_path)),
                      lambda r, label: None)
    finally:
        tracemalloc.stop()
    commands = _command_lines(rng, tmp_path)
    inputs = {p: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    for argv in commands:
        tally.tried += 1
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:            # argparse: usage errors
            code = exc.code
        out, err = capsys.readouterr()
        assert code in (0, 2), (argv, code, err)
        if code == 2:
            tally.rejected += 1
            assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, (argv, err)
        else:
            tally.accepted += 1
        intended = {Path(str(argv[j + 1])).resolve() for j, a in enumerate(argv[:-1])
                    if a in ("-o", "--output", "--trace-out")}
        for p, data in inputs.items():
            if p.resolve() not in intended:
                assert p.read_bytes() == data, (argv, p)     # inputs and bystanders untouched
            elif p.read_bytes() != data:
                assert code == 0, (argv, p)                  # only a successful command writes its output
        for p in list(tmp_path.iterdir()):
            assert ".part" not in p.name, (argv, p)
            if p not in inputs:
                assert p.resolve() in intended and code == 0, (argv, p)
                p.unlink()
        for p, data in inputs.items():                      # the next command starts from the same files
            if p.read_bytes() != data:
                p.write_bytes(data)
    seconds = time.perf_counter() - t0
    assert tally.tried == N_STROKES + N_TRACES + N_SCENES + N_COMMANDS == 2000
    print("\n" + tally.line("malformed strokes, traces, scenes, command lines") + f"; {seconds:.1f} s")


def _trace_npz_bytes(tmp_path) -> bytes:
    from shapedisplay.render.cursor import parse_stroke
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.render.sinks import write_trace
    table = small_table()
    r = Renderer(table, model="jump")
    res = r.render(parse_stroke("0,3 -> 9,3 @ 50mm/s", r.tick_rate))
    p = write_trace(tmp_path / "good_trace.npz", res, table.checksum)
    data = p.read_bytes()
    p.unlink()
    return data


def _trace_mutant(rng, data: bytes) -> bytes:
    kind = rng.randrange(3)
    if kind == 0:
        return _flip(rng, data)
    if kind == 1:
        return _truncate(rng, data)
    with np.load(io.BytesIO(data)) as z:
        arrays = {n: z[n] for n in z.files}
    name = rng.choice(list(arrays))
    a = arrays[name]
    arrays[name] = rng.choice([a[:-1] if a.ndim else a, np.full(a.shape, np.nan) if a.dtype.kind == "f" else a,
                               a.astype(np.float64) if a.dtype.kind in "fiu" else a, np.zeros((2, 2)),
                               np.array(["x" * 300]), np.zeros(10 ** 5), -a if a.dtype.kind == "f" else a])
    if rng.random() < 0.2:
        arrays["extra"] = np.zeros(3)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _check_trace_dict(d, label):
    for k, v in d.items():
        if isinstance(v, np.ndarray) and v.dtype.kind == "f":
            assert np.isfinite(v).all(), (label, k)


def _mutate_toml(rng, text: str) -> str:
    lines = text.splitlines()
    for _ in range(rng.randrange(1, 4)):
        i = rng.randrange(len(lines))
        line = lines[i]
        kind = rng.randrange(6)
        if kind == 0:
            del lines[i]
        elif kind == 1 and "=" in line:
            key = line.split("=", 1)[0]
            lines[i] = key + "= " + rng.choice(['"nan mm"', '"-1 mm"', '"1e300 mm"', "nan", "inf", '"x"', "[]",
                                                 "{}", "true", '"0 mm"', "-5", '"1e9 N"', '"1 kg"', "1e400"])
        elif kind == 2:
            lines.insert(i, line)
        elif kind == 3:
            lines[i] = line[:rng.randrange(len(line) + 1)]
        elif kind == 4:
            lines.insert(i, rng.choice(["[[widget]]", "[canvas]", 'type = "button"', 'size = "1e9 x 1e9 mm"',
                                        'spacing = "1e-9 mm"', "count = 100000000", '[device]', "x = 1"]))
        else:
            lines[i] = line.replace("mm", rng.choice(["m", "km", "", "mmm", "N"]))
    return "\n".join(lines) + "\n"


def _command_lines(rng, tmp_path) -> list[list]:
    from PIL import Image
    png = tmp_path / "in.png"
    Image.fromarray((np.arange(48).reshape(4, 12) * 5).astype(np.uint8)).save(png)
    table = tmp_path / "in.npz"
    small_table().save(table)
    out = lambda s: tmp_path / s  # noqa: E731
    values = ["-1N", "-60x4mm", "-y", "-5ms", "nan", "inf", "0", "1e308", "", "-", "--", "0:NaNmm", "1e-300",
              "10x", "x", "5 kHz", "-5 Hz", "1,2", "1e400", "..", "/", "+1N"]
    compile_opts = ["--size", "--height", "--resolution", "--n-base", "--n-gain", "--mapping", "--max-slope",
                    "--weber", "--gradient", "--sigma", "--device", "--lateral-gain", "--slope-gain", "--up"]
    play_opts = ["--tick-rate", "--rate", "--audio-rate", "--model", "--sample-format", "--burst-policy", "--burst-gain",
                 "--max-stick-period", "--start", "--device"]
    lines = []
    for i in range(N_COMMANDS):
        kind = rng.randrange(4)
        if kind == 0:
            argv = ["compile", png, "-o", out("out.npz"), "--size", "12x4mm", "--height", "0:1mm"]
            for _ in range(rng.randrange(1, 4)):
                argv += [rng.choice(compile_opts), rng.choice(values)]
        elif kind == 1:
            argv = ["play", table, "--stroke", rng.choice(["0:5mm @ 50mm/s", "0,0 -> 5,3 @ 20mm/s", _stroke(rng)]),
                    "-o", out("out.wav")]
            if rng.random() < 0.3:
                argv += ["--trace-out", rng.choice([out("trace.npz"), out("out.wav"), table])]
            for _ in range(rng.randrange(1, 3)):
                argv += [rng.choice(play_opts), rng.choice(values)]
        elif kind == 2:
            argv = ["export", table, "--format", rng.choice(["json", "c", "bin", "x", "-1"]),
                    "-o", rng.choice([out("out.json"), out("out.h"), table, png, tmp_path])]
        else:
            argv = [rng.choice(["inspect", "play", "compile", "export", "check", "heightmap"])]
            argv += [rng.choice([table, png, tmp_path, "missing.npz", "-", "--", "-1N"])
                     for _ in range(rng.randrange(0, 4))]
        if rng.random() < 0.1:
            argv.insert(rng.randrange(1, len(argv) + 1), rng.choice(values))
        lines.append(argv)
    return lines
