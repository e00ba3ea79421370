"""The documented sections on scenes (README) and the 3D preview (docs/preview.md): every command shown runs as written.

Each ``shapedisplay`` line of their ``sh`` blocks must parse with the real
command-line parser, and every file it reads must be in the repository or
written by a command shown before it (in reading order).
"""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: (file, heading) of each section, in reading order.
SECTIONS = (("README.md", "## Five-minute walkthrough"), ("README.md", "## Designing a tactile screen"),
            ("docs/preview.md", "# 3D preview"))
FILE_SUFFIXES = (".toml", ".npz", ".png", ".npy", ".stl", ".obj", ".ply", ".wav", ".json")
OUTPUT_FLAGS = ("-o", "--output", "--trace-out")


def section(text: str, heading: str) -> str:
    start = text.index(heading + "\n")
    end = text.find("\n## ", start + len(heading)) if heading.startswith("## ") else -1
    return text[start:end if end >= 0 else len(text)]


def commands(program: str = "shapedisplay") -> list[list[str]]:
    """argv of every line of the sh blocks of the sections (in reading order) that runs ``program``."""
    out = []
    for name, heading in SECTIONS:
        text = (ROOT / name).read_text(encoding="utf-8")
        for block in re.findall(r"```sh\n(.*?)```", section(text, heading), flags=re.S):
            for line in block.replace("\\\n", " ").splitlines():
                argv = shlex.split(line, comments=True)
                if argv and argv[0] in ("shapedisplay", "mkdir") and (program in (None, argv[0])):
                    out.append(argv if program is None else argv[1:])
    return out


def in_a_fresh_checkout(directory: str) -> bool:
    """True when ``directory`` holds files git tracks (so it exists in a fresh clone)."""
    import subprocess
    res = subprocess.run(["git", "ls-files", "--", directory], cwd=ROOT, capture_output=True, text=True)
    if res.returncode != 0:          # not a git checkout: what is on disk is what a reader has
        return (ROOT / directory).is_dir()
    return bool(res.stdout.strip())


def files_of(argv: list[str]) -> tuple[list[str], list[str]]:
    """(files read, files written) by one command line."""
    reads, writes = [], []
    if argv[:2] == ["new", "scene"]:
        rest = [a for a in argv[2:] if not a.startswith("-")]
        writes.append(argv[argv.index("-o") + 1] if "-o" in argv else f"{rest[0]}.toml")
        return reads, writes
    for i, arg in enumerate(argv):
        if not arg.lower().endswith(FILE_SUFFIXES):
            continue
        (writes if i > 0 and argv[i - 1] in OUTPUT_FLAGS else reads).append(arg)
    return reads, writes


def test_sections_show_commands():
    argvs = commands()
    assert len(argvs) >= 10
    assert {a[0] for a in argvs} >= {"new", "check", "compile", "inspect", "play", "preview"}


def test_every_command_parses_and_reads_only_files_that_exist_or_were_written_before():
    """Run in reading order from a fresh clone: inputs exist or were written, output folders exist."""
    from shapedisplay.cli.main import build_parser
    parser = build_parser()
    written: set = set()
    made: set = set()
    for line in commands(None):
        if line[0] == "mkdir":
            made.update(a.rstrip("/") for a in line[1:] if not a.startswith("-"))
            continue
        argv = line[1:]
        try:
            args = parser.parse_args(argv)
        except SystemExit:
            pytest.fail(f"README command does not parse: shapedisplay {shlex.join(argv)}")
        assert getattr(args, "func", None) is not None, argv
        reads, writes = files_of(argv)
        for f in reads:
            assert f in written or (ROOT / f).is_file(), \
                f"`shapedisplay {shlex.join(argv)}` reads '{f}', which neither exists nor is written before"
        for f in writes:
            folder = str(Path(f).parent)
            assert folder == "." or folder in made or in_a_fresh_checkout(folder), \
                f"`shapedisplay {shlex.join(argv)}` writes into '{folder}/', which a fresh clone lacks (mkdir -p?)"
        written.update(writes)


def test_the_pictures_are_written_by_a_command_shown():
    """Each picture of the sections is the output of a `preview` command shown beside it."""
    for name, heading in SECTIONS:
        body = section((ROOT / name).read_text(encoding="utf-8"), heading)
        for link in re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", body):
            path = ((ROOT / name).parent / link).resolve()
            picture = path.relative_to(ROOT).as_posix()       # as the command, run from the checkout, writes it
            assert path.is_file() and path.stat().st_size < 300_000, picture
            # as written into the repository, or (in a runnable example) under out/
            shown = re.findall(r"shapedisplay preview [^`\n]*-o (?:" + re.escape(picture) + "|out/"
                               + re.escape(path.name) + ")", body)
            assert shown, f"no `shapedisplay preview ... -o {picture}` in section {heading!r}"
