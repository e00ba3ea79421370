"""The package's compiled libraries: extension modules built at install (``setup.py``), loaded with ctypes.

``shapedisplay._engine`` (the C runtime, :mod:`.runtime.native`) and
``shapedisplay._kernels_c`` (the compiler's kernels, :mod:`._kernels`) are
compiled when the package is built or installed; nothing is compiled at run
time. Their files are found as Python finds the modules (no import: the
modules are empty) and loaded with :class:`ctypes.CDLL`.

In a checkout (an editable install) a changed C source is not rebuilt by
itself: a library older than its sources is refused with the command that
rebuilds it, instead of running code that no longer matches the Python side.
"""
from __future__ import annotations

import ctypes
from pathlib import Path

from shapedisplay.errors import InputError

PACKAGE = Path(__file__).resolve().parent


def extension_path(module: str, what: str) -> Path:
    """The file of the extension module ``module`` (say ``shapedisplay._engine``); ``what`` names it in messages.

    Raises :class:`InputError` where it is missing (a broken install).
    """
    import importlib.util
    try:
        spec = importlib.util.find_spec(module)
    except ImportError:
        spec = None
    if spec is None or not spec.origin or not Path(spec.origin).is_file():
        raise InputError(f"{what} ({module}) is missing from this installation; reinstall shapedisplay")
    return Path(spec.origin)


def _stale(path: Path, sources) -> Path | None:
    """In a checkout, the first of ``sources`` changed after ``path`` was built; None otherwise (installed)."""
    if path.parent != PACKAGE or not (PACKAGE.parent / ".git").exists():
        return None
    built = path.stat().st_mtime
    return next((s for s in sources if s.stat().st_mtime > built), None)


def load_extension(path: Path, what: str, sources=()) -> ctypes.CDLL:
    """Load the extension module file ``path`` (:func:`extension_path`) as a ctypes library.

    ``sources`` (paths) are the C files and headers it is built from: in a
    checkout, a library older than one of them is refused. Raises
    :class:`InputError` with one line saying how to mend the installation.
    """
    newer = _stale(path, sources)
    if newer is not None:
        raise InputError(f"{what} ({path.name}) is older than {newer.relative_to(PACKAGE.parent)}; "
                         f"rebuild it: pip install -e . in the checkout")
    try:
        return ctypes.CDLL(str(path))
    except OSError as exc:
        raise InputError(f"loading {what} {path} failed ({exc}); reinstall shapedisplay") from None
