"""Will it be felt, and can it be told apart? A legibility check of a scene's widgets from the renderer.

For every widget the check plays canonical strokes with the device's pad
model — through the widget's centre along both axes, in both directions, at
the slow, typical and fast exploration speeds (:func:`~shapedisplay.author.
perception.exploration_speeds`) — and measures what the finger gets: the
normal force, the friction force and the burst amplitude on the feature and on
the flat ground around it, the stick-slip event rate, the longest stick, the
time spent on the feature and the skin stretch. It states the result in
just-noticeable differences (JNDs) of the cue that carries it, with the
published figures of :mod:`shapedisplay.author.perception`, and gives verdicts:

* **detectable** at a speed: on every canonical stroke some cue differs from
  flat ground by at least 1 JND, the finger stays on the feature (where it is
  at least half as strong as at its extreme) for at least the burst rise time,
  and, for the burst cue, at least one stick-slip event falls there;
* **continuous** (devices with bursts): no stick on the widget lasts longer
  than one burst (rise + decay): beyond it the vibration stops between bursts;
* **saturated**: a rise longer than 15 mm at 0.15 N/mm or steeper, beyond
  which perceived height no longer grows;
* **stretch**: skin stretch at or beyond the 0.75 mm ceiling;
* **feel-alike** (pairs): two widgets of the same type, or a pair a scene marks
  ``distinct_from``, less than 1 JND apart at the typical speed.

Slider detents are checked against the track floor between them, and each
state of a toggle its knob against the track beside it. The rules, numbers
and sources are in docs/perception.md; the check predicts from population
figures, it is not a user study.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from shapedisplay.author.perception import (FIGURES, HEIGHT_SATURATION_RATE, HEIGHT_SATURATION_SPAN_M,
                                            SPEED_NAMES, STRETCH_CEILING_M, VIBROTACTILE_UNKNOWN, cues,
                                            exploration_speeds, mean_friction, stick_period, burst_amplitude)

#: Flat ground before and after the widget on each canonical stroke (m): the reference the contrast is taken against.
MARGIN_M = 4e-3
#: Ticks per second of the analysis (at most; the device's own rate if lower). Event times of the pad
#: models do not depend on the tick rate; at 2 kHz a stroke at 120 mm/s reads the table every 0.06 mm.
TICK_RATE_MAX = 2000.0
#: The top of a feature: where it is at least this fraction of its extreme difference from flat ground.
TOP = 0.9
#: Where the finger is "on" a feature: at least half its extreme difference from flat ground.
HALF = 0.5
#: A rise counts as "at 0.15 N/mm" within this fraction (the measured rate reads a sampled, quantized table).
SATURATION_RATE_TOLERANCE = 0.02
#: Most pair records listed (n widgets of one type make n(n-1)/2 pairs).
MAX_PAIRS = 5000
#: Verdict words (the command line prints them in its warnings).
WORDS = ("detectable", "not detectable", "continuous", "not continuous", "saturated", "stretch", "feel-alike")


def device_model(device) -> str:
    """The pad model a device plays with: ``stribeck`` for a Stribeck contactor, ``karnopp`` for a Karnopp
    profile, else ``exact``."""
    if "stribeck" in device.extra or "contactor" in device.outputs:
        return "stribeck"
    if "karnopp" in device.extra:
        return "karnopp"
    return "exact"


@dataclass
class _Widget:
    """What the check knows of a widget: id, type, box (m) and, from a scene, its parameters."""

    id: str
    type: str
    bbox: tuple
    params: dict | None = None
    origin: tuple | None = None          # unclipped box corner (m), from a scene
    size: tuple | None = None            # unclipped (width, height) (m), from a scene


def _widgets_of(scene, table) -> list[_Widget]:
    if scene is not None:
        return [_Widget(w.id, w.type, tuple(w.bbox), w.params, (w.col0 * w.spacing, w.row0 * w.spacing), w.size)
                for w in scene.widgets]
    return [_Widget(w["id"], w["type"], tuple(w["bbox_m"])) for w in table.meta.get("scene", {}).get("widgets", [])]


# ------------------------------------------------------------------ strokes
class _Player:
    """One renderer per table: plays straight strokes at a speed and keeps the per-tick arrays needed."""

    def __init__(self, table, device, model):
        from shapedisplay.render.renderer import Renderer
        rate = min(TICK_RATE_MAX, device.tick_rate_hz)
        audio = max(1000.0, 4.0 * device.burst.carrier_hz)
        self.r = Renderer(table, device=device, model=model, tick_rate=rate, audio_rate=audio)
        self.rate = self.r.tick_rate
        g = table.grid
        self.extent = ((g.cols - 1) * g.dx, (g.rows - 1) * g.dy)

    def play(self, p0, p1, v):
        from shapedisplay.render.cursor import CursorPath
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        L = float(np.hypot(*(p1 - p0)))
        n = max(int(math.floor(L / v * self.rate + 1e-9)) + 1, 2)
        t = np.arange(n) / self.rate
        d = np.minimum(v * t, L)
        u = (p1 - p0) / L
        res = self.r.render(CursorPath(t, p0[0] + u[0] * d, p0[1] + u[1] * d, self.rate, "perception"))
        return res, d


def _canonical(w: _Widget, extent, is_1d: bool, axes=("x", "y")):
    """(axis, p0, p1) of the strokes through the widget's centre along ``axes``, both directions."""
    x0, y0, x1, y1 = w.bbox
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    W, H = extent
    out = []
    for axis in axes:
        if axis == "y" and is_1d:
            continue
        if axis == "x":
            a, b = (max(x0 - MARGIN_M, 0.0), cy), (min(x1 + MARGIN_M, W), cy)
        else:
            a, b = (cx, max(y0 - MARGIN_M, 0.0)), (cx, min(y1 + MARGIN_M, H))
        if math.hypot(b[0] - a[0], b[1] - a[1]) <= 0:
            continue
        out += [(axis, a, b), (axis, b, a)]
    return out


