"""The result of an offline render."""
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
    mu_s : (n,), the static friction coefficient of each tick
    events_dropped : int, events the engine's event ring could not hold while they sounded: their bursts are
        missing from ``audio`` (``event_time`` keeps them); 0 unless thousands of bursts sound at once

    ``t``, ``x`` and ``y`` are those of the path played: resampled onto the tick grid
    ``t[0] + k / tick_rate`` if the path was not on it.
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
    events_dropped: int = 0

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
            "events_dropped": int(self.events_dropped),
            "peak": float(np.max(np.abs(self.audio), initial=0.0)),
        }

