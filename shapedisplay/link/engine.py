"""The device's render engine: cursor samples in, the burst drive of every renderer tick out.

One engine for every place that renders a stream the way the firmware does:
the emulated device (:mod:`.emulator`), the host's actuator-stream mode
(``shapedisplay device play --mode actuator``); the ticks are the C engine's
(:class:`~shapedisplay.render.Renderer`), as on the firmware. Between two cursor samples
the cursor moves linearly over ``tick_rate_hz // stream_rate_hz`` ticks
(:func:`step_period`); force input integrates ``v = alpha f`` per sample
(:func:`force_to_position`). No transport, no fault injection: those are the
emulator's.
"""
from __future__ import annotations

import numpy as np

from shapedisplay.link import protocol as P


def step_period(renderer, prev, x: float, y: float, per: int, out: np.ndarray) -> int:
    """Advance ``renderer`` over one cursor period; return the number of drive values written.

    The first cursor sample (``prev is None``) is the renderer's tick 0 at
    (x, y): one value. Every later sample runs ``per`` ticks with the cursor
    interpolated linearly from ``prev`` to (x, y), the last tick exactly at
    (x, y). ``out`` receives the burst drive of each tick (Renderer.step).
    Allocation-free; the device and the host (actuator mode, tests) share it.
    """
    if prev is None:
        out[0] = renderer.step(x, y)
        return 1
    x0, y0 = prev
    for j in range(1, per + 1):
        if j == per:
            out[j - 1] = renderer.step(x, y)
        else:
            f = j / per
            out[j - 1] = renderer.step(x0 + (x - x0) * f, y0 + (y - y0) * f)
    return per


def render_stream(renderer, x, y, per: int) -> np.ndarray:
    """Drive values the device renders for cursor samples ``x, y`` (m), flat, 1 + (n - 1) * per.

    Resets ``renderer`` first. Positions are used as given: pass them through
    float32 (``np.float32(x)``) to match what crossed the wire.
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.zeros_like(x) if y is None else np.asarray(y, dtype=np.float64)
    renderer.reset()
    out = np.empty(1 + max(x.size - 1, 0) * per)
    buf = np.empty(per)
    prev = None
    k = 0
    for i in range(x.size):
        m = step_period(renderer, prev, float(x[i]), float(y[i]), per, buf)
        out[k:k + m] = buf[:m]
        k += m
        prev = (float(x[i]), float(y[i]))
    return out


def actuator_blocks(renderer, x, y, per: int) -> np.ndarray:
    """Host-side rendering for an actuator-stream device: drive blocks of shape (n - 1, per).

    One block of ``per`` tick values per cursor sample after the first (tick 0
    carries no burst and is not sent), as :func:`render_stream` renders them.
    """
    return render_stream(renderer, x, y, per)[1:].reshape(-1, per)


def force_to_position(prev_pos, prev_v, fx: float, fy: float, alpha: float, dt: float):
    """One step of ``v = alpha f`` with the trapezoid rule (as :func:`runtime.cursor.force_input`)."""
    vx, vy = alpha * fx, alpha * fy
    if prev_pos is None:
        return (0.0, 0.0), (vx, vy)
    return (prev_pos[0] + 0.5 * (vx + prev_v[0]) * dt, prev_pos[1] + 0.5 * (vy + prev_v[1]) * dt), (vx, vy)


class RenderEngine:
    """Device-side renderer: one cursor sample in, the drive of each renderer tick out.

    Wraps :class:`shapedisplay.render.Renderer` through :func:`step_period`,
    exactly as the host's :func:`render_stream`, so host and emulated device
    produce identical samples. Input ``FORCE`` integrates ``v = alpha f``
    with the table's device cursor gain.
    """

    def __init__(self, table, model: str, tick_rate_hz: int, stream_rate_hz: int, input_kind: int,
                 renderer=None):
        from shapedisplay.errors import InputError
        from shapedisplay.render import Renderer
        self.per = max(1, tick_rate_hz // stream_rate_hz)
        self.input_kind = input_kind
        self.renderer = renderer if renderer is not None else Renderer(table, model=model,
                                                                        tick_rate=float(tick_rate_hz))
        self.alpha = float(self.renderer.device.cursor_gain)
        if input_kind == P.Input.FORCE and not self.alpha > 0:
            raise InputError(f"force input needs a cursor gain; the table's device profile "
                             f"'{self.renderer.device.name}' has cursor_gain 0")
        self.dt = 1.0 / stream_rate_hz
        self._buf = np.zeros(self.per)
        self._prev = None
        self._v = None

    def render(self, x: float, y: float) -> np.ndarray:
        if self.input_kind == P.Input.FORCE:
            pos, self._v = force_to_position(self._prev, self._v, x, y, self.alpha, self.dt)
            x, y = pos
        m = step_period(self.renderer, self._prev, x, y, self.per, self._buf)
        self._prev = (x, y)
        return self._buf[:m]


def warm_engine(model: str, tick_rate_hz: int, stream_rate_hz: int, engine=None) -> None:
    """Load and compile the runtime kernels once, on a one-sample table (not on a device's I/O path)."""
    from shapedisplay.table.model import FrictionTable, Grid, choose_quantization
    z = np.full((1, 2), 1.0)
    t = FrictionTable.from_dense(Grid(1, 2, 1e-3, 1e-3), {"normal_force": z},
                                 {"normal_force": choose_quantization(z, "float32")})
    eng = (engine or RenderEngine)(t, model, tick_rate_hz, stream_rate_hz, P.Input.POSITION)
    eng.render(0.0, 0.0)
    eng.render(1e-4, 0.0)
