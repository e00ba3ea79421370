"""The result of an offline render."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np


class Event(NamedTuple):
    """One stick-to-slip event: when and where it fired, under what load, how loud, on which widget.

    t : s; ``x, y`` : m, the cursor at ``t`` (along the played path);
    normal_force : N, of the tick the event fired in; ``amplitude`` : full
    scale, of its burst; ``widget`` : the id of the scene widget whose box
    holds ``(x, y)`` (the topmost, the last in scene order), or None.
    """

    t: float
    x: float
    y: float
    normal_force: float
    amplitude: float
    widget: str | None


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
    widgets : the table's widgets as ``(id, (x0, y0, x1, y1))`` boxes in m (a scene table; else empty)
    events : (see :attr:`events`) the stick-slip events as :class:`Event` records
    event_kind, event_widget, event_t, event_value : (n_reactions,), the reaction events of reactive widgets
        (docs/reactive.md) in order: kind (str: press, release, click, toggle, value, grab, drop), widget id
        (str), time of the tick (s) and value (toggle: the new state's index; value, grab, drop: the slider's
        value; click: the detent number, 0 for a press click)
    press : (n,), N, the press force of each tick (0 where not pressing)

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
    widgets: tuple = ()
    event_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, "U7"))
    event_widget: np.ndarray = field(default_factory=lambda: np.zeros(0, "U1"))
    event_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    event_value: np.ndarray = field(default_factory=lambda: np.zeros(0))
    press: np.ndarray = field(default=None, repr=False)

    @property
    def reactions(self) -> tuple:
        """The reaction events as :class:`~shapedisplay.render.reactions.ReactionEvent` records, in time order."""
        from shapedisplay.render.reactions import ReactionEvent
        return tuple(ReactionEvent(str(k), str(w), float(t), float(v)) for k, w, t, v in
                     zip(self.event_kind, self.event_widget, self.event_t, self.event_value))

    @property
    def events(self) -> tuple:
        """The stick-to-slip events as :class:`Event` records (t, x, y, normal_force, amplitude, widget), in time order."""
        et = np.asarray(self.event_time, dtype=np.float64)
        if et.size == 0:
            return ()
        x = np.interp(et, self.t, self.x)
        y = np.interp(et, self.t, self.y)
        k = np.clip(np.searchsorted(self.t, et, side="left"), 0, self.t.size - 1)
        n = np.asarray(self.normal_force)[k]
        wid = np.full(et.size, -1)
        for i, (_, (x0, y0, x1, y1)) in enumerate(self.widgets):
            wid[(x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)] = i
        names = [w[0] for w in self.widgets]
        return tuple(Event(float(et[j]), float(x[j]), float(y[j]), float(n[j]), float(self.event_amplitude[j]),
                           names[wid[j]] if wid[j] >= 0 else None) for j in range(et.size))

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
            "reactions": int(np.size(self.event_kind)),
        }

