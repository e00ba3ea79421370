"""shapedisplay: tactile shapes for friction-based shape displays.

Pipeline (imports flow one way): sources -> :mod:`heightfield` ->
:mod:`gradients` -> :mod:`forces` -> :mod:`compile` -> :mod:`table` ->
:mod:`runtime` -> :mod:`sinks`. The runtime side (``table``, ``devices``,
``runtime``, ``sinks``) never imports the authoring side.

``import shapedisplay`` is cheap: submodules load on first attribute access,
and no optional dependency (trimesh, pyvista, pyserial, matplotlib) is
imported until a feature that needs it is used.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

from .errors import (  # noqa: E402  (light, always needed)
    FileFormatError, InputError, MissingDependencyError, ModelError, ShapeDisplayError,
    TableError, UnitError,
)

_LAZY = {
    "HeightField": "heightfield",
    "FrictionTable": "table",
    "DeviceProfile": "devices",
    "load_device": "devices",
    "parse_quantity": "units",
    "load_source": "sources",
    "MappingOptions": "forces",
    "CompileOptions": "compile",
    "compile_heightfield": "compile",
}


def __getattr__(name):
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'shapedisplay' has no attribute {name!r}")


__all__ = ["ShapeDisplayError", "InputError", "UnitError", "FileFormatError", "TableError",
           "ModelError", "MissingDependencyError", *_LAZY]
