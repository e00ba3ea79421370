"""Atomic file writes: a crash never leaves a partial file under the final name."""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from .errors import FileFormatError, ShapeDisplayError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it over ``path`` on success.

    The temporary file keeps the final suffix (some writers, such as
    ``numpy.savez``, append one otherwise). On any exception the temporary
    file is removed and the final name is left untouched.
    """
    final = Path(path)
    if not str(path).strip() or final.is_dir():
        raise FileFormatError(f"output '{final}': is a directory or empty; give a file name")
    parent = final.parent if str(final.parent) else Path(".")
    if not parent.is_dir():
        raise FileFormatError(f"output '{final}': directory '{parent}' does not exist")
    suffix = final.suffix if suffix is None else suffix
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{final.stem}.", suffix=f".part{suffix}", dir=parent)
    except OSError as exc:
        raise FileFormatError(f"output '{final}': cannot write in '{parent}' ({exc.strerror or exc})") from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp creates 0600; give the file the permissions a plain open() would
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, final)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        if isinstance(exc, OSError) and not isinstance(exc, ShapeDisplayError):
            # disk full, permissions, a name that cannot be replaced: one line, no partial file
            raise FileFormatError(f"output '{final}': cannot write ({exc.strerror or exc})") from None
        raise


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes(path, text.encode("utf-8"))
