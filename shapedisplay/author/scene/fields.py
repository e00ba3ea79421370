"""Scene field parsing: the parsing context, scene errors, value parsers and the records they fill.

Every value of a scene file goes through one of these parsers
(:func:`length`, :func:`quantity`, :func:`pair`, :func:`number`,
:func:`choice`, :func:`check_keys`), so an error always names the scene,
the widget and the field as written. The scene loader (:mod:`.spec`) and the
widget types (:mod:`~shapedisplay.author.scene.widgets`) both use them; this module imports neither.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from shapedisplay.errors import InputError, UnitError, did_you_mean
from shapedisplay.table.model import Grid
from shapedisplay.units import parse_pair, parse_quantity

#: How overlapping widgets combine: max (default), min, add, over (the later widget wins).
OVERLAP_RULES = ("max", "min", "add", "over")
#: Names of the widget types, the keys of :data:`~shapedisplay.author.scene.widgets.WIDGET_TYPES` (a test holds them
#: equal): what an SVG's elements are checked against to tell a mock-up from an icon without loading the widgets.
WIDGET_TYPE_NAMES = ("button", "dent", "well", "slider", "toggle", "ridge", "edge", "groove", "image", "mesh", "data")
#: Largest length a scene may state, metres (positions, sizes, ramps, heights): 1 km. Checked
#: as each value is read, so that snapping a box to the grid never meets an infinite sample index.
MAX_LENGTH_M = 1000.0


class SceneError(InputError):
    """A scene file breaks a rule; the message names widget, field, rule and value."""


class SceneUnitError(SceneError, UnitError):
    """A quantity of a scene file lacks its unit or has the wrong one."""


@dataclass(frozen=True)
class Canvas:
    """The scene's sample grid.

    ``width``/``height`` in metres (``height`` 0 for a 1-D strip); samples at
    ``(c * spacing, r * spacing)`` for ``c < cols``, ``r < rows``. ``origin``
    says how the file's coordinates read: ``"bottom-left"`` (y up, a
    ``position`` is the lower-left corner) or ``"top-left"`` (y down from the
    top edge, as in most mock-ups; a ``position`` is the top-left corner); the
    table itself is the same either way.
    """

    width: float
    height: float
    spacing: float
    dpi: float | None = None
    origin: str = "bottom-left"

    @property
    def is_1d(self) -> bool:
        return self.height == 0.0

    @property
    def cols(self) -> int:
        return int(round(self.width / self.spacing)) + 1

    @property
    def rows(self) -> int:
        return 1 if self.is_1d else int(round(self.height / self.spacing)) + 1

    @property
    def grid(self) -> Grid:
        return Grid(self.rows, self.cols, self.spacing, self.spacing, 0.0, 0.0)


@dataclass(frozen=True)
class Widget:
    """One widget after validation.

    ``params`` holds SI values (metres, newtons) after defaults; ``bbox`` is
    the snapped box ``(x0, y0, x1, y1)`` in metres before clipping; ``col0``,
    ``row0`` the canvas sample of the box corner and ``ncols``, ``nrows`` its
    sample counts (the box may reach outside the canvas; see ``clipped``).
    ``height_m`` is the signed height of the widget's main feature.
    """

    id: str
    type: str
    index: int
    params: dict
    col0: int
    row0: int
    ncols: int
    nrows: int
    spacing: float
    overlap: str = "max"
    clipped: bool = False
    label: str = ""
    box: tuple = (0, 0, 0, 0)   # (row0, col0, row1, col1) inclusive, clipped to the canvas
    overlap_given: bool = False  # `overlap` written in the file (or its [defaults]), not the built-in max

    @property
    def where(self) -> str:
        return f"widget[{self.index}] '{self.id}'"

    @property
    def bbox(self) -> tuple[float, float, float, float]:
        """Snapped box (x0, y0, x1, y1) in metres, clipped to the canvas; y0 == y1 == 0 on a 1-D canvas."""
        s = self.spacing
        r0, c0, r1, c1 = self.box
        return (c0 * s, r0 * s, c1 * s, r1 * s)

    @property
    def size(self) -> tuple[float, float]:
        """Snapped (width, height) in metres (height 0 on a 1-D canvas)."""
        return (self.ncols - 1) * self.spacing, (self.nrows - 1) * self.spacing


# --------------------------------------------------------------- value parsing
class Ctx:
    """Parsing context: where we are, the canvas dpi, the scene directory.

    ``confine``: when True every file the scene names must resolve (symlinks
    followed) inside ``base_dir`` (the studio); ``origins`` maps a field path
    to what it was written as in another format (an SVG's ``data-device``).
    """

    def __init__(self, path: str, base_dir: Path, dpi: float | None = None, is_1d: bool = False,
                 confine: bool = False, origins: dict | None = None):
        self.path, self.base_dir, self.dpi, self.is_1d = path, base_dir, dpi, is_1d
        self.confine = confine
        self.origins = origins or {}
        self.warnings: list[str] = []

    def file(self, where: str, field_path: str, value) -> Path:
        """The file the key ``field_path`` names: relative to the scene's folder, inside it when confined.

        Every path-bearing key of a scene is resolved here (see ``spec.PATH_KEYS``).
        """
        p = Path(str(value))
        if not p.is_absolute():
            p = self.base_dir / p
        if self.confine:
            root = Path(self.base_dir).resolve()
            real = p.resolve()
            if not real.is_relative_to(root):
                origin = self.origins.get(field_path)
                named = f"`{field_path}`" + (f" ({origin})" if origin else "")
                head = f"scene '{self.path}'" + (f": {where}" if where else "")
                raise SceneError(f"{head}: {named} = {str(value)!r} resolves to '{real}', outside the scene's "
                                 f"folder '{root}'; the studio reads only under that folder (copy the file there)")
        return p

    def error(self, where: str, field_path: str, msg: str) -> SceneError:
        head = f"scene '{self.path}'" + (f": {where}" if where else "")
        return SceneError(f"{head}: `{field_path}` {msg}")

    def warn(self, where: str, msg: str) -> None:
        self.warnings.append(f"{where}: {msg}" if where else msg)


def _px(value, field_path: str, ctx: Ctx, where: str):
    """Turn '12 px' into a length string in mm using the canvas dpi."""
    if isinstance(value, str) and value.strip().endswith("px"):
        if not ctx.dpi:
            raise ctx.error(where, field_path, f"is in px but the canvas has no `dpi` (got {value!r})")
        try:
            n = float(value.strip()[:-2])
        except ValueError:
            raise ctx.error(where, field_path, f"must be a number of px (got {value!r})") from None
        return f"{n * 25.4 / ctx.dpi!r} mm"
    return value


def wrap_unit_errors(ctx: Ctx, where: str, fn, *args):
    """``fn(*args)``, with a unit error restated as a :class:`SceneUnitError` naming the scene and widget."""
    try:
        return fn(*args)
    except UnitError as exc:
        head = f"scene '{ctx.path}'" + (f": {where}" if where else "")
        raise SceneUnitError(f"{head}: {exc}") from None


def _bounded(v: float, value, field_path: str, ctx: Ctx, where: str) -> float:
    if not abs(v) <= MAX_LENGTH_M:
        raise ctx.error(where, field_path, f"must be a length within {MAX_LENGTH_M:g} m of 0 (got {value!r})")
    return v


def length(value, field_path: str, ctx: Ctx, where: str = "", positive: bool = False,
           nonneg: bool = False) -> float:
    v = wrap_unit_errors(ctx, where, parse_quantity, _px(value, field_path, ctx, where), "m", field_path)
    _bounded(v, value, field_path, ctx, where)
    if positive and not v > 0:
        raise ctx.error(where, field_path, f"must be a length > 0 (got {value!r})")
    if nonneg and v < 0:
        raise ctx.error(where, field_path, f"must be a length >= 0 (got {value!r})")
    return v


def quantity(value, unit: str, field_path: str, ctx: Ctx, where: str = "", bare_ok: bool = False) -> float:
    return wrap_unit_errors(ctx, where, lambda: parse_quantity(value, unit, field_path, bare_ok=bare_ok))


def pair(value, sep: str, field_path: str, ctx: Ctx, where: str = "") -> tuple[float, float]:
    """'10,20 mm' / '30x16 mm' / ['10 mm', '20 mm'] -> two lengths in metres."""
    if isinstance(value, list):
        if len(value) != 2:
            raise ctx.error(where, field_path, f"must hold two lengths (got {value!r})")
        return (length(value[0], field_path, ctx, where), length(value[1], field_path, ctx, where))
    if isinstance(value, str) and value.strip().endswith("px"):
        parts = value.strip()[:-2].split(sep)
        if len(parts) != 2:
            raise ctx.error(where, field_path, f"must look like 'A{sep}B px' (got {value!r})")
        return (length(parts[0].strip() + " px", field_path, ctx, where),
                length(parts[1].strip() + " px", field_path, ctx, where))
    a, b = wrap_unit_errors(ctx, where, parse_pair, value, sep, "m", field_path)
    return _bounded(a, value, field_path, ctx, where), _bounded(b, value, field_path, ctx, where)


def number(value, field_path: str, ctx: Ctx, where: str = "", lo=None, hi=None, integer=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ctx.error(where, field_path, f"must be a number (got {value!r})")
    try:
        v = parse_quantity(value, "1", field_path, bare_ok=True)
    except UnitError:
        raise ctx.error(where, field_path, f"must be a number (got {value!r})") from None
    if integer and (float(v) != int(v)):
        raise ctx.error(where, field_path, f"must be a whole number (got {value!r})")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        rng = f"{lo if lo is not None else '-inf'}..{hi if hi is not None else 'inf'}"
        raise ctx.error(where, field_path, f"must lie within {rng} (got {value!r})")
    return int(v) if integer else v


def choice(value, options, field_path: str, ctx: Ctx, where: str = "") -> str:
    if not isinstance(value, str) or value not in options:
        hint = did_you_mean(str(value), options)
        raise ctx.error(where, field_path, f"must be one of {', '.join(options)} (got {value!r}){hint}")
    return value


def check_keys(raw: dict, valid, ctx: Ctx, where: str, prefix: str, kind: str = "key") -> None:
    for key in raw:
        if key not in valid:
            hint = did_you_mean(key, valid)
            raise SceneError(
                f"scene '{ctx.path}'" + (f": {where}" if where else "")
                + f": unknown {kind} `{prefix}{key}`{hint}; valid: {', '.join(sorted(valid))}")
