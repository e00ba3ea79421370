"""A played stroke as an Apple Core Haptics pattern (AHAP) and as a drive time series (CSV).

AHAP (:func:`ahap_document`, ``shapedisplay play ... --ahap FILE``)
--------------------------------------------------------------------
A JSON pattern with ``Version`` 1.0, ``Metadata`` and a ``Pattern`` list:

* one ``HapticTransient`` event per burst (per stick-to-slip event), at
  the event time from the start of the stroke, with
  ``HapticIntensity = min(1, A)`` — the burst's peak amplitude ``A`` as a
  fraction of full scale (the WAV's ±1) — and ``HapticSharpness`` from the
  carrier frequency (:func:`sharpness_of_carrier`: an octave scale,
  80 Hz → 0, 320 Hz → 1, so the default 300 Hz carrier is 0.95);
* ``HapticContinuous`` events at intensity 1 covering the stroke (at most
  30 s each), with ``HapticIntensityControl`` parameter curves that follow
  the drive envelope (:func:`drive_envelope`: the peak of ``|drive|`` over each
  carrier period, normalised to the stroke's peak, simplified to a
  piecewise-linear curve within ``tolerance`` of full scale and split into
  curves of at most 16 control points that join end to start).

Core Haptics multiplies the intensity of every event playing by the
current ``HapticIntensityControl`` value (its parameter curves apply to the
whole pattern), so a transient is felt at its intensity times the envelope
at that moment; write ``envelope=False`` (``--ahap-envelope off``) for
transients at their own intensity and no curves.

:func:`check_ahap` checks a document against the keys, types and value
ranges of the format; files are checked before they are written.

Drive CSV (:func:`write_drive_csv`, ``--drive-csv FILE``)
---------------------------------------------------------
``t_s,drive`` — the burst drive at the audio rate (the WAV's samples, full
scale ±1) with time from the first tick; one header line.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from shapedisplay.atomic import atomic_path, write_text
from shapedisplay.errors import InputError

AHAP_VERSION = 1.0
#: Most control points Core Haptics takes in one parameter curve.
MAX_CURVE_POINTS = 16
#: Longest HapticContinuous event, s.
MAX_CONTINUOUS_S = 30.0

# key -> (allowed range) of the event parameters and dynamic parameters written here and read by check_ahap
EVENT_PARAMETERS = {"HapticIntensity": (0.0, 1.0), "HapticSharpness": (0.0, 1.0), "AttackTime": (0.0, 1e9),
                    "DecayTime": (0.0, 1e9), "ReleaseTime": (0.0, 1e9), "Sustained": (0.0, 1.0)}
DYNAMIC_PARAMETERS = {"HapticIntensityControl": (0.0, 1.0), "HapticSharpnessControl": (-1.0, 1.0),
                      "HapticAttackTimeControl": (-1.0, 1.0), "HapticDecayTimeControl": (-1.0, 1.0),
                      "HapticReleaseTimeControl": (-1.0, 1.0)}
EVENT_TYPES = ("HapticTransient", "HapticContinuous")


def sharpness_of_carrier(carrier_hz: float) -> float:
    """HapticSharpness of a burst carrier: ``clip(log2(f / 80 Hz) / 2, 0, 1)`` (80 Hz → 0, 320 Hz → 1)."""
    return float(min(1.0, max(0.0, math.log2(carrier_hz / 80.0) / 2.0)))


def drive_envelope(drive: np.ndarray, rate: float, carrier_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Envelope of a burst drive: the peak of ``|drive|`` over each carrier period.

    Parameters
    ----------
    drive : ndarray (n,), float, full scale ±1, first sample at time 0
    rate : float, Hz
    carrier_hz : float, Hz

    Returns
    -------
    t : ndarray (m,), s, centre of each window (first at 0, last at the end)
    env : ndarray (m,), in [0, 1]
    """
    d = np.abs(np.asarray(drive, dtype=np.float64))
    if d.size == 0:
        return np.zeros(1), np.zeros(1)
    w = max(1, int(round(rate / carrier_hz)))
    m = -(-d.size // w)
    pad = np.zeros(m * w)
    pad[:d.size] = d
    env = pad.reshape(m, w).max(axis=1)
    t = (np.arange(m) * w + (w - 1) / 2) / rate
    t[0], env[0] = 0.0, env[0]
    return t, np.minimum(env, 1.0)


def simplify(t: np.ndarray, v: np.ndarray, tolerance: float) -> np.ndarray:
    """Indices of a piecewise-linear subset of (t, v) within ``tolerance`` of every point (Douglas-Peucker)."""
    keep = np.zeros(t.size, dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, t.size - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        seg_t, seg_v = t[a + 1:b], v[a + 1:b]
        line = v[a] + (v[b] - v[a]) * (seg_t - t[a]) / (t[b] - t[a])
        err = np.abs(seg_v - line)
        k = int(np.argmax(err))
        if err[k] > tolerance:
            i = a + 1 + k
            keep[i] = True
            stack += [(a, i), (i, b)]
    return np.flatnonzero(keep)


def _r(x: float) -> float:
    return float(round(x, 6))


def ahap_document(event_time, event_amplitude, drive, audio_rate: float, carrier_hz: float, t0: float = 0.0,
                  envelope: bool = True, tolerance: float = 0.02, description: str = "") -> dict:
    """The AHAP pattern of a played stroke (module docs).

    Parameters
    ----------
    event_time : (n_events,), s; ``event_amplitude`` : (n_events,), full scale
    drive : (n_audio,), full scale ±1, first sample at ``t0``
    audio_rate, carrier_hz : Hz
    t0 : s, time of the stroke's first tick (AHAP times start at 0)
    envelope : bool, write the continuous events and the envelope curves
    tolerance : float, largest envelope error of the curves, fraction of the stroke's peak
    """
    et = np.asarray(event_time, dtype=np.float64) - t0
    ea = np.asarray(event_amplitude, dtype=np.float64)
    if not (np.all(np.isfinite(et)) and np.all(np.isfinite(ea))):
        raise InputError("AHAP: event times and amplitudes must be finite")
    if not (math.isfinite(tolerance) and 0 < tolerance < 1):
        raise InputError(f"`tolerance` must be within (0, 1) (got {tolerance!r})")
    sharp = _r(sharpness_of_carrier(carrier_hz))
    pattern = []
    for t, a in zip(et.tolist(), ea.tolist()):
        pattern.append({"Event": {"Time": _r(max(t, 0.0)), "EventType": "HapticTransient", "EventParameters": [
            {"ParameterID": "HapticIntensity", "ParameterValue": _r(min(1.0, max(0.0, a)))},
            {"ParameterID": "HapticSharpness", "ParameterValue": sharp}]}})
    n_curves = 0
    duration = max(0.0, (len(drive) - 1) / audio_rate)
    if envelope and duration > 0:
        start = 0.0
        while start < duration:
            length = min(MAX_CONTINUOUS_S, duration - start)
            pattern.append({"Event": {"Time": _r(start), "EventType": "HapticContinuous",
                                      "EventDuration": _r(length), "EventParameters": [
                                          {"ParameterID": "HapticIntensity", "ParameterValue": 1.0},
                                          {"ParameterID": "HapticSharpness", "ParameterValue": sharp}]}})
            start += length
        t, env = drive_envelope(drive, audio_rate, carrier_hz)
        peak = float(env.max())
        g = env / peak if peak > 0 else env
        idx = simplify(t, g, tolerance)
        step = MAX_CURVE_POINTS - 1
        for k in range(0, max(1, idx.size - 1), step):
            pts = idx[k:k + MAX_CURVE_POINTS]
            if pts.size < 2:
                break
            c0 = t[pts[0]]
            pattern.append({"ParameterCurve": {
                "ParameterID": "HapticIntensityControl", "Time": _r(c0),
                "ParameterCurveControlPoints": [{"Time": _r(t[i] - c0), "ParameterValue": _r(g[i])} for i in pts]}})
            n_curves += 1
    pattern.sort(key=lambda e: next(iter(e.values()))["Time"])
    doc = {"Version": AHAP_VERSION,
           "Metadata": {"Project": "shapedisplay", "Created": "shapedisplay play",
                        "Description": description or "stroke played by the stick-slip renderer",
                        "Transients": len(et), "EnvelopeCurves": n_curves}}
    doc["Pattern"] = pattern
    check_ahap(doc)
    return doc


def _num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def check_ahap(doc) -> None:
    """Raise :class:`InputError` naming the first key, type or range that is not valid AHAP."""
    def bad(where, rule, value):
        raise InputError(f"AHAP {where}: {rule} (got {value!r})")

    if not isinstance(doc, dict):
        bad("document", "must be an object", type(doc).__name__)
    for k in doc:
        if k not in ("Version", "Metadata", "Pattern"):
            bad(f"key '{k}'", "top-level keys are Version, Metadata, Pattern", k)
    if not _num(doc.get("Version")):
        bad("Version", "must be a number", doc.get("Version"))
    if "Metadata" in doc and not isinstance(doc["Metadata"], dict):
        bad("Metadata", "must be an object", doc["Metadata"])
    pattern = doc.get("Pattern")
    if not isinstance(pattern, list):
        bad("Pattern", "must be an array", pattern)
    for i, item in enumerate(pattern):
        where = f"Pattern[{i}]"
        if not isinstance(item, dict) or len(item) != 1:
            bad(where, "must be an object with one key: Event, Parameter or ParameterCurve", item)
        (kind, body), = item.items()
        if not isinstance(body, dict):
            bad(f"{where}.{kind}", "must be an object", body)
        if not (_num(body.get("Time")) and body["Time"] >= 0):
            bad(f"{where}.{kind}.Time", "must be a number >= 0 (s)", body.get("Time"))
        if kind == "Event":
            allowed = {"Time", "EventType", "EventDuration", "EventParameters", "EventWaveformPath"}
            for k in body:
                if k not in allowed:
                    bad(f"{where}.Event key '{k}'", f"keys are {sorted(allowed)}", k)
            et = body.get("EventType")
            if et not in EVENT_TYPES:
                bad(f"{where}.Event.EventType", f"must be one of {EVENT_TYPES}", et)
            if et == "HapticContinuous":
                d = body.get("EventDuration")
                if not (_num(d) and 0 < d <= MAX_CONTINUOUS_S):
                    bad(f"{where}.Event.EventDuration", f"a continuous event lasts > 0 and <= {MAX_CONTINUOUS_S:g} s", d)
            params = body.get("EventParameters", [])
            if not isinstance(params, list):
                bad(f"{where}.Event.EventParameters", "must be an array", params)
            for j, p in enumerate(params):
                pid = p.get("ParameterID") if isinstance(p, dict) else None
                if pid not in EVENT_PARAMETERS or set(p) != {"ParameterID", "ParameterValue"}:
                    bad(f"{where}.Event.EventParameters[{j}]", f"needs ParameterID in {sorted(EVENT_PARAMETERS)} "
                        "and ParameterValue", p)
                lo, hi = EVENT_PARAMETERS[pid]
                v = p["ParameterValue"]
                if not (_num(v) and lo <= v <= hi):
                    bad(f"{where}.Event.EventParameters[{j}] {pid}", f"must be within [{lo:g}, {hi:g}]", v)
        elif kind == "ParameterCurve":
            pid = body.get("ParameterID")
            if pid not in DYNAMIC_PARAMETERS:
                bad(f"{where}.ParameterCurve.ParameterID", f"must be one of {sorted(DYNAMIC_PARAMETERS)}", pid)
            pts = body.get("ParameterCurveControlPoints")
            if not (isinstance(pts, list) and 1 <= len(pts) <= MAX_CURVE_POINTS):
                bad(f"{where}.ParameterCurve.ParameterCurveControlPoints",
                    f"must be an array of 1..{MAX_CURVE_POINTS} points", pts if not isinstance(pts, list) else len(pts))
            lo, hi = DYNAMIC_PARAMETERS[pid]
            last = -1.0
            for j, p in enumerate(pts):
                if not (isinstance(p, dict) and set(p) == {"Time", "ParameterValue"}):
                    bad(f"{where}.ParameterCurve point {j}", "needs exactly Time and ParameterValue", p)
                if not (_num(p["Time"]) and p["Time"] >= last and p["Time"] >= 0):
                    bad(f"{where}.ParameterCurve point {j} Time", "must be >= 0 and not decrease", p["Time"])
                last = p["Time"]
                if not (_num(p["ParameterValue"]) and lo <= p["ParameterValue"] <= hi):
                    bad(f"{where}.ParameterCurve point {j} {pid}", f"must be within [{lo:g}, {hi:g}]",
                        p["ParameterValue"])
        elif kind == "Parameter":
            pid = body.get("ParameterID")
            if pid not in DYNAMIC_PARAMETERS:
                bad(f"{where}.Parameter.ParameterID", f"must be one of {sorted(DYNAMIC_PARAMETERS)}", pid)
            lo, hi = DYNAMIC_PARAMETERS[pid]
            if not (_num(body.get("ParameterValue")) and lo <= body["ParameterValue"] <= hi):
                bad(f"{where}.Parameter {pid}", f"must be within [{lo:g}, {hi:g}]", body.get("ParameterValue"))
        else:
            bad(where, "must hold Event, Parameter or ParameterCurve", kind)


def ahap_of_result(result, carrier_hz: float, envelope: bool = True, description: str = "") -> dict:
    """:func:`ahap_document` of a :class:`~shapedisplay.render.renderer.RenderResult`."""
    return ahap_document(result.event_time, result.event_amplitude, result.audio, result.audio_rate, carrier_hz,
                         t0=float(result.t[0]) if result.t.size else 0.0, envelope=envelope,
                         description=description)


def write_ahap(path: str | os.PathLike, doc: dict) -> Path:
    """Check ``doc`` (:func:`check_ahap`) and write it as JSON, atomically."""
    check_ahap(doc)
    write_text(path, json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return Path(path)


def write_drive_csv(path: str | os.PathLike, drive, rate: float) -> Path:
    """Write ``t_s,drive`` rows (module docs), atomically."""
    d = np.asarray(drive, dtype=np.float64)
    if not np.all(np.isfinite(d)):
        raise InputError("drive CSV: the drive must be finite")
    t = np.arange(d.size) / float(rate)
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="ascii", newline="\n") as f:
            f.write("t_s,drive\n")
            np.savetxt(f, np.column_stack([t, d]), fmt=["%.9g", "%.9g"], delimiter=",")
    return Path(path)
