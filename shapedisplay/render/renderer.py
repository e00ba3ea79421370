"""The stick-slip renderer: a friction-envelope table played by the C engine as the cursor moves.

One :class:`Renderer`, one engine: the C runtime (``shapedisplay/engine/``,
compiled into the package's extension ``shapedisplay._engine`` and loaded by
:mod:`.native`) is the only implementation of table lookup, the pad models,
the bursts and the renderer's state; the same sources build the studio's
WebAssembly module and the firmware. The renderer runs two ways:

* offline, :meth:`Renderer.render` over a whole cursor path: one call into
  the engine plays every tick (``sd_play_path``: ``sd_renderer_step`` per
  cursor sample, keeping each tick's outputs, every audio sample and every
  stick-to-slip event);
* online, :meth:`Renderer.step` once per tick from a host loop or a device
  link (``sd_renderer_step``; O(1) per tick plus O(events)).

Both are the same ticks, so a path rendered offline equals the same path
stepped tick by tick, output for output and sample for sample.

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

Ticks are played at ``t0 + k / tick_rate`` (the engine counts ticks, not
times); a path whose sample times differ from that grid is resampled onto it.

The offline result keeps every event. The audio is the engine's, whose event
ring holds 4096 bursts (``SD_EVENT_RING``): a path with more than half of that
sounding at once (thousands of bursts within one burst's 35 ms) loses the
oldest from the audio and says so in ``RenderResult.events_dropped``.

Real-time rules for :meth:`Renderer.step`
-----------------------------------------
* Build the renderer before the real-time loop; :meth:`reset` allocates
  nothing.
* The engine allocates nothing per tick: outputs go into the renderer's own
  state (:attr:`Renderer.last` values, :attr:`audio_block`), the event ring
  has a fixed size. Only the call from Python allocates (and frees before
  returning) the float returned; a hard real-time host calls the C runtime
  itself (``sd_runtime.h``).
* Work per call is one table lookup, one model tick and the audio samples of
  the tick; the worst cases per tick are documented in
  ``engine/README.md``.
* Call ``step`` exactly once per tick, ``1 / tick_rate`` apart in cursor
  time; do not call :meth:`render` or read list-building properties from
  the real-time thread.
* ``step`` raises :class:`~shapedisplay.errors.ModelError` only if an
  explicit baseline model (``euler``/``rk4``) diverges.
"""
from __future__ import annotations

import ctypes
import math

import numpy as np

from shapedisplay.errors import InputError, ModelError
from shapedisplay.table.model import FrictionTable
from shapedisplay.table.widgets import widget_boxes
from shapedisplay.render.cursor import CursorPath
from shapedisplay.render.image import to_image
from shapedisplay.render.layouts import EVENT_KINDS, NSLOT, OUTPUTS, PAD_STATE, REACT_EVENT, REACT_STATE, RUN_STATE, SLOTS
from shapedisplay.render.models import PadModel, divergence_message
from shapedisplay.render.native import (PLAY_EVENTS_FULL, PLAY_REACT_FULL, address, aligned_buffer, library,
                                        renderer_layout)
from shapedisplay.render.reactions import ReactionEvent, events_of, widget_ids
from shapedisplay.render.result import RenderResult
from shapedisplay.render.settings import audio_length, derive_config, render_settings

#: Names of the per-tick outputs of :meth:`Renderer.step` (fields of :data:`~.layouts.OUTPUTS`).
OUT_NAMES = OUTPUTS.names


class TableImage:
    """A table bound in the C runtime: its binary image, loaded in place as firmware loads an upload.

    The image buffer is 8-byte aligned and lives as long as this object.
    """

    def __init__(self, table, device):
        lib = library()
        data = to_image(table, device)
        self._buf = aligned_buffer(len(data))
        ctypes.memmove(self._buf.ctypes.data, data, len(data))
        self.handle = aligned_buffer(lib.sd_image_size())
        rc = lib.sd_image_load(self.handle.ctypes.data, self._buf.ctypes.data, len(data))
        if rc != 0:
            raise InputError(f"the C runtime refused the table image (code {rc})")


def _view(buf: np.ndarray, offset: int, dtype, count: int = 1) -> np.ndarray:
    """``count`` items of ``dtype`` at byte ``offset`` of the engine state ``buf`` (a view: the same memory)."""
    dtype = np.dtype(dtype)
    return buf[offset:offset + count * dtype.itemsize].view(dtype)


