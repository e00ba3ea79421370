"""Offline play of a whole path with the engine that starts fastest: the C runtime or the Python kernels.

Both engines play the same settings (:mod:`.settings`) with the same
arithmetic, so they give the same result bit for bit
(``tests/test_native_play.py``); they differ in what they cost before the
first tick:

* ``"c"`` — the C runtime as a shared library (:mod:`.native`): built once
  with the system C compiler in about a second, then loaded in about a
  millisecond; numba is never imported. Models :data:`~.native.C_MODELS`.
* ``"python"`` — the numba kernels (:class:`~.renderer.Renderer`): every model.
  Importing numba takes about half a second per process, and the first run
  after an install compiles the kernels (about 20 s; cached on disk after).
* ``"auto"`` (default) — ``"c"`` where the C runtime can play the model and a
  C compiler is there (or the library is already built), else ``"python"``.
  A path the runtime's fixed buffers would play differently (more than half
  its event ring sounding at once, sample times off the tick grid) goes to
  ``"python"`` too. :attr:`PathRenderer.engine` says which engine played and
  :attr:`PathRenderer.note` why not the C runtime.
"""
from __future__ import annotations

from ..errors import InputError, unknown_key
from .result import RenderResult
from .settings import render_settings

#: Engine names (``play --engine``).
ENGINES = ("auto", "c", "python")


class PathRenderer:
    """Plays whole cursor paths offline over one table (the interface of :meth:`.renderer.Renderer.render`).

    Parameters
    ----------
    table : FrictionTable
    engine : {"auto", "c", "python"}
        See the module docstring. ``"c"`` raises
        :class:`~shapedisplay.errors.InputError` where the C runtime cannot
        play (model, compiler, path).
    **options
        The :class:`~.renderer.Renderer` arguments (device, model, tick_rate,
        audio_rate, burst_policy, max_stick_period, model options), validated
        here before any engine is loaded.
    """

    def __init__(self, table, engine: str = "auto", **options):
        if engine not in ENGINES:
            raise unknown_key("engine", engine, ENGINES)
        self.table = table
        self.settings = render_settings(table, **options)
        self.device = self.settings.device
        self.tick_rate = self.settings.tick_rate
        self.audio_rate = self.settings.audio_rate
        self._options = options
        self._requested = engine
        #: Why the C runtime does not play (None while it does or may).
        self.note: str | None = None
        #: The engine that plays: "c" or "python" (auto may still turn to "python" for one path).
        self.engine = engine
        if engine != "python":
            from .native import unavailable
            self.note = unavailable(self.settings.model.name)
            if self.note is not None and engine == "c":
                raise InputError(f"`engine` 'c' cannot play here: {self.note}")
            self.engine = "c" if self.note is None else "python"
        self._python = None

    def _python_renderer(self):
        if self._python is None:
            from .renderer import Renderer
            self._python = Renderer(self.table, **self._options)
        return self._python

    def render(self, cursor) -> RenderResult:
        """Render ``cursor`` (a :class:`~.cursor.CursorPath`) offline; see :meth:`.renderer.Renderer.render`."""
        if self.engine == "c":
            from .native import render_path
            try:
                return render_path(self.table, self.settings, cursor)
            except InputError as exc:     # not built, refused, or a path its fixed buffers play differently
                if self._requested == "c":
                    raise
                self.note = str(exc)
                self.engine = "python"
        return self._python_renderer().render(cursor)