# ------------------------------------------------------------------ what one stroke gives
def _runs(mask) -> int:
    """Length of the longest run of True in ``mask``."""
    if not mask.any():
        return 0
    m = np.concatenate([[0], mask.astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(m))
    return int((edges[1::2] - edges[::2]).max())


class _Stroke:
    """The measurements of one played stroke across one widget."""

    def __init__(self, res, dist, box, n_ground, mu_s, cue_list, v):
        self.v = v
        t = res.t
        N = np.asarray(res.normal_force)
        self.N, self.dist, self.res = N, dist, res
        x0, y0, x1, y1 = box
        eps = 1e-9
        self.in_box = (res.x >= x0 - eps) & (res.x <= x1 + eps) & (res.y >= y0 - eps) & (res.y <= y1 + eps)
        et = np.asarray(res.event_time)
        self.k = np.clip(np.searchsorted(t, et, side="left"), 0, t.size - 1)
        self.amp = np.asarray(res.event_amplitude)
        self.et = et
        self.dN = N - n_ground
        self.ground = (np.abs(self.dN) <= 1e-9 * max(n_ground, 1.0)) & (np.abs(np.asarray(res.mu_s) - mu_s) <= 1e-12)
        self.cues = cue_list
        dev = np.where(self.in_box, np.abs(self.dN), -1.0)
        i = int(np.argmax(dev))
        self.peak = float(self.dN[i]) if dev[i] >= 0 else 0.0
        self.ext = i
        self.flat = abs(self.peak) <= 1e-6 * max(n_ground, 1.0)
        s = 1.0 if self.peak >= 0 else -1.0
        self.sign = s
        on = self.in_box & (not self.flat)
        self.top = on & (s * self.dN >= TOP * abs(self.peak))
        self.half = on & (s * self.dN >= HALF * abs(self.peak))
        self.dwell = _runs(self.half) / res.tick_rate
        self.events_half = int(self.half[self.k].sum()) if self.k.size else 0

    # -- levels of the cues over a set of ticks (``ticks``) and the events there (``ev``)
    def levels(self, ticks, ev=None) -> dict:
        r = self.res
        ev = ticks[self.k] if ev is None else ev
        out = {}
        for cue in self.cues:
            if cue.name == "burst_amplitude":
                out[cue.name] = float(np.median(self.amp[ev])) if ev.any() else None
            elif cue.name == "friction_force":
                out[cue.name] = self.friction_mean(ticks)
            elif cue.name == "skin_stretch":
                out[cue.name] = float(np.median(np.abs(r.skin_stretch[ticks]))) if ticks.any() else None
            else:
                out[cue.name] = float(np.median(self.N[ticks])) if ticks.any() else None
        return out

    def friction_mean(self, ticks):
        """Mean |friction| over ``ticks``: over whole stick-slip cycles (first to last event there) when the
        longest run of them holds two events, else over every tick of the run."""
        if not ticks.any():
            return None
        m = np.concatenate([[0], ticks.astype(np.int8), [0]])
        edges = np.flatnonzero(np.diff(m))
        j = int(np.argmax(edges[1::2] - edges[::2]))
        a, b = int(edges[2 * j]), int(edges[2 * j + 1])
        ks = self.k[(self.k >= a) & (self.k < b)]
        if ks.size >= 2 and ks[-1] > ks[0]:
            a, b = int(ks[0]), int(ks[-1])
        return float(np.mean(np.abs(self.res.friction_force[a:b])))

    def feature(self) -> dict:
        """Levels on the top of the widget's main feature (its extreme; see TOP), or near its extreme."""
        if self.flat:
            return {}
        lv = self.levels(self.top)
        if "burst_amplitude" in lv and lv["burst_amplitude"] is None and self.events_half:
            ev = np.flatnonzero(self.half[self.k])
            j = ev[np.argmax(self.sign * self.dN[self.k[ev]])]
            lv["burst_amplitude"] = float(self.amp[j])
        return lv

    def longest_stick(self):
        """Longest time between consecutive events of which one falls on the widget (s), or None."""
        if self.et.size < 2:
            return None
        inb = self.in_box[self.k]
        pair = inb[:-1] | inb[1:]
        return float(np.diff(self.et)[pair].max()) if pair.any() else None

    def rise(self):
        """(span m, rate N/m) of the rise into a raised feature, from its 10 %-90 % part; None otherwise."""
        if self.flat or self.sign < 0:
            return None
        s = self.sign * self.dN[:self.ext + 1]
        low = np.flatnonzero(s <= 0.1 * abs(self.peak))
        if not low.size:
            return None
        i10 = int(low[-1])
        hi = np.flatnonzero(s[i10:] >= 0.9 * abs(self.peak))
        if not hi.size:
            return None
        i90 = i10 + int(hi[0])
        d = abs(self.dist[i90] - self.dist[i10])
        if d <= 0:
            return None
        return float(d / 0.8), float(0.8 * abs(self.peak) / d)


# ------------------------------------------------------------------ the check
def check_perception(source, device=None, scene=None) -> dict:
    """The legibility check of a scene or a compiled scene table.

    Parameters
    ----------
    source : Scene, str or Path, or FrictionTable
        A scene (``.toml``/``.svg`` path or loaded), or a compiled scene table
        (``.npz`` path or loaded; only what its header holds is known: boxes
        and types, not a slider's detents).
    device : optional
        Overrides the scene's device (scene sources only).

    Returns
    -------
    dict
        ``{"widgets": [...], "pairs": [...], "ground": {...}, "warnings": [...], ...}`` (schema in
        docs/perception.md).
    """
    from shapedisplay.author.scene import Scene, compile_scene, load_scene
    from shapedisplay.table.model import FrictionTable
    table = None
    if isinstance(source, FrictionTable):
        table = source
    elif isinstance(source, Scene):
        scene = source
    elif Path(str(source)).suffix.lower() in (".toml", ".svg"):
        scene = load_scene(source, device=device)
    else:
        table = FrictionTable.load(source)
    if table is None:
        table = compile_scene(scene).table
    from shapedisplay.render.settings import device_for_table
    dev = device_for_table(table)
    return _Check(table, dev, scene).run()


class _Check:
    def __init__(self, table, dev, scene):
        self.table, self.dev, self.scene = table, dev, scene
        self.cues = cues(dev)
        self.model = device_model(dev)
        self.speeds, self.speed_why = exploration_speeds(dev)
        bg = table.background.get("normal_force") if isinstance(table.background, dict) else None
        if bg is None:
            bg = float((table.meta.get("mapping") or {}).get("n_base", 0.0))
        self.n_ground = float(bg)
        self.player = _Player(table, dev, self.model)
        self.is_1d = table.grid.rows == 1
        self.widgets = _widgets_of(scene, table)
        self.rise_s = dev.burst.rise_s
        self.burst_s = dev.burst.rise_s + dev.burst.decay_s
        self.warnings: list[str] = []

    def cue(self, name):
        return next(c for c in self.cues if c.name == name)

    def play(self, w, player=None, axes=("x", "y"), speeds=SPEED_NAMES):
        player = player or self.player
        out = {}
        for sp in speeds:
            v = self.speeds[sp]
            out[sp] = []
            for axis, a, b in _canonical(w, player.extent, self.is_1d, axes):
                res, dist = player.play(a, b, v)
                st = _Stroke(res, dist, w.bbox, self.n_ground, self.dev.friction.mu_s, self.cues, v)
                st.axis = axis
                out[sp].append(st)
        return out

    def contrast(self, lv: dict, ref: dict):
        """(JNDs, cue) of levels ``lv`` against ``ref``: the cue with the most JNDs."""
        best = (0.0, None)
        for c in self.cues:
            a, b = ref.get(c.name), lv.get(c.name)
            if a is None or b is None:
                continue
            j = c.jnds(a, b)
            if j > best[0] or best[1] is None:
                best = (j, c.name)
        return best

    def detectable(self, st: _Stroke, lv: dict, ref: dict, dwell=None, events=None) -> tuple[bool, float, str]:
        dwell = st.dwell if dwell is None else dwell
        events = st.events_half if events is None else events
        rows = []                         # (felt, JNDs, cue) per cue with levels on both sides
        for c in self.cues:
            a, b = ref.get(c.name), lv.get(c.name)
            if a is None or b is None:
                continue
            j = c.jnds(a, b)
            rows.append((j >= 1.0 and dwell >= self.rise_s and (c.name != "burst_amplitude" or events >= 1), j, c.name))
        if not rows:
            return False, 0.0, None
        return max(rows, key=lambda r: (r[0], r[1]))

    # ---------------------------------------------------------------- run
    def run(self) -> dict:
        played = {w.id: self.play(w) for w in self.widgets if w.type != "data"}
        self.ground = self._ground(played)
        recs = [self._widget(w, played.get(w.id)) for w in self.widgets]
        pairs = self._pairs(recs)
        dev = self.dev
        return {
            "device": dev.name, "model": self.model,
            "speeds_m_s": dict(self.speeds), "speeds_from": self.speed_why,
            "cues": [{"cue": c.name, "weber": c.weber, "jnd_step": c.step, "unit": c.unit, "source": c.source}
                     for c in self.cues],
            "rules": {"detectable_jnd": 1.0, "min_dwell_s": self.rise_s, "continuity_limit_s": self.burst_s,
                      "top_fraction": TOP, "on_feature_fraction": HALF,
                      "saturation_span_m": HEIGHT_SATURATION_SPAN_M,
                      "saturation_rate_n_per_m": HEIGHT_SATURATION_RATE, "stretch_ceiling_m": STRETCH_CEILING_M},
            "ground": self.ground, "widgets": recs, "pairs": pairs, "warnings": self.warnings,
            "vibrotactile_detection": VIBROTACTILE_UNKNOWN if "burst" in dev.outputs else "no burst output",
        }

    def _ground(self, played) -> dict:
        """Levels on flat ground per speed, pooled over every stroke, with the jump-model closed forms."""
        out = {}
        dev, n = self.dev, self.n_ground
        for sp in SPEED_NAMES:
            v = self.speeds[sp]
            amps, fr, periods = [], [], []
            for strokes in played.values():
                for st in strokes[sp]:
                    g = st.ground
                    ev = g[st.k]
                    amps.append(st.amp[ev])
                    f = st.friction_mean(g)
                    if f is not None:
                        fr.append(f)
                    both = ev[:-1] & ev[1:]
                    periods.append(np.diff(st.et)[both])
            a = np.concatenate(amps) if amps else np.zeros(0)
            p = np.concatenate(periods) if periods else np.zeros(0)
            lv = {"burst_amplitude": float(np.median(a)) if a.size else burst_amplitude(n, v, dev),
                  "friction_force": float(np.median(fr)) if fr else mean_friction(n, v, dev),
                  "skin_stretch": None, "normal_force": n}
            if "skin_stretch" in dev.outputs:
                vals = [float(np.median(np.abs(st.res.skin_stretch[st.ground])))
                        for strokes in played.values() for st in strokes[sp] if st.ground.any()]
                lv["skin_stretch"] = float(np.median(vals)) if vals else 0.0
            out[sp] = {"speed_m_s": v, "normal_force_n": n, "levels": {c.name: lv[c.name] for c in self.cues},
                       "friction_mean_n": lv["friction_force"], "burst_amplitude": lv["burst_amplitude"],
                       "stick_period_s": float(np.median(p)) if p.size else None,
                       "measured": bool(a.size or fr),
                       "closed_form": {"friction_mean_n": mean_friction(n, v, dev),
                                       "breakaway_n": dev.friction.mu_s * n,
                                       "stick_period_s": stick_period(n, v, dev) if n > 0 else None,
                                       "burst_amplitude": burst_amplitude(n, v, dev)}}
        return out

    def _fmt_speed(self, sp):
        return f"{self.speeds[sp] * 1e3:.3g} mm/s ({sp})"

    def _widget(self, w: _Widget, strokes) -> dict:
        rec = {"id": w.id, "type": w.type}
        if strokes is None:
            rec.update(contrast_jnd=None, cue=None, verdicts=["not assessed"],
                       note="a data layer: it scales friction or bursts, not the normal force the check follows")
            return rec
        ground = {sp: self.ground[sp]["levels"] for sp in SPEED_NAMES}
        by_speed, det_by_speed, dwell, stick, worst = {}, {}, {}, {}, {}
        for sp in SPEED_NAMES:
            js, oks = [], []
            for st in strokes[sp]:
                ok, j, cue = self.detectable(st, st.feature(), ground[sp])
                js.append((j, cue, st))
                oks.append(ok)
            j, cue, st = min(js, key=lambda x: x[0])
            by_speed[sp] = j
            det_by_speed[sp] = all(oks)
            bad = [x for x, ok in zip(js, oks) if not ok]
            worst[sp] = (min(bad, key=lambda x: (x[2].dwell, x[0])) if bad else (j, cue, st))
            dwell[sp] = min(s.dwell for s in strokes[sp])
            ls = [s.longest_stick() for s in strokes[sp]]
            ls = [x for x in ls if x is not None]
            stick[sp] = max(ls) if ls else None
        main = max(strokes["typical"], key=lambda s: abs(s.peak))
        lv = main.feature()
        j_t, cue_t = self.contrast(lv, ground["typical"]) if lv else (0.0, None)
        rec.update(cue=cue_t, contrast_jnd=round(by_speed["typical"], 3),
                   contrast_jnd_by_speed={sp: round(by_speed[sp], 3) for sp in SPEED_NAMES},
                   detectable_by_speed=det_by_speed,
                   level={k: v for k, v in lv.items()}, ground_level=ground["typical"],
                   normal_force_n={"ground": self.n_ground, "top": self.n_ground + main.peak},
                   friction_mean_n={"ground": self.ground["typical"]["friction_mean_n"],
                                    "top": main.friction_mean(main.top) if not main.flat else None},
                   event_rate_hz=(main.events_half / main.dwell if main.dwell > 0 else None),
                   dwell_s=dwell, longest_stick_s=stick)
        verdicts = []
        if main.flat:
            verdicts.append("not detectable")
            self.warn(f"not detectable: '{w.id}' ({w.type}) leaves the normal force at flat ground's "
                      f"{self.n_ground:.3g} N on every canonical stroke")
        elif all(det_by_speed.values()):
            verdicts.append("detectable")
        else:
            verdicts.append("not detectable")
            miss = [sp for sp in SPEED_NAMES if not det_by_speed[sp]]
            j, cue, st = worst[miss[-1]]
            self.warn(f"not detectable: '{w.id}' ({w.type}) at " + ", ".join(self._fmt_speed(sp) for sp in miss)
                      + f": {j:.2f} JND of {(cue or 'any cue').replace('_', ' ')}, {st.dwell * 1e3:.3g} ms on the "
                        f"feature, {st.events_half} stick-slip event(s) there (needs >= 1 JND for >= "
                        f"{self.rise_s * 1e3:.3g} ms with an event)")
        longest = max((x for x in stick.values() if x is not None), default=None)
        if "burst" not in self.dev.outputs:   # the rule is about bursts falling silent between sticks
            rec["continuity"] = "not applicable (no burst output)"
        elif longest is not None and longest > self.burst_s * (1 + 1e-9):
            verdicts.append("not continuous")
            over = [sp for sp in SPEED_NAMES if stick[sp] is not None and stick[sp] > self.burst_s]
            self.warn(f"not continuous: '{w.id}' ({w.type}) sticks for up to {longest * 1e3:.3g} ms at "
                      + ", ".join(self._fmt_speed(sp) for sp in over)
                      + f", longer than one {self.burst_s * 1e3:.3g} ms burst: the stroke breaks into separate "
                        f"clicks (lower its force or set the device's [burst] max_stick_period)")
        else:
            verdicts.append("continuous")
        rises = [r for r in (s.rise() for s in strokes["typical"]) if r is not None]
        rise = max(rises, key=lambda r: r[0]) if rises else None
        rec["rise"] = {"span_m": rise[0], "rate_n_per_m": rise[1]} if rise else None
        if rise and rise[0] > HEIGHT_SATURATION_SPAN_M and rise[1] >= HEIGHT_SATURATION_RATE * (1 - SATURATION_RATE_TOLERANCE):
            verdicts.append("saturated")
            self.warn(f"saturated: '{w.id}' ({w.type}) rises over {rise[0] * 1e3:.3g} mm at "
                      f"{rise[1] * 1e-3:.3g} N/mm; beyond {HEIGHT_SATURATION_SPAN_M * 1e3:g} mm at "
                      f"{HEIGHT_SATURATION_RATE * 1e-3:g} N/mm perceived height no longer grows (shorten the ramp)")
        if "skin_stretch" in self.dev.outputs:
            rec["skin_stretch_rendered_max_m"] = max(float(np.max(np.abs(s.res.skin_stretch[s.in_box]), initial=0.0))
                                                     for sp in SPEED_NAMES for s in strokes[sp])
            smax = self._stretch_target(strokes["typical"])
            rec["skin_stretch_max_m"] = smax
            if smax >= STRETCH_CEILING_M * (1 - 1e-6):
                verdicts.append("stretch")
                self.warn(f"stretch: '{w.id}' ({w.type}) stretches the skin by {smax * 1e3:.3g} mm, at or beyond "
                          f"{STRETCH_CEILING_M * 1e3:g} mm where the tactor slides and friction feels lower")
        rec["verdicts"] = verdicts
        rec["vibrotactile"] = VIBROTACTILE_UNKNOWN if "burst" in self.dev.outputs else "no burst output"
        feats = self._features(w, strokes)
        if feats:
            rec["features"] = feats
        if self.scene is not None and w.id in self.scene.perception.get("contrast", {}):
            rec["contrast_asked"] = self.scene.perception["contrast"][w.id]
        return rec

    def warn(self, msg):
        self.warnings.append(msg)

    def _stretch_target(self, strokes) -> float:
        """The largest stretch the widget asks for: the stretch at breakaway, the table's ``skin_stretch``
        channel (clamped to the device's maximum by the compiler) or the profile's constant target."""
        if "skin_stretch" in self.table.channels:
            return max(float(np.max(np.abs(self.table.sample("skin_stretch", s.res.x[s.in_box], s.res.y[s.in_box])),
                                    initial=0.0)) for s in strokes)
        from shapedisplay.render.settings import mapping_settings
        return float(mapping_settings(self.table, self.dev)[1])

    # ---------------------------------------------------------------- features against their neighbours
    def _features(self, w, strokes) -> list:
        out = []
        if w.type == "slider" and w.params and w.params.get("detents"):
            out.append(self._detents(w, strokes))
        if w.type == "toggle":
            out += self._toggle_states(w)
        return [f for f in out if f]

    def _along(self, w, params=None):
        x0, y0, x1, y1 = w.bbox
        if params is not None and "vertical" in params:
            return "y" if params["vertical"] else "x"
        return "y" if (y1 - y0) > (x1 - x0) and not self.is_1d else "x"

    def _judge(self, name, w, per_speed) -> dict:
        """A feature record from ``per_speed[sp] = [(ok, jnds, cue, stroke-note), ...]``; warns if not felt."""
        rec = {"name": name, "contrast_jnd_by_speed": {}, "detectable_by_speed": {}}
        for sp, rows in per_speed.items():
            rec["contrast_jnd_by_speed"][sp] = round(min(r[1] for r in rows), 3)
            rec["detectable_by_speed"][sp] = all(r[0] for r in rows)
        t = per_speed.get("typical") or next(iter(per_speed.values()))
        rec["contrast_jnd"] = round(min(r[1] for r in t), 3)
        rec["cue"] = min(t, key=lambda r: r[1])[2]
        ok = all(rec["detectable_by_speed"].values())
        rec["verdicts"] = ["detectable" if ok else "not detectable"]
        if not ok:
            miss = [sp for sp in per_speed if not rec["detectable_by_speed"][sp]]
            r = min(per_speed[miss[-1]], key=lambda r: r[1])
            self.warn(f"not detectable: '{w.id}' ({w.type}) {name} at " + ", ".join(self._fmt_speed(sp) for sp in miss)
                      + f": {r[1]:.2f} JND of {(r[2] or 'any cue').replace('_', ' ')} {r[3]}")
        return rec

    def _detents(self, w, strokes) -> dict | None:
        p = w.params
        axis = self._along(w, p)
        i = 0 if axis == "x" else 1
        L = w.size[i] if w.size else w.bbox[2 + i] - w.bbox[i]
        origin = w.origin[i] if w.origin else w.bbox[i]
        R = p["thumb_size"] / 2
        thumb = origin + R + p["value"] * (L - 2 * R)       # as widgets.Slider.thumb_center
        centres = [origin + k * p["detent_spacing"] for k in range(1, p["detents"] + 1)]
        half_w = p["detent_width"] / 4
        keep = [c for c in centres if abs(c - thumb) > R + p["detent_width"]]
        if not keep:
            return None
        mids = [c + p["detent_spacing"] / 2 for c in keep[:-1]] or [keep[0] - p["detent_spacing"] / 2]
        mids = [m for m in mids if abs(m - thumb) > R + p["detent_spacing"] / 2] or mids
        per_speed = {}
        for sp in SPEED_NAMES:
            rows = []
            for st in (s for s in strokes[sp] if s.axis == axis):
                pos = (st.res.x if i == 0 else st.res.y)
                crest_levels, felt = [], 0
                for c in keep:
                    m = np.abs(pos - c) <= half_w
                    ev = m[st.k]
                    if ev.any():            # the event nearest the crest: the most force there
                        felt += 1
                        ev = np.zeros_like(ev)
                        j = np.flatnonzero(m[st.k])
                        ev[j[np.argmax(st.N[st.k[j]])]] = True
                    crest_levels.append(st.levels(m, ev))
                floor = np.zeros(pos.size, bool)
                for mid in mids:
                    floor |= np.abs(pos - mid) <= p["detent_spacing"] / 6
                ref = st.levels(floor)
                lv = {c.name: _median([d[c.name] for d in crest_levels]) for c in self.cues}
                dwell = 2 * half_w / st.v
                ok, j, cue = self.detectable(st, lv, ref, dwell=dwell, events=felt if felt == len(keep) else 0)
                rows.append((ok, j, cue, f"against the track between them, {dwell * 1e3:.3g} ms on each, stick-slip "
                                         f"events on {felt} of {len(keep)} detents"))
            per_speed[sp] = rows
        rec = self._judge("detents", w, per_speed)
        rec["count"] = len(keep)
        return rec

    def _toggle_states(self, w) -> list:
        from shapedisplay.author.scene.compiler import select_state
        toggles = self.table.meta.get("scene", {}).get("toggles", {})
        if w.id not in toggles:
            return []
        axis = self._along(w, w.params)
        out = []
        for state in toggles[w.id]["states"]:
            tab = select_state(self.table, w.id, state)
            player = _Player(tab, self.dev, self.model)
            strokes = self.play(w, player, axes=(axis,))
            per_speed = {}
            for sp in SPEED_NAMES:
                rows = []
                for st in strokes[sp]:
                    if st.flat:
                        rows.append((False, 0.0, None, "(no knob)"))
                        continue
                    lo = float(np.min(st.N[st.in_box]))
                    floor = st.in_box & (st.N <= lo + 0.1 * (st.N[st.ext] - lo))
                    ok, j, cue = self.detectable(st, st.feature(), st.levels(floor))
                    rows.append((ok, j, cue, f"against the track beside it, {st.dwell * 1e3:.3g} ms on the knob"))
                per_speed[sp] = rows
            out.append(self._judge(f"knob ({state})", w, per_speed))
        return out

    # ---------------------------------------------------------------- pairs
    def _pairs(self, recs) -> list:
        by_id = {r["id"]: r for r in recs if r.get("level")}
        wanted = {}
        ids = [r["id"] for r in recs if r["id"] in by_id]
        for a_i, a in enumerate(ids):
            for b in ids[a_i + 1:]:
                if by_id[a]["type"] == by_id[b]["type"]:
                    wanted[(a, b)] = "same type"
        if self.scene is not None:
            order = {i: k for k, i in enumerate(ids)}
            for a, others in self.scene.perception.get("distinct_from", {}).items():
                for b in others:
                    if a in by_id and b in by_id:
                        key = (a, b) if order[a] < order[b] else (b, a)
                        wanted[key] = "distinct_from"
        pairs = []
        for (a, b), why in list(wanted.items())[:MAX_PAIRS]:
            j, cue = self.contrast(by_id[b]["level"], by_id[a]["level"])
            pairs.append({"a": a, "b": b, "cue": cue, "contrast_jnd": round(j, 3),
                          "verdict": "feel-alike" if j < 1.0 else "distinct", "why": why,
                          "levels": {a: by_id[a]["level"].get(cue), b: by_id[b]["level"].get(cue)},
                          "speed_m_s": self.speeds["typical"]})
        if len(wanted) > MAX_PAIRS:
            self.warn(f"pairs: {len(wanted)} pairs of widgets to compare; the first {MAX_PAIRS} are listed")
        self._pair_warnings(pairs, by_id)
        return pairs

    def _pair_warnings(self, pairs, by_id):
        """One line per feel-alike pair; widgets that feel the same (within 0.01 JND) as a group."""
        parent = {}

        def find(x):
            while parent.get(x, x) != x:
                x = parent[x]
            return x

        for p in pairs:
            if p["contrast_jnd"] < 0.01 and p["why"] == "same type":
                parent[find(p["b"])] = find(p["a"])
        groups: dict = {}
        for i in by_id:
            groups.setdefault(find(i), []).append(i)
        lines: dict = {}
        for p in pairs:
            if p["verdict"] != "feel-alike":
                continue
            ga, gb = find(p["a"]), find(p["b"])
            key = (ga, gb) if ga != gb else (ga,)
            if (gb, ga) not in lines:        # one line per pair of groups, whichever widget came first
                lines.setdefault(key, p)
        v = self.speeds["typical"] * 1e3
        for key, p in lines.items():
            cue = (p["cue"] or "any cue").replace("_", " ")
            la, lb = p["levels"][p["a"]], p["levels"][p["b"]]
            figs = f" ({_num(la)} vs {_num(lb)} at {v:.3g} mm/s)" if la is not None and lb is not None else ""
            names = [", ".join(f"'{i}'" for i in groups[g]) for g in key]
            t = by_id[p["a"]]["type"]
            if len(key) == 1:
                self.warn(f"feel-alike: {names[0]} ({len(groups[key[0]])} {t}s) feel the same: "
                          f"{p['contrast_jnd']:.2f} JND apart in {cue}{figs}, under 1 JND")
            else:
                what = "marked distinct_from" if p["why"] == "distinct_from" else f"{t}s"
                self.warn(f"feel-alike: {names[0]} and {names[1]} ({what}) are {p['contrast_jnd']:.2f} JND apart "
                          f"in {cue}{figs}, under 1 JND")


def _median(vals):
    vals = [v for v in vals if v is not None]
    return float(np.median(vals)) if vals else None


def _num(x) -> str:
    return f"{x:.3g}"


# ------------------------------------------------------------------ text
def format_perception(rep: dict) -> list[str]:
    """The check as lines: one per widget (contrast, cue, verdicts, the numbers behind them), then the pairs."""
    sp = rep["speeds_m_s"]
    lines = [f"perception: device '{rep['device']}', model {rep['model']}, strokes at "
             + "/".join(f"{sp[k] * 1e3:.3g}" for k in SPEED_NAMES) + f" mm/s ({rep['speeds_from']})"]
    for r in rep["widgets"]:
        if r.get("contrast_jnd") is None:
            lines.append(f"  {r['id']:<14} {r['type']:<7} not assessed: {r.get('note', '')}")
            continue
        cue = (r["cue"] or "-").replace("_", " ")
        stick = r["longest_stick_s"]["typical"]
        rate = r.get("event_rate_hz")
        extra = [f"{r['dwell_s']['typical'] * 1e3:.3g} ms on it"]
        if rate:
            extra.append(f"{rate:.3g} events/s")
        if stick is not None:
            extra.append(f"longest stick {stick * 1e3:.3g} ms")
        lines.append(f"  {r['id']:<14} {r['type']:<7} {r['contrast_jnd']:5.2f} JND {cue:<15} "
                     f"{', '.join(r['verdicts']):<36} {', '.join(extra)}")
        for f in r.get("features", []):
            lines.append(f"  {'':<14} {'':<7} {f['contrast_jnd']:5.2f} JND {f['name']} against its neighbours: "
                         f"{', '.join(f['verdicts'])}")
    alike = sum(p["verdict"] == "feel-alike" for p in rep["pairs"])
    lines.append(f"  pairs: {len(rep['pairs'])} compared, {alike} feel alike; vibrotactile detection: "
                 f"{rep['vibrotactile_detection']}")
    return lines


__all__ = ["check_perception", "format_perception", "device_model", "FIGURES", "MARGIN_M", "WORDS"]
