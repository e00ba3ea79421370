"""The studio's model: one source file, compiled into the table the page plays.

A :class:`Session` owns the source (a scene, an image, a mesh or a table), the
last good compile (table, report, generation number) and the last error.
Compiling again never loses the last good table: a scene with an error keeps
the previous table playing and records the error with the line it points at.

Files: the session reads only under the source's folder: every file a scene
or an SVG mockup names (``scene.path_keys()``: image, mesh and data widget
files, the device profile, from a widget or from ``[defaults]``) must
resolve there, symlinks followed, or the compile is refused with one line
naming the key and the path (``compile_scene(..., confine=True)``); a
``--device`` given as a path must lie there too, and a device given by name
is only ever a bundled profile. The studio writes only the scene the page
edits (through :mod:`~shapedisplay.studio.scenefile`) and files under the
output folder.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from shapedisplay.errors import FileFormatError, InputError, ShapeDisplayError, unknown_key
from shapedisplay.author.sources import source_kind

#: Largest scene text the page may save, bytes (the page saves through scenefile.SceneFile).
MAX_SCENE_BYTES = 1 << 20


def inside(path: Path, root: Path) -> bool:
    """True if ``path`` (resolved, symlinks followed) lies under the folder ``root``."""
    try:
        Path(path).resolve().relative_to(root)
        return True
    except ValueError:
        return False


@dataclass
class Compiled:
    """One good compile: the table, its report, the ``.npz`` bytes (made when first asked for) and a
    generation number."""

    table: object
    report: dict
    report_text: str
    npz: bytes | None
    generation: int
    seconds: float               # wall time of the compile

    @property
    def checksum(self) -> str:
        """The table's checksum (computed once)."""
        if getattr(self, "_checksum", None) is None:
            self._checksum = self.table.checksum
        return self._checksum

    def data(self) -> bytes:
        """The table as ``.npz`` bytes."""
        if self.npz is None:
            self.npz = self.table.to_bytes()
        return self.npz


@dataclass
class SourceError:
    """The last failed compile: message, the line it points at (scene text) and when."""

    message: str
    line: int | None
    generation: int


@dataclass
class Session:
    """A studio session on one source file.

    Parameters
    ----------
    source : Path
        Scene (.toml or an .svg mockup), image, mesh or table (.npz).
    device : str or None
        Device profile (bundled name or a TOML under the source's folder);
        None keeps the scene's or the table's own.
    out_dir : Path
        The only folder (besides the scene file itself) the studio writes to.
    options : dict
        Compile options by name as the command line's, unit strings
        (``{"size": "60x4mm"}``): the source compiles through
        :func:`shapedisplay.author.policy.compile_file`, as ``shapedisplay compile`` does.
    """

    source: Path
    device: str | None = None
    out_dir: Path | None = None
    options: dict = field(default_factory=dict)
    current: Compiled | None = None
    error: SourceError | None = None
    generation: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def __post_init__(self):
        src = Path(self.source)
        if not src.is_file():
            raise FileFormatError(f"studio source '{src}': no such file")
        self.kind = source_kind(src)
        self.source = src.resolve()
        self.root = self.source.parent
        from shapedisplay.author.scene.spec import is_device_path
        if self.device is not None and is_device_path(self.device):
            dev = Path(self.device)
            dev = dev if dev.is_absolute() else Path.cwd() / dev
            if not inside(dev, self.root):
                raise InputError(f"`--device` '{self.device}' lies outside the source's folder '{self.root}'; "
                                 "the studio reads only under that folder (copy the profile there)")
        out = Path(self.out_dir) if self.out_dir is not None else self.root / "studio-out"
        self.out_dir = out.resolve()

    # -------------------------------------------------------------- reading
    def source_text(self) -> str:
        """The scene text (scenes only)."""
        if self.kind != "scene":
            raise InputError(f"studio source '{self.source.name}' is a {self.kind}, not a scene: no text to edit")
        return self.source.read_text(encoding="utf-8")

    # -------------------------------------------------------------- compiling
    def compile(self, scene=None) -> bool:
        """Compile the source again (``scene``: the scene as already read and validated from the file's
        current text, not read again). True if a new table replaced the current one.

        On an error the current table stays; :attr:`error` holds the message and line.
        """
        with self._lock:
            self.generation += 1
            gen = self.generation
            t0 = time.perf_counter()
            text = None
            try:
                table, report, report_text = self._compile_source(scene)
            except ShapeDisplayError as exc:
                message = str(exc)
                line = None
                if self.kind == "scene":
                    from shapedisplay.studio.lines import error_line
                    try:
                        text = self.source.read_text(encoding="utf-8")
                        line = error_line(text, message)
                    except (OSError, UnicodeDecodeError):
                        pass
                self.error = SourceError(message, line, gen)
                return False
            self.current = Compiled(table, report, report_text, None, gen, time.perf_counter() - t0)
            self.error = None
            return True

    def _compile_source(self, scene=None):
        from shapedisplay.author.compile import format_report
        if self.kind == "table":
            from shapedisplay.table.model import FrictionTable
            table = FrictionTable.load(self.source)
            report = table.meta.get("report") or {}
            return table, report, (format_report(report) if report.get("grid") else "")
        from shapedisplay.author.policy import compile_file
        result = compile_file(scene if scene is not None else self.source,
                              device=self._device() if self.device else None, confine=True, **self.options)
        report_text = format_report(result.report)
        if self.kind in ("scene", "svg"):
            from shapedisplay.author.scene import format_widget_report
            report_text += "\n" + format_widget_report(result.report)
        return result.table, result.report, report_text

    def _device(self):
        """The ``--device`` profile: a file checked to lie under the folder, or a bundled name
        (never a file of the current directory that happens to have that name)."""
        from shapedisplay.table.devices import BUNDLED_DEVICES, load_device
        from shapedisplay.author.scene.spec import is_device_path
        if self.device is None or is_device_path(self.device):
            return load_device(self.device)
        bundled = BUNDLED_DEVICES / f"{self.device}.toml"
        if not bundled.is_file():
            raise unknown_key("device", self.device, (p.stem for p in BUNDLED_DEVICES.glob("*.toml")))
        return load_device(bundled)

    # -------------------------------------------------------------- page state
    def state(self) -> dict:
        """What the page shows: generation, table summary, report, widgets, error."""
        cur = self.current
        d = {"source": self.source.name, "kind": self.kind, "generation": self.generation,
             "table_generation": cur.generation if cur else None, "error": None}
        if self.error is not None:
            d["error"] = {"message": self.error.message, "line": self.error.line,
                          "generation": self.error.generation}
        if cur is not None:
            t = cur.table
            g = t.grid
            d.update({
                "grid": {"rows": g.rows, "cols": g.cols, "dx": g.dx, "dy": g.dy, "x0": g.x0, "y0": g.y0},
                "channels": t.channels,
                "widgets": (t.meta.get("scene") or {}).get("widgets", []),
                "report": cur.report_text,
                "compile_seconds": cur.seconds,
                "checksum": cur.checksum,
            })
        return d

    def watch_filter(self, path: str) -> bool:
        """True for a changed file that may change the compile (under the root, not in the output folder)."""
        p = Path(path)
        name = p.name
        if name.startswith(".") or name.endswith((".part", "~")) or ".part." in name:
            return False
        try:
            p.resolve().relative_to(self.out_dir)
            return False
        except ValueError:
            pass
        return inside(p, self.root)
