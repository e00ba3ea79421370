"""``shapedisplay`` command: argument parsing and error reporting only.

Each sub-command lives in its own module exposing ``register(subparsers)``
(which adds its parser and sets ``func``). Command modules import only
argparse at module level so that ``shapedisplay --help`` stays fast; the
library is imported inside each command's function.
"""
from __future__ import annotations

import argparse
import importlib
import re
import sys

#: Sub-command modules, in help order, with the commands each registers (tests/test_cli_args.py checks them):
#: a command line that names its command builds only that command's parser.
COMMAND_MODULES = {
    "shapedisplay.cli.cmd_compile": ("compile",),
    "shapedisplay.cli.cmd_table": ("inspect", "export", "diff"),
    "shapedisplay.cli.cmd_heightmap": ("heightmap",),
    "shapedisplay.cli.cmd_preview": ("preview",),
    "shapedisplay.cli.cmd_scene": ("check", "new"),
    "shapedisplay.cli.cmd_import_svg": ("import-svg",),
    "shapedisplay.cli.cmd_device": ("device",),
    "shapedisplay.cli.cmd_play": ("play",),
    "shapedisplay.cli.cmd_study": ("study",),
    "shapedisplay.cli.cmd_report": ("report",),
    "shapedisplay.cli.cmd_studio": ("studio",),
}


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit 2), like the library's errors.

    Sub-command parsers inherit the class, so every level reports the same way:
    ``shapedisplay play: error: the following arguments are required: -o/--output``.

    It keeps its own record of what is added to it, through itself, its argument
    groups and its set of sub-commands: ``option_actions`` (each option string,
    ``-h`` and hidden spellings included, to its action) and ``command_parsers``
    (each sub-command name and alias to its parser). :class:`CommandLine` reads
    the command line against these records.
    """

    def __init__(self, *args, **kwargs):
        self.option_actions: dict[str, argparse.Action] = {}
        self.command_parsers: dict[str, argparse.ArgumentParser] = {}
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def record(self, action: argparse.Action) -> argparse.Action:
        self.option_actions.update(dict.fromkeys(action.option_strings, action))
        return action

    def add_argument(self, *args, **kwargs) -> argparse.Action:
        return self.record(super().add_argument(*args, **kwargs))

    def add_argument_group(self, *args, **kwargs):
        return _Recorded(super().add_argument_group(*args, **kwargs), self)

    def add_mutually_exclusive_group(self, *args, **kwargs):
        return _Recorded(super().add_mutually_exclusive_group(*args, **kwargs), self)

    def add_subparsers(self, *args, **kwargs):
        return _Recorded(super().add_subparsers(*args, **kwargs), self)


class _Recorded:
    """An argument group or set of sub-commands of ``parser``, as argparse made it, that also tells
    ``parser`` about each option and sub-command added to it; everything else is the object's own."""

    def __init__(self, target, parser: OneLineParser):
        self._target, self._parser = target, parser

    def __getattr__(self, name):
        return getattr(self._target, name)

    def add_argument(self, *args, **kwargs) -> argparse.Action:
        return self._parser.record(self._target.add_argument(*args, **kwargs))

    def add_argument_group(self, *args, **kwargs):
        return _Recorded(self._target.add_argument_group(*args, **kwargs), self._parser)

    def add_mutually_exclusive_group(self, *args, **kwargs):
        return _Recorded(self._target.add_mutually_exclusive_group(*args, **kwargs), self._parser)

    def add_parser(self, name: str, **kwargs) -> argparse.ArgumentParser:
        parser = self._target.add_parser(name, **kwargs)
        self._parser.command_parsers.update(dict.fromkeys((name, *kwargs.get("aliases", ())), parser))
        return parser


def old_spelling(parser, old: str, new: str, dest: str, flag: bool = False, why: str = "") -> argparse.Action:
    """Accept ``old``, the former name of option ``new`` (same ``dest``), hidden from --help.

    One name has one meaning in every command; where a name changed, the old
    spelling still works and the command prints a one-line note on stderr
    saying what to write instead (``why`` adds the reason).
    """
    action = parser.add_argument(old, dest=dest, help=argparse.SUPPRESS, default=argparse.SUPPRESS,
                                 **({"action": "store_true"} if flag else {}))
    action.renamed_to = new
    action.rename_why = why
    return action


def _takes_one_value(action: argparse.Action) -> bool:
    """An option followed by exactly one value (flags, counts, -h and --version have ``nargs`` 0)."""
    return bool(action.option_strings) and action.nargs is None


