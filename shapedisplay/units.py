"""Quantities with units written out: "2 N/mm", "1e-5 N*s/mm", "80 mm/(N*s)".

Internal units are SI (m, kg, s, N, Hz). :func:`parse_quantity` turns a string
into a float in the SI unit the caller asks for and checks the dimension. A
bare number where a unit is required is an error that names the field.

Grammar: ``NUMBER [UNIT]`` where UNIT is atoms joined by ``*``, ``·``, ``/`` or
spaces, with ``^n`` powers and parentheses, e.g. ``mm/(N*s)``, ``N s/m``,
``m/s^2``. Atoms: m g s N Hz Pa rad deg in %, with prefixes n u µ m c k M
(``cm`` only for metres).
"""
from __future__ import annotations

import math
import re
from typing import Tuple

from shapedisplay.errors import InputError, UnitError

Dim = Tuple[int, int, int]  # exponents of (m, kg, s)

_BASE = {
    "m": (1.0, (1, 0, 0)),
    "g": (1e-3, (0, 1, 0)),
    "s": (1.0, (0, 0, 1)),
    "N": (1.0, (1, 1, -2)),
    "Hz": (1.0, (0, 0, -1)),
    "Pa": (1.0, (-1, 1, -2)),
}
_PREFIX = {"n": 1e-9, "u": 1e-6, "µ": 1e-6, "m": 1e-3, "k": 1e3, "M": 1e6}
_ATOMS: dict[str, tuple[float, Dim]] = {}
for _name, (_scale, _dim) in _BASE.items():
    _ATOMS[_name] = (_scale, _dim)
    for _p, _f in _PREFIX.items():
        _ATOMS[_p + _name] = (_f * _scale, _dim)
_ATOMS.update({
    "cm": (1e-2, (1, 0, 0)),
    "in": (0.0254, (1, 0, 0)),
    "inch": (0.0254, (1, 0, 0)),
    "rad": (1.0, (0, 0, 0)),
    "deg": (math.pi / 180.0, (0, 0, 0)),
    "%": (1e-2, (0, 0, 0)),
    "1": (1.0, (0, 0, 0)),
})
_ATOMS.pop("Mm", None)  # megametre is never meant; avoid confusion with mm
_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")
_NON_FINITE = re.compile(r"^\s*[-+]?(nan|inf)", re.IGNORECASE)
_TOKEN = re.compile(r"\s*(\(|\)|\*|·|/|\^\s*[-+]?\d+|[A-Za-zµ%]+|1)")

_DIM_NAMES = {
    (1, 0, 0): "length", (0, 1, 0): "mass", (0, 0, 1): "time",
    (1, 1, -2): "force", (0, 0, -1): "frequency", (0, 1, -2): "stiffness",
    (0, 1, -1): "damping", (1, 0, -1): "velocity", (0, -1, 1): "velocity per force",
    (-1, -1, 2): "length per force", (0, 0, 0): "dimensionless", (-1, 0, 0): "per length",
}


def _dim_name(dim: Dim) -> str:
    return _DIM_NAMES.get(tuple(dim), "m^%d kg^%d s^%d" % tuple(dim))


