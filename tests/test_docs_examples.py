"""Every code block of README.md and docs/*.md runs as written (the convention is in docs/README.md).

Each document is run on its own, top to bottom, in a fresh temporary folder
that holds a copy of the shipped samples (``assets/``) and nothing else:

* ```` ```sh ```` blocks run line by line (a line ending in ``\\`` continues);
  ``shapedisplay ...`` lines go through the command's own ``main()`` (the
  console script's entry point) in one Python process per document, other
  lines through ``bash -e``. Every line must exit with status 0.
* ```` ```python ```` blocks run in that process, each in a fresh namespace.
* ```` ```sh background ```` starts a command that serves until stopped (the
  studio, the device emulator): it runs in the background, the blocks after
  it run once it has printed its first line, and it is stopped at the end.
* ```` ```LANG file=out/NAME ```` writes the block to that file for the
  blocks after it to use.
* ```` ```LANG not-run: REASON ```` is not run; each one is reported here as
  a skipped test with its reason.
* ```` ```text ```` (output, diagrams) and ```` ```json ````, ```` ```c ````,
  ```` ```toml ```` without ``file=`` (excerpts of formats) are for reading.

Afterwards nothing outside ``out/`` may have been written or changed.

Run one document by hand: ``python tests/test_docs_examples.py docs/renderer.md /tmp/somewhere``.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RUN = ("sh", "python")
READ_ONLY = ("text", "json", "c", "toml")
#: What a block needs, found by these words in it -> (import name or program, reason when missing).
NEEDS = (
    (re.compile(r"shapedisplay preview|viewer\.render"), "offscreen", "off-screen OpenGL (pyvista + EGL/OSMesa)"),
    (re.compile(r"shapedisplay device|shapedisplay\.link\.host"), "serial", "pyserial (the serial extra)"),
    (re.compile(r"\.(stl|obj|ply|glb|gltf)\b"), "trimesh", "trimesh (the mesh extra)"),
    (re.compile(r"shapedisplay studio"), "uvicorn", "uvicorn/starlette (the studio extra)"),
    (re.compile(r"\.svg\b"), "svgelements", "svgelements (the svg extra)"),
    (re.compile(r"--plot\b|matplotlib"), "matplotlib", "matplotlib (the plot extra)"),
)


@dataclass
class Block:
    doc: str          # path relative to the repository
    line: int         # line of the opening fence
    lang: str
    attrs: str        # the rest of the info string
    text: str

    @property
    def where(self) -> str:
        return f"{self.doc}:{self.line}"

    @property
    def not_run(self) -> str | None:
        m = re.match(r"not-run:\s*(.+)", self.attrs)
        return m.group(1).strip() if m else None

    @property
    def file(self) -> str | None:
        m = re.search(r"\bfile=(\S+)", self.attrs)
        return m.group(1) if m else None

    @property
    def background(self) -> bool:
        return self.attrs.split()[:1] == ["background"]

    @property
    def runs(self) -> bool:
        return self.not_run is None and (self.file is not None or self.lang in RUN)


FENCE = re.compile(r"^(?P<fence>```+)(?P<info>[^\n`]*)\n(?P<body>.*?)^(?P=fence)[ \t]*$", re.M | re.S)


def blocks_of(path: Path) -> list[Block]:
    return blocks_in(path.read_text(encoding="utf-8"), path.relative_to(ROOT).as_posix())


def blocks_in(text: str, name: str) -> list[Block]:
    out = []
    for m in FENCE.finditer(text):
        info = m.group("info").strip()
        lang, _, attrs = info.partition(" ")
        out.append(Block(name, text.count("\n", 0, m.start()) + 1, lang,
                         attrs.strip(), m.group("body")))
    return out


def sh_lines(text: str) -> list[str]:
    """The command lines of an sh block: continuations joined, comment lines and blank lines dropped."""
    lines, current = [], ""
    for raw in text.splitlines():
        current += raw
        if current.endswith("\\"):
            current = current[:-1] + " "
            continue
        if current.strip() and not current.lstrip().startswith("#"):
            lines.append(current.strip())
        current = ""
    if current.strip():
        lines.append(current.strip())
    return lines


SHELL_SYNTAX = re.compile(r"[|&;<>$`]|\(\)")


def _snapshot(folder: Path) -> dict[str, str]:
    """path -> content hash of every file outside out/."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if rel == "out" or rel.startswith("out/") or p.is_dir():
            continue
        out[rel] = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "?"
    return out