class _State:
    """One ``sd_renderer_t`` in numpy memory, bound to a table image and settings, with views of its parts."""

    def __init__(self, lib, image: TableImage, config: np.ndarray):
        self.lib = lib
        self.buf = aligned_buffer(lib.sd_renderer_size())
        self.address = self.buf.ctypes.data
        self._image, self._config = image.handle.ctypes.data, config.ctypes.data
        self.init()
        L = renderer_layout()
        self.out = _view(self.buf, L["out"], OUTPUTS)[0]
        self.run = _view(self.buf, L["run"], RUN_STATE)[0]
        self.pad = _view(self.buf, L["pad"], PAD_STATE)[0]
        self.audio = _view(self.buf, L["audio"], np.float64, L["audio_block_max"])
        self.ev_t = _view(self.buf, L["ev_t"], np.float64, L["event_ring"])
        self.ev_a = _view(self.buf, L["ev_a"], np.float64, L["event_ring"])
        self.position_faults = _view(self.buf, L["position_faults"], np.int64)
        self.react_state = _view(self.buf, L["react_state"], REACT_STATE, L["max_reactive"])
        self.react_n = _view(self.buf, L["react_n"], np.int32)
        self.react_total = _view(self.buf, L["react_total"], np.int64, 2)     # total, dropped
        self.react_held = _view(self.buf, L["react_held"], np.int32)

    def init(self) -> None:
        """Bind the state to its table and settings afresh (``sd_renderer_init``: no allocation)."""
        rc = self.lib.sd_renderer_init(self.address, self._image, self._config)
        if rc != 0:
            raise InputError(f"the C engine refused the table or the settings (code {rc})")

    def reset(self, t0: float) -> None:
        self.lib.sd_renderer_reset(self.address, float(t0))

    def check_pad(self, model: PadModel, rate: float) -> None:
        """Raise :class:`ModelError` if the pad model cut a tick or diverged."""
        if self.pad["truncated"] > 0:
            raise ModelError(f"model '{model.name}' reached its cap on phase changes in one tick "
                             f"({int(self.pad['truncated'])} ticks cut); inputs are outside the model's range")
        if self.pad["diverged"] != 0:
            raise ModelError(divergence_message(model, rate, float(self.pad["diverged_at"])))