class _Parser:
    def __init__(self, text: str, field: str):
        self.text, self.field = text, field
        self.tokens: list[str] = []
        pos = 0
        while pos < len(text):
            if text[pos:].strip() == "":
                break
            m = _TOKEN.match(text, pos)
            if not m:
                raise UnitError(f"`{field}`: cannot read unit '{text}' at '{text[pos:]}'")
            self.tokens.append(m.group(1).replace(" ", ""))
            pos = m.end()
        self.i = 0

    def peek(self):
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self):
        tok = self.peek()
        self.i += 1
        return tok

    def expr(self) -> tuple[float, Dim]:
        scale, dim = self.term()
        while True:
            tok = self.peek()
            if tok in ("*", "·"):
                self.take()
                s2, d2 = self.term()
                scale, dim = scale * s2, _add(dim, d2)
            elif tok == "/":
                self.take()
                s2, d2 = self.term()
                scale, dim = scale / s2, _add(dim, d2, -1)
            elif tok is not None and tok != ")" and not tok.startswith("^"):
                s2, d2 = self.term()  # implicit product: "N s/m"
                scale, dim = scale * s2, _add(dim, d2)
            else:
                return scale, dim

    def term(self) -> tuple[float, Dim]:
        tok = self.take()
        if tok is None:
            raise UnitError(f"`{self.field}`: unit '{self.text}' ends too early")
        if tok == "(":
            scale, dim = self.expr()
            if self.take() != ")":
                raise UnitError(f"`{self.field}`: unbalanced parentheses in unit '{self.text}'")
        elif tok in _ATOMS:
            scale, dim = _ATOMS[tok]
        else:
            from shapedisplay.errors import did_you_mean
            raise UnitError(
                f"`{self.field}`: unknown unit '{tok}' in '{self.text}'{did_you_mean(tok, _ATOMS)}"
            )
        nxt = self.peek()
        if nxt is not None and nxt.startswith("^"):
            self.take()
            p = int(nxt[1:])
            if abs(p) > 9:   # also keeps scale**p finite (1e3**999 overflows)
                raise UnitError(f"`{self.field}`: unit power must be between -9 and 9 (got '^{p}' in '{self.text}')")
            scale, dim = scale ** p, tuple(d * p for d in dim)
        return scale, dim


def _add(a: Dim, b: Dim, sign: int = 1) -> Dim:
    return tuple(x + sign * y for x, y in zip(a, b))


def parse_unit(unit: str, field: str = "unit") -> tuple[float, Dim]:
    """Return (scale to SI, dimension) of a unit expression such as ``"mm/(N*s)"``."""
    p = _Parser(unit, field)
    if not p.tokens:
        return 1.0, (0, 0, 0)
    scale, dim = p.expr()
    if p.peek() is not None:
        raise UnitError(f"`{field}`: cannot read unit '{unit}' near '{p.peek()}'")
    return scale, dim


#: The unit a hint proposes for a quantity stored in an SI unit: the unit designers
#: write it in (lengths in mm on a screen, stiffness in N/mm, speeds in mm/s).
NATURAL_UNITS = {"m": "mm", "N/m": "N/mm", "m/s": "mm/s", "N*s/m": "N*s/mm", "m/(N*s)": "mm/(N*s)",
                 "1/m": "1/mm"}


def natural_unit(unit: str) -> str:
    """The unit to propose in a hint for a value stored in ``unit`` (``"m"`` -> ``"mm"``)."""
    return NATURAL_UNITS.get(unit.replace(" ", ""), unit)


def parse_quantity(value, unit: str, field: str, *, bare_ok: bool = False) -> float:
    """Parse ``value`` into a float expressed in ``unit`` (usually SI).

    Parameters
    ----------
    value : str or float
        ``"2 N/mm"``, ``"0.5N"``, ``"10kHz"``; a plain number only if ``bare_ok``
        (it is then taken to be in ``unit``).
    unit : str
        Target unit, e.g. ``"N/m"``; the dimension of ``value`` must match it.
    field : str
        Name used in error messages.

    Raises
    ------
    UnitError
        bare number where a unit is required, unknown unit, wrong dimension,
        or a non-finite value.
    """
    target_scale, target_dim = parse_unit(unit, field)
    if isinstance(value, bool):
        raise UnitError(f"`{field}` must be a quantity in {unit} (got {value!r})")
    if isinstance(value, (int, float)):
        if not bare_ok and target_dim != (0, 0, 0):
            raise UnitError(
                f"`{field}` needs a unit, e.g. '{value} {natural_unit(unit)}' (got bare number {value!r})"
            )
        out = float(value)
    elif isinstance(value, str):
        m = _NUMBER.match(value)
        if not m and _NON_FINITE.match(value):
            raise UnitError(f"`{field}` must be finite (got {value!r})")
        if not m:
            raise UnitError(f"`{field}` must be a number with a unit such as '2 {natural_unit(unit)}' (got {value!r})")
        number, unit_text = float(m.group(1)), m.group(2)
        if not unit_text:
            if not bare_ok and target_dim != (0, 0, 0):
                raise UnitError(
                    f"`{field}` needs a unit, e.g. '{m.group(1)} {natural_unit(unit)}' (got bare number {value!r})"
                )
            out = number
        else:
            scale, dim = parse_unit(unit_text, field)
            if tuple(dim) != tuple(target_dim):
                raise UnitError(
                    f"`{field}` must be a {_dim_name(target_dim)} in {unit} "
                    f"(got {value!r}, a {_dim_name(dim)})"
                )
            out = number * scale / target_scale
    else:
        raise UnitError(f"`{field}` must be a quantity in {unit} (got {value!r})")
    if not math.isfinite(out):
        raise UnitError(f"`{field}` must be finite (got {value!r})")
    return out