def _lookup_option(parser: argparse.ArgumentParser, token: str):
    """The action ``token`` names in ``parser`` (exact, or an unambiguous long prefix), else None."""
    actions = getattr(parser, "option_actions", {})
    if token in actions:
        return actions[token]
    if token.startswith("--") and parser.allow_abbrev:
        hits = {a for s, a in actions.items() if s.startswith(token)}
        if len(hits) == 1:
            return hits.pop()
    return None


class CommandLine:
    """What the user typed, read once against the parser tree.

    ``argv`` is the command line with every value that starts with '-' attached
    to the option before it (argparse takes ``--n-base -1N``, ``--size
    -60x4mm`` or ``--up -y`` for two options and stops with a usage message):
    where an option that takes one value is followed by a word that is not an
    option of that (sub-)command, the two are joined (``--n-base=-1N``,
    ``-o-x``) so the value reaches the library, which accepts it or says in one
    line why not. A following word that *is* an option (``--device --model
    exact``) is left alone, so a forgotten value is still reported as one.

    ``typed`` maps each option's destination (``n_base``) to the spelling the
    user typed (``--n-base``, or an abbreviation), so that an error naming the
    library's parameter can name the option instead.
    """

    def __init__(self, parser: argparse.ArgumentParser, argv: list[str]):
        self.argv: list[str] = []
        self.typed: dict[str, str] = {}
        self.notes: list[str] = []       # one line per old option spelling used (see old_spelling)
        current = parser
        i = 0
        while i < len(argv):
            token = argv[i]
            if token == "--":
                self.argv.extend(argv[i:])
                break
            subs = getattr(current, "command_parsers", {})
            if token in subs:
                current = subs[token]
                self.argv.append(token)
                i += 1
                continue
            name = token.split("=", 1)[0] if token.startswith("--") else token[:2]
            action = _lookup_option(current, name) if token.startswith("-") and len(token) > 1 else None
            if action is not None:
                self.typed.setdefault(action.dest, name)
                if getattr(action, "renamed_to", None):
                    self.notes.append(f"{current.prog}: note: {name} is now {action.renamed_to}"
                                      f"{action.rename_why}; {name} still works")
            if action is not None and name == token and _takes_one_value(action) and i + 1 < len(argv):
                value = argv[i + 1]
                if value.startswith("-") and value not in ("-", "--") and _lookup_option(current, value) is None:
                    self.argv.append(f"{token}={value}" if token.startswith("--") else token + value)
                    i += 2
                    continue
            self.argv.append(token)
            i += 1

    def name_options(self, message: str) -> str:
        """Replace the library's parameter names in ``message`` with the options as typed.

        ```n_base``` becomes ```--n-base``` and ``n_base=`` becomes ``--n-base=``
        when the user gave ``--n-base``; a parameter the user did not type
        (a scene file's field, a device profile's value) keeps its name.
        """
        for field, typed in self.typed.items():
            for alias in (field, *PARAMETER_ALIASES.get(field, ())):
                message = re.sub(rf"`{re.escape(alias)}`", f"`{typed}`", message)
                message = re.sub(rf"(?<![\w-]){re.escape(alias)}=", f"{typed}=", message)
        return message


#: Option destination -> the library parameter names it is passed as.
PARAMETER_ALIASES = {
    "perceptual": ("perceptual_exponent",),
    "tick_rate": ("tick_rate_hz",),
    "stream_rate": ("stream_rate_hz",),
    "queue": ("queue_capacity",),
    "weber": ("weber_fraction",),
}


#: Characters a terminal acts on instead of showing: C0 and C1 controls, DEL, line and paragraph
#: separators, and the bidirectional marks, embeddings, overrides and isolates (U+202E turns the rest
#: of a line around).
_UNPRINTABLE = re.compile("[\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]")


def printable(text: str) -> str:
    """``text`` as one line a terminal shows as written: whitespace runs become one space, and every
    other control or bidirectional-formatting character is written as its escape (``\\x00``, ``\\u202e``).

    Messages quote file names and file contents; these must not move the cursor, ring, clear the
    screen or reorder what follows on the line.
    """
    text = " ".join(text.split())
    return _UNPRINTABLE.sub(lambda m: f"\\x{ord(m.group()):02x}" if ord(m.group()) < 0x100
                            else f"\\u{ord(m.group()):04x}", text)


