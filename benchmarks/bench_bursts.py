"""Burst drive: quality figures and the cost per audio sample against the number of live bursts.

Run: ``.venv/bin/python benchmarks/bench_bursts.py [--plot docs/images/burst-spectrum.png]``.

Quality, on the published Konyo pad at N = 1 N and 20 / 30 mm/s (events every
8.5 / 5.7 ms, far closer than one 35 ms burst), for each overlap policy:

* the largest sample-to-sample step of the drive over the carrier's largest
  step ``2 E sin(pi f_c / rate)`` at the envelope ``E`` of the current carrier
  cycle ("local"), and at the largest envelope of the stroke ("global");
* the frequency of the drive's spectral peak.

Each figure is printed beside the same figure for a *restarting* synthesis
(every burst restarting the carrier phase and the envelope, the way bursts
are often synthesised: ``A env(t - t_e) sin(2 pi f_c (t - t_e))`` per burst),
computed here with numpy as the baseline of the comparison.

Cost: seconds per audio sample of :func:`~shapedisplay.render.bursts.render_bursts`
with 1 .. 1000 bursts live at once, as a ratio to the 1-burst case measured in
the same run (O(1) per sample means ratios near 1).
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from shapedisplay.table.devices import load_device
from shapedisplay.render.bursts import BURST_POLICIES, burst_envelope, render_bursts
from shapedisplay.render.models import simulate_pad

RATE, FC, RISE, DECAY = 48_000.0, 300.0, 0.005, 0.030
STEP = 2.0 * math.sin(math.pi * FC / RATE)


def envelope(tau, rise, decay):
    """The published burst envelope at ``tau`` s after the event: linear rise, then quadratic decay (numpy)."""
    tau = np.asarray(tau, dtype=np.float64)
    up = tau / rise
    down = (1.0 - (tau - rise) / decay) ** 2
    return np.where(tau < 0, 0.0, np.where(tau < rise, up, np.where(tau < rise + decay, down, 0.0)))


def restarting(et, ea, n, policy):
    """Baseline: each burst restarts the carrier; retrigger plays the newest, add sums, max the loudest."""
    t = np.arange(n) / RATE
    def env(tau):
        return envelope(tau, RISE, DECAY)
    out = np.zeros(n)
    best = np.full(n, -1.0)
    if policy == "retrigger":
        i = np.searchsorted(et, t, side="left") - 1
        ok = i >= 0
        tau = np.where(ok, t - et[np.maximum(i, 0)], -1.0)
        return np.where(ok, ea[np.maximum(i, 0)] * env(tau) * np.sin(2 * np.pi * FC * np.clip(tau, 0, None)), 0.0)
    for te, a in zip(et, ea):
        j0, j1 = int(te * RATE) + 1, min(n, int((te + RISE + DECAY) * RATE) + 2)
        tau = t[j0:j1] - te
        e = a * env(tau)
        v = e * np.sin(2 * np.pi * FC * tau)
        if policy == "add":
            out[j0:j1] += v
        else:
            m = e > best[j0:j1]
            best[j0:j1] = np.where(m, e, best[j0:j1])
            out[j0:j1] = np.where(m, v, out[j0:j1])
    return np.clip(out, -1, 1)


def local_ratio(audio, env):
    w = int(round(RATE / FC))
    cyc = np.lib.stride_tricks.sliding_window_view(np.pad(env, w, mode="edge"), 2 * w + 1).max(axis=1)
    cur = np.maximum(cyc[:-1], cyc[1:])
    ok = cur > 0.02 * env.max()
    return float(np.max(np.abs(np.diff(audio))[ok] / (STEP * cur[ok])))


def peak_hz(audio):
    spec = np.abs(np.fft.rfft(audio * np.hanning(audio.size)))
    return float(np.fft.rfftfreq(audio.size, 1 / RATE)[np.argmax(spec)]), spec


def events(V, N=1.0, duration=2.0):
    dev = load_device("handheld-stick")
    r = simulate_pad("exact", V=V, N=N, pad=dev.pad, friction=dev.friction, tick_rate=10_000, duration=duration)
    return r.event_time, dev.burst.gain * r.event_amplitude


def quality(plot=None):
    dur = 2.0
    n = int(dur * RATE) + 1
    spectra = {}
    print("drive quality at N = 1 N on the published pad (B = 0.25/N, 48 kHz)")
    print(f"{'speed':>8} {'policy':>10} {'events':>7} | {'restarting: step/A':>19} {'peak Hz':>8} | "
          f"{'continuous: local':>18} {'global':>7} {'peak Hz':>8}")
    for V in (0.020, 0.030):
        et, ea = events(V, duration=dur)
        A = float(ea.max())
        for policy in BURST_POLICIES:
            old = restarting(et, ea, n, policy)
            new, _ = render_bursts(et, ea, 0.0, dur, RATE, policy=policy)
            env = burst_envelope(et, ea, 0.0, dur, RATE, policy=policy)
            p_old, s_old = peak_hz(old)
            p_new, s_new = peak_hz(new)
            spectra[(V, policy)] = (s_old, s_new)
            print(f"{V * 1e3:>5.0f}mm/s {policy:>10} {et.size:>7} | {np.abs(np.diff(old)).max() / (STEP * A):>18.2f}x "
                  f"{p_old:>8.1f} | {local_ratio(new, env):>17.3f}x {np.abs(np.diff(new)).max() / (STEP * env.max()):>6.3f}x "
                  f"{p_new:>8.1f}")
    if plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        f = np.fft.rfftfreq(n, 1 / RATE)
        keep = f <= 1200
        fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        for i, V in enumerate((0.020, 0.030)):
            s_old, s_new = spectra[(V, "retrigger")]
            ref = max(s_old.max(), s_new.max())
            ax[i].plot(f[keep], 20 * np.log10(s_old[keep] / ref + 1e-12), lw=0.8, label="carrier restarted per burst")
            ax[i].plot(f[keep], 20 * np.log10(s_new[keep] / ref + 1e-12), lw=0.8, label="one continuous carrier")
            ax[i].axvline(FC, color="k", lw=0.5, ls=":")
            ax[i].set_ylim(-120, 5)
            ax[i].set_ylabel("dB")
            ax[i].set_title(f"retrigger, N = 1 N, {V * 1e3:.0f} mm/s on the Konyo pad")
            ax[i].legend(fontsize=8)
        ax[1].set_xlabel("frequency (Hz)")
        fig.tight_layout()
        fig.savefig(plot, dpi=100, metadata={"Software": None})
        print(f"spectrum -> {plot}")


def cost():
    print("\ncost per audio sample against bursts live at once (ratio to 1 live burst, same run)")
    dur = 1.0
    for policy in BURST_POLICIES:
        base = None
        row = []
        for live in (1, 10, 100, 1000):
            # events spread so that `live` bursts overlap all the time (35 ms each)
            et = np.arange(0.0, dur, (RISE + DECAY) / live)
            ea = np.full(et.size, 0.5 / live)
            render_bursts(et[:10], ea[:10], 0.0, 0.01, RATE, policy=policy)      # warm-up
            best = min(_timed(lambda: render_bursts(et, ea, 0.0, dur, RATE, policy=policy)) for _ in range(3))
            per = best / (dur * RATE)
            base = base or per
            row.append(f"{live:>5} live: {per * 1e9:6.1f} ns ({per / base:4.2f}x)")
        print(f"{policy:>10}: " + "  ".join(row))


def _timed(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plot", help="write the before/after spectrum (PNG)")
    a = ap.parse_args()
    quality(a.plot)
    cost()