def friction_limits(channels: dict, mu_s: float, mu_k: float) -> tuple[np.ndarray, np.ndarray]:
    """Breakaway and kinetic force of each sample with the cursor at rest, as every tick derives them.

    Runs the engine's own per-tick derivation (``sd_derive``) on every
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
    vals = np.zeros((n, NSLOT))
    present = np.zeros(NSLOT, np.int32)
    for i, name in enumerate(SLOTS):
        if name in channels:
            present[i] = 1
            vals[:, i] = np.broadcast_to(np.asarray(channels[name], dtype=np.float64), shape).ravel()
    config = derive_config(float(mu_s), float(mu_k))
    breakaway, kinetic = np.empty(n), np.empty(n)
    library().sd_friction_limits(config.ctypes.data, present.ctypes.data, vals.ctypes.data, n,
                                 breakaway.ctypes.data, kinetic.ctypes.data)
    return breakaway.reshape(shape), kinetic.reshape(shape)


class Renderer:
    """Stick-slip renderer of a friction-envelope table, played by the C engine.

    Parameters
    ----------
    table : FrictionTable
        Channels are used when present (see the module docstring); without
        ``normal_force`` N is the header's constant ``mapping.n_base``.
    device : DeviceProfile, path, bundled name or None
        Pad, friction and burst parameters. Default: ``table.meta["device"]``
        if present, else the built-in Konyo profile.
    model : str or PadModel
        A name from :data:`~shapedisplay.render.models.MODELS`.
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
        cfg = render_settings(table, device, model, tick_rate, audio_rate, burst_policy, max_stick_period,
                              **model_options)
        self.settings = cfg
        self.table = table
        self.device = cfg.device
        self.model: PadModel = cfg.model
        #: N (newtons) of a table without a ``normal_force`` channel, else None.
        self.normal_force_constant = cfg.normal_force_constant
        self.tick_rate = cfg.tick_rate
        self.audio_rate = cfg.audio_rate
        self.burst_policy = cfg.burst_policy
        self.present = cfg.present
        #: The renderer's settings, a RENDER_CONFIG record (the C engine's sd_config_t, byte for byte).
        self._config = cfg.config
        self.config = self._config[0]
        self._lib = library()
        self._image = TableImage(table, cfg.device)
        self._online = _State(self._lib, self._image, self._config)
        self._offline = None
        self._step = self._lib.sd_renderer_step
        #: The tick's audio samples after :meth:`step`: ``audio_block[:audio_samples]`` (a view).
        self.audio_block = self._online.audio[:int(math.ceil(self.audio_rate / self.tick_rate)) + 2]
        #: Per-tick outputs of the last :meth:`step`: an OUTPUTS record (a view; ``last["drive"]``).
        self.last = self._online.out
        #: The table's scene widgets, ``(id, (x0, y0, x1, y1))`` in m: what each event's ``widget`` names.
        self.widgets = widget_boxes(table)
        self._widget_ids = widget_ids(table)
        self._t0 = 0.0
        self._event = np.zeros(1, REACT_EVENT)
        self._step_press = self._lib.sd_renderer_step_press
        self.reset()

    # ------------------------------------------------------------------ offline
    def _on_grid(self, cursor) -> CursorPath:
        """``cursor`` on this renderer's tick grid ``t0 + k / tick_rate`` (resampled if it is not)."""
        if not isinstance(cursor, CursorPath):
            raise InputError(f"`cursor` must be a CursorPath (got {type(cursor).__name__})")
        cp = cursor if cursor.tick_rate == self.tick_rate else cursor.resample(self.tick_rate)
        n = cp.t.size
        if n and not np.array_equal(cp.t, cp.t[0] + np.arange(n) / self.tick_rate):
            cp = cp.resample(self.tick_rate)
        return cp

    def _play(self, cp: CursorPath):
        """Every tick of ``cp`` through the engine from a fresh state: ``(outputs, audio, events, counts,
        reaction events)`` (REACT_EVENT records)."""
        n = cp.t.size
        n_audio = audio_length(cp.duration, self.audio_rate)      # refuse an impossible stream before the work
        x = np.ascontiguousarray(cp.x, dtype=np.float64)
        y = np.ascontiguousarray(cp.y, dtype=np.float64)
        press = None if cp.press is None else np.ascontiguousarray(cp.press, dtype=np.float64)
        out = np.empty(n, OUTPUTS)
        audio = np.empty(n_audio)
        counts = np.zeros(6, np.int64)
        ev_cap = n // 8 + 1024
        rev_cap = 256
        if self._offline is None:            # the offline runs' own state, kept from render to render
            self._offline = _State(self._lib, self._image, self._config)
        st = self._offline
        while True:
            st.init()
            st.reset(cp.t[0] if n else 0.0)
            ev = np.empty((2, ev_cap))
            rev = np.empty(rev_cap, REACT_EVENT)
            rc = self._lib.sd_play_path(st.address, address(x), address(y), None if press is None else address(press),
                                        n, address(out), address(audio), n_audio, address(ev),
                                        address(ev) + 8 * ev_cap, ev_cap, address(rev), rev_cap, address(counts))
            if rc == PLAY_EVENTS_FULL:
                ev_cap *= 4
            elif rc == PLAY_REACT_FULL:
                rev_cap = max(4 * rev_cap, n // 4)
            else:
                break
        if rc != 0 or counts[0] != n_audio:
            raise ModelError(f"the C engine stopped playing the path (code {rc}, {int(counts[0])} of {n_audio} "
                             "audio samples)")
        st.check_pad(self.model, self.tick_rate)
        return out, audio, ev[:, :int(counts[1])], counts, rev[:int(counts[5])]

    def model_inputs(self, cursor: CursorPath):
        """The per-tick inputs the engine gives the pad model for ``cursor`` (after the table lookup).

        Returns ``(t, V, N, mu_s, mu_k, gain)``, each ndarray (n,), float64
        (s, m/s, N, 1, 1, 1): the arguments of :func:`~.models.run_kernel`
        after the model. A path not on this renderer's tick grid is resampled.
        """
        cp = self._on_grid(cursor)
        out = self._play(cp)[0]
        return (np.array(cp.t, dtype=np.float64), *(np.ascontiguousarray(out[k]) for k in
                                                     ("pad_speed", "normal_force", "mu_s", "mu_k", "burst_gain")))

    def render(self, cursor: CursorPath) -> RenderResult:
        """Render a whole cursor path offline (one call into the engine).

        A path not on this renderer's tick grid is resampled onto it. Raises
        :class:`ModelError` if an explicit baseline diverges or a model cuts a
        tick, :class:`InputError` if the audio would exceed
        :data:`~shapedisplay.render.settings.MAX_AUDIO_SAMPLES`.
        """
        cp = self._on_grid(cursor)
        out, audio, ev, counts, rev = self._play(cp)
        # per-tick rows as views of the engine's output records (strided, not copied)
        col = {k: out[k] for k in ("vx", "vy", "normal_force", "friction_force", "lateral_x", "lateral_y",
                                   "skin_stretch", "mu_s", "press")}
        t, x, y = (np.array(a, dtype=np.float64) for a in (cp.t, cp.x, cp.y))
        kinds = rev["kind"]
        return RenderResult(t, x, y, col["vx"], col["vy"], col["normal_force"], col["friction_force"],
                            out["state"].astype(np.int8), col["lateral_x"], col["lateral_y"], col["skin_stretch"],
                            ev[0].copy(), ev[1].copy(), audio, self.audio_rate, int(counts[2]), self.model.name,
                            self.tick_rate, self.burst_policy, col["mu_s"], int(counts[3]), self.widgets,
                            event_kind=np.array([EVENT_KINDS[k - 1] for k in kinds], dtype=str).astype("U7"),
                            event_widget=np.array([self._widget_ids[w] if 0 <= w < len(self._widget_ids) else str(w)
                                                   for w in rev["widget"]], dtype=str),
                            event_t=(t[0] if t.size else 0.0) + rev["tick"] / self.tick_rate,
                            event_value=rev["value"].astype(np.float64), press=col["press"])

    # ------------------------------------------------------------------ online
    def reset(self, t0: float = 0.0, keep_widgets: bool = False) -> None:
        """Start a new online run at cursor time ``t0`` (s): state stuck and relaxed, no bursts, every
        reactive widget back in its initial state -- or, with ``keep_widgets``, where it is (a flipped toggle
        stays flipped, a dropped thumb or object where it was; nothing pressed or held)."""
        self._t0 = float(t0)
        if keep_widgets:
            self._lib.sd_react_restart(self._online.address, float(t0))
        else:
            self._online.reset(t0)

    def step(self, x: float, y: float, press: float | None = None) -> float:
        """Advance one tick with the cursor at (x, y) metres; return the burst drive in [-1, 1].

        ``press`` is the press force of the tick (N along z; None or 0: not
        pressing): the table's reactive widgets react to it
        (docs/reactive.md), their events wait in the engine's queue for
        :meth:`reactions`. Outputs of the tick are in :attr:`last` (fields
        named in ``OUT_NAMES``; also :meth:`outputs`) and the tick's audio
        samples in ``audio_block[:audio_samples]``. See the real-time rules in
        the module docstring.

        A position that is not finite or lies beyond 1 km is not played: the
        last valid position is held and :attr:`held_positions` counts it (a
        stream from a device host cannot be refused sample by sample).
        """
        drive = (self._step(self._online.address, x, y) if press is None else
                 self._step_press(self._online.address, x, y, press))
        if self._online.pad["diverged"] != 0:
            raise ModelError(divergence_message(self.model, self.tick_rate, float(self._online.pad["diverged_at"])))
        return drive

    @property
    def held_positions(self) -> int:
        """Cursor samples not played since the last :meth:`reset` (non-finite or beyond 1 km; the last valid
        position was held instead)."""
        return int(self._online.position_faults[0])

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
        return int(self._online.run["clipped"])

    @property
    def event_count(self) -> int:
        """Stick-to-slip events since :meth:`reset`."""
        return int(self._online.run["events_total"])

    @property
    def events_dropped(self) -> int:
        """Events the event ring could not hold while they sounded, since :meth:`reset`."""
        return int(self._online.run["events_dropped"])

    @property
    def value_faults(self) -> int:
        """Ticks since :meth:`reset` whose values overflowed (a NaN drive played as 0, a force beyond the
        reals played without contact, a pad restarted at rest); 0 for any table the reader accepts played
        with finite cursors."""
        return int(self._online.run["value_faults"])

    def reactions(self) -> list:
        """The reaction events queued since the last call, oldest first, as
        :class:`~shapedisplay.render.reactions.ReactionEvent` (kind, widget id, t, value); empties the queue.
        The engine's queue holds 64 events: call it at least every few ticks (allocates: not per tick in a
        hard real-time loop)."""
        recs = []
        addr = self._event.ctypes.data
        while self._lib.sd_react_pop(self._online.address, addr):
            recs.append(self._event[0].copy())
        return events_of(recs, self._widget_ids, self._t0, self.tick_rate)

    @property
    def reactions_dropped(self) -> int:
        """Reaction events lost since :meth:`reset` because the queue was full (64 waiting)."""
        return int(self._online.react_total[1])

    def widget_states(self) -> dict:
        """Each reactive widget's state: ``{id: {"pressed", "state", "grabbed", "dx", "dy", "thumb", "value",
        ...}}`` (REACT_STATE fields; SI), copies."""
        from shapedisplay.render.reactions import reactions_meta
        ids = [str(e.get("id")) for e in reactions_meta(self.table)]
        n = int(self._online.react_n[0])
        return {wid: {k: float(self._online.react_state[i][k]) for k in REACT_STATE.names}
                for i, wid in enumerate(ids[:n])}

    def recent_events(self):
        """(times, amplitudes) of the bursts still sounding (copies)."""
        n = int(self._online.run["n_recent"])
        return self._online.ev_t[:n].copy(), self._online.ev_a[:n].copy()
