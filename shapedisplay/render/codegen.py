"""Build step of the runtime: writes the C header derived from the layouts and the model registry.

``make generate`` (``python -m shapedisplay.render.codegen``) writes
``engine/sd_layout.h``: the C structs and enums of :mod:`.layouts` and
the model numbering of :data:`~.models.MODELS`, so the Python records the
binding reads and the C engine's structs are one definition. ``--check``
(and ``tests/test_layouts.py``) fails when the header is out of date.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
C_DIR = HERE.parent / "engine"


def generated_files() -> dict[Path, str]:
    """Every generated file and its text as it should be."""
    from shapedisplay.render.layouts import c_header
    from shapedisplay.render.models import MODELS
    return {C_DIR / "sd_layout.h": c_header(list(MODELS))}


def stale_files() -> list[Path]:
    """Generated files whose text on disk differs from what ``make generate`` would write."""
    return [p for p, text in generated_files().items() if not p.is_file() or p.read_text() != text]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m shapedisplay.render.codegen", description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only report files that are out of date (exit 1)")
    args = ap.parse_args(argv)
    if args.check:
        stale = stale_files()
        for p in stale:
            print(f"out of date: {p} (run `make generate`)", file=sys.stderr)
        return 1 if stale else 0
    for p, text in generated_files().items():
        if not p.is_file() or p.read_text() != text:
            p.write_text(text)
            print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
