"""Export buttons of the studio: the current table in every format, written under the output folder."""
from __future__ import annotations

from pathlib import Path

from shapedisplay.errors import unknown_key

#: File suffix of each export format the library knows (new formats get ".FORMAT").
SUFFIXES = {"table": ".npz", "json": ".json", "c": ".h", "bin": ".bin", "glb": ".glb", "friction-png": ".png",
            "hjif": ".hjif"}


def formats() -> list[str]:
    """Every format the page offers: the table itself and each of ``shapedisplay export``."""
    from shapedisplay.exchange import FORMATS
    return ["table", *FORMATS]


def export_bytes(table, fmt: str, out_dir: Path, stem: str) -> tuple[str, bytes]:
    """Write ``table`` as ``fmt`` to ``out_dir/STEM.SUFFIX`` and return (file name, bytes)."""
    from shapedisplay.exchange import export_table
    if fmt not in formats():
        raise unknown_key("export format", fmt, formats())
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{stem}{SUFFIXES.get(fmt, '.' + fmt)}"
    if fmt == "table":
        table.save(path)
    else:
        export_table(table, path, fmt)
    return path.name, path.read_bytes()
