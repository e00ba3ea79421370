"""The result of an offline render, whichever engine played it (numba kernels or the C runtime)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class RenderResult:
    """Everything one offline run produced (arrays are float64 of shape (n,) unless stated).

    Attributes
    ----------
    t : s, tick times; ``x, y`` : m, cursor; ``vx, vy`` : m/s, cursor velocity
    normal_force : N; ``friction_force`` : N, on the pad, signed along the pad axis
    state : int8, 0 stick / 1 slip at the end of each tick (a slip shorter than a tick shows only as an event)
    lateral_x, lateral_y : N, lateral-force cue; ``skin_stretch`` : m
    event_time, event_amplitude : (n_events,), s and full-scale amplitude
    audio : (n_audio,), float64 in [-1, 1] at ``audio_rate`` Hz, first sample at ``t[0]``
    clipped : int, audio samples limited to full scale
    model : str; ``tick_rate`` : Hz; ``burst_policy`` : str
    mu_s : (n,), the static friction coefficient of each tick (None when the C runtime played the path)

    :meth:`~.renderer.Renderer.render` returns ``t``, ``x`` and ``y`` as read-only views of the cursor path's
    own rows (of the path resampled to the tick rate if it was not on the tick grid; converted to float64 if
    it held another type), not copies. Copy them (``np.array(result.t)``) to write into them.

    A row that holds one value on every tick (``mu_s`` where the friction coefficients do not vary along
    the path, ``lateral_x``/``lateral_y`` of a table without them, ``vy`` on a path along x) may be a
    read-only view of that value (stride 0) rather than n stored copies: read it as any array; copy it
    (``np.array(result.vy)``) to write into it.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    normal_force: np.ndarray
    friction_force: np.ndarray
    state: np.ndarray
    lateral_x: np.ndarray
    lateral_y: np.ndarray
    skin_stretch: np.ndarray
    event_time: np.ndarray
    event_amplitude: np.ndarray
    audio: np.ndarray
    audio_rate: float
    clipped: int
    model: str
    tick_rate: float
    burst_policy: str = "retrigger"
    mu_s: np.ndarray = field(default=None, repr=False)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def summary(self) -> dict:
        """Short numbers for a CLI line or a report."""
        return {
            "model": self.model,
            "tick_rate_hz": self.tick_rate,
            "ticks": int(self.t.size),
            "duration_s": self.duration,
            "events": int(self.event_time.size),
            "max_friction_n": float(np.max(np.abs(self.friction_force), initial=0.0)),
            "slip_fraction": float(np.mean(self.state)) if self.state.size else 0.0,
            "audio_samples": int(self.audio.size),
            "audio_rate_hz": self.audio_rate,
            "clipped": int(self.clipped),
            "peak": float(np.max(np.abs(self.audio), initial=0.0)),
        }

