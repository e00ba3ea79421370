"""Published stimulus sets run through the pad models.

:func:`imaizumi_study` — lateral vibration of a contactor under a sliding
finger (Imaizumi et al.): stimuli #0 still, #1 3 Hz 1.25 mm,
#2 6 Hz 0.625 mm, #3 6 Hz 1.25 mm, #4 9 Hz 1.25 mm, at finger speeds 0.1
and 0.04 m/s, on the Stribeck pad (m = 1e-4 kg, k = 1e3 N/m, c = 1 N s/m,
mu_s = 2.1, mu_k = 1.4, a = 55, b = 1.9, W = 1 N).
"""
from __future__ import annotations

import numpy as np

from shapedisplay.table.devices import FrictionParams, PadParams
from shapedisplay.render.models import simulate_pad

#: (label, frequency Hz, amplitude m)
IMAIZUMI_STIMULI = (
    ("#0 still", 0.0, 0.0),
    ("#1 3 Hz 1.25 mm", 3.0, 1.25e-3),
    ("#2 6 Hz 0.625 mm", 6.0, 0.625e-3),
    ("#3 6 Hz 1.25 mm", 6.0, 1.25e-3),
    ("#4 9 Hz 1.25 mm", 9.0, 1.25e-3),
)
IMAIZUMI_SPEEDS = (0.1, 0.04)          # m/s
IMAIZUMI_PAD = PadParams(1.0e-4, 1.0e3, 1.0)
IMAIZUMI_FRICTION = FrictionParams(2.1, 1.4)


def imaizumi_study(duration: float = 1.0, settle: float = 0.2, tick_rate: float = 10_000.0,
                   load: float = 1.0, variant: str = "stribeck") -> list[dict]:
    """Run stimuli #0-#4 at both finger speeds.

    Each run lasts ``settle + duration`` s; statistics cover the last
    ``duration`` s (a whole number of periods for 1, 3, 6 and 9 Hz when
    ``duration`` is a whole second).

    Returns
    -------
    list of dict
        One row per (stimulus, speed): ``stimulus``, ``frequency_hz``,
        ``amplitude_m``, ``finger_speed_m_s``, ``mean_friction_n`` (mean of
        ``|F|``), ``max_friction_n``, ``events`` (stick-to-slip transitions),
        ``stick_fraction``.
    """
    rows = []
    for speed in IMAIZUMI_SPEEDS:
        for label, hz, amp in IMAIZUMI_STIMULI:
            r = simulate_pad("stribeck", V=speed, N=load, pad=IMAIZUMI_PAD, friction=IMAIZUMI_FRICTION,
                             tick_rate=tick_rate, duration=settle + duration, variant=variant,
                             contactor_hz=hz, contactor_amplitude_m=amp)
            keep = r.t >= settle - 1e-12
            F = np.abs(r.friction_force[keep])
            rows.append({
                "stimulus": label, "frequency_hz": hz, "amplitude_m": amp, "finger_speed_m_s": speed,
                "mean_friction_n": float(F.mean()), "max_friction_n": float(F.max()),
                "events": int(np.sum(r.event_time >= settle)),
                "stick_fraction": float(np.mean(r.state[keep] == 0)),
            })
    return rows