def _split_unit(text: str) -> tuple[str, str]:
    m = _NUMBER.match(text)
    return (m.group(1), m.group(2)) if m else (text, "")


def parse_pair(text: str, sep: str, unit: str, field: str) -> tuple[float, float]:
    """Parse ``"60x4mm"`` (sep ``x``) or ``"0:2mm"`` (sep ``:``) into two SI floats.

    A unit on the second part only applies to both ("0:2mm" means 0 mm to 2 mm).
    """
    if not isinstance(text, str) or text.count(sep) != 1:
        raise UnitError(f"`{field}` must look like 'A{sep}B {unit}' (got {text!r})")
    a, b = (part.strip() for part in text.split(sep))
    _, unit_b = _split_unit(b)
    _, unit_a = _split_unit(a)
    if unit_b and not unit_a:
        a = f"{a} {unit_b}"
    second = parse_quantity(b, unit, field)   # first: a bad B ("0:NaNmm") is the error, not A's missing unit
    return parse_quantity(a, unit, field), second


def format_quantity(value: float, unit: str) -> str:
    """Format an SI value in ``unit`` with 4 significant digits: ``"2 N/mm"``."""
    scale, _ = parse_unit(unit)
    return f"{value / scale:.4g} {unit}"


#: Byte-size units: decimal (kB, MB) and binary (KiB, MiB, GiB).
BYTE_UNITS = {"b": 1, "kb": 1000, "kib": 1024, "mb": 10**6, "mib": 1024**2, "gb": 10**9, "gib": 1024**3}


def parse_byte_size(text, field: str, lo: int | None = None, hi: int | None = None) -> int:
    """A size in bytes from ``"64 KiB"``, ``"65536 B"`` or ``"65536"`` (bytes), checked against ``lo..hi``.

    Raises :class:`~shapedisplay.errors.InputError` naming ``field``, the rule and the value.
    """
    t = str(text).strip().lower().replace(" ", "")
    num = t.rstrip("abcdefghijklmnopqrstuvwxyz")
    unit = t[len(num):] or "b"
    try:
        value = float(num) * BYTE_UNITS[unit]
    except (ValueError, KeyError):
        raise InputError(f"`{field}` must be a size like '64 KiB' or '65536 B' (got {text!r})") from None
    if not math.isfinite(value) or value != int(value):
        raise InputError(f"`{field}` must be a whole number of bytes (got {text!r})")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise InputError(f"`{field}` must be within {format_byte_size(lo or 0)}..{format_byte_size(hi)} "
                         f"(got {text!r})")
    return int(value)


def format_byte_size(n) -> str:
    """``1024`` -> ``"1 KiB"``, ``2**31`` -> ``"2 GiB"``; sizes that are no whole binary unit in bytes."""
    if n is None:
        return "inf"
    for name, f in (("GiB", 1024**3), ("MiB", 1024**2), ("KiB", 1024)):
        if n >= f and n % f == 0:
            return f"{n // f} {name}"
    return f"{n} B"
