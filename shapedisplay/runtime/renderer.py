"""The stick-slip renderer: plays a friction-envelope table as the cursor moves.

One :class:`Renderer` runs two ways over the same kernels (:mod:`.pads`):

* offline, :meth:`Renderer.render` over a whole cursor path (the fast path:
  vectorised table lookups, one compiled loop over all ticks, then burst
  synthesis);
* online, :meth:`Renderer.step` once per tick from a host loop or a device
  link (compiled, allocation-free, O(1) per tick plus O(events)).

Per tick ``i`` (from ``t[i-1]`` to ``t[i]``)
--------------------------------------------
* cursor velocity ``(p[i] - p[i-1]) / h``; the pad axis follows the motion
  direction and keeps its orientation within 90 degrees from tick to tick,
  so a reversal gives a negative pad speed ``V`` (tick 0 has ``V = 0``);
* channels are looked up (bilinear) at the midpoint of the tick's motion;
  outside the table the edge value is held;
* ``N = normal_force`` (clamped at >= 0); a table that does not store
  ``normal_force`` (a mapping without a height term) plays its constant
  ``n_base`` from the header (:func:`constant_normal_force`);
  ``mu_s, mu_k`` from the device profile, times ``friction_scale`` if
  stored (or ``breakaway_force / N`` and ``kinetic_force / N`` if those are
  stored), plus the one-sided slope term ``K_mu * max(0, grad . v_hat)``
  (``K_mu = table.meta["mapping"]["slope_friction_gain"]``; uphill resists,
  downhill releases; needs ``grad_x``/``grad_y``);
* burst gain ``B * burst_gain``; lateral outputs are the ``lateral_x/y``
  channels (0 if absent); skin stretch is ``target * f / (mu_s N)`` with
  ``target`` the ``skin_stretch`` channel or ``[skin_stretch] target`` of
  the profile (0 if neither).

Real-time rules for :meth:`Renderer.step`
-----------------------------------------
* Build the renderer (and so compile and warm the kernels) before the
  real-time loop; :meth:`reset` also allocates nothing.
* The tick itself allocates no memory: inputs are two floats, outputs go
  into preallocated buffers (:attr:`Renderer.last` values,
  :attr:`audio_block`), the event ring has a fixed size. Only the call from
  Python allocates (and frees before returning) small objects: the float
  returned, and numba's wrappers of the record and the workspace arrays. A
  hard real-time host calls :func:`online_step` from its own compiled loop
  (with ``Renderer.online_state, _blocks, _data, _bg, _ev, _audio``; tested
  to allocate nothing per tick) or uses the C runtime.
* Work per call is one table lookup (a scan over the table's blocks), one
  model tick, and the audio samples of the tick; the exact model adds one
  closed-form root search per phase change.
* Call ``step`` exactly once per tick, ``1 / tick_rate`` apart in cursor
  time; do not call :meth:`render` or read list-building properties from
  the real-time thread.
* ``step`` raises :class:`~shapedisplay.errors.ModelError` only if an
  explicit baseline model (``euler``/``rk4``) diverges.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..errors import InputError, ModelError
from ..table import FrictionTable
from .borrow import unsigned
from .bursts import (CARRIER_BLOCK, carrier_anchors, carrier_at, envelope_at, finished_events, forget_events,
                     new_burst_state, render_bursts, sample_times, synth)
from .cursor import MAX_POSITION_M, CursorPath
from .dispatch import model_tick, render_ticks
from .layouts import NSLOT, ONLINE, OUTPUTS, PAD_STATE, SLOTS, Slot
from .lookup import _packed_index, axis_cell_at, bilinear, corners, sample_all
from .models import PadModel, check_dispatch, divergence_message
from .result import RenderResult
# the settings' home is .settings (numba-free, shared with the C engine); these names stay importable from here
from .settings import (audio_length, constant_normal_force, derive_config, device_for_table,  # noqa: F401
                       mapping_settings, render_settings, slot_channels)


def _read_only(a):
    """A read-only view of the array ``a`` (the same memory)."""
    view = a.view()
    view.setflags(write=False)          # (about half the time of setting flags.writeable)
    return view


def _one_value(row, n):
    """``row`` as shape (n,): itself if it has n elements, else a read-only view of its one value on
    every tick (stride 0; no memory written per tick)."""
    if row.shape[0] == n:
        return row
    view = np.ndarray((n,), row.dtype, row, 0, (0,))
    view.setflags(write=False)
    return view


#: Names of the per-tick outputs of :meth:`Renderer.step` (fields of :data:`~.layouts.OUTPUTS`).
OUT_NAMES = OUTPUTS.names

_RING = 4096
#: Carrier anchors a renderer keeps from render to render (blocks of CARRIER_BLOCK samples: about 5.8 minutes of
#: audio at 48 kHz, 4 MiB); a longer stream computes the anchors past them as it goes.
_KEPT_ANCHOR_BLOCKS = 1 << 18
#: Audio sample times a renderer keeps from render to render for paths that start at t = 0 (8 MiB: about 21.8 s
#: of audio at 48 kHz); a longer stream computes its times.
_KEPT_TIME_SAMPLES = 1 << 20

#: See shapedisplay.runtime.codegen: numba's cache does not notice changes to the kernels that
#: online_step compiles in (dispatch/pads, lookup, bursts) or to the constants of layouts.py.
KERNEL_SOURCES_SHA256 = "e6c4ce15c51f0a1daa1568d8001fe712c49e1dc40d386de541b463e03dd14dfd"


@njit(cache=True, inline="always")
def _derive(vals, cfg, slot_channel, vx, vy, speed):
    """Per-tick model inputs from the slot values: (N, mu_s, mu_k, gain).

    ``cfg`` is a RENDER_CONFIG record; slot ``s`` is stored if ``slot_channel[s] >= 0``.
    """
    N = vals[Slot.NORMAL_FORCE] if slot_channel[Slot.NORMAL_FORCE] >= 0 else cfg.normal_force_constant
    if N < 0.0:
        N = 0.0
    fs = vals[Slot.FRICTION_SCALE] if slot_channel[Slot.FRICTION_SCALE] >= 0 else 1.0
    if fs < 0.0:
        fs = 0.0
    mus = cfg.mu_s * fs
    muk = cfg.mu_k * fs
    if slot_channel[Slot.BREAKAWAY_FORCE] >= 0 and N > 0.0:
        mus = max(vals[Slot.BREAKAWAY_FORCE], 0.0) / N
    if slot_channel[Slot.KINETIC_FORCE] >= 0 and N > 0.0:
        muk = max(vals[Slot.KINETIC_FORCE], 0.0) / N
    if cfg.k_mu != 0.0 and speed > 0.0 and slot_channel[Slot.GRAD_X] >= 0:
        gy = vals[Slot.GRAD_Y] if slot_channel[Slot.GRAD_Y] >= 0 else 0.0
        slope = (vals[Slot.GRAD_X] * vx + gy * vy) / speed
        if slope > 0.0:
            mus += cfg.k_mu * slope
            muk += cfg.k_mu * slope
    if muk > mus:
        muk = mus
    gain = vals[Slot.BURST_GAIN] if slot_channel[Slot.BURST_GAIN] >= 0 else 1.0
    if gain < 0.0:
        gain = 0.0
    return N, mus, muk, gain


@njit(cache=True, inline="always")
def _axis_speed(vx, vy, ax, ay):
    """Signed pad speed along an axis that follows the motion (reversal -> negative)."""
    sp = math.sqrt(vx * vx + vy * vy)
    if sp == 0.0:
        return 0.0, ax, ay
    dx = vx / sp
    dy = vy / sp
    if dx * ax + dy * ay >= 0.0:
        return sp, dx, dy
    return -sp, -dx, -dy


@njit(cache=True)
def prepare_inputs(t, x, y, vals, config, slot_channel, V, vx, vy, N, mus, muk, gain):
    """Offline: per-tick velocities and model inputs (arrays of shape (n,); ``vals`` (NSLOT, n);
    ``config`` a one-element RENDER_CONFIG array)."""
    cfg = config[0]
    n = t.shape[0]
    ax = 1.0
    ay = 0.0
    for i in range(n):
        if i == 0:
            vx[i] = 0.0
            vy[i] = 0.0
        else:
            h = t[i] - t[i - 1]
            vx[i] = (x[i] - x[i - 1]) / h
            vy[i] = (y[i] - y[i - 1]) / h
        V[i], ax, ay = _axis_speed(vx[i], vy[i], ax, ay)
        sp = abs(V[i])
        N[i], mus[i], muk[i], gain[i] = _derive(vals[:, i], cfg, slot_channel, vx[i], vy[i], sp)


#: Rows of the block :func:`lookup_inputs` fills, in order.
INPUT_ROWS = ("V", "vx", "vy", "normal_force", "mu_s", "mu_k", "gain", "lateral_x", "lateral_y", "skin_target")


@njit(cache=True, error_model="numpy")
def lookup_inputs(t, x, y, blocks, data, bg, grid, config, slot_channel, out, scratch, every_row):
    """Offline: each tick's table lookup at its motion midpoint, velocities and model inputs.

    ``blocks, data, bg, grid``: the packed table (:func:`.lookup.pack_channels`); ``config``: a
    one-element RENDER_CONFIG array; ``out``: (len(INPUT_ROWS), n) float64, rows named by
    :data:`INPUT_ROWS`; ``scratch``: (4, n) int64, overwritten. Per tick the arithmetic of
    :meth:`FrictionTable.sample` (the lookup) and of :func:`prepare_inputs` (the rest), so the values are
    theirs bit for bit; but no (NSLOT, n) array of looked-up values is written and read back.

    Returns a bit mask of the rows that hold one value on every tick (bit ``r`` for row ``r``; 0 unless
    the table takes :func:`_lookup_passes`, where ``mu_s`` and ``mu_k`` always do): ``mu_s``, ``mu_k``;
    ``gain``, ``lateral_x``, ``lateral_y``, ``skin_target`` of a table without their channel; ``vy`` on
    a path along x. Unless ``every_row``, those rows get only their first element:
    :meth:`Renderer.render` hands :func:`~.dispatch.render_ticks` one-element rows and returns
    read-only views of the one value instead of writing it once per tick. Bit 0 (``V``) has its own
    meaning: ``V`` is ``vx`` bit for bit (a path along x with no ``-0`` in ``vx``) and was not written
    (only without ``every_row``): read ``vx``.

    A table whose friction coefficients do not vary along the path (no ``friction_scale``,
    ``breakaway_force`` or ``kinetic_force`` channel, no active slope term) takes
    :func:`_lookup_passes`: one pass per quantity, each a short loop the compiler vectorises where it
    can. Any other table takes :func:`_lookup_fused`, one pass over the ticks that derives every input.

    Compiled with numpy's error model: no division here can have a zero divisor (``h > 0`` on a cursor
    path, the grid spacing > 0, ``N``, speed and ``sp`` tested before dividing), so only the
    ZeroDivisionError checks go, which otherwise kept the inlined lookup and derivation from being
    optimised as one loop body (the same values, about 1.3x faster).
    """
    cfg = config[0]
    varying = (slot_channel[Slot.FRICTION_SCALE] >= 0 or slot_channel[Slot.BREAKAWAY_FORCE] >= 0
               or slot_channel[Slot.KINETIC_FORCE] >= 0 or (cfg.k_mu != 0.0 and slot_channel[Slot.GRAD_X] >= 0))
    if varying:
        _lookup_fused(t, x, y, blocks, data, bg, grid, config, slot_channel, out)
        return 0
    return _lookup_passes(t, x, y, blocks, data, bg, grid, config, slot_channel, out, scratch, every_row)


#: Magnitudes whose squares are normal numbers (with margin; see :func:`_motion`).
_SQUARE_LO = 2.0 ** -500
_SQUARE_HI = 2.0 ** 500


@njit(cache=True, error_model="numpy")
def _motion(t, x, y, grid, two_d, out, every_row):
    """Rows 0-2 of :func:`lookup_inputs` (``V``, ``vx``, ``vy``) and each tick's midpoint in table samples
    (rows 4 and 5, ``(x_mid - x0) / dx`` and the same in y if ``two_d``): what :func:`_axis_speed` and
    :func:`.lookup.corners` compute, in loops over whole rows (loops over views, which the compiler
    vectorises, divisions and square roots included). Returns ``(along_x, v_is_vx)``: True on a path along x,
    where ``vy`` is +0 on every tick (then written only at its first element unless ``every_row``); and True
    where ``V`` is ``vx`` bit for bit and was not written (only without ``every_row``)."""
    n = t.shape[0]
    if n == 0:
        return False, False
    sp = out[0]
    vx = out[1]
    vy = out[2]
    ux = out[4]
    uy = out[5]
    vx[0] = 0.0
    vy[0] = 0.0
    t1 = t[1:]
    t0 = t[:-1]
    x1 = x[1:]
    x0 = x[:-1]
    y1 = y[1:]
    y0 = y[:-1]
    vx1 = vx[1:]
    vy1 = vy[1:]
    # a path along x (every y the same finite number): vy is (y - y) / h = +0 and uy = +0 / |v| = +0 (unused
    # where the speed is 0), so neither is divided out, and |v| = sqrt(vx vx + 0) is sqrt(vx vx) (the unit
    # vector's x is unused where the speed is 0 too)
    y_first = y[0]
    along_x = math.isfinite(y_first)
    v_is_vx = False
    for i in range(n - 1):
        along_x &= y1[i] == y_first
    axis_pass = True
    midpoints = False
    if along_x:
        # one pass for vx, the checks below on it and the midpoints in table samples (row 4, which this path
        # needs for nothing else unless a check fails: then computed again after the unit vectors)
        gx0 = grid.x0
        gdx = grid.dx
        fx1 = ux[1:]
        in_range = True
        neg_zero = False
        for i in range(n - 1):
            b = x1[i]
            a = x0[i]
            v = (b - a) / (t1[i] - t0[i])
            vx1[i] = v
            fx1[i] = (0.5 * (b + a) - gx0) / gdx
            m = abs(v)
            in_range &= (m == 0.0) | ((m >= _SQUARE_LO) & (m <= _SQUARE_HI))
            neg_zero |= (m == 0.0) & (math.copysign(1.0, v) < 0.0)
        ux[0] = (x[0] - gx0) / gdx
        midpoints = True
        if every_row:
            vy[:] = 0.0
        # sqrt(vx vx) is |vx| where vx vx is a normal number (in binary floating point the rounded square root
        # of a rounded square is the magnitude), and then vx / |vx| is +-1: checked to hold on every tick first.
        # Then the unit vector is (+-1, +0), and the pad axis, (1, 0) at the start, stays (1, +-0) from tick to
        # tick: a tick along it keeps it and gets |vx|, a tick against it (dx ax + dy ay = -1 < 0) gets -|vx|
        # and the axis -(-1, +0) = (1, -0); so V is vx itself, +0 where vx is a zero (the speed is 0), and
        # the pass in order is not needed. V is vx bit for bit unless some vx is -0 (V is +0 there): then V is
        # not written at all (vx[0] = +0 passes both checks).
        if not every_row and in_range and not neg_zero:
            v_is_vx = True
        if not v_is_vx:
            in_range = True
            for i in range(n):
                v = vx[i]
                a = abs(v)
                in_range &= (a == 0.0) | ((a >= _SQUARE_LO) & (a <= _SQUARE_HI))
                sp[i] = v if v != 0.0 else 0.0
        if in_range:
            axis_pass = False
        else:
            uy[:] = 0.0
            midpoints = False
            for i in range(n):
                s = math.sqrt(vx[i] * vx[i])
                sp[i] = s
                ux[i] = vx[i] / s
    else:
        for i in range(n - 1):
            h = t1[i] - t0[i]
            vx1[i] = (x1[i] - x0[i]) / h
            vy1[i] = (y1[i] - y0[i]) / h
        # the unit vector of the motion (rows 4, 5; unused where the speed is 0)
        for i in range(n):
            s = math.sqrt(vx[i] * vx[i] + vy[i] * vy[i])
            sp[i] = s
            ux[i] = vx[i] / s
            uy[i] = vy[i] / s
    if axis_pass:
        # the pad axis follows the motion: one short pass in order (each tick's sign depends on the last axis)
        ax = 1.0
        ay = 0.0
        for i in range(n):
            s = sp[i]
            if s == 0.0:
                sp[i] = 0.0
            else:
                dx = ux[i]
                dy = uy[i]
                if dx * ax + dy * ay >= 0.0:
                    ax = dx
                    ay = dy
                else:
                    sp[i] = -s
                    ax = -dx
                    ay = -dy
    # the midpoints in table samples
    if not midpoints:
        ux[0] = (x[0] - grid.x0) / grid.dx
        fx = ux[1:]
        for i in range(n - 1):
            fx[i] = (0.5 * (x1[i] + x0[i]) - grid.x0) / grid.dx
    if two_d:
        uy[0] = (y[0] - grid.y0) / grid.dy
        fy = uy[1:]
        for i in range(n - 1):
            fy[i] = (0.5 * (y1[i] + y0[i]) - grid.y0) / grid.dy
    return along_x, v_is_vx


#: Row of :func:`lookup_inputs`' block that each stored channel's slot fills (-1: none).
_CHANNEL_ROW = np.full(NSLOT, -1, np.int64)
_CHANNEL_ROW[[Slot.NORMAL_FORCE, Slot.BURST_GAIN, Slot.LATERAL_X, Slot.LATERAL_Y, Slot.SKIN_STRETCH]] = 3, 6, 7, 8, 9


@njit(cache=True, error_model="numpy")
def _lookup_passes(t, x, y, blocks, data, bg, grid, config, slot_channel, out, scratch, every_row):
    """:func:`lookup_inputs` for a table whose ``mu_s``, ``mu_k`` are the device's: motion, cells, channels,
    then the derivation of :func:`_derive` row by row. Returns the mask of rows that hold one value."""
    cfg = config[0]
    n = t.shape[0]
    two_d = grid.rows != 1
    ones = (1 << 4) | (1 << 5)
    along_x, v_is_vx = _motion(t, x, y, grid, two_d, out, every_row)
    if along_x:
        ones |= 1 << 2
    if v_is_vx:
        ones |= 1
    # the four samples around each midpoint (scratch rows) and their weights (rows 4, 5 in place)
    fx = out[4]
    fy = out[5]
    last = data.shape[1] - 1
    i00 = scratch[0]
    i01 = scratch[1]
    i10 = scratch[2]
    i11 = scratch[3]
    single = False
    if bg.shape[0] > 0:
        cols = grid.cols
        rows = grid.rows
        # one block covering the canvas (a dense table): a sample's index is the block's offset + r cols + c,
        # no search over the blocks
        whole = (blocks.shape[0] == 1 and blocks[0, 0] == 0 and blocks[0, 1] == 0 and blocks[0, 2] == rows
                 and blocks[0, 3] == cols)
        off = blocks[0, 4] if whole else 0
        nstored = 0
        one = Slot.NORMAL_FORCE
        for sl in (Slot.NORMAL_FORCE, Slot.BURST_GAIN, Slot.LATERAL_X, Slot.LATERAL_Y, Slot.SKIN_STRETCH):
            if slot_channel[sl] >= 0:
                nstored += 1
                one = sl
        if whole and not two_d and nstored == 1:
            # a dense one-row table with one channel for these rows (a profile along x): its cell and value in
            # one loop, without the index and weight rows
            single = True
            row = _CHANNEL_ROW[one]
            clamp = one == Slot.NORMAL_FORCE or one == Slot.BURST_GAIN
            d = data[slot_channel[one]]
            dst = out[row]
            # (cells >= 0: indexed as unsigned, without the check for a negative index)
            if clamp:
                for i in range(n):
                    c0, c1, tx = axis_cell_at(fx[i], cols)
                    v = d[unsigned(off + c0)] * (1 - tx) + d[unsigned(off + c1)] * tx
                    dst[i] = 0.0 if v < 0.0 else v
            else:
                for i in range(n):
                    c0, c1, tx = axis_cell_at(fx[i], cols)
                    dst[i] = d[unsigned(off + c0)] * (1 - tx) + d[unsigned(off + c1)] * tx
        elif whole and not two_d:
            for i in range(n):
                c0, c1, tx = axis_cell_at(fx[i], cols)
                fx[i] = tx
                i00[i] = off + c0
                i01[i] = off + c1
        elif whole:
            for i in range(n):
                c0, c1, tx = axis_cell_at(fx[i], cols)
                r0, r1, ty = axis_cell_at(fy[i], rows)
                fx[i] = tx
                fy[i] = ty
                i00[i] = off + r0 * cols + c0
                i01[i] = off + r0 * cols + c1
                i10[i] = off + r1 * cols + c0
                i11[i] = off + r1 * cols + c1
        else:
            for i in range(n):
                c0, c1, tx = axis_cell_at(fx[i], cols)
                fx[i] = tx
                if two_d:
                    r0, r1, ty = axis_cell_at(fy[i], rows)
                    fy[i] = ty
                    i00[i] = _packed_index(blocks, r0, c0, last)
                    i01[i] = _packed_index(blocks, r0, c1, last)
                    i10[i] = _packed_index(blocks, r1, c0, last)
                    i11[i] = _packed_index(blocks, r1, c1, last)
                else:
                    i00[i] = _packed_index(blocks, 0, c0, last)
                    i01[i] = _packed_index(blocks, 0, c1, last)
    # each stored channel into its row (N, gain, lateral x/y, skin target); a missing one gets its default. N and
    # the gain are clamped at 0 in the same loop (the derivation of _derive with fs = 1 and no slope term).
    for s, row, default, clamp in ((Slot.NORMAL_FORCE, 3, cfg.normal_force_constant, True),
                                   (Slot.BURST_GAIN, 6, 1.0, True), (Slot.LATERAL_X, 7, 0.0, False),
                                   (Slot.LATERAL_Y, 8, 0.0, False), (Slot.SKIN_STRETCH, 9, cfg.skin_target, False)):
        ch = slot_channel[s]
        dst = out[row]
        if ch < 0:
            if every_row or row == 3:
                dst[:] = 0.0 if clamp and default < 0.0 else default
            elif n > 0:                     # one value on every tick: its first element
                dst[0] = 0.0 if clamp and default < 0.0 else default
            if row != 3:
                ones |= 1 << row
            continue
        if single:
            continue
        d = data[ch]
        if two_d and clamp:
            for i in range(n):
                tx = fx[i]
                ty = fy[i]
                top = d[i00[i]] * (1 - tx) + d[i01[i]] * tx
                bot = d[i10[i]] * (1 - tx) + d[i11[i]] * tx
                v = top * (1 - ty) + bot * ty
                dst[i] = 0.0 if v < 0.0 else v
        elif two_d:
            for i in range(n):
                tx = fx[i]
                ty = fy[i]
                top = d[i00[i]] * (1 - tx) + d[i01[i]] * tx
                bot = d[i10[i]] * (1 - tx) + d[i11[i]] * tx
                dst[i] = top * (1 - ty) + bot * ty
        elif clamp:
            for i in range(n):
                tx = fx[i]
                v = d[i00[i]] * (1 - tx) + d[i01[i]] * tx
                dst[i] = 0.0 if v < 0.0 else v
        else:
            for i in range(n):
                tx = fx[i]
                dst[i] = d[i00[i]] * (1 - tx) + d[i01[i]] * tx
    # constant mu_s, mu_k
    mus = cfg.mu_s * 1.0
    muk = cfg.mu_k * 1.0
    if muk > mus:
        muk = mus
    if every_row:
        out[4, :] = mus
        out[5, :] = muk
    elif n > 0:
        out[4, 0] = mus
        out[5, 0] = muk
    return ones


@njit(cache=True, error_model="numpy")
def _lookup_fused(t, x, y, blocks, data, bg, grid, config, slot_channel, out):
    """:func:`lookup_inputs` in one pass over the ticks (any table)."""
    cfg = config[0]
    n = t.shape[0]
    nch = bg.shape[0]
    vals = np.zeros(NSLOT)
    skin = slot_channel[Slot.SKIN_STRETCH]
    last = data.shape[1] - 1
    one_row = grid.rows == 1
    ax = 1.0
    ay = 0.0
    for i in range(n):
        if i == 0:
            vx = 0.0
            vy = 0.0
            xm = x[0]
            ym = y[0]
        else:
            h = t[i] - t[i - 1]
            vx = (x[i] - x[i - 1]) / h
            vy = (y[i] - y[i - 1]) / h
            xm = 0.5 * (x[i] + x[i - 1])
            ym = 0.5 * (y[i] + y[i - 1])
        if nch > 0:
            i00, i01, i10, i11, tx, ty = corners(blocks, grid, last, xm, ym)
            for s in range(NSLOT):
                j = slot_channel[s]
                vals[s] = bilinear(data, j, one_row, i00, i01, i10, i11, tx, ty) if j >= 0 else 0.0
        V, ax, ay = _axis_speed(vx, vy, ax, ay)
        N, mus, muk, gain = _derive(vals, cfg, slot_channel, vx, vy, abs(V))
        out[0, i] = V
        out[1, i] = vx
        out[2, i] = vy
        out[3, i] = N
        out[4, i] = mus
        out[5, i] = muk
        out[6, i] = gain
        out[7, i] = vals[Slot.LATERAL_X]
        out[8, i] = vals[Slot.LATERAL_Y]
        out[9, i] = vals[Slot.SKIN_STRETCH] if skin >= 0 else cfg.skin_target


@njit(cache=True, error_model="numpy")
def skin_stretch_of(target, f, mus, N, out):
    """``out = target * f / (mus * N)`` where ``mus * N > 0``, else 0 (arrays of shape (n,); ``mus`` may
    have shape (1,), one value on every tick).

    numpy's error model: the division is only taken where ``mus * N > 0``, so no ZeroDivisionError check
    is needed, and without it the loop vectorises (the same values)."""
    if mus.shape[0] != f.shape[0]:
        mu = mus[0]
        for i in range(f.shape[0]):
            lim = mu * N[i]
            out[i] = target[i] * f[i] / lim if lim > 0.0 else 0.0
        return
    for i in range(f.shape[0]):
        lim = mus[i] * N[i]
        out[i] = target[i] * f[i] / lim if lim > 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def skin_stretch_uniform(target, f, mus, N, out):
    """:func:`skin_stretch_of` for one ``target`` (float) on every tick, the same values.

    A zero target (a table without a ``skin_stretch`` channel on a profile without a skin-stretch
    target) needs no division: ``target * f`` is a signed zero (or NaN), which dividing by a positive
    ``mus * N`` leaves as it is. ``mus`` may have shape (1,), one value on every tick."""
    if mus.shape[0] != f.shape[0]:
        _skin_uniform_mu(target, f, mus[0], N, out)
    elif target == 0.0:
        for i in range(f.shape[0]):
            lim = mus[i] * N[i]
            out[i] = target * f[i] if lim > 0.0 else 0.0
    else:
        for i in range(f.shape[0]):
            lim = mus[i] * N[i]
            out[i] = target * f[i] / lim if lim > 0.0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _skin_uniform_mu(target, f, mu, N, out):
    """:func:`skin_stretch_uniform` for one ``mu`` (float) on every tick."""
    if target == 0.0:
        for i in range(f.shape[0]):
            lim = mu * N[i]
            out[i] = target * f[i] if lim > 0.0 else 0.0
    else:
        for i in range(f.shape[0]):
            lim = mu * N[i]
            out[i] = target * f[i] / lim if lim > 0.0 else 0.0


def friction_limits(channels: dict, mu_s: float, mu_k: float) -> tuple[np.ndarray, np.ndarray]:
    """Breakaway and kinetic force of each sample with the cursor at rest, as every tick derives them.

    Runs the renderer's own per-tick derivation (:func:`_derive`) on every
    sample, so a preview shows what the renderer plays: ``N`` clamped at 0,
    ``mu_s`` and ``mu_k`` times ``friction_scale`` (or ``breakaway_force / N``
    and ``kinetic_force / N`` where stored), ``mu_k <= mu_s``. At rest the
    direction-dependent slope term is zero.

    Parameters
    ----------
    channels : dict name -> ndarray, all of one shape, SI
        Table channels (names from :data:`SLOTS`; others are ignored); must
        hold ``normal_force``.
    mu_s, mu_k : float
        The device's static and kinetic friction coefficients.

    Returns
    -------
    breakaway, kinetic : ndarray of the channels' shape, float64, N
        ``mu_s N`` and ``mu_k N`` as the renderer derives them.
    """
    if "normal_force" not in channels:
        raise InputError(f"friction limits need channel 'normal_force' (got {sorted(channels)})")
    shape = np.shape(channels["normal_force"])
    n = int(np.prod(shape))
    present = [name for name in SLOTS if name in channels]
    vals = np.zeros((NSLOT, n))
    for i, name in enumerate(SLOTS):
        if name in channels:
            vals[i] = np.broadcast_to(np.asarray(channels[name], dtype=np.float64), shape).ravel()
    t = np.arange(n, dtype=np.float64)          # any increasing times: the cursor stands still
    still = np.zeros(n)
    V, vx, vy, N, mus, muk, gain = arrs = np.empty((7, n))
    prepare_inputs(t, still, still, vals, derive_config(mu_s, mu_k), slot_channels(present), *arrs)
    return (mus * N).reshape(shape), (muk * N).reshape(shape)


@njit(cache=True)
def online_step(state, blocks, data, bg, ev, audio, x, y):
    """Online: one tick at cursor position (x, y) m. Returns the burst drive value.

    ``state`` is the float64 buffer of one :data:`~.layouts.ONLINE` record (pad
    state, settings, counters and outputs; a plain array crosses from Python to
    the compiled code faster than a structured one); ``blocks, data, bg`` the packed table (:func:`.lookup.pack_channels`);
    ``ev`` the (2, ring) event times and amplitudes; ``audio`` the tick's audio block.
    """
    R = state.view(ONLINE)[0]
    st = R.pad
    cfg = R.cfg
    run = R.run
    out = R.out
    vals = R.vals
    k = run.tick
    rate = cfg.tick_rate
    t = run.t0 + k / rate
    if k == 0.0:
        h = 0.0
        vx = 0.0
        vy = 0.0
        xm = x
        ym = y
    else:
        h = t - (run.t0 + (k - 1.0) / rate)
        vx = (x - run.xp) / h
        vy = (y - run.yp) / h
        xm = 0.5 * (x + run.xp)
        ym = 0.5 * (y + run.yp)
    V, ax, ay = _axis_speed(vx, vy, run.ax, run.ay)
    run.ax = ax
    run.ay = ay
    if bg.shape[0] > 0:
        sample_all(blocks, data, bg, R.grid, xm, ym, R.scratch)
    for s in range(NSLOT):
        j = R.slot_channel[s]
        vals[s] = R.scratch[j] if j >= 0 else 0.0
    N, mus, muk, gain = _derive(vals, cfg, R.slot_channel, vx, vy, abs(V))
    ev_t = ev[0]
    ev_a = ev[1]
    bs = R.bursts
    # forget bursts that have finished (and that the burst state no longer needs)
    dur = cfg.rise_s + cfg.decay_s
    nrec = run.n_recent
    done = finished_events(bs, cfg.policy)
    drop = 0
    while drop < nrec and drop < done and ev_t[drop] + dur <= t - h:
        drop += 1
    if nrec > ev_t.shape[0] // 2 and drop == 0:
        drop = nrec - ev_t.shape[0] // 4
        run.events_dropped += drop
    if drop > 0:
        forget_events(bs, ev_t, ev_a, drop, cfg.rise_s, cfg.decay_s, cfg.policy)
        for i in range(drop, nrec):
            ev_t[i - drop] = ev_t[i]
            ev_a[i - drop] = ev_a[i]
        nrec -= drop
    nev = 0
    if h > 0.0:
        n1 = model_tick(cfg.model, st, cfg.pad, t - h, h, V, N, mus, muk, gain, ev_t, ev_a, nrec)
        nev = n1 - nrec
        if n1 > ev_t.shape[0]:
            run.events_dropped += n1 - ev_t.shape[0]
            n1 = ev_t.shape[0]
        nrec = n1
    run.n_recent = nrec
    run.events_total += nev
    # audio samples with times in (t - h, t]
    j0 = run.next_sample
    j1 = int(math.floor((t - run.t0) * cfg.audio_rate + 1e-9)) + 1
    if j1 - j0 > audio.shape[0]:
        j0 = j1 - audio.shape[0]
    if j1 > j0:
        run.clipped += synth(bs, ev_t, ev_a, nrec, run.t0, cfg.audio_rate, j0, j1, cfg.carrier_hz, cfg.rise_s,
                             cfg.decay_s, cfg.policy, audio)
    run.next_sample = j1
    drive = envelope_at(bs, ev_t, ev_a, nrec, t, cfg.rise_s, cfg.decay_s, cfg.policy) \
        * carrier_at(t, run.t0, cfg.carrier_hz)
    drive = min(max(drive, -1.0), 1.0)
    f = st.f
    out.t = t
    out.x = x
    out.y = y
    out.vx = vx
    out.vy = vy
    out.pad_speed = V
    out.normal_force = N
    out.friction_force = f
    out.state = st.phase
    out.lateral_x = vals[Slot.LATERAL_X]
    out.lateral_y = vals[Slot.LATERAL_Y]
    target = vals[Slot.SKIN_STRETCH] if R.slot_channel[Slot.SKIN_STRETCH] >= 0 else cfg.skin_target
    out.skin_stretch = target * f / (mus * N) if mus * N > 0.0 else 0.0
    out.events = nev
    out.drive = drive
    out.audio_samples = max(j1 - j0, 0)
    run.xp = x
    run.yp = y
    run.tick = k + 1.0
    return drive


class Renderer:
    """Stick-slip renderer of a friction-envelope table.

    Parameters
    ----------
    table : FrictionTable
        Channels are used when present (see the module docstring); without
        ``normal_force`` N is the header's constant ``mapping.n_base``.
    device : DeviceProfile, path, bundled name or None
        Pad, friction and burst parameters. Default: ``table.meta["device"]``
        if present, else the built-in Konyo profile.
    model : str or PadModel
        A name from :data:`~shapedisplay.runtime.models.MODELS`.
    tick_rate : float, optional
        Hz (100 Hz .. 192 kHz); default the device's tick rate.
    audio_rate : float, optional
        Hz (1 kHz .. 384 kHz); default the device's audio rate.
    burst_policy : {"retrigger", "add", "max"}
    max_stick_period : float, optional
        s; force a slip (and burst) when stuck longer (0 or None = device
        setting, off by default).
    **model_options
        Passed to the model class (e.g. ``variant="premax"`` for stribeck).
    """

    def __init__(self, table: FrictionTable, device=None, model="exact", tick_rate=None, audio_rate=None,
                 burst_policy="retrigger", max_stick_period=None, **model_options):
        check_dispatch()
        cfg = render_settings(table, device, model, tick_rate, audio_rate, burst_policy, max_stick_period,
                              **model_options)
        self.table = table
        self.device = cfg.device
        self.model: PadModel = cfg.model
        #: N (newtons) of a table without a ``normal_force`` channel, else None.
        self.normal_force_constant = cfg.normal_force_constant
        self.tick_rate = cfg.tick_rate
        self.audio_rate = cfg.audio_rate
        self.burst_policy = cfg.burst_policy
        self._policy = int(cfg.config[0]["policy"])
        self.present = cfg.present
        #: The renderer's settings, a RENDER_CONFIG record (the C runtime's sd_config_t, byte for byte).
        self._config = cfg.config
        self.config = self._config[0]
        self._slot_channel = slot_channels(self.present)
        self._anchors = np.empty(0)
        self._times = np.empty(0)
        self._build_online()
        self.reset()
        # warm the compiled step on a scratch copy (compilation never happens in the real-time loop)
        R = self.online_state.copy()
        online_step(R, self._blocks, self._data, self._bg, self._ev.copy(), self._audio.copy(), 0.0, 0.0)

    # ------------------------------------------------------------------ offline
    def _inputs(self, cp: CursorPath, block=None, scratch=None) -> np.ndarray:
        """The (len(INPUT_ROWS), n) block of per-tick inputs of an offline run (:func:`lookup_inputs`),
        written into ``block`` if given; ``scratch``: 4 rows of n float64 it may overwrite."""
        if block is None:
            block = np.empty((len(INPUT_ROWS), cp.t.size))
        scratch = (np.empty((4, cp.t.size)) if scratch is None else scratch).view(np.int64)
        lookup_inputs(cp.t, cp.x, cp.y, self._blocks, self._data, self._bg, self._grid, self._config,
                      self._slot_channel, block, scratch, True)
        return block

    def model_inputs(self, cursor: CursorPath):
        """The per-tick inputs :meth:`render` gives the model for ``cursor`` (after the table lookup).

        Returns ``(t, V, N, mu_s, mu_k, gain)``, each ndarray (n,), float64
        (s, m/s, N, 1, 1, 1): the arguments of :func:`~.models.run_kernel`
        after the model. A path not on this renderer's tick grid is resampled.
        """
        cp = cursor if cursor.tick_rate == self.tick_rate else cursor.resample(self.tick_rate)
        V, _, _, N, mus, muk, gain, _, _, _ = self._inputs(cp)
        return cp.t, V, N, mus, muk, gain

    def render(self, cursor: CursorPath) -> RenderResult:
        """Render a whole cursor path offline (the fast path).

        A path not on this renderer's tick grid is resampled to ``tick_rate``.
        Raises :class:`ModelError` if an explicit baseline diverges, :class:`InputError` if the
        audio would exceed :data:`~shapedisplay.runtime.bursts.MAX_AUDIO_SAMPLES`.
        """
        if not isinstance(cursor, CursorPath):
            raise InputError(f"`cursor` must be a CursorPath (got {type(cursor).__name__})")
        cp = cursor if cursor.tick_rate == self.tick_rate else cursor.resample(self.tick_rate)
        n_audio = audio_length(cp.duration, self.audio_rate)     # refuse an impossible stream before the work
        # every per-tick array of the run in one block: the inputs, the friction force, skin stretch and the
        # lookup's scratch rows (untouched by most tables). Fewer, larger allocations are reused by the allocator
        # from run to run instead of being returned to the system and faulted in again (most of a short render's
        # cost).
        k = len(INPUT_ROWS)
        n = cp.t.size
        block = np.empty((k + 6, n))
        ins = block[:k]
        # the lookup leaves each row that holds one value on every tick with its first element only (bit r of
        # `ones` for row r)
        ones = lookup_inputs(cp.t, cp.x, cp.y, self._blocks, self._data, self._bg, self._grid, self._config,
                             self._slot_channel, ins, block[k + 2:].view(np.int64), False)
        f, ss = block[k], block[k + 1]
        # one-element rows for the model and the skin stretch (they read the value once), read-only views of
        # the value on every tick for the result
        rows = [ins[r, :1] if ones >> r & 1 and r > 0 and n > 0 else ins[r] for r in range(k)]
        V, vx, vy, N, mus, muk, gain, lat_x, lat_y, target = rows
        if ones & 1:                       # V is vx bit for bit (and was not written)
            V = vx
        phase = np.empty(n, np.int8)
        et, ea = self._run_model(cp.t, V, N, mus, muk, gain, f, phase)
        if self._slot_channel[Slot.SKIN_STRETCH] >= 0:
            skin_stretch_of(target, f, mus, N, ss)
        else:                              # every tick's target is the profile's
            skin_stretch_uniform(float(self.config["skin_target"]), f, mus, N, ss)
        vy, mus, lat_x, lat_y = (_one_value(a, n) for a in (vy, mus, lat_x, lat_y))
        # the result's t, x, y: the path's own rows as read-only views (float64 rows of another type), not copied
        t, x, y = (_read_only(np.asarray(a, np.float64)) for a in (cp.t, cp.x, cp.y))
        b = self.device.burst
        audio, clipped = render_bursts(et, ea, cp.t[0], cp.duration, self.audio_rate, b.carrier_hz, b.rise_s,
                                       b.decay_s, self.burst_policy, self._carrier_anchors(n_audio),
                                       self._sample_times(n_audio) if cp.t[0] == 0.0 else None)
        return RenderResult(t, x, y, vx, vy, N, f, phase, lat_x, lat_y, ss, et, ea, audio,
                            self.audio_rate, clipped, self.model.name, self.tick_rate, self.burst_policy, mus)

    def _carrier_anchors(self, n_audio):
        """The carrier's anchors (:func:`.bursts.carrier_anchors`) for a stream of ``n_audio`` samples, kept from
        render to render: they depend only on the carrier and the audio rate, and their sin/cos pairs cost
        about a fifth of the burst audio. Up to :data:`_KEPT_ANCHOR_BLOCKS` blocks are kept."""
        nb = min(-(-n_audio // CARRIER_BLOCK), _KEPT_ANCHOR_BLOCKS)
        if self._anchors.shape[0] < 2 * nb:
            self._anchors = carrier_anchors(float(self.device.burst.carrier_hz), float(self.audio_rate), nb)
        return self._anchors

    def _sample_times(self, n_audio):
        """The audio sample times of a stream from t = 0 (:func:`.bursts.sample_times`), kept from render to
        render for streams of up to :data:`_KEPT_TIME_SAMPLES` samples: the envelope reads them instead of
        writing them first (empty for a longer stream, whose times are computed as it is rendered)."""
        if n_audio > _KEPT_TIME_SAMPLES:
            return np.empty(0)
        if self._times.shape[0] < n_audio:
            times = np.empty(n_audio)
            sample_times(0.0, float(self.audio_rate), times)
            self._times = times
        return self._times

    def _run_model(self, t, V, N, mus, muk, gain, f, phase):
        """The model over one path's inputs, keeping what the render returns: friction force into ``f``,
        phase into ``phase`` (int8), and the events (times, amplitudes). The values of
        :func:`~.models.run_kernel` (``dispatch.render_ticks`` runs the same arithmetic and only stores
        less); raises :class:`ModelError` as :meth:`render` documents. ``mus, muk, gain``: shape (n,), or
        (1,) for one value on every tick."""
        model = self.model
        n = t.shape[0]
        cap = n // 8 + 1024          # grown and re-run if a path has more events
        while True:
            S = np.frombuffer(bytearray(model._fresh_state_bytes), PAD_STATE)
            ev = np.empty((2, cap))
            n_ev = render_ticks(model.model_id, S, model.param_block, t, V, N, mus, muk, gain, f, phase, ev[0], ev[1])
            if n_ev <= cap:
                break
            cap = n_ev + 64
        st = S[0]
        if st["truncated"] > 0:
            raise ModelError(f"model '{model.name}' reached its cap on phase changes in one tick "
                             f"({int(st['truncated'])} ticks cut); inputs are outside the model's range")
        if st["diverged"] != 0:
            raise ModelError(divergence_message(model, self.tick_rate, float(st["diverged_at"])))
        ev = ev[:, :n_ev].copy()
        return ev[0], ev[1]

    # ------------------------------------------------------------------ online
    def _build_online(self):
        from .lookup import pack_channels
        blocks, data, bg, grid = pack_channels(self.table, self.present)
        self._blocks, self._data, self._bg, self._grid = blocks, data, bg, grid
        R0 = np.zeros(ONLINE.itemsize // 8).view(ONLINE)       # one record on a float64 buffer
        R0["cfg"] = self.config
        R0["grid"] = grid
        R0["slot_channel"] = self._slot_channel
        self._R0 = R0
        self._R = R0.copy()
        self._ev = np.zeros((2, _RING))
        self._audio = np.zeros(int(math.ceil(self.audio_rate / self.tick_rate)) + 2)
        self.audio_block = self._audio
        #: The online state: the float64 buffer of one ONLINE record (argument of :func:`online_step`);
        #: ``_R`` is the same memory as a one-element ONLINE array.
        self.online_state = self._R.view(np.float64)
        self._diverged = self._R["pad"]["diverged"]      # a view: checked after every step

    def reset(self, t0: float = 0.0) -> None:
        """Start a new online run at cursor time ``t0`` (s): state stuck and relaxed, no bursts."""
        #: Cursor samples not played since the last reset (non-finite or beyond MAX_POSITION_M; the last
        #: valid position was held instead).
        self.held_positions = 0
        g = self.table.grid
        self._last_xy = (g.x0, g.y0)
        R = self._R
        R[:] = self._R0
        R["pad"] = self.model.new_state()
        R["run"]["ax"] = 1.0
        R["run"]["t0"] = float(t0)
        R["bursts"] = new_burst_state(self.device.burst.carrier_hz, self.audio_rate)
        self._ev[:] = 0.0
        self._audio[:] = 0.0
        #: Per-tick outputs of the last :meth:`step`: an OUTPUTS record (a view; ``last["drive"]``).
        self.last = R["out"][0]

    def step(self, x: float, y: float) -> float:
        """Advance one tick with the cursor at (x, y) metres; return the burst drive in [-1, 1].

        Outputs of the tick are in :attr:`last` (fields named in ``OUT_NAMES``;
        also :meth:`outputs`) and the tick's audio samples in
        ``audio_block[:audio_samples]``. Allocation-free; see the
        real-time rules in the module docstring.

        A position that is not finite or lies beyond ``MAX_POSITION_M`` (1 km)
        is not played: the last valid position is held and
        :attr:`held_positions` counts it (a stream from a device host cannot
        be refused sample by sample).
        """
        if abs(x) <= MAX_POSITION_M and abs(y) <= MAX_POSITION_M:      # False for NaN too
            self._last_xy = (x, y)
        else:
            self.held_positions += 1
            x, y = self._last_xy
        drive = online_step(self.online_state, self._blocks, self._data, self._bg, self._ev, self._audio, x, y)
        if self._diverged[0] != 0:
            pad = self._R[0]["pad"]
            raise ModelError(divergence_message(self.model, self.tick_rate, float(pad["diverged_at"])))
        return drive

    def outputs(self) -> dict:
        """The last tick's outputs as a dict (allocates; not for the real-time loop)."""
        return {name: float(self.last[name]) for name in OUT_NAMES}

    @property
    def audio_samples(self) -> int:
        """Number of valid samples in :attr:`audio_block` after the last :meth:`step`."""
        return int(self.last["audio_samples"])

    @property
    def clipped(self) -> int:
        """Audio samples limited to full scale since :meth:`reset`."""
        return int(self._R["run"]["clipped"][0])

    @property
    def event_count(self) -> int:
        """Stick-to-slip events since :meth:`reset`."""
        return int(self._R["run"]["events_total"][0])

    def recent_events(self):
        """(times, amplitudes) of the bursts still sounding (copies)."""
        n = int(self._R["run"]["n_recent"][0])
        return self._ev[0, :n].copy(), self._ev[1, :n].copy()
