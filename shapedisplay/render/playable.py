"""A table that plays: :class:`Table` is a :class:`~shapedisplay.table.model.FrictionTable` with :meth:`Table.play`.

``shapedisplay.load`` and ``shapedisplay.compile`` return one::

    t = sd.compile("bump.png", size="40x40mm", height="0:2mm")
    r = t.play("0,20 -> 40,20 @ 20mm/s", model="exact")
    r.events[0]         # Event(t=..., x=..., y=..., normal_force=..., amplitude=..., widget=None)
"""
from __future__ import annotations

import dataclasses

import numpy as np

from shapedisplay.errors import InputError
from shapedisplay.table.model import FrictionTable


class Table(FrictionTable):
    """A friction-envelope table with :meth:`play` (everything else is :class:`FrictionTable`'s)."""

    @classmethod
    def of(cls, table: FrictionTable) -> "Table":
        """``table`` as a :class:`Table` (the same arrays, not copied)."""
        if isinstance(table, cls):
            return table
        if not isinstance(table, FrictionTable):
            raise InputError(f"`table` must be a FrictionTable (got {type(table).__name__})")
        return cls(**{f.name: getattr(table, f.name) for f in dataclasses.fields(table)})

    def play(self, stroke, model: str = "exact", *, tick_rate=None, device=None, **settings):
        """Play ``stroke`` on this table with the C engine.

        Parameters
        ----------
        stroke : str, CursorPath or array (n, 3)
            A stroke as the command line writes it (``"0,10 -> 40,10 @ 20mm/s"``,
            positions in mm), a :class:`~shapedisplay.render.cursor.CursorPath`,
            or rows ``(t [s], x [m], y [m])`` (resampled onto the tick grid).
        model : str
            Pad model: ``exact``, ``jump``, ``karnopp``, ``stribeck`` (and the baselines).
        tick_rate : float or str, optional
            Hz, or a string with its unit (``"10kHz"``); default the device's.
        device : DeviceProfile, str or None
            Default: the table's own device.
        **settings
            Further :class:`~shapedisplay.render.renderer.Renderer` settings
            (``audio_rate``, ``burst_policy``, ``max_stick_period``, model options).

        Returns
        -------
        RenderResult
            Per-tick arrays, the audio, and :attr:`~shapedisplay.render.result.RenderResult.events`.
        """
        from shapedisplay.render.cursor import CursorPath, parse_stroke
        from shapedisplay.render.renderer import Renderer
        if isinstance(tick_rate, str):
            from shapedisplay.units import parse_quantity
            tick_rate = parse_quantity(tick_rate, "Hz", "tick_rate")
        r = Renderer(self, device=device, model=model, tick_rate=tick_rate, **settings)
        if isinstance(stroke, str):
            path = parse_stroke(stroke, r.tick_rate)
        elif isinstance(stroke, CursorPath):
            path = stroke
        else:
            a = np.asarray(stroke, dtype=np.float64)
            if a.ndim != 2 or a.shape[1] != 3:
                raise InputError(f"`stroke` as an array must have rows (t, x, y), shape (n, 3) (got {a.shape})")
            path = CursorPath(a[:, 0], a[:, 1], a[:, 2], None, "array")
        return r.render(path)
