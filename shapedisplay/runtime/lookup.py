"""Bilinear table lookup inside numba kernels, on the packed table layout.

The same arithmetic as :meth:`shapedisplay.table.FrictionTable.sample`
(edge value held outside the canvas, 1-D tables ignore y), but on
:meth:`~shapedisplay.table.FrictionTable.packed` blocks so that a sparse
table (widgets with empty space between them) is never expanded to a dense
canvas. A C port does exactly this.

The kernels here are inlined into their callers (``inline="always"``, at
numba's IR level): as separate functions every lookup paid a call and the
checks numba's Python error model adds to each callee, and the per-tick
offline loop (:func:`~.renderer.lookup_inputs`) ran about 1.6x slower than
with the same arithmetic inlined. The arithmetic, and so every value, is
unchanged.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..table import FrictionTable
from .layouts import GRID, record


def pack_channels(table: FrictionTable, names: list[str]):
    """Pack several channels sharing the table's blocks.

    Returns
    -------
    blocks : ndarray (n_blocks, 5), int64 — row0, col0, rows, cols, offset
    data : ndarray (len(names), n_values + 1), float64 — decoded values, SI, then the background value
        in the last column (where :func:`sample_all` reads a sample no block covers)
    background : ndarray (len(names),), float64
    grid : :data:`~.layouts.GRID` record — rows, cols, dx, dy, x0, y0
    """
    g = table.grid
    grid = record(GRID, rows=g.rows, cols=g.cols, dx=g.dx, dy=g.dy, x0=g.x0, y0=g.y0)[0]
    if not names:
        return np.zeros((0, 5), np.int64), np.zeros((0, 1)), np.zeros(0), grid
    rows = []
    bgs = []
    blocks = None
    for n in names:
        blk, data, bg = table.packed(n)
        blocks = blk if blocks is None else blocks
        rows.append(np.asarray(data, dtype=np.float64))
        bgs.append(float(bg))
    bg = np.array(bgs)
    data = np.hstack([np.vstack(rows), bg[:, None]])
    return np.ascontiguousarray(blocks), np.ascontiguousarray(data), bg, grid


@njit(cache=True, inline="always")
def cell_index(blocks, r, c):
    """Flat offset of canvas sample (r, c) in the packed data, or -1 for background."""
    for b in range(blocks.shape[0]):
        r0 = blocks[b, 0]
        c0 = blocks[b, 1]
        nr = blocks[b, 2]
        nc = blocks[b, 3]
        if r0 <= r < r0 + nr and c0 <= c < c0 + nc:
            return blocks[b, 4] + (r - r0) * nc + (c - c0)
    return -1


@njit(cache=True, inline="always")
def _axis_cell(p, origin, spacing, count):
    """Samples ``(i0, i1)`` around position ``p`` (m) on one axis and the weight of ``i1``; edge held outside."""
    return axis_cell_at((p - origin) / spacing, count)


@njit(cache=True, inline="always")
def axis_cell_at(f, count):
    """:func:`_axis_cell` from the position in samples ``f = (p - origin) / spacing``."""
    if f < 0.0:
        f = 0.0
    if f > count - 1:
        f = count - 1.0
    i0 = int(np.floor(f))
    if i0 > max(count - 2, 0):
        i0 = max(count - 2, 0)
    return i0, min(i0 + 1, count - 1), f - i0


@njit(cache=True, inline="always")
def _packed_index(blocks, r, c, background):
    """:func:`cell_index`, with the background column's index where no block covers (r, c)."""
    i = cell_index(blocks, r, c)
    return i if i >= 0 else background


@njit(cache=True, inline="always")
def corners(blocks, grid, last, x, y):
    """The four samples around (x, y) metres and their weights: ``(i00, i01, i10, i11, tx, ty)``.

    ``i..`` index a column of the packed ``data`` (``last``, its background column, where no block
    covers the sample); row ``r0`` then ``r1``, column ``c0`` then ``c1``. A one-row table
    (``grid.rows == 1``) ignores ``y``: ``i10, i11`` repeat ``i00, i01`` and ``ty`` is 0.
    """
    c0, c1, tx = _axis_cell(x, grid.x0, grid.dx, grid.cols)
    if grid.rows == 1:
        i0 = _packed_index(blocks, 0, c0, last)
        i1 = _packed_index(blocks, 0, c1, last)
        return i0, i1, i0, i1, tx, 0.0
    r0, r1, ty = _axis_cell(y, grid.y0, grid.dy, grid.rows)
    return (_packed_index(blocks, r0, c0, last), _packed_index(blocks, r0, c1, last),
            _packed_index(blocks, r1, c0, last), _packed_index(blocks, r1, c1, last), tx, ty)


@njit(cache=True, inline="always")
def bilinear(data, ch, one_row, i00, i01, i10, i11, tx, ty):
    """Channel ``ch`` of the packed ``data`` at the samples and weights :func:`corners` gives
    (``one_row``: the table has one row; the value is then interpolated along x only)."""
    if one_row:
        return data[ch, i00] * (1 - tx) + data[ch, i01] * tx
    top = data[ch, i00] * (1 - tx) + data[ch, i01] * tx
    bot = data[ch, i10] * (1 - tx) + data[ch, i11] * tx
    return top * (1 - ty) + bot * ty


@njit(cache=True, inline="always")
def sample_all(blocks, data, bg, grid, x, y, out):
    """Bilinear values of every packed channel at (x, y) metres into ``out[:n_channels]`` (``grid``: a GRID record).

    Background samples read the last column of ``data`` (:func:`pack_channels`): every
    corner is one plain load (a branch choosing between ``data`` and ``bg`` per corner
    made the lookup several times slower).
    """
    i00, i01, i10, i11, tx, ty = corners(blocks, grid, data.shape[1] - 1, x, y)
    one_row = grid.rows == 1
    for ch in range(bg.shape[0]):
        out[ch] = bilinear(data, ch, one_row, i00, i01, i10, i11, tx, ty)