def join_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with values that start with '-' attached to their option (see :class:`CommandLine`)."""
    return CommandLine(parser, argv).argv


#: Option destinations that name files a command writes.
OUTPUT_DESTS = ("output", "trace_out", "plot", "link", "port_file", "ahap", "drive_csv")


def _check_outputs(args, line: CommandLine) -> None:
    """No output may be an input (any other argument naming an existing file) or another output."""
    import os

    from shapedisplay.atomic import check_outputs
    outputs, inputs = {}, {}
    for dest, value in vars(args).items():
        if dest in ("command", "func"):
            continue
        values = [v for v in value if isinstance(v, str)] if isinstance(value, list) else [value]
        for k, v in enumerate(values):
            if not isinstance(v, str) or not v:
                continue
            name = line.typed.get(dest, dest.upper())
            if len(values) > 1:               # several sources: name each one
                name = f"{name} {k + 1}"
            if dest in OUTPUT_DESTS:
                outputs[name] = v
            elif os.path.isfile(v):
                inputs[name] = v
    check_outputs(inputs, outputs)


def build_parser(command: str | None = None, list_only: bool = False) -> argparse.ArgumentParser:
    """The command-line parser: every command, or only ``command`` (a name from :data:`COMMAND_MODULES`).

    ``list_only``: every command is listed, with its help, but its parser is not
    built (see :class:`_Unbuilt`): enough for ``shapedisplay --help``, a command
    line without a command and a mistyped command name, and about 9 ms sooner.
    """
    parser = OneLineParser(
        prog="shapedisplay",
        description="Author tactile shapes for friction-based shape displays and play them.",
    )
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", **({"parser_class": _Unbuilt} if list_only else {}))
    for name, commands in COMMAND_MODULES.items():
        if command is None or command in commands:
            importlib.import_module(name).register(sub)
    return parser


class _Unbuilt:
    """A listed command's parser, not built: it takes what a command module adds to it and keeps none of it.

    Each parser argparse builds looks its own words up in a message catalog
    (``gettext``: 3 searches on disk, 0.03-0.07 ms each) and makes help
    formatters; building the 20 parsers of the command tree was most of
    ``--help``'s own time.
    """

    def __init__(self, **kwargs):
        pass

    def __getattr__(self, name):
        return lambda *args, **kwargs: _Unbuilt()


def _numpy_environment() -> None:
    """Settings numpy reads once, at import, unless the user set them.

    One BLAS thread: the package's linear algebra is 3 x 3 and 3 x N products,
    which one thread does as fast as many; starting the BLAS thread pool costs
    every command about 80 ms of CPU at ``import numpy``.

    No huge pages asked for (``NUMPY_MADVISE_HUGEPAGE=0``): a command walks
    its large arrays (a 4096 x 4096 map's 128 MiB) once or twice, so the
    cost of its memory is the page faults that bring it in; where the kernel
    makes a huge page on request by compacting memory first, those faults
    stall, and a compile spent 0.30-0.40 s in the kernel instead of 0.19-0.24 s
    with ordinary pages (docs/speed.md).
    """
    import os
    if "numpy" in sys.modules:
        return
    if not any(name in os.environ for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")):
        os.environ["OPENBLAS_NUM_THREADS"] = "1"
    os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")


def main(argv=None) -> int:
    _numpy_environment()
    argv = list(sys.argv[1:] if argv is None else argv)
    known = {c for commands in COMMAND_MODULES.values() for c in commands}
    if argv and argv[0] in known:
        parser = build_parser(argv[0])
    else:   # --help, no command, a typo: every command, listed only unless a command is named later on
        parser = build_parser(list_only=known.isdisjoint(argv))
    line = CommandLine(parser, argv)
    args = parser.parse_args(line.argv)
    if args.version:
        from importlib.metadata import version
        print(f"shapedisplay {version('shapedisplay')}")
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from shapedisplay.errors import ShapeDisplayError
    for note in line.notes:
        print(note, file=sys.stderr)
    try:
        _check_outputs(args, line)
        return int(args.func(args) or 0)
    except ShapeDisplayError as exc:
        message = printable(line.name_options(str(exc)))   # one line, whatever the text held
        print(f"shapedisplay {args.command}: error: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("shapedisplay: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader closed the pipe (e.g. `| head`): stop quietly.
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


def entry() -> None:
    """The ``shapedisplay`` program: :func:`main`, then exit with its status.

    At exit Python collects garbage once more, walking every object numpy
    and the package made: about 20 ms of a 0.3 s ``play``. The process ends
    right after, so those objects are frozen first (``gc.freeze``: the last
    collection leaves them). :func:`main` itself leaves the collector alone,
    for callers that go on.
    """
    code = main()
    import gc
    gc.freeze()
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    entry()
