"""Friction-envelope tables: the model, its container, its schema and the devices that play it.

Runtime side: nothing here imports the authoring side. Submodules:

* :mod:`.model` — :class:`FrictionTable` (grid, quantised channels, metadata,
  checksum) and the header's rules;
* :mod:`.container` — bounded reading and writing of ``.npz`` containers and
  their JSON;
* :mod:`.devices` — :class:`DeviceProfile` (what a device renders, its pad and
  friction model) and the bundled profiles;
* :mod:`.diff` — what differs between two tables.
"""
from __future__ import annotations

from shapedisplay.table.model import FORMAT_NAME, FORMAT_VERSION, FrictionTable, Grid, Quantization

__all__ = ["FrictionTable", "Grid", "Quantization", "FORMAT_NAME", "FORMAT_VERSION"]
