"""The package's front door: :func:`compile` any source into a playable table, :func:`load` any file.

In the habits of trimesh and scipy::

    import shapedisplay as sd
    t = sd.compile("bump.png", size="40x40mm", height="0:2mm")     # options as the command line's
    r = t.play("0,20 -> 40,20 @ 20mm/s", model="exact")
    for e in r.events[:5]:
        print(e.t, e.x, e.y, e.normal_force, e.widget)

Both go through the same rules as ``shapedisplay compile`` (one compile
policy, :mod:`shapedisplay.author.policy`): the same source and options give
the same table, checksum for checksum.
"""
from __future__ import annotations

import os
from pathlib import Path


def compile(source, device=None, **options):
    """Compile a source into a :class:`~shapedisplay.render.playable.Table`.

    Parameters
    ----------
    source : str, Path, HeightField, Scene or dict
        A picture, ``.npy``, mesh, scene (``.toml``, ``.svg``) or haptic
        ``.glb`` file; a height field; a scene, or a scene's data as a dict
        (what its TOML holds).
    device : str, Path, DeviceProfile or None
        A bundled profile name or a TOML file; None: a scene's own, else the
        built-in Konyo pad.
    **options
        The options of ``shapedisplay compile`` by name, quantities as unit
        strings: ``size="60x4mm"``, ``height="0:2mm"``, ``resolution="0.1mm"``,
        ``mapping="height+slope"``, ``n_base="0.5N"``, ``n_gain="2N/mm"``,
        ``quantize="uint16"`` ... (:data:`shapedisplay.author.policy.OPTIONS`).

    Returns
    -------
    Table
        With ``checksum`` (as ``inspect --json`` prints it), the compile report
        in ``meta["report"]``, and :meth:`~shapedisplay.render.playable.Table.play`.
    """
    from shapedisplay.author.policy import compile_file
    from shapedisplay.render.playable import Table
    return Table.of(compile_file(source, device, **options).table)


def load(path, **options):
    """Read any file the package knows, by its suffix.

    ``.npz`` -> a :class:`~shapedisplay.render.playable.Table`; a scene
    (``.toml``, ``.svg``) -> a validated :class:`~shapedisplay.author.scene.Scene`;
    a picture, ``.npy``, instrument scan (``.txt``, ``.gsf``) or mesh -> a
    :class:`~shapedisplay.author.heightfield.HeightField`,
    with the source options of ``shapedisplay compile`` by name
    (``size="60x4mm"``, ``height="0:2mm"``, ``resolution``, ``channel``,
    ``z_units``, ``up``, ``units``).
    """
    from shapedisplay.author.sources import load_source, source_kind, source_options
    p = Path(os.fspath(path))
    kind = source_kind(p)
    if kind == "table":
        if options:
            raise_unknown(options)
        from shapedisplay.render.playable import Table
        return Table.load(p)
    if kind in ("scene", "svg"):
        if options:
            raise_unknown(options)
        from shapedisplay.author.scene import load_scene
        return load_scene(p)
    return load_source(p, **source_options(p, flags={k: k for k in options}, **options))


def raise_unknown(options: dict):
    from shapedisplay.errors import InputError
    name = next(iter(options))
    raise InputError(f"`{name}` does not apply to this file: tables and scenes take no options")
