"""shapedisplay: tactile shapes for friction-based shape displays.

Subpackages follow the pipeline (imports flow one way): :mod:`.author`
(sources, height fields, gradients, forces, compile, scenes) -> :mod:`.table`
(the table, its container and devices) -> :mod:`.render` (the C engine's
binding, cursor, results, sinks); around them :mod:`.link` (devices over a
serial link), :mod:`.exchange` (exports), :mod:`.reports` (accuracy,
stability, studies), :mod:`.studio`, :mod:`.viewer` and :mod:`.cli`. The
runtime side (``table``, ``render``, ``link``) never imports the authoring side.

``import shapedisplay`` is cheap: submodules load on first attribute access,
and no optional dependency (trimesh, pyvista, pyserial, matplotlib) is
imported until a feature that needs it is used.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

from shapedisplay.errors import (  # noqa: E402  (light, always needed)
    FileFormatError, InputError, MissingDependencyError, ModelError, ShapeDisplayError,
    TableError, UnitError,
)

_LAZY = {
    "compile": "api",
    "load": "api",
    "Table": "render.playable",
    "HeightField": "author.heightfield",
    "FrictionTable": "table.model",
    "DeviceProfile": "table.devices",
    "load_device": "table.devices",
    "parse_quantity": "units",
    "load_source": "author.sources",
    "MappingOptions": "author.forces",
    "CompileOptions": "author.compile",
    "compile_heightfield": "author.compile",
}


def __getattr__(name):
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'shapedisplay' has no attribute {name!r}")


__all__ = ["ShapeDisplayError", "InputError", "UnitError", "FileFormatError", "TableError",
           "ModelError", "MissingDependencyError", *_LAZY]
