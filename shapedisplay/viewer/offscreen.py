"""Off-screen OpenGL for the preview: is there a display, and does VTK render without one.

Off-screen rendering works on a headless machine without a GPU through EGL
and Mesa's software rasterizer (or OSMesa); :func:`check_offscreen` probes it
once, in a child process, so a machine without any off-screen OpenGL gets a
clear error instead of a crash inside VTK. ``scripts/install-system-deps.sh``
installs the Debian packages it needs.
"""
from __future__ import annotations

import os
import subprocess
import sys

from shapedisplay.errors import ShapeDisplayError, require

#: Window classes tried for off-screen rendering without a display, in order.
OFFSCREEN_WINDOWS = ("vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow")

_PROBE = """
import vtkmodules.vtkRenderingOpenGL2, vtkmodules.vtkRenderingCore as rc
from vtkmodules.vtkCommonCore import vtkUnsignedCharArray, vtkLogger
vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
w = rc.vtkRenderWindow(); w.SetOffScreenRendering(1); w.SetSize(8, 8)
r = rc.vtkRenderer(); r.SetBackground(1.0, 0.0, 0.0); w.AddRenderer(r); w.Render()
a = vtkUnsignedCharArray(); w.GetPixelData(0, 0, 7, 7, 1, a, 0)
print(w.GetClassName(), *a.GetTuple3(0))
"""

_offscreen_cache: dict = {}


def has_display() -> bool:
    """True when an interactive window can be opened (X11/Wayland on Linux; always elsewhere)."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_offscreen(env: dict | None = None) -> str:
    """Make sure VTK can render off-screen here; return the window class used.

    Without a display, each class of :data:`OFFSCREEN_WINDOWS` is tried in a
    child process (a missing OpenGL library crashes VTK rather than raising),
    and the first that renders correctly is selected through
    ``VTK_DEFAULT_OPENGL_WINDOW``. With a display the default window is used.
    The answer is cached per process (``env`` given: not cached, not selected).

    Raises
    ------
    ShapeDisplayError
        No off-screen OpenGL is available; names the packages to install.
    """
    probe_env = dict(os.environ if env is None else env)
    if env is None and "window" in _offscreen_cache:
        return _offscreen_cache["window"]
    display = bool(probe_env.get("DISPLAY") or probe_env.get("WAYLAND_DISPLAY")) \
        or not sys.platform.startswith("linux")
    wanted = probe_env.get("VTK_DEFAULT_OPENGL_WINDOW")
    candidates = [wanted] if wanted else ([None] if display else list(OFFSCREEN_WINDOWS))
    tried = []
    for cls in candidates:
        e = dict(probe_env)
        if cls:
            e["VTK_DEFAULT_OPENGL_WINDOW"] = cls
        try:
            res = subprocess.run([sys.executable, "-c", _PROBE], env=e, capture_output=True, text=True,
                                 timeout=60)
        except subprocess.TimeoutExpired:
            tried.append(f"{cls or 'default'}: timed out")
            continue
        words = res.stdout.split()
        if res.returncode == 0 and len(words) == 4 and words[1:] == ["255.0", "0.0", "0.0"]:
            if env is None:
                if cls:
                    os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = cls
                _offscreen_cache["window"] = words[0]
            return words[0]
        tried.append(f"{cls or 'default'}: " + ("crashed" if res.returncode < 0 else f"exit {res.returncode}"))
    where = "the display's OpenGL" if display and not wanted else "EGL/OSMesa OpenGL"
    raise ShapeDisplayError(
        f"off-screen rendering is not available: {where} does not work here ({'; '.join(tried)}); "
        "install libegl1 libegl-mesa0 libgl1-mesa-dri (scripts/install-system-deps.sh), "
        "or unset DISPLAY to render through EGL")


def load_pyvista(off_screen: bool):
    """pyvista, ready to draw on screen (a display is needed) or off screen (probed first)."""
    if not off_screen and not has_display():
        raise ShapeDisplayError("interactive preview needs a display (DISPLAY is not set); "
                                "render off-screen instead: -o shot.png")
    pv = require("pyvista", "viewer", "3D preview")
    if off_screen:
        check_offscreen()     # VTK reads VTK_DEFAULT_OPENGL_WINDOW when a window is made, not at import
    try:
        from vtkmodules.vtkCommonCore import vtkLogger
        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except ImportError:  # pragma: no cover - vtk always ships vtkLogger with pyvista >= 0.43
        pass
    return pv

