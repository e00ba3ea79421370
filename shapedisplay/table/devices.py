"""Device profiles: what a tactile device can render, and the pad/friction model.

Profiles are TOML files (see ``shapedisplay/table/data/devices/``). ``[pad]`` and
``[friction]`` entries are plain numbers (SI: kg, N/m, N*s/m; friction
coefficients) or quantities with units; every other entry is a quantity with
its unit written out ("1 kHz", "80 mm/(N*s)"). This module is on the runtime
side: a table plus a profile is all a host needs.
"""
from __future__ import annotations

import functools
import math
import sys
import typing
from dataclasses import MISSING, asdict, dataclass, field, fields, is_dataclass, replace
from pathlib import Path

from shapedisplay.errors import FileFormatError, InputError, ModelError, unknown_key
from shapedisplay.units import parse_quantity


def toml_module():
    """The TOML parser (``tomllib``, or ``tomli`` before Python 3.11), imported on first use.

    Loading it costs a process about 8 ms; a ``play`` takes its device from
    the table and never parses TOML.
    """
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    return tomllib


#: Tick rates a renderer runs at and a device profile may declare, Hz (the one home of this range).
TICK_RATE_RANGE = (100.0, 192_000.0)
#: Largest h * omega_n of a pad: its natural frequency sqrt(k/m) over the tick rate (the C engine's
#: SD_H_OMEGA_MAX). Beyond it the pad rings through hundreds of stick-slip transitions within one tick
#: (1,000 already gives about 140 a tick on a lightly damped pad); the stability report's sweeps reach 1,000.
H_OMEGA_MAX = 1000.0


def check_tick_rate(rate: float, field: str = "tick_rate") -> float:
    """Return ``rate`` (Hz) as float, or raise naming ``field`` if outside :data:`TICK_RATE_RANGE`."""
    try:
        r = float(rate)
    except (TypeError, ValueError):
        raise InputError(f"`{field}` must be a number in Hz (got {rate!r})") from None
    lo, hi = TICK_RATE_RANGE
    if not (math.isfinite(r) and lo <= r <= hi):
        raise InputError(f"`{field}` must be within {lo:g} Hz..{hi / 1e3:g} kHz (got {rate!r} Hz)")
    return r

#: Bundled device profiles, shipped inside the package (a wheel carries them).
BUNDLED_DEVICES = Path(__file__).resolve().parent / "data" / "devices"
#: Output channels a device may have.
OUTPUTS = ("burst", "lateral", "skin_stretch", "normal", "contactor")


