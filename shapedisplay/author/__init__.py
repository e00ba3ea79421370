"""The authoring side: from a designer's source to a friction-envelope table.

Pipeline (imports flow one way): :mod:`.sources` (every loader, by suffix) ->
:mod:`.heightfield` -> :mod:`.gradients` -> :mod:`.forces` -> :mod:`.compile`;
:mod:`.scene` builds GUI scenes (buttons, sliders, toggles) into the same
tables. :mod:`.imageio`, :mod:`.mesh` and :mod:`.raster` read pictures and
meshes; :mod:`.kernels` holds the compiler's C kernels; :mod:`.batch`
compiles several sources into one folder.
"""
