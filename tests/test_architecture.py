"""The package's import graph: one way, no cycles, and a runtime that needs no authoring module.

Every ``import`` in the package counts, also the ones inside functions (lazy
imports keep ``import shapedisplay`` cheap, but they are dependencies all the
same). Imports of a package's ``__init__`` by its own submodules are Python's
doing, not the code's, and are not edges.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "shapedisplay"

#: The shared leaves at the top of the package: every subpackage may import them.
LEAVES = {"shapedisplay", "shapedisplay.errors", "shapedisplay.units", "shapedisplay.atomic",
          "shapedisplay.extensions"}
#: What the runtime and the device link may import: a table file plus these run a device host.
RUNTIME_SIDE = LEAVES
RUNTIME_PACKAGES = ("shapedisplay.table", "shapedisplay.render", "shapedisplay.link")
#: Subpackage -> the subpackages it may import (besides the leaves): the pipeline's direction.
ALLOWED = {
    "table": set(),
    "render": {"table"},
    "link": {"table", "render"},
    "author": {"table"},
    "exchange": {"table", "render", "author"},
    "viewer": {"table", "render", "author"},
    "reports": {"table", "render", "author", "exchange"},
    "studio": {"table", "render", "author", "exchange", "viewer"},
    "cli": {"table", "render", "link", "author", "exchange", "viewer", "reports", "studio"},
}
#: Top-level modules that sit above everything: ``python -m shapedisplay`` and the API's front door.
FRONT_DOORS = ("shapedisplay.__main__", "shapedisplay.api")
#: Top-level modules besides subpackages (the leaves and the ``python -m`` entry point).
TOP_LEVEL_LIMIT = 8


def _modules() -> dict[str, tuple[Path, bool]]:
    mods = {}
    for p in PACKAGE.rglob("*.py"):
        parts = list(p.relative_to(PACKAGE.parent).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        mods[".".join(parts[:-1] if is_pkg else parts)] = (p, is_pkg)
    return mods


def import_graph() -> dict[str, set[str]]:
    """module -> the package modules it imports (anywhere in its code)."""
    mods = _modules()
    graph = {}
    for name, (path, is_pkg) in mods.items():
        pkg = name if is_pkg else name.rsplit(".", 1)[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                deps.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = pkg.split(".")[:len(pkg.split(".")) - (node.level - 1)]
                    mod = ".".join(base + ([node.module] if node.module else []))
                else:
                    mod = node.module or ""
                for a in node.names:
                    deps.add(f"{mod}.{a.name}" if f"{mod}.{a.name}" in mods else mod)
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def _closure(graph, start) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for d in graph[todo.pop()]:
            if d not in seen:
                seen.add(d)
                todo.append(d)
    return seen


def find_cycle(graph) -> list[str] | None:
    """One import cycle (as a list of modules, first == last), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                return stack[stack.index(d):] + [d]
            if d not in state:
                found = visit(d)
                if found:
                    return found
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return None


def test_graph_sees_lazy_and_relative_imports():
    """The walker itself: it finds a function-level relative import and a package-level one."""
    g = import_graph()
    assert "shapedisplay.render.renderer" in g["shapedisplay.viewer.model"]      # lazy, inside a function
    assert "shapedisplay.render.native" in g["shapedisplay.render.models"]      # from .native import ..., lazy
    assert "shapedisplay.link.protocol" in g["shapedisplay.link.engine"]          # from . import protocol
    assert "shapedisplay.author.scene.fields" in g["shapedisplay.author.scene.widgets"]


def test_no_import_cycles():
    assert find_cycle(import_graph()) is None, " -> ".join(find_cycle(import_graph()))


def test_find_cycle_reports_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def _subpackage(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and (PACKAGE / parts[1]).is_dir()) else None


