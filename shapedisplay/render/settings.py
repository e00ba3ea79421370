"""What a renderer plays with: its settings from a table, a device and the options, validated once.

:class:`~.renderer.Renderer` takes its settings from here, and so do the
studio's payload and the binary table image. This module does not load the C
engine: settings are validated before anything is played.

The settings are one :data:`~.layouts.RENDER_CONFIG` record (the C
runtime's ``sd_config_t``, byte for byte): device friction, the table's
slope-friction gain, skin-stretch target and constant normal force, tick and
audio rates, burst envelope and policy, model id and pad parameters.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from shapedisplay.table.devices import H_OMEGA_MAX, DeviceProfile, check_tick_rate, load_device
from shapedisplay.errors import InputError, ModelError, TableError, unknown_key
from shapedisplay.table.model import FrictionTable
from shapedisplay.units import parse_quantity
from shapedisplay.render.layouts import BURST_POLICIES, RENDER_CONFIG, SLOTS, record

#: Most audio samples one offline render writes (1000 s at 48 kHz; 384 MB as float64).
MAX_AUDIO_SAMPLES = 48_000_001


def audio_length(duration: float, rate: float) -> int:
    """Samples ``floor(duration * rate + 1e-9) + 1`` of an offline stream; refused beyond :data:`MAX_AUDIO_SAMPLES`."""
    n = duration * rate
    if not (math.isfinite(n) and math.floor(n + 1e-9) + 1 <= MAX_AUDIO_SAMPLES):
        raise InputError(f"audio of {duration:.4g} s at {rate:g} Hz needs {n:.4g} samples, more than the "
                         f"{MAX_AUDIO_SAMPLES:,} of one offline render (shorten the path or lower the audio rate)")
    return int(math.floor(n + 1e-9)) + 1


def policy_id(name: str) -> int:
    """The number of burst policy ``name`` (:data:`~.layouts.BURST_POLICIES`; ``SD_*`` in C)."""
    if name not in BURST_POLICIES:
        raise unknown_key("burst policy", name, BURST_POLICIES)
    return BURST_POLICIES[name]


def constant_normal_force(table: FrictionTable) -> float | None:
    """The normal force (N) of a table that stores no ``normal_force`` channel, else None.

    A mapping without a height term leaves ``normal_force`` out of the table:
    N is then the constant ``n_base`` of the header's mapping. A table with
    neither is refused (the pad models need N).
    """
    if "normal_force" in table.channels:
        return None
    mapping = table.meta.get("mapping")
    n0 = mapping.get("n_base") if isinstance(mapping, dict) else None
    if n0 is None:
        raise TableError(f"table stores no 'normal_force' and its header gives no constant `mapping.n_base`; "
                         f"the pad models need N (it holds {table.channels})")
    if isinstance(n0, bool) or not isinstance(n0, (int, float)) or not (math.isfinite(n0) and n0 >= 0):
        raise TableError(f"table header `mapping.n_base` must be a finite force >= 0 N (got {n0!r})")
    return float(n0)


def device_for_table(table: FrictionTable, device=None) -> DeviceProfile:
    """The profile a renderer uses: ``device`` (profile, path or bundled name) if given,
    else ``table.meta["device"]``, else the built-in Konyo profile."""
    if isinstance(device, DeviceProfile):
        return device.validate()
    if device is not None:
        return load_device(device)
    if isinstance(table.meta.get("device"), dict):
        return DeviceProfile.from_json(table.meta["device"])
    return load_device(None)


def mapping_settings(table: FrictionTable, dev: DeviceProfile) -> tuple[float, float]:
    """The renderer settings a table's mapping and device add to the pad and burst parameters:
    ``(slope_friction_gain, skin_stretch_target_m)``, validated (one home for both rules)."""
    mapping = table.meta.get("mapping", {}) or {}
    kmu = float(mapping.get("slope_friction_gain", 0.0) or 0.0)
    if not (math.isfinite(kmu) and kmu >= 0):
        raise InputError(f"table mapping `slope_friction_gain` must be >= 0 (got {kmu!r})")
    if kmu > 0 and "grad_x" not in table.channels:
        raise TableError(f"table mapping sets slope_friction_gain={kmu:g} but the table lacks channel "
                         f"'grad_x' (and 'grad_y') needed for direction-dependent friction; "
                         f"it holds {table.channels}")
    sst = 0.0
    if "skin_stretch" in dev.extra and "target" in dev.extra["skin_stretch"]:
        sst = parse_quantity(dev.extra["skin_stretch"]["target"], "m", "skin_stretch.target")
    return kmu, sst


def derive_config(mu_s: float, mu_k: float, kmu: float = 0.0, sst: float = 0.0, n_const: float | None = None,
                  **settings) -> np.ndarray:
    """The RENDER_CONFIG the per-tick derivation reads (a one-element array): device friction, K_mu, skin
    target and the constant N of a table without ``normal_force`` (plus any other ``settings`` fields)."""
    return record(RENDER_CONFIG, mu_s=mu_s, mu_k=mu_k, k_mu=kmu, skin_target=sst,
                  normal_force_constant=n_const or 0.0, **settings)


def slot_channels(present) -> np.ndarray:
    """Packed channel of each slot (position in ``present``), -1 where the table lacks it."""
    return np.array([present.index(n) if n in present else -1 for n in SLOTS], dtype=np.int64)


@dataclass(frozen=True)
class RenderSettings:
    """A renderer's validated settings (see :func:`render_settings`).

    Attributes
    ----------
    device : DeviceProfile
        The profile played (the table's, or the one given, with the options applied).
    model : PadModel
        The pad model, its parameters packed (``model.params``).
    tick_rate, audio_rate : float, Hz
    burst_policy : str
    present : list of str
        The renderer slots the table stores, in slot order.
    config : ndarray, shape (1,), RENDER_CONFIG
        Everything the kernels read, pad parameters included.
    normal_force_constant : float or None
        N (newtons) of a table without a ``normal_force`` channel, else None.
    """

    device: DeviceProfile
    model: object
    tick_rate: float
    audio_rate: float
    burst_policy: str
    present: list
    config: np.ndarray
    normal_force_constant: float | None


def check_h_omega(mass: float, stiffness: float, rate: float, model: str) -> None:
    """Refuse a pad whose natural frequency the tick cannot resolve: h * omega_n > :data:`H_OMEGA_MAX`.

    The C engine holds the same rule (``sd_renderer_init``); this one names the numbers.
    """
    h_omega = math.sqrt(stiffness / mass) / rate
    if not h_omega <= H_OMEGA_MAX:
        raise ModelError(f"pad of model '{model}': h * omega_n = sqrt(stiffness / mass) / tick_rate = "
                         f"sqrt({stiffness:g} N/m / {mass:g} kg) / {rate:g} Hz = {h_omega:.4g}, beyond the limit "
                         f"of {H_OMEGA_MAX:g} (raise the tick rate or soften the pad)")


def render_settings(table: FrictionTable, device=None, model="exact", tick_rate=None, audio_rate=None,
                    burst_policy="retrigger", max_stick_period=None, **model_options) -> RenderSettings:
    """Validate a renderer's options against ``table`` (arguments as :class:`~.renderer.Renderer`)."""
    from shapedisplay.render.models import get_model
    if not isinstance(table, FrictionTable):
        raise InputError(f"`table` must be a FrictionTable (got {type(table).__name__})")
    dev = device_for_table(table, device)
    if max_stick_period is not None:
        msp = float(max_stick_period)
        if not (math.isfinite(msp) and msp >= 0):
            raise InputError(f"`max_stick_period` must be >= 0 s (got {max_stick_period!r})")
        dev = dev.with_(burst=replace(dev.burst, max_stick_period_s=msp))
    pad_model = get_model(model, dev, **model_options)
    table.require(*pad_model.needs)
    n_const = constant_normal_force(table)
    rate = check_tick_rate(dev.tick_rate_hz if tick_rate is None else tick_rate)
    ar = float(dev.audio_rate_hz if audio_rate is None else audio_rate)
    if not (math.isfinite(ar) and 1000.0 <= ar <= 384_000.0):
        raise InputError(f"`audio_rate` must be within 1 kHz..384 kHz (got {audio_rate!r} Hz)")
    pid = policy_id(burst_policy)
    present = [name for name in SLOTS if name in table.channels]
    kmu, sst = mapping_settings(table, dev)
    b = dev.burst
    config = derive_config(dev.friction.mu_s, dev.friction.mu_k, kmu, sst, n_const, tick_rate=rate, audio_rate=ar,
                           carrier_hz=b.carrier_hz, rise_s=b.rise_s, decay_s=b.decay_s, policy=pid,
                           model=pad_model.model_id)
    config[0]["pad"] = pad_model.params
    check_h_omega(float(pad_model.params["mass"]), float(pad_model.params["stiffness"]), rate, pad_model.name)
    return RenderSettings(dev, pad_model, rate, ar, burst_policy, present, config, n_const)
