"""Regenerate the pictures in docs/images from the shipped samples (``make docs-images``).

Every picture is made from files under ``assets/`` with fixed settings and
written without a timestamp or software version, so running this twice
gives the same bytes on the same machine (``tests/test_docs_images.py``
checks that for every picture it can make here).

    python scripts/docs_images.py                  # every picture, into docs/images
    python scripts/docs_images.py --out DIR        # somewhere else
    python scripts/docs_images.py play-phone ...   # only these

The 3D previews need off-screen OpenGL (EGL/OSMesa, see
scripts/install-system-deps.sh); the studio screenshot needs Chromium and
playwright. A picture whose tools are missing is skipped with a note
(exit 0); ``--strict`` makes that an error.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "assets"

#: The README's stroke up the phone scene: crosses wifi, volume, app-6, app-3 and the frame.
PHONE_STROKE = "62,2 -> 62,156 @ 30mm/s"


class Skipped(Exception):
    """A picture's tools are missing here."""


def _phone(work: Path):
    """The phone scene compiled, the README stroke played on it: (table, renderer, result, trace path)."""
    from shapedisplay.render.cursor import parse_stroke
    from shapedisplay.render.renderer import Renderer
    from shapedisplay.author.scene import compile_scene
    from shapedisplay.render.sinks import write_trace

    table = compile_scene(ASSETS / "scenes" / "phone.toml").table
    r = Renderer(table, model="exact", tick_rate=10000.0)
    res = r.render(parse_stroke(PHONE_STROKE, r.tick_rate))
    trace = work / "phone-trace.npz"
    write_trace(trace, res, table.checksum)
    return table, r, res, trace


def _need_offscreen():
    from shapedisplay.errors import ShapeDisplayError
    try:
        from shapedisplay.viewer.offscreen import check_offscreen
        import pyvista  # noqa: F401
        check_offscreen()
    except (ImportError, ShapeDisplayError) as exc:
        raise Skipped(f"no off-screen OpenGL here ({exc})") from None


def play_phone(out: Path, work: Path) -> None:
    """``play --plot`` of the README stroke over the phone scene."""
    from shapedisplay.table.widgets import widget_map
    from shapedisplay.render.sinks import plot_trace
    table, _, res, _ = _phone(work)
    plot_trace(out, res, widgets=widget_map(table))


def preview_phone(out: Path, work: Path) -> None:
    """3D preview of the phone table coloured by N, with the played stroke and its chart."""
    _need_offscreen()
    from shapedisplay import viewer
    table, _, _, trace = _phone(work)
    path = work / "phone.npz"
    table.save(path)
    model = viewer.load_model(path)
    model.title = "assets/scenes/phone.toml, stroke " + PHONE_STROKE
    p = viewer.render(model, "N", trace=viewer.load_trace(trace), size=(1200, 860))
    try:
        p.save(out)
    finally:
        p.close()


def preview_keycap(out: Path, work: Path) -> None:
    """3D preview of the keycap mesh compiled at 0.1 mm: half of its samples are walls."""
    _need_offscreen()
    from shapedisplay import viewer
    path = work / "keycap.npz"
    _cli("compile", str(ASSETS / "meshes" / "keycap.stl"), "-o", str(path), "--resolution", "0.1mm", "--up", "z")
    model = viewer.load_model(path)
    model.title = "assets/meshes/keycap.stl compiled at 0.1 mm"
    p = viewer.render(model, "height", size=(1100, 760))
    try:
        p.save(out)
    finally:
        p.close()


def slope_height_study(out: Path, work: Path) -> None:
    """The slope-height study's summary plot."""
    _cli("study", "slope-height", "-o", str(work / "sh"))
    shutil.copyfile(work / "sh" / "summary.png", out)


def burst_spectrum(out: Path, work: Path) -> None:
    """Spectrum of the retrigger drive: restarted carrier against one continuous carrier."""
    subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_bursts.py"), "--plot", str(out)],
                   check=True, stdout=subprocess.DEVNULL, cwd=work)