def run_document(doc: str, folder: Path) -> list[dict]:
    """Run the blocks of ``doc`` in ``folder`` (this process, cwd changed); one result per block run."""
    import contextlib
    import io
    import signal
    import traceback

    from shapedisplay.cli.main import main

    os.chdir(folder)
    os.environ["PATH"] = os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", "")
    results, background = [], []

    def record(block, ok, output, started):
        results.append({"where": block.where, "ok": ok, "seconds": round(time.monotonic() - started, 2),
                        "output": output[-4000:], "source": block.text})
        return ok

    try:
        for block in blocks_of(ROOT / doc):
            if not block.runs:
                continue
            started = time.monotonic()
            if block.file:
                target = (folder / block.file).resolve()
                if not target.is_relative_to(folder.resolve() / "out"):
                    record(block, False, f"file={block.file} is not under out/", started)
                    return results
                target.parent.mkdir(parents=True, exist_ok=True)
                target.write_text(block.text, encoding="utf-8")
                record(block, True, "", started)
                continue
            if block.background:
                (line,) = sh_lines(block.text)
                proc = subprocess.Popen(["bash", "-c", "exec " + line], stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, start_new_session=True)
                background.append(proc)
                first = proc.stdout.readline()
                ok = bool(first) and proc.poll() is None
                if not record(block, ok, first + ("" if ok else proc.stdout.read()), started):
                    return results
                continue
            out = io.StringIO()
            ok = True
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
                try:
                    if block.lang == "python":
                        exec(compile(block.text, block.where, "exec"), {"__name__": "__main__"})
                    else:
                        for line in sh_lines(block.text):
                            print(f"$ {line}")
                            argv = shlex.split(line, comments=True)
                            if argv and argv[0] == "shapedisplay" and not SHELL_SYNTAX.search(line):
                                try:
                                    status = main(argv[1:])
                                except SystemExit as exc:       # argparse usage errors, --help
                                    status = exc.code if isinstance(exc.code, int) else 1
                            else:
                                sys.stdout.flush()
                                res = subprocess.run(["bash", "-e", "-c", line], capture_output=True, text=True)
                                print(res.stdout + res.stderr, end="")
                                status = res.returncode
                            if status != 0:
                                print(f"exit status {status}")
                                ok = False
                                break
                except Exception:
                    print(traceback.format_exc())
                    ok = False
            if not record(block, ok, out.getvalue(), started):
                return results
    finally:
        for proc in background:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    return results


# ------------------------------------------------------------------ the tests

import pytest  # noqa: E402


def _missing(need: str) -> bool:
    if need == "offscreen":
        try:
            import pyvista  # noqa: F401

            from shapedisplay import viewer
            from shapedisplay.errors import ShapeDisplayError
            try:
                viewer.check_offscreen()
            except ShapeDisplayError:
                return True
        except ImportError:
            return True
        return False
    import importlib.util
    return importlib.util.find_spec(need) is None


