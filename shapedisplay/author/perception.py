"""Published perception figures and the closed forms a legibility check and the scene compiler share.

One table of numbers, :data:`FIGURES`, each with its unit and its source;
``docs/perception.md`` prints the same table and a test holds the two equal.
The renderer-based check (:mod:`shapedisplay.reports.perception`) measures
what the finger gets along canonical strokes and states it in just-noticeable
differences (JNDs) of the cue that carries it; the scene compiler solves a
widget's ``contrast = "3 jnd"`` with the closed forms here (it may not render).

Cues and their JNDs
-------------------
* ``burst_amplitude`` (devices with a ``burst`` output): the peak amplitude of
  the bursts, ``A = B (mu_s N - c V)``; its JND is the vibration-amplitude
  discrimination threshold, 2.5 dB (the upper, more cautious end of
  2.2-2.5 dB), a Weber fraction of 10^(2.5/20) - 1 = 0.334.
* ``friction_force`` (``skin_stretch``, ``contactor`` outputs): the mean friction
  force; its Weber fraction is the friction JND over mu_s, interpolated in the
  table of JNDs at mu_s = 0.2 ... 0.8 (0.28 -> 0.19).
* ``skin_stretch`` (``skin_stretch`` output): about 0.27 mm of stretch is one
  friction JND (an absolute step, not a fraction).
* ``normal_force`` (``normal`` output): force discrimination, 10 % (the upper
  end of 7-10 %, which holds above 0.5 N).

The number of JNDs between two levels a, b of a cue with Weber fraction w is
Fechner's count ``|ln(b / a)| / ln(1 + w)``: each JND multiplies the level by
``1 + w``, so for a small difference it is ``|b - a| / (w a)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from shapedisplay.author.forces import EXPONENTS


@dataclass(frozen=True)
class Figure:
    """One published number: its value, unit, what it is and where it comes from."""

    value: float | None
    unit: str
    what: str
    source: str


_PS = "Provancher & Sylvester 2009"
_KONYO = "Konyo et al. 2008"
_FORCE_REVIEW = "Sci. Rep. 2022, doi:10.1038/s41598-022-12010-0"
#: Every published figure the check uses, by key. ``docs/perception.md`` lists the same rows.
FIGURES: dict[str, Figure] = {
    "friction_jnd_mu_0.2": Figure(0.056, "1", "friction JND at mu_s = 0.2", _PS),
    "friction_jnd_mu_0.4": Figure(0.087, "1", "friction JND at mu_s = 0.4", _PS),
    "friction_jnd_mu_0.6": Figure(0.118, "1", "friction JND at mu_s = 0.6", _PS),
    "friction_jnd_mu_0.8": Figure(0.150, "1", "friction JND at mu_s = 0.8", _PS),
    "friction_weber_low_mu": Figure(0.28, "1", "friction Weber fraction at mu_s = 0.2", _PS),
    "friction_weber_high_mu": Figure(0.19, "1", "friction Weber fraction at mu_s = 0.8", _PS),
    "force_weber_low": Figure(0.07, "1", "force discrimination above 0.5 N, low end", "Pang, Tan & Durlach 1991"),
    "force_weber_high": Figure(0.10, "1", "force discrimination above 0.5 N, high end", _FORCE_REVIEW),
    "force_weber_min_force": Figure(0.5, "N", "reference force above which 7-10 % holds", _FORCE_REVIEW),
    "amplitude_jnd_db_low": Figure(2.2, "dB", "vibration amplitude discrimination, low end", "Israr et al. 2006"),
    "amplitude_jnd_db_high": Figure(2.5, "dB", "vibration amplitude discrimination, high end", "Israr et al. 2006"),
    "speed_slow": Figure(23.0, "mm/s", "slowest exploration speed", _PS),
    "speed_typical": Figure(53.0, "mm/s", "mean exploration speed", _PS),
    "speed_fast": Figure(80.0, "mm/s", "fastest exploration speed", _PS),
    "press_force_low": Figure(1.0, "N", "lowest normal force people explored with", _PS),
    "press_force_mean": Figure(1.31, "N", "mean normal force people explored with", _PS),
    "press_force_high": Figure(1.5, "N", "highest normal force people explored with", _PS),
    "height_saturation_span": Figure(15.0, "mm", "ramp span above which perceived height saturates", _KONYO),
    "height_saturation_rate": Figure(0.15, "N/mm", "ramp rate at which the saturation was found", _KONYO),
    "stretch_ceiling": Figure(0.75, "mm", "stretch beyond which the tactor slid and friction felt lower", _PS),
    "stretch_jnd": Figure(0.27, "mm", "stretch worth one friction JND", _PS),
    "exponent_bumpiness": Figure(EXPONENTS["bumpiness"], "1", "Stevens exponent, bumpiness", "Hollins/Seeger lineage"),
    "exponent_friction": Figure(EXPONENTS["friction"], "1", "Stevens exponent, friction", "Hollins/Seeger lineage"),
    "vibrotactile_best_frequency_low": Figure(250.0, "Hz", "detection threshold minimum, low end", "Verrillo 1963"),
    "vibrotactile_best_frequency_high": Figure(300.0, "Hz", "detection threshold minimum, high end", "Verrillo 1963"),
    "vibrotactile_threshold_300hz": Figure(None, "um", "detection threshold at 300 Hz: not stored", "Verrillo 1963"),
}


def figure(key: str) -> float:
    """The value of published figure ``key`` (a KeyError names a key that is not in :data:`FIGURES`)."""
    return FIGURES[key].value


#: Friction JND (Delta mu) against mu_s, as (mu_s, JND) rows of :data:`FIGURES`.
FRICTION_JND = tuple((mu, figure(f"friction_jnd_mu_{mu}")) for mu in (0.2, 0.4, 0.6, 0.8))
#: Weber fraction of burst amplitude: the cautious end of the amplitude JND in dB.
AMPLITUDE_WEBER = 10.0 ** (figure("amplitude_jnd_db_high") / 20.0) - 1.0
#: Weber fraction of a normal force felt as a force (the cautious end of 7-10 %).
FORCE_WEBER = figure("force_weber_high")
#: Skin stretch worth one friction JND, m.
STRETCH_JND_M = figure("stretch_jnd") * 1e-3
#: Skin stretch beyond which perceived friction falls, m.
STRETCH_CEILING_M = figure("stretch_ceiling") * 1e-3
#: Perceived height saturates for ramps longer than this (m) at rates of at least HEIGHT_SATURATION_RATE.
HEIGHT_SATURATION_SPAN_M = figure("height_saturation_span") * 1e-3
#: N/m: the rate at which the saturation was measured (0.15 N/mm).
HEIGHT_SATURATION_RATE = figure("height_saturation_rate") * 1e3
#: The names of the speeds of the canonical strokes, slowest first.
SPEED_NAMES = ("slow", "typical", "fast")
#: JNDs counted between a zero level and a non-zero one (a finite stand-in for "no end of JNDs").
NOTHING_AGAINST_SOMETHING = 100.0
#: What the vibrotactile detection check says without an actuator calibration.
VIBROTACTILE_UNKNOWN = "unknown (no actuator calibration in the device profile)"


def friction_weber(mu_s: float) -> float:
    """Friction Weber fraction JND(mu_s) / mu_s, the JND interpolated linearly in :data:`FRICTION_JND`
    (held at the end values outside mu_s = 0.2 ... 0.8)."""
    mus = [m for m, _ in FRICTION_JND]
    jnds = [j for _, j in FRICTION_JND]
    m = min(max(float(mu_s), mus[0]), mus[-1])
    for i in range(len(mus) - 1):
        if m <= mus[i + 1]:
            f = (m - mus[i]) / (mus[i + 1] - mus[i])
            return (jnds[i] + f * (jnds[i + 1] - jnds[i])) / m
    return jnds[-1] / mus[-1]     # pragma: no cover - the loop always returns


@dataclass(frozen=True)
class Cue:
    """A cue a device gives the finger: ``weber`` (a fraction) or ``step`` (an absolute JND, SI)."""

    name: str
    weber: float | None = None
    step: float | None = None
    unit: str = ""
    source: str = ""

    def jnds(self, a: float, b: float) -> float:
        """JNDs between levels ``a`` and ``b`` of this cue (Fechner's count, or the absolute step)."""
        if self.step is not None:
            return abs(b - a) / self.step
        if a <= 0 or b <= 0:                 # nothing against something: far beyond any JND, kept finite
            return NOTHING_AGAINST_SOMETHING if a != b else 0.0
        return abs(math.log(b / a)) / math.log1p(self.weber)

    def level_at(self, ref: float, jnds: float) -> float:
        """The level ``jnds`` JNDs above ``ref`` (below for a negative count)."""
        if self.step is not None:
            return ref + jnds * self.step
        return ref * (1.0 + self.weber) ** jnds


def cues(device) -> list[Cue]:
    """The cues ``device`` gives, in a fixed order (see the module doc)."""
    outs = set(device.outputs)
    out = []
    if "burst" in outs:
        out.append(Cue("burst_amplitude", weber=AMPLITUDE_WEBER, unit="full scale",
                       source=FIGURES["amplitude_jnd_db_high"].source))
    if outs & {"skin_stretch", "contactor"}:
        out.append(Cue("friction_force", weber=friction_weber(device.friction.mu_s), unit="N", source=_PS))
    if "skin_stretch" in outs:
        out.append(Cue("skin_stretch", step=STRETCH_JND_M, unit="m", source=_PS))
    if "normal" in outs:
        out.append(Cue("normal_force", weber=FORCE_WEBER, unit="N", source=FIGURES["force_weber_high"].source))
    return out


def exploration_speeds(device) -> tuple[dict, str]:
    """Speeds (m/s) of the canonical strokes by :data:`SPEED_NAMES`, and where they come from.

    A position-input device: the exploration speeds people used (23, 53, 80 mm/s).
    A pointing stick (``cursor_gain`` alpha > 0): v = alpha f with the forces
    people pressed with (1.0, 1.31, 1.5 N). Both are held to the device's
    velocity range.
    """
    vlo, vhi = device.velocity_range
    alpha = float(device.cursor_gain or 0.0)
    if alpha > 0:
        forces = (figure("press_force_low"), figure("press_force_mean"), figure("press_force_high"))
        raw = [alpha * f for f in forces]
        why = (f"pointing stick: v = alpha f, alpha = {alpha * 1e3:g} mm/(N s), f = "
               + "/".join(f"{f:g}" for f in forces) + " N")
    else:
        raw = [figure(f"speed_{n}") * 1e-3 for n in SPEED_NAMES]
        why = "exploration speeds " + "/".join(f"{v * 1e3:g}" for v in raw) + " mm/s"
    held = [min(max(v, vlo), vhi) for v in raw]
    if held != raw:
        why += f", held to the device's {vlo * 1e3:g}..{vhi * 1e3:g} mm/s"
    return dict(zip(SPEED_NAMES, held)), why


def typical_speed(device) -> float:
    """The typical speed of the canonical strokes (m/s)."""
    return exploration_speeds(device)[0]["typical"]


# ------------------------------------------------------------------ jump-model closed forms
def overshoot(device) -> float:
    """``e^(-zeta pi / sqrt(1 - zeta^2))``: how far a fresh slip overshoots the kinetic level (0 if not underdamped)."""
    z = device.pad.zeta
    return math.exp(-z * math.pi / math.sqrt(1.0 - z * z)) if z < 1 else 0.0


def breakaway_force(N: float, device) -> float:
    """Friction at breakaway, ``mu_s N`` (N)."""
    return device.friction.mu_s * N


def restick_force(N: float, device) -> float:
    """Friction where a slip from rest re-sticks (jump model, V -> 0): ``mu_k N - Delta mu N e^(...)``."""
    f = device.friction
    return f.mu_k * N - (f.mu_s - f.mu_k) * N * overshoot(device)


def slip_time(device) -> float:
    """How long a slip lasts, ``pi / omega_d`` (s)."""
    p = device.pad
    return math.pi / (p.omega_n * math.sqrt(max(1.0 - p.zeta ** 2, 1e-300)))


def stick_period(N: float, V: float, device) -> float:
    """Stick-slip period ``Delta mu N (1 + e^(...)) / (k V) + pi / omega_d`` (s) at constant N and V."""
    f = device.friction
    return (f.mu_s - f.mu_k) * N * (1.0 + overshoot(device)) / (device.pad.stiffness * V) + slip_time(device)


def mean_friction(N: float, V: float, device) -> float:
    """Time-mean friction over a stick-slip cycle (N): the stick's linear rise from the re-stick level to
    ``mu_s N``, then the slip at ``mu_k N``."""
    T = stick_period(N, V, device)
    ts = slip_time(device)
    stick = (breakaway_force(N, device) + restick_force(N, device)) / 2.0
    return (stick * (T - ts) + device.friction.mu_k * N * ts) / T


def burst_amplitude(N: float, V: float, device) -> float:
    """Burst peak amplitude ``B (mu_s N - c V)`` (full scale) at breakaway under N at speed V."""
    return device.burst.gain * (device.friction.mu_s * N - device.pad.damping * V)


def cue_level(cue: Cue, N: float, V: float, device, mapping=None) -> float:
    """The closed-form level of ``cue`` on a plateau of normal force N crossed at speed V."""
    if cue.name == "burst_amplitude":
        return burst_amplitude(N, V, device)
    if cue.name == "friction_force":
        return N          # the mean friction is proportional to N: ratios are those of N
    if cue.name == "skin_stretch":
        n_base = getattr(mapping, "n_base", 0.0) or N
        target = float(getattr(mapping, "skin_stretch", 0.0) or 0.0)
        return min(target * N / n_base, device.skin_stretch_max or math.inf)
    return N


def solve_contrast(n_ref: float, jnds: float, device, V: float | None = None, mapping=None) -> tuple[float, str]:
    """The plateau normal force (N) whose contrast against a plateau of ``n_ref`` is ``jnds`` JNDs
    (negative: below it), on the cue of ``device`` that gets there with the smallest change of N.

    Returns ``(N, cue name)``. Closed form per cue: the burst amplitude
    ``B (mu_s N - c V)`` at the typical speed V; the mean friction and a felt
    normal force in proportion to N; skin stretch through its mapping.
    """
    V = typical_speed(device) if V is None else V
    best = None
    for cue in cues(device):
        ref = cue_level(cue, n_ref, V, device, mapping)
        want = cue.level_at(ref, jnds)
        if cue.name == "burst_amplitude":
            n = (want / device.burst.gain + device.pad.damping * V) / device.friction.mu_s
        elif cue.name == "skin_stretch":
            target = float(getattr(mapping, "skin_stretch", 0.0) or 0.0)
            if target <= 0 or (device.skin_stretch_max and want > device.skin_stretch_max):
                continue
            n = want * mapping.n_base / target
        else:
            n = want
        if n <= 0:
            continue
        if best is None or abs(n - n_ref) < abs(best[0] - n_ref):
            best = (n, cue.name)
    if best is None:
        raise ValueError(f"no cue of device '{device.name}' (outputs {list(device.outputs)}) reaches "
                         f"{jnds:g} JND from {n_ref:g} N")
    return best
