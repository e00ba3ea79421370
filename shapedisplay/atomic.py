"""Atomic, durable file writes: a crash or a power loss never leaves a partial file under the final name.

A file is written under a temporary name beside the target, flushed to disk
(``fsync``), renamed over the target, and the directory is flushed so the
rename survives a power loss too (SQLite's and git's order).

Also the rules every command's outputs follow: an output never resolves to
an input or to another output of the same command (:func:`check_outputs`),
and temporary files left by a killed writer (``.NAME.XXXXXXXX.part.SUFFIX``,
locked while their writer lives) are removed when a later write of the same
name finds them.
"""
from __future__ import annotations

import contextlib
import glob
import os
import tempfile
from pathlib import Path
from typing import Iterator

from shapedisplay.errors import FileFormatError, ShapeDisplayError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success flush it, rename it over ``path``, flush the folder.

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
    _remove_stale_parts(parent, final.stem, suffix)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{final.stem}.", suffix=f".part{suffix}", dir=parent)
    except OSError as exc:
        raise FileFormatError(f"output '{final}': cannot write in '{parent}' ({exc.strerror or exc})") from None
    _lock(fd)                  # held while this process lives: a later writer knows the file is not stale
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp creates 0600; give the file the permissions a plain open() would
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.fsync(fd)               # the data on disk before the name points at it (any descriptor of the file)
        os.replace(tmp_path, final)
        os.close(fd)
        _fsync_dir(parent)         # the rename itself on disk
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        os.close(fd)
        if isinstance(exc, OSError) and not isinstance(exc, ShapeDisplayError):
            # disk full, permissions, a name that cannot be replaced: one line, no partial file
            raise FileFormatError(f"output '{final}': cannot write ({exc.strerror or exc})") from None
        raise


def replace_dir(src: str | os.PathLike, dst: str | os.PathLike) -> None:
    """Rename the complete folder ``src`` to ``dst`` (absent or an empty folder) durably.

    ``src`` is flushed first (the names in it on disk), then renamed, then
    the parent of ``dst`` is flushed (the rename on disk): after a power loss
    ``dst`` is the whole folder or absent. Both must be on one file system
    (``src`` made beside ``dst``). Files in ``src`` are written with
    :func:`atomic_path`, which flushes each file before its name.
    """
    src, dst = Path(src), Path(dst)
    _fsync_dir(src)
    os.replace(src, dst)
    _fsync_dir(dst.parent if str(dst.parent) else Path("."))


def _fsync_dir(parent: Path) -> None:
    """Flush directory ``parent`` (a rename in it) to disk, where the platform can.

    Windows cannot open a directory for this (and its rename is journalled);
    a file system that does not support it (EINVAL) is left as it is.
    """
    if os.name == "nt":  # pragma: no cover - no directory descriptors
        return
    try:
        dfd = os.open(parent, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(dfd)
    except OSError:
        pass
    finally:
        os.close(dfd)


def _lock(fd: int) -> bool:
    """Take a non-blocking exclusive lock on ``fd``; False if another process holds it (or no locks here)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - no advisory locks on this platform
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    return True


def _remove_stale_parts(parent: Path, stem: str, suffix: str) -> list[Path]:
    """Remove ``.STEM.*.partSUFFIX`` files in ``parent`` whose writer is gone (their lock is free).

    A writer holds an exclusive lock on its temporary file until it renames or
    removes it; a file whose lock can be taken was left by a killed process.
    Where the platform has no locks nothing is removed (a live writer could
    not be told from a dead one).
    """
    removed = []
    pattern = os.path.join(glob.escape(str(parent)), f".{glob.escape(stem)}.*.part{glob.escape(suffix)}")
    for name in glob.glob(pattern):
        try:
            fd = os.open(name, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except OSError:
            continue
        try:
            if _lock(fd) and os.path.isfile(name):
                os.unlink(name)
                removed.append(Path(name))
        except OSError:
            pass
        finally:
            os.close(fd)
    return removed


def prepare_output_dir(path: str | os.PathLike) -> str:
    """Create the output folder ``path`` if missing and check that files can be written in it.

    Called before any work, so a long computation never ends in a write that fails.
    """
    out = os.fspath(path)
    if os.path.exists(out) and not os.path.isdir(out):
        raise FileFormatError(f"output folder '{out}' is a file")
    try:
        os.makedirs(out, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-test.", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise FileFormatError(f"output folder '{out}': cannot write ({exc.strerror or exc})") from None
    return out


def check_outputs(inputs: dict, outputs: dict) -> None:
    """Refuse outputs that resolve to an input or to another output.

    Parameters
    ----------
    inputs, outputs : dict
        ``{name as the user gave it (option or argument): path}``; None values are skipped.

    Raises
    ------
    FileFormatError
        One line naming both, e.g. "`-o` 'in.png' is the input SOURCE 'in.png'; refusing to overwrite an input".
    """
    def same(a, b) -> bool:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
        try:
            return os.path.samefile(a, b)          # hard links, bind mounts
        except OSError:
            return False

    outs = [(name, os.fspath(p)) for name, p in outputs.items() if p]
    ins = [(name, os.fspath(p)) for name, p in inputs.items() if p]
    for i, (oname, opath) in enumerate(outs):
        for iname, ipath in ins:
            if same(opath, ipath):
                raise FileFormatError(f"`{oname}` '{opath}' is the input {iname} '{ipath}'; "
                                      f"refusing to overwrite an input")
        for oname2, opath2 in outs[:i]:
            if same(opath, opath2):
                raise FileFormatError(f"`{oname}` '{opath}' is also the output of `{oname2}`; "
                                      f"give each output its own file")


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