def test_subpackages_import_one_way():
    """Each subpackage imports only the leaves and the subpackages upstream of it (ALLOWED): no cycle between them."""
    g = import_graph()
    wrong = []
    for mod, deps in g.items():
        a = _subpackage(mod)
        for d in deps:
            b = _subpackage(d)
            if a and b and a != b and b not in ALLOWED.get(a, set()):
                wrong.append(f"{mod} -> {d}")
            if a is None and b and mod not in FRONT_DOORS:
                wrong.append(f"{mod} (a leaf) -> {d}")
            if a and d in FRONT_DOORS:
                wrong.append(f"{mod} -> {d} (a front door: nothing inside the package imports it)")
    assert not wrong, "imports against the pipeline's direction:\n" + "\n".join(sorted(wrong))
    assert set(ALLOWED) == {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    sub = {a: {b for b in deps} for a, deps in ALLOWED.items()}
    assert find_cycle(sub) is None


def test_top_level_is_small_and_modules_are_readable():
    """At most TOP_LEVEL_LIMIT modules beside the subpackages; no hand-written module over 900 lines."""
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= TOP_LEVEL_LIMIT, top
    long = [f"{p.relative_to(PACKAGE)}: {n}" for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 900]
    assert not long, long


@pytest.mark.parametrize("package", RUNTIME_PACKAGES)
def test_runtime_and_link_import_no_authoring_module(package):
    g = import_graph()
    for mod in sorted(m for m in g if m == package or m.startswith(package + ".")):
        outside = sorted(d for d in _closure(g, mod) - RUNTIME_SIDE
                         if not d.startswith(RUNTIME_PACKAGES))
        assert not outside, f"{mod} imports authoring modules {outside}"


def _docs():
    root = PACKAGE.parent
    return [root / "README.md", *sorted((root / "docs").glob("*.md")), *sorted(PACKAGE.rglob("README.md"))]


def test_imports_named_in_the_docs_exist():
    """Every ``from shapedisplay... import ...`` line in README.md and docs/ names something that exists."""
    import importlib
    import importlib.util
    import re
    lines = set()
    for doc in _docs():
        for m in re.finditer(r"^\s*from (shapedisplay[\w.]*) import ([\w, ]+?)\s*(?:#.*)?$", doc.read_text(), re.M):
            lines.add((doc.name, m.group(1), tuple(n.strip() for n in m.group(2).split(","))))
    assert lines
    for doc, module, names in sorted(lines):
        mod = importlib.import_module(module)
        for name in names:
            assert hasattr(mod, name) or importlib.util.find_spec(f"{module}.{name}"), \
                f"{doc}: 'from {module} import {name}' names nothing"


def test_dotted_names_and_paths_in_the_docs_exist():
    """``shapedisplay.x.y`` names and ``shapedisplay/x/y.py`` paths written in the docs are still there."""
    import importlib
    import re
    root = PACKAGE.parent
    for doc in _docs():
        text = doc.read_text()
        for dotted in sorted(set(re.findall(r"\bshapedisplay(?:\.[A-Za-z_]\w*)+", text))):
            parts = dotted.split(".")
            for i in range(len(parts), 0, -1):          # the longest importable module, then attributes
                try:
                    obj = importlib.import_module(".".join(parts[:i]))
                except ImportError:
                    continue
                for attr in parts[i:]:
                    assert hasattr(obj, attr), f"{doc.name}: '{dotted}' does not exist"
                    obj = getattr(obj, attr)
                break
        for path in sorted(set(re.findall(r"\bshapedisplay/[\w/]+\.\w+", text))):
            assert (root / path).exists(), f"{doc.name}: path '{path}' does not exist"


def test_c_runtime_checks_the_same_tick_rate_range():
    """The C runtime cannot import the range; its own check must hold the numbers of devices.TICK_RATE_RANGE."""
    import re
    from shapedisplay.table.devices import TICK_RATE_RANGE
    src = (PACKAGE / "engine" / "sd_render.c").read_text()
    found = re.findall(r"tick_rate\s*>=\s*([\d.eE+]+)f?\s*&&\s*\w+->tick_rate\s*<=\s*([\d.eE+]+)", src)
    assert found, "sd_render.c: no tick-rate range check found"
    assert {(float(lo), float(hi)) for lo, hi in found} == {TICK_RATE_RANGE}


def test_c_runtime_checks_the_same_h_omega_limit():
    """sd_renderer_init's pad rule holds the number of devices.H_OMEGA_MAX (the renderer names it first)."""
    import re
    from shapedisplay.table.devices import H_OMEGA_MAX
    found = re.findall(r"#define SD_H_OMEGA_MAX ([\d.eE+]+)", (PACKAGE / "engine" / "sd_runtime.h").read_text())
    assert found and float(found[0]) == H_OMEGA_MAX
    assert "SD_H_OMEGA_MAX * SD_H_OMEGA_MAX" in (PACKAGE / "engine" / "sd_render.c").read_text()


def _tracked_text_files():
    import subprocess
    root = PACKAGE.parent
    res = subprocess.run(["git", "ls-files"], cwd=root, capture_output=True, text=True)
    names = res.stdout.split() if res.returncode == 0 else [
        p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file() and ".venv" not in p.parts]
    suffixes = (".py", ".md", ".c", ".h", ".js", ".html", ".css", ".toml", ".sh", ".txt", ".cfg", ".json")
    return [root / n for n in names if n.endswith(suffixes) or n.endswith("Makefile")]


def test_no_reference_to_documents_outside_the_repository():
    """Code, comments, docstrings and docs cite the project's own docs/, never a design or style document."""
    import re
    outside = re.compile(r"\bDESIGN\b|\bSTYLE\.md\b|design (?:doc|document|reference)\w*,? (?:§|section )?\d")
    found = []
    for path in _tracked_text_files():
        if path == Path(__file__):
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, FileNotFoundError):
            continue
        for i, line in enumerate(text.splitlines(), 1):
            if outside.search(line):
                found.append(f"{path.relative_to(PACKAGE.parent)}:{i}: {line.strip()[:100]}")
    assert not found, "references to documents outside the repository:\n" + "\n".join(found)