def _doc_id(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


@pytest.mark.parametrize("doc", [d for d in DOCUMENTS if any(b.runs for b in blocks_of(d))], ids=_doc_id)
def test_every_block_of_the_document_runs(doc, tmp_path):
    blocks = [b for b in blocks_of(doc) if b.runs]
    for pattern, need, what in NEEDS:
        if any(pattern.search(b.text) for b in blocks) and _missing(need):
            pytest.skip(f"{_doc_id(doc)} needs {what}, which this machine lacks (make test installs it)")
    folder = tmp_path / "docs-examples"
    shutil.copytree(ROOT / "assets", folder / "assets")
    before = _snapshot(folder)
    env = {**os.environ, "MPLBACKEND": "Agg", "BROWSER": "true", "PYTHONPATH": str(ROOT)}
    res = subprocess.run([sys.executable, __file__, _doc_id(doc), str(folder)], capture_output=True, text=True,
                         env=env, timeout=600)
    try:
        results = json.loads(res.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):
        pytest.fail(f"{_doc_id(doc)}: the runner stopped without a result:\n{res.stdout[-3000:]}{res.stderr[-3000:]}")
    failed = [r for r in results if not r["ok"]]
    if failed:
        r = failed[0]
        pytest.fail(f"block at {r['where']} failed:\n{r['source']}\n--- output ---\n{r['output']}")
    assert len(results) == len(blocks), f"ran {len(results)} of {len(blocks)} blocks"
    after = _snapshot(folder)
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    assert not changed, f"{_doc_id(doc)}: examples wrote outside out/: {changed}"


def _not_run_blocks():
    return [b for doc in DOCUMENTS for b in blocks_of(doc) if b.not_run is not None]


@pytest.mark.parametrize("block", _not_run_blocks(), ids=lambda b: b.where)
def test_blocks_marked_not_run_say_why(block):
    assert len(block.not_run) >= 10, f"{block.where}: `not-run:` needs a reason a reader understands"
    pytest.skip(f"{block.where} is not run: {block.not_run}")


def test_every_block_has_a_known_kind():
    for doc in DOCUMENTS:
        for b in blocks_of(doc):
            assert b.lang in RUN + READ_ONLY, \
                f"{b.where}: info string {b.lang!r} (use sh, python, text, json, c or toml; docs/README.md)"
            assert not (b.background and b.lang != "sh"), f"{b.where}: only sh blocks run in the background"
            if b.background:
                assert len(sh_lines(b.text)) == 1, f"{b.where}: a background block holds one command"
            if b.file:
                assert b.file.startswith("out/"), f"{b.where}: file={b.file} must be under out/"


def test_no_indented_code_blocks():
    """Code is fenced, with an info string the test reads; an indented block would escape the convention."""
    for doc in DOCUMENTS:
        lines = FENCE.sub("", doc.read_text(encoding="utf-8")).split("\n")
        for i in range(1, len(lines)):
            assert not (lines[i].startswith("    ") and not lines[i - 1].strip()), \
                f"{_doc_id(doc)}: indented code block {lines[i].strip()[:40]!r}; fence it (docs/README.md)"


def test_every_document_shows_runnable_examples():
    """The convention is not emptied by marking everything read-only."""
    runnable = sum(b.runs for doc in DOCUMENTS for b in blocks_of(doc))
    assert runnable >= 20
    assert sum(b.not_run is not None for doc in DOCUMENTS for b in blocks_of(doc)) <= 8


def test_parser_reads_the_convention():
    text = ("# t\n```sh\nshapedisplay a \\\n   --b c  # note\n# comment\n\nmkdir -p out\n```\n"
            "```toml file=out/x.toml\nk = 1\n```\n````python not-run: needs a serial device\nprint(1)\n````\n"
            "```sh background\nshapedisplay studio x\n```\n")
    bs = blocks_in(text, "probe.md")
    assert [(b.lang, b.runs, b.file, b.not_run, b.background) for b in bs] == [
        ("sh", True, None, None, False), ("toml", True, "out/x.toml", None, False),
        ("python", False, None, "needs a serial device", False), ("sh", True, None, None, True)]
    assert sh_lines(bs[0].text) == ["shapedisplay a     --b c  # note", "mkdir -p out"]
    assert shlex.split(sh_lines(bs[0].text)[0], comments=True) == ["shapedisplay", "a", "--b", "c"]


if __name__ == "__main__":
    doc_arg, folder_arg = sys.argv[1], Path(sys.argv[2])
    folder_arg.mkdir(parents=True, exist_ok=True)
    if not (folder_arg / "assets").exists():
        shutil.copytree(ROOT / "assets", folder_arg / "assets")
    outcome = run_document(doc_arg, folder_arg.resolve())
    for r in outcome:
        print(f"{'ok  ' if r['ok'] else 'FAIL'} {r['seconds']:6.2f} s  {r['where']}", file=sys.stderr)
    print(json.dumps(outcome))
