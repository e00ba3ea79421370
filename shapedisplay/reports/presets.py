"""Published experiments as study presets (``shapedisplay study NAME -o DIR``).

Each preset in :data:`STUDIES` is a list of conditions (a table, a device,
a cursor input and renderer options). :func:`run_study` plays every
condition through the :class:`~shapedisplay.render.renderer.Renderer` and
writes, into a new folder:

* ``<condition>.wav`` — the burst drive (float32 WAV at the device's audio rate);
* ``<condition>.npz`` — the per-tick trace (:func:`shapedisplay.render.sinks.write_trace`);
* ``manifest.json`` — the study, every condition's parameters, files and summary;
* ``summary.csv`` — one row per condition (columns below);
* ``summary.png`` — the study's plot (needs matplotlib).

Every file is written through :mod:`shapedisplay.atomic` into a temporary
folder beside the new one, which is renamed into place once complete and
its parent flushed (:func:`shapedisplay.atomic.replace_dir`): after a crash
or a power loss the folder is whole or absent.

This package module is only the registry (cheap to import: the CLI lists
the presets in its help); conditions, summaries, plots and the runner live
in :mod:`.presets` and load on first use.

Summary columns (over the analysed window, or a region of the stroke)
---------------------------------------------------------------------
``events``, ``event_rate_hz`` (stick-to-slip events per second),
``stick_period_s`` (median interval between successive events: one stick
and its slip), ``longest_stick_s`` (the longest such interval),
``burst_amplitude`` (median peak amplitude A of the bursts, full scale),
``mean_friction_n`` / ``max_friction_n`` (of ``|f|``), ``clipped`` (audio
samples limited to full scale). Ramp and bump studies add the same numbers
for the base (``base_*``) and the top of the profile (``top_*``).

Presets
-------
``friction``
    Konyo's friction study: mu_s 0.375 .. 0.600 in 0.025 steps x
    delta_mu in {0.1, 0.2, 0.3}, N = 2 N (a constant-N table), at 20 mm/s,
    on the handheld pointing stick (constant stick force 0.25 N, v = alpha f)
    and on the linear slider (a 20 mm/s stroke).
``slope-height``
    Ramp from N1 = 0.5 N with span L 5 .. 30 mm x rate k 0.05 .. 0.15 N/mm
    (plateau N2 = N1 + k L), pointing stick at 20 mm/s, each without and
    with a 20 ms maximum stick period: shows what the limit changes on the
    plateau (stick period, event rate) and what it keeps (burst amplitude,
    friction).
``bump``
    Tent from N1 = 0.5 N rising over L to N1 + delta_N and back:
    delta_N 2 .. 6 N at L = 20 mm, and L 10 .. 30 mm at delta_N = 4 N.
``imaizumi``
    Lateral vibration under a sliding finger on the Stribeck pad: stimuli
    #0 still, #1 3 Hz 1.25 mm, #2 6 Hz 0.625 mm, #3 6 Hz 1.25 mm,
    #4 9 Hz 1.25 mm at finger speeds 0.1 and 0.04 m/s, W = 1 N (a
    constant-N table); statistics after 0.2 s of settling.
"""
from __future__ import annotations

import importlib
from collections import namedtuple

from shapedisplay.errors import unknown_key

#: Maximum stick period of the slope-height preset's limited conditions, s.
STUDY_STICK_LIMIT = 0.020


class Study(namedtuple("Study", "name title description conditions columns plot")):
    """A study preset (immutable).

    ``conditions`` and ``plot`` name functions of :mod:`.presets`:
    ``conditions(duration_s_or_None, **options) -> list[Condition]`` and
    ``plot(rows, path)``; ``columns`` are the summary columns the CLI prints.
    A named tuple rather than a dataclass: ``dataclasses`` imports ``inspect``, which cost
    ``shapedisplay --help`` (which lists the presets) about 15 ms of its start.
    """

    __slots__ = ()

    def build(self, duration=None, **options) -> list:
        return getattr(importlib.import_module("shapedisplay.reports.studies"), self.conditions)(duration, **options)

    def draw(self, rows, path) -> None:
        getattr(importlib.import_module("shapedisplay.reports.studies"), self.plot)(rows, path)


_COMMON = ("events", "event_rate_hz", "stick_period_s", "burst_amplitude", "mean_friction_n", "max_friction_n",
           "clipped")

STUDIES = {
    "friction": Study(
        "friction", "Friction study (Konyo)",
        "mu_s 0.375-0.600 in 0.025 steps x delta_mu 0.1/0.2/0.3 at N = 2 N and 20 mm/s, "
        "on the pointing stick (v = alpha f) and the linear slider",
        "_friction_conditions", ("device", "mu_s", "delta_mu", *_COMMON), "_plot_friction"),
    "slope-height": Study(
        "slope-height", "Slope-height study (ramp profiles)",
        "ramp from N1 = 0.5 N, span L 5-30 mm x rate k 0.05-0.15 N/mm, without and with a 20 ms "
        "maximum stick period, pointing stick at 20 mm/s",
        "_slope_conditions", ("span_mm", "rate_n_per_mm", "n2_n", "max_stick_period_s", "top_stick_period_s",
                            "top_longest_stick_s", "top_burst_amplitude", "top_mean_friction_n", "base_burst_amplitude",
                            "clipped"),
        "_plot_slope"),
    "bump": Study(
        "bump", "Bump study (tent profiles)",
        "tent from N1 = 0.5 N: delta_N 2-6 N at L = 20 mm, L 10-30 mm at delta_N = 4 N, pointing stick at 20 mm/s",
        "_bump_conditions", ("delta_n_n", "span_mm", "events", "top_events", "top_burst_amplitude",
                           "base_burst_amplitude", "top_stick_period_s", "max_friction_n", "clipped"),
        "_plot_bump"),
    "imaizumi": Study(
        "imaizumi", "Imaizumi lateral-vibration study (Stribeck pad)",
        "stimuli #0 still, #1 3 Hz 1.25 mm, #2 6 Hz 0.625 mm, #3 6 Hz 1.25 mm, #4 9 Hz 1.25 mm at finger "
        "speeds 0.1 and 0.04 m/s, W = 1 N (statistics after 0.2 s)",
        "_imaizumi_conditions", ("stimulus", "finger_speed_m_s", "mean_friction_n", "max_friction_n", "events"),
        "_plot_imaizumi"),
}




def get_study(name) -> Study:
    """The preset called ``name`` (or ``name`` itself if it is a :class:`Study`)."""
    if isinstance(name, Study):
        return name
    if name not in STUDIES:
        raise unknown_key("study", name, STUDIES)
    return STUDIES[name]


_LAZY = ("run_study", "study_conditions", "summarize", "format_summary", "summary_csv", "StudyResult",
         "Condition", "constant_table")


def __getattr__(name):
    if name in _LAZY:
        return getattr(importlib.import_module("shapedisplay.reports.studies"), name)
    raise AttributeError(f"module 'shapedisplay.reports.presets' has no attribute {name!r}")


__all__ = ["STUDIES", "Study", "get_study", "STUDY_STICK_LIMIT", *_LAZY]
