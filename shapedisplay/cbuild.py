"""Shared libraries built from C sources shipped in the package, with the system C compiler, cached.

The C runtime (:mod:`.runtime.native`) and the compiler's kernels
(:mod:`._kernels`) are C sources inside the package. Each is built once per
source version by the system C compiler (``$CC``, else ``cc``, ``gcc`` or
``clang``) into the cache directory (``$XDG_CACHE_HOME/shapedisplay``, by
default ``~/.cache/shapedisplay``) and loaded with ctypes. Building takes
about a second; later loads take about a millisecond. The build is atomic
(a temporary name, then a rename), so processes building at once do not
see each other's partial files.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
from pathlib import Path

from .errors import InputError

#: How every library is built: IEEE double arithmetic as written (no contraction into fused multiply-adds).
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared")


def compiler() -> str | None:
    """The C compiler the builds use: ``$CC``, else ``cc``, ``gcc`` or ``clang`` on the PATH; None if none."""
    return os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")


def cache_dir() -> Path:
    """Where built libraries are kept: ``$XDG_CACHE_HOME/shapedisplay`` (default ``~/.cache/shapedisplay``)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "shapedisplay"


def shared_library_path(stem: str, sources: list[Path], headers: list[Path] = ()) -> Path:
    """The cached file a library of ``sources`` is built into (it may not exist yet).

    Named ``STEM-DIGEST.so`` with the digest of the sources, the headers and
    :data:`CFLAGS`: a changed source builds a new file.
    """
    if not all(p.is_file() for p in sources):
        missing = [str(p) for p in sources if not p.is_file()]
        raise InputError(f"C sources are missing ({', '.join(missing)})")
    digest = hashlib.sha256(b"".join(p.read_bytes() for p in [*sources, *headers])
                            + " ".join(CFLAGS).encode()).hexdigest()[:16]
    return cache_dir() / f"{stem}-{digest}.so"


def build_shared(lib_path: Path, sources: list[Path], include: Path | None = None,
                 what: str = "the C runtime", hint: str = "") -> None:
    """Compile ``sources`` into the shared library ``lib_path`` (atomically: a temporary name, then a rename).

    ``what`` names the library in messages; ``hint`` ends the one for a missing compiler.
    """
    import subprocess       # only to build: about 5 ms of every play's start otherwise
    import tempfile
    cc = compiler()
    if not cc:
        raise InputError(f"{what} needs a C compiler (cc, gcc or clang, or $CC){hint}")
    try:
        lib_path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(dir=lib_path.parent) as d:
            tmp = Path(d) / lib_path.name
            inc = ["-I", str(include)] if include is not None else []
            try:
                res = subprocess.run([cc, *CFLAGS, *inc, *map(str, sources), "-lm", "-o", str(tmp)],
                                     capture_output=True, text=True, timeout=300)
            except (OSError, subprocess.TimeoutExpired) as exc:
                raise InputError(f"building {what} failed: cannot run {cc!r} ({exc})") from None
            if res.returncode != 0:
                raise InputError(f"building {what} with {cc!r} failed: "
                                 f"{' '.join(res.stderr.strip().splitlines()[-1:])}")
            os.replace(tmp, lib_path)
    except OSError as exc:
        raise InputError(f"building {what} failed: cannot write its cache directory {lib_path.parent} "
                         f"({exc.strerror or exc}); set XDG_CACHE_HOME to a writable folder") from None


def load_shared(lib_path: Path, sources: list[Path], include: Path | None = None,
                what: str = "the C runtime", hint: str = "") -> ctypes.CDLL:
    """Load the library at ``lib_path``, building it from ``sources`` first if it is not there."""
    if not lib_path.is_file():
        build_shared(lib_path, sources, include, what, hint)
    try:
        return ctypes.CDLL(str(lib_path))
    except OSError as exc:
        raise InputError(f"loading {what} {lib_path} failed ({exc}); delete the file to rebuild it") from None
