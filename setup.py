"""The package's compiled parts, built when the package is built or installed (pyproject.toml has the rest).

Two extension modules, loaded from Python with ctypes (their files are found
with ``importlib.util.find_spec``; the engine's module is also imported for its
one Python-level function, ``pad_run``, see ``_module.c``):

* ``shapedisplay._engine``: the C runtime (every ``shapedisplay/engine/sd_*.c``
  but the WebAssembly entry points ``sd_wasm.c``) and its offline play loop
  ``shapedisplay/render/sd_play_path.c`` (:mod:`shapedisplay.render.native`), and the reports'
  timing floors ``shapedisplay/render/sd_floors.c`` (:mod:`shapedisplay.reports.common`);
* ``shapedisplay._kernels_c``: the compiler's kernels ``shapedisplay/author/sd_kernels.c``
  (:mod:`shapedisplay.author.kernels`). Kept apart from the runtime: compiling a
  table does not load the runtime, the runtime library holds none of the
  compiler's code, and neither can clash with the other's names.

``shapedisplay/_module.c`` makes each a valid extension module on every
platform (its ``PyInit_`` function). Arithmetic is IEEE double as written
(no contraction into fused multiply-adds): the C runtime plays bit for bit as
the Python renderer does, and the C kernels give numpy's values.
"""
from __future__ import annotations

import re
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).resolve().parent
PACKAGE = Path("shapedisplay")

#: Flags for gcc and clang: C99, IEEE double as written.
UNIX_FLAGS = ["-std=c99", "-O2", "-ffp-contract=off"]
#: Flags for MSVC: no contraction or reassociation of floating-point operations.
MSVC_FLAGS = ["/O2", "/fp:precise"]

#: A C function definition at the start of a line that is not ``static``: what ctypes looks up.
_DEFINITION = re.compile(r"^(?!static\b)[A-Za-z_][\w \t*]*?\b(sd_\w+)\s*\([^;{]*\)\s*\{", re.MULTILINE)


def runtime_sources() -> list[str]:
    """The C runtime's sources, whatever models it has (a glob: a new model file builds in)."""
    return [*(str(p) for p in sorted((PACKAGE / "engine").glob("sd_*.c")) if p.name != "sd_wasm.c"),
            str(PACKAGE / "render" / "sd_play_path.c"),
            str(PACKAGE / "render" / "sd_floors.c")]


def exported(sources: list[str]) -> list[str]:
    """Names of the functions ``sources`` define (not static): MSVC exports from a DLL only those it is told."""
    return sorted({m.group(1) for s in sources for m in _DEFINITION.finditer((HERE / s).read_text(encoding="utf-8"))})


def extension(name: str, sources: list[str], macros=(), **kw) -> Extension:
    short = name.rsplit(".", 1)[1]
    return Extension(name, [*sources, str(PACKAGE / "_module.c")], define_macros=[("SD_MODULE", short), *macros],
                     export_symbols=exported(sources), **kw)


class BuildExt(build_ext):
    """Compiler flags by compiler family; the math library where it is separate."""

    def build_extensions(self):
        msvc = self.compiler.compiler_type == "msvc"
        for ext in self.extensions:
            ext.extra_compile_args = MSVC_FLAGS if msvc else UNIX_FLAGS
            if not msvc:
                ext.libraries = ["m"]           # (export_symbols only matter to MSVC: gcc and clang export all)
        super().build_extensions()


setup(
    ext_modules=[
        extension("shapedisplay._engine", runtime_sources(), macros=[("SD_ENGINE_METHODS", None)],
                  include_dirs=[str(PACKAGE / "engine")]),
        extension("shapedisplay._kernels_c", [str(PACKAGE / "author" / "sd_kernels.c")]),
    ],
    cmdclass={"build_ext": BuildExt},
)