@dataclass(frozen=True)
class PadParams:
    """1-DOF fingerpad (Konyo et al.). Published Konyo values by default."""

    mass: float = 1.0e-6        # kg
    stiffness: float = 2.0e3    # N/m   (2.0 N/mm)
    damping: float = 1.0e-2     # N*s/m (1.0e-5 N*s/mm)

    def validate(self) -> "PadParams":
        for name in ("mass", "stiffness"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ModelError(f"pad `{name}` must be finite and > 0 (got {name}={v!r})")
        if not (math.isfinite(self.damping) and self.damping >= 0):
            raise ModelError(f"pad `damping` must be finite and >= 0 (got damping={self.damping!r})")
        return self

    @property
    def omega_n(self) -> float:
        """Natural angular frequency sqrt(k/m), rad/s."""
        return math.sqrt(self.stiffness / self.mass)

    @property
    def zeta(self) -> float:
        """Damping ratio c / (2 sqrt(k m))."""
        return self.damping / (2.0 * math.sqrt(self.stiffness * self.mass))


@dataclass(frozen=True)
class FrictionParams:
    """Coulomb friction coefficients; mu_k = mu_s - delta_mu."""

    mu_s: float = 0.5
    mu_k: float = 0.3

    def validate(self) -> "FrictionParams":
        if not (math.isfinite(self.mu_s) and self.mu_s > 0):
            raise ModelError(f"friction `mu_s` must be finite and > 0 (got mu_s={self.mu_s!r})")
        if not (math.isfinite(self.mu_k) and self.mu_k >= 0):
            raise ModelError(f"friction `mu_k` must be finite and >= 0 (got mu_k={self.mu_k!r})")
        if self.mu_k > self.mu_s:
            raise ModelError(f"`mu_k` must be <= `mu_s` (got mu_k={self.mu_k}, mu_s={self.mu_s})")
        return self


@dataclass(frozen=True)
class BurstParams:
    """Vibrotactile burst at each stick-to-slip transition (Konyo et al.)."""

    carrier_hz: float = 300.0     # Hz; > 200 Hz targets Pacinian receptors
    rise_s: float = 0.005         # s, linear rise
    decay_s: float = 0.030        # s, quadratic decay
    gain: float = 0.25            # B, output amplitude per newton of breakaway force (full scale 1 at 4 N)
    max_stick_period_s: float = 0.0  # s; 0 = off (published fix for long periods at high N)

    def validate(self) -> "BurstParams":
        for name in ("carrier_hz", "rise_s", "decay_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ModelError(f"burst `{name}` must be finite and > 0 (got {v!r})")
        if not (math.isfinite(self.gain) and self.gain >= 0):
            raise ModelError(f"burst `gain` must be finite and >= 0 (got {self.gain!r})")
        if not (math.isfinite(self.max_stick_period_s) and self.max_stick_period_s >= 0):
            raise ModelError(f"burst `max_stick_period` must be >= 0 (0 = off) (got {self.max_stick_period_s!r})")
        return self


@dataclass(frozen=True)
class DeviceProfile:
    """What a device renders and how. Lengths m, forces N, rates Hz."""

    name: str = "default"
    description: str = "published Konyo pad, burst output only"
    outputs: tuple = ("burst",)
    tick_rate_hz: float = 10_000.0
    audio_rate_hz: float = 48_000.0
    normal_force_range: tuple = (0.0, 10.0)          # N
    velocity_range: tuple = (1e-4, 0.5)              # m/s
    cursor_gain: float = 0.0                         # alpha, m/(N*s); 0 = position input
    force_sample_rate_hz: float = 0.0
    resolution_m: float = 0.5e-3                     # smallest feature felt apart
    lateral_force_max: float = 0.0                   # N
    skin_stretch_max: float = 0.0                    # m
    pad: PadParams = field(default_factory=PadParams)
    friction: FrictionParams = field(default_factory=FrictionParams)
    burst: BurstParams = field(default_factory=BurstParams)
    extra: dict = field(default_factory=dict)        # model-specific sections (karnopp, stribeck, contactor)

    def validate(self) -> "DeviceProfile":
        self.pad.validate()
        self.friction.validate()
        self.burst.validate()
        try:
            check_tick_rate(self.tick_rate_hz)
        except InputError as exc:
            raise InputError(f"device {exc}") from None
        h_omega = self.pad.omega_n / self.tick_rate_hz
        if not h_omega <= H_OMEGA_MAX:
            raise ModelError(f"device pad: h * omega_n = sqrt(stiffness / mass) / tick_rate = {h_omega:.4g}, beyond "
                             f"the limit of {H_OMEGA_MAX:g} (a stiffer or lighter pad needs a faster tick)")
        lo, hi = self.normal_force_range
        if not (0 <= lo < hi and math.isfinite(hi)):
            raise InputError(f"device `normal_force_range` must satisfy 0 <= low < high (got {lo}..{hi} N)")
        vlo, vhi = self.velocity_range
        if not (0 <= vlo < vhi and math.isfinite(vhi)):
            raise InputError(f"device `velocity_range` must satisfy 0 <= low < high (got {vlo}..{vhi} m/s)")
        for o in self.outputs:
            if o not in OUTPUTS:
                raise unknown_key("device output", o, OUTPUTS)
        if not self.burst.carrier_hz < self.audio_rate_hz / 2:
            raise InputError(f"burst `carrier` must be below half the audio rate, {self.audio_rate_hz / 2:g} Hz "
                             f"(got carrier={self.burst.carrier_hz:g} Hz, audio_rate={self.audio_rate_hz:g} Hz)")
        return self

    def to_json(self) -> dict:
        """Every field by name (a table header's ``device``): sections as objects, tuples as lists."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_json(cls, d: dict) -> "DeviceProfile":
        """The validated profile :meth:`to_json` wrote; a missing key keeps the field's default."""
        d = dict(d)
        for name, kind in field_types(cls).items():
            if is_dataclass(kind):
                d[name] = kind(**d.get(name, {}))
            elif kind is tuple and name in d:
                d[name] = tuple(d[name])
        return cls(**d).validate()

    def with_(self, **changes) -> "DeviceProfile":
        return replace(self, **changes).validate()


@functools.lru_cache(maxsize=None)
def field_types(cls) -> dict:
    """Field name -> type of dataclass ``cls`` (its annotations resolved: ``float``, ``tuple``, ``PadParams``, ...)."""
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in fields(cls)}


#: The JSON kind a header holds a field of each type as (see :func:`header_kinds`).
_TYPE_KINDS = {str: "str", bool: "bool", float: "number", int: "number", float | None: "number?", dict: "object"}


@functools.lru_cache(maxsize=None)
def header_kinds(cls) -> dict:
    """Field name -> the kind of JSON value a table header holds each field of dataclass ``cls`` as.

    The header schema of :class:`DeviceProfile` (``header["device"]``,
    checked by ``table.model.check_meta``) is derived here from the fields,
    so a field added to the dataclass is checked with no other edit. Kinds:
    "str", "bool", "number", "number?" (``float | None``: a number or null),
    "object" (a dict), "names" (a tuple of strings, as the default is), an
    int n (a tuple of n numbers, as the default is) or, for a nested
    dataclass, the dict of its own fields' kinds. A field type with no JSON
    form is a TypeError.
    """
    kinds = {}
    for f in fields(cls):
        kind = field_types(cls)[f.name]
        if is_dataclass(kind):
            kinds[f.name] = header_kinds(kind)
        elif kind is tuple:
            default = f.default_factory() if f.default is MISSING else f.default
            kinds[f.name] = "names" if all(isinstance(v, str) for v in default) else len(default)
        elif kind in _TYPE_KINDS:
            kinds[f.name] = _TYPE_KINDS[kind]
        else:
            raise TypeError(f"{cls.__name__}.{f.name}: a table header has no form for type {kind!r}")
    return kinds


# TOML key -> (attribute, unit, kind) ; kind: q quantity, r range of 2, s str, l list
_DEVICE_KEYS = {
    "name": ("name", None, "s"),
    "description": ("description", None, "s"),
    "outputs": ("outputs", None, "l"),
    "tick_rate": ("tick_rate_hz", "Hz", "q"),
    "audio_rate": ("audio_rate_hz", "Hz", "q"),
    "normal_force_range": ("normal_force_range", "N", "r"),
    "velocity_range": ("velocity_range", "m/s", "r"),
    "cursor_gain": ("cursor_gain", "m/(N*s)", "q"),
    "force_sample_rate": ("force_sample_rate_hz", "Hz", "q"),
    "resolution": ("resolution_m", "m", "q"),
    "lateral_force_max": ("lateral_force_max", "N", "q"),
    "skin_stretch_max": ("skin_stretch_max", "m", "q"),
}
_PAD_KEYS = {"mass": "kg", "stiffness": "N/m", "damping": "N*s/m"}
_FRICTION_KEYS = {"mu_s": "1", "mu_k": "1"}
_BURST_KEYS = {"carrier": ("carrier_hz", "Hz"), "rise": ("rise_s", "s"), "decay": ("decay_s", "s"),
               "gain": ("gain", "1/N"), "max_stick_period": ("max_stick_period_s", "s")}
_SECTIONS = ("device", "pad", "friction", "burst", "karnopp", "stribeck", "contactor", "skin_stretch")


def load_device(source: str | Path | None = None) -> DeviceProfile:
    """Load a device profile from a TOML file, or a bundled one by name.

    ``None`` gives the built-in default (published Konyo pad). A bare name
    such as ``"handheld-stick"`` is looked up in ``shapedisplay/table/data/devices/``.
    """
    if source is None:
        return DeviceProfile().validate()
    path = Path(source)
    if not path.suffix and not path.exists():
        path = BUNDLED_DEVICES / f"{source}.toml"
        if not path.exists():
            names = sorted(p.stem for p in (BUNDLED_DEVICES).glob("*.toml"))
            raise unknown_key("device", str(source), names)
    tomllib = toml_module()
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FileFormatError(f"device file '{path}': no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise FileFormatError(f"device file '{path}': unreadable ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise FileFormatError(f"device file '{path}': invalid TOML ({exc})") from None
    try:
        return parse_device(data, str(path))
    except InputError as exc:
        raise type(exc)(f"device file '{path}': {exc}") from None


def parse_device(data: dict, where: str = "device") -> DeviceProfile:
    """Build a validated :class:`DeviceProfile` from parsed TOML."""
    for sec in data:
        if sec not in _SECTIONS:
            raise unknown_key("section", sec, _SECTIONS)
        if not isinstance(data[sec], dict):
            raise InputError(f"`{sec}` must be a [{sec}] table of keys (got {data[sec]!r})")
    kw: dict = {}
    for key, value in data.get("device", {}).items():
        if key not in _DEVICE_KEYS:
            raise unknown_key("[device] key", key, _DEVICE_KEYS)
        attr, unit, kind = _DEVICE_KEYS[key]
        if kind == "q":
            kw[attr] = parse_quantity(value, unit, f"device.{key}")
        elif kind == "r":
            if not isinstance(value, list) or len(value) != 2:
                raise InputError(f"`device.{key}` must be a list of two quantities (got {value!r})")
            kw[attr] = tuple(parse_quantity(v, unit, f"device.{key}") for v in value)
        elif kind == "l":
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise InputError(f"`device.{key}` must be a list of names such as [\"burst\"] (got {value!r})")
            kw[attr] = tuple(value)
        else:
            if not isinstance(value, str):
                raise InputError(f"`device.{key}` must be a string (got {value!r})")
            kw[attr] = value
    pad = {}
    for key, value in data.get("pad", {}).items():
        if key not in _PAD_KEYS:
            raise unknown_key("[pad] key", key, _PAD_KEYS)
        pad[key] = parse_quantity(value, _PAD_KEYS[key], f"pad.{key}", bare_ok=True)
    fr = {}
    for key, value in data.get("friction", {}).items():
        if key not in _FRICTION_KEYS:
            raise unknown_key("[friction] key", key, _FRICTION_KEYS)
        fr[key] = parse_quantity(value, "1", f"friction.{key}", bare_ok=True)
    burst = {}
    for key, value in data.get("burst", {}).items():
        if key not in _BURST_KEYS:
            raise unknown_key("[burst] key", key, _BURST_KEYS)
        attr, unit = _BURST_KEYS[key]
        if key == "max_stick_period" and value in ("off", 0):
            burst[attr] = 0.0
            continue
        burst[attr] = parse_quantity(value, unit, f"burst.{key}", bare_ok=(key == "gain"))
    extra = {sec: dict(data[sec]) for sec in ("karnopp", "stribeck", "contactor", "skin_stretch") if sec in data}
    return DeviceProfile(pad=PadParams(**pad), friction=FrictionParams(**fr), burst=BurstParams(**burst),
                         extra=extra, **kw).validate()


def bundled_devices() -> list[str]:
    """Names of the profiles in ``shapedisplay/table/data/devices/``."""
    return sorted(p.stem for p in (BUNDLED_DEVICES).glob("*.toml"))