def test_links_in_the_docs_point_into_the_repository():
    """Every relative link of README.md and docs/ names a file that exists (anchors aside)."""
    import re
    for doc in _docs():
        for target in re.findall(r"\]\(([^)\s]+)\)", doc.read_text(encoding="utf-8")):
            if re.match(r"[a-z]+:", target) or target.startswith("#"):
                continue
            path = (doc.parent / target.split("#")[0]).resolve()
            assert path.exists(), f"{doc.name}: link '{target}' points to nothing"


def test_sizes_are_printed_cols_by_rows():
    """Every message prints a grid as cols x rows samples (W x H), never rows first."""
    import re
    rows_first = re.compile(r"\{[^{}]*\brows?\b[^{}]*\}\s*[x×]\s*\{[^{}]*\bcols?\b[^{}]*\}|"
                            r"\{[^{}]*shape\[0\][^{}]*\}\s*[x×]\"?\s*f?\"?\s*\{[^{}]*shape\[1\]")
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if rows_first.search(line):
                found.append(f"{path.relative_to(PACKAGE.parent)}:{i}: {line.strip()}")
    assert not found, "\n".join(found)
    assert rows_first.search('f"{grid.rows}x{grid.cols} samples"') and rows_first.search('f"{a.shape[0]}x{a.shape[1]}"')


def test_physics_page_covers_every_model_of_the_registry():
    """docs/physics.md has a section per renderer model, with its published sources listed."""
    from shapedisplay.render.models import MODELS
    text = (PACKAGE.parent / "docs" / "physics.md").read_text(encoding="utf-8")
    headings = [line for line in text.splitlines() if line.startswith("### ")]
    for name in MODELS:
        assert any(f"`{name}`" in h for h in headings), f"docs/physics.md: no section for model '{name}'"
    assert "## References" in text and text.count("\n- ") >= 5
    readme = (PACKAGE.parent / "README.md").read_text(encoding="utf-8")
    assert "(docs/physics.md)" in readme and "(physics.md)" in (PACKAGE.parent / "docs" / "renderer.md").read_text()


def test_readme_stays_within_20_kb():
    """The README is the designer's first hour; detail goes to docs/."""
    assert (PACKAGE.parent / "README.md").stat().st_size <= 20_000
