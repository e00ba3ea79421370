"""The one error hierarchy of shapedisplay, and small helpers for messages.

Every message names the parameter or file, the rule, and the value received,
on one line: "`mu_k` must be <= `mu_s` (got mu_k=0.7, mu_s=0.5)".
"""
from __future__ import annotations

import importlib
from typing import Iterable


class ShapeDisplayError(Exception):
    """Base class of every error raised on purpose by shapedisplay."""


class InputError(ShapeDisplayError, ValueError):
    """A parameter, option or value breaks a rule."""


class UnitError(InputError):
    """A quantity is missing its unit, has an unknown unit or the wrong dimension."""


class FileFormatError(ShapeDisplayError, OSError):
    """A file is missing, unreadable, truncated or not in the expected format."""

    def __str__(self) -> str:  # OSError would format (errno, strerror) pairs
        return str(self.args[0]) if self.args else ""


class TableError(FileFormatError):
    """A friction-envelope table has a wrong version, checksum or layout."""


class ModelError(InputError):
    """Model parameters are not physically admissible (m <= 0, mu_k > mu_s, ...)."""


class MissingDependencyError(ShapeDisplayError, ImportError):
    """An optional extra is needed for this feature and is not installed."""


def did_you_mean(name: str, valid: Iterable[str]) -> str:
    """Return " (did you mean 'x'?)" for the closest valid name, or ""."""
    import difflib          # on first use: about 2 ms of every start otherwise
    match = difflib.get_close_matches(str(name), list(valid), n=1, cutoff=0.5)
    return f" (did you mean '{match[0]}'?)" if match else ""


def unknown_key(kind: str, name: str, valid: Iterable[str]) -> InputError:
    """Build the error for an unknown key, listing the valid ones and the nearest."""
    valid = sorted(valid)
    return InputError(
        f"unknown {kind} '{name}'{did_you_mean(name, valid)}; valid: {', '.join(valid)}"
    )


def require(module: str, extra: str, feature: str):
    """Import an optional dependency or raise a one-line install hint.

    >>> require("pyvista", "viewer", "3D preview")  # doctest: +SKIP
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependencyError(
            f"{feature} needs {module}: pip install 'shapedisplay[{extra}]' ({exc})"
        ) from None
