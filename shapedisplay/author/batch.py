"""Batch compile: several sources into one folder, with a summary.

``shapedisplay compile A B C -o DIR/`` compiles each source to
``DIR/<stem>.npz``. :func:`plan_outputs` checks everything it can before
the first compile (every source exists, no two sources share an output
name, the folder exists or can be made); each table is written atomically,
so a source that fails leaves no file and does not stop the others.
:func:`summary_row` gives the line of the summary table for one source.
"""
from __future__ import annotations

import os
from pathlib import Path

from shapedisplay.errors import FileFormatError, InputError


def is_batch(sources, output) -> bool:
    """Several sources, or an output that names a folder (ends with a separator or is one)."""
    out = os.fspath(output)
    return len(sources) > 1 or out.endswith(("/", os.sep)) or Path(out).is_dir()


def plan_outputs(sources, output) -> list[tuple[Path, Path]]:
    """``[(source, DIR/<stem>.npz), ...]`` after checking sources, names and the folder.

    The folder is created when missing (its parent must exist).
    """
    folder = Path(os.fspath(output))
    if folder.exists() and not folder.is_dir():
        raise InputError(f"`-o` must be a folder when compiling several sources (got file '{output}')")
    missing = [str(s) for s in sources if not Path(s).is_file()]
    if missing:
        raise FileFormatError(f"source '{missing[0]}': no such file" +
                              (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
    plan, seen = [], {}
    for s in sources:
        out = folder / (Path(s).stem + ".npz")
        if out.name in seen:
            raise InputError(f"sources '{seen[out.name]}' and '{s}' would both be written to '{out}'; "
                             f"compile them into different folders")
        seen[out.name] = s
        plan.append((Path(s), out))
    if not folder.exists():
        if not folder.parent.is_dir():
            raise FileFormatError(f"output folder '{folder}': its parent '{folder.parent}' does not exist")
        folder.mkdir()
    return plan


def summary_row(source, output, result=None, error: str | None = None) -> dict:
    """One line of the batch summary: source, output, grid, size, channels, bytes, or the error."""
    if result is None:
        return {"source": str(source), "output": "-", "status": f"error: {error}"}
    t, rep = result.table, result.report
    g = t.grid
    return {
        "source": str(source), "output": str(output), "status": "ok",
        "samples": f"{g.cols} x {g.rows}", "size_mm": f"{g.cols * g.dx * 1e3:.4g} x {g.rows * g.dy * 1e3:.4g}",
        "channels": ", ".join(t.channels), "stored_bytes": int(t.stored_bytes),
        "saved": f"{100 * (1 - t.stored_bytes / t.dense_bytes):.1f} %" if t.dense_bytes else "-",
        "warnings": len(rep.get("warnings", []) or []),
    }