def _browser_shot(out: Path, work: Path, test: str, select: str, name: str) -> None:
    """Copy to ``out`` the screenshot ``name`` that the headless-browser test ``test -k select`` takes."""
    if shutil.which("chromium") is None and shutil.which("chromium-browser") is None:
        raise Skipped("no chromium here")
    try:
        import playwright  # noqa: F401
    except ImportError:
        raise Skipped("playwright is not installed (pip install 'shapedisplay[studio,test]')") from None
    shots = work / f"shots-{select}"
    shots.mkdir()
    env = dict(os.environ, SHAPEDISPLAY_SCREENSHOT_DIR=str(shots))
    subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-x",
                    str(ROOT / "tests" / test), "-k", select], check=True, env=env, cwd=ROOT, stdout=subprocess.DEVNULL)
    if not (shots / name).exists():
        raise Skipped("the browser test was skipped here")
    shutil.copyfile(shots / name, out)


def studio_phone(out: Path, work: Path) -> None:
    """The studio page on the phone scene (a screenshot from the headless-browser test)."""
    _browser_shot(out, work, "test_studio_browser.py", "scripted_stroke", "studio-phone.png")


def studio_design(out: Path, work: Path) -> None:
    """The studio as a design tool: a widget selected with its handles, the inspector, rulers, A/B lines."""
    _browser_shot(out, work, "test_studio_design.py", "ab_switch", "studio-design.png")


def _cli(*argv: str) -> None:
    from shapedisplay.cli.main import main
    import contextlib
    import io
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = main(list(argv))
    if rc:
        raise RuntimeError(f"shapedisplay {' '.join(argv)} exited {rc}")


#: Picture name (docs/images/NAME.png) -> function writing it; deterministic ones first.
PICTURES = {
    "play-phone": play_phone,
    "preview-phone": preview_phone,
    "preview-keycap": preview_keycap,
    "slope-height-study": slope_height_study,
    "burst-spectrum": burst_spectrum,
    "studio-phone": studio_phone,
    "studio-design": studio_design,
}
#: Pictures that are not byte-stable (a live browser page): regenerated, not compared.
NOT_BYTE_STABLE = ("studio-phone", "studio-design")


def drawing_versions() -> dict:
    """Versions of the libraries that decide the pixels (the same versions give the same bytes)."""
    from importlib.metadata import PackageNotFoundError, version
    out = {}
    for dist in ("matplotlib", "vtk", "pyvista", "pillow", "numpy"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = None
    import platform
    out["machine"] = platform.machine()
    mesa = None                       # the software rasterizer of the off-screen previews (Debian package)
    if shutil.which("dpkg-query"):
        res = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "libgl1-mesa-dri"], capture_output=True,
                             text=True)
        mesa = res.stdout.strip() or None if res.returncode == 0 else None
    out["mesa"] = mesa
    return out


def make(names, out_dir: Path, strict: bool = False) -> dict:
    """Write the pictures ``names`` into ``out_dir``; returns name -> "written" or the reason skipped."""
    out_dir.mkdir(parents=True, exist_ok=True)
    done = {}
    for name in names:
        with tempfile.TemporaryDirectory() as tmp:
            target = Path(tmp) / f"{name}.png"
            try:
                PICTURES[name](target, Path(tmp))
            except Skipped as why:
                if strict:
                    raise SystemExit(f"{name}: {why}") from None
                done[name] = f"skipped: {why}"
                continue
            shutil.copyfile(target, out_dir / f"{name}.png")
            done[name] = "written"
    return done


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help=f"pictures to make (default all): {', '.join(PICTURES)}")
    ap.add_argument("--out", default=str(ROOT / "docs" / "images"), help="folder to write (default docs/images)")
    ap.add_argument("--strict", action="store_true", help="fail when a picture cannot be made here")
    args = ap.parse_args(argv)
    unknown = [n for n in args.names if n not in PICTURES]
    if unknown:
        ap.error(f"unknown picture(s) {', '.join(unknown)}; known: {', '.join(PICTURES)}")
    done = make(args.names or list(PICTURES), Path(args.out), args.strict)
    for name, what in done.items():
        print(f"{name}.png: {what}")
    if "written" in done.values():   # what the pictures were drawn with (tests compare bytes only under these)
        import json
        (Path(args.out) / "versions.json").write_text(json.dumps(drawing_versions(), indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
