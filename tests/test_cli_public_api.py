"""The command line reads its parsers through argparse's public API and its own records of what it added."""
import argparse
import re
import subprocess
import sys
from pathlib import Path

import pytest

from shapedisplay.cli.main import CommandLine, OneLineParser, _takes_one_value, build_parser, join_negative_values

MAIN = Path(__file__).resolve().parent.parent / "shapedisplay" / "cli" / "main.py"


def parsers(parser, path=()):
    """Every parser of the tree, with the command words that reach it."""
    yield path, parser
    for name, sub in parser.command_parsers.items():
        yield from parsers(sub, (*path, name))


@pytest.fixture(scope="module")
def tree():
    return list(parsers(build_parser()))


def test_main_uses_no_private_argparse_names():
    source = MAIN.read_text()
    assert not re.search(r"argparse\._|sys\.modules\[", source)
    # every `._name` main.py reads is its own (the recorder's two fields), none of argparse's
    own = {"_target", "_parser"}
    assert set(re.findall(r"\.(_[A-Za-z]\w*)", source)) <= own
    private = {n for n in (*dir(argparse), *dir(argparse.ArgumentParser()), *vars(argparse.ArgumentParser()))
               if n.startswith("_") and not n.startswith("__")}
    assert not own & private


def test_every_option_in_usage_is_recorded(tree):
    """The records are complete: options added through the parser, argument groups, mutually exclusive groups
    (play's --stroke | --cursor-csv) and hidden old spellings are all there, in every (sub-)command."""
    assert len(tree) > 15
    for path, parser in tree:
        usage = parser.format_usage()
        shown = set(re.findall(r"(?<=[\[( |])(--?[A-Za-z][\w-]*)", usage.split(":", 1)[1]))
        assert shown <= set(parser.option_actions), (path, shown - set(parser.option_actions))
        assert {"-h", "--help"} <= set(parser.option_actions)
    play = dict(tree)[("play",)]
    assert {"--stroke", "--cursor-csv", "--trace", "--format"} <= set(play.option_actions)
    assert play.option_actions["--format"].renamed_to == "--sample-format"


def test_takes_one_value_is_argparse_s_own_view(tree, capsys):
    """An option takes the following '-word' as its value exactly when argparse, given the option alone, asks
    for one value (flags, counts and --version have ``nargs`` 0; the old code also named their private classes)."""
    root = tree[0][1]
    checked = 0
    for path, parser in tree:
        for option, action in parser.option_actions.items():
            if option in ("-h", "--help"):
                continue
            try:
                parser.parse_args([option])
            except SystemExit:
                pass
            asks = "expected one argument" in capsys.readouterr().err
            assert _takes_one_value(action) == asks, (path, option)
            joined = join_negative_values(root, [*path, option, "-9x"])
            assert joined[len(path):] == ([f"{option}=-9x" if option.startswith("--") else f"{option}-9x"] if asks
                                          else [option, "-9x"]), (path, option, joined)
            checked += 1
    assert checked > 100


def test_records_follow_groups_aliases_and_abbreviations():
    parser = OneLineParser(prog="t")
    parser.add_argument("--flag", action="store_true")
    group = parser.add_argument_group("g")
    group.add_argument("--level", "-l")
    group.add_argument("--count", action="count")
    one_of = group.add_mutually_exclusive_group()
    one_of.add_argument("--up")
    one_of.add_argument("--down", action="store_true")
    sub = parser.add_subparsers(dest="command")
    run = sub.add_parser("run", aliases=["r"])
    run.add_argument("--offset")
    assert set(parser.option_actions) == {"-h", "--help", "--flag", "--level", "-l", "--count", "--up", "--down"}
    assert parser.command_parsers == {"run": run, "r": run} and sub.choices["r"] is run
    line = CommandLine(parser, ["--lev", "-2", "-l", "-3", "--up", "-z", "--flag", "--count", "r", "--offset", "-2,-3"])
    assert line.argv == ["--lev=-2", "-l-3", "--up=-z", "--flag", "--count", "r", "--offset=-2,-3"]
    assert line.typed == {"level": "--lev", "up": "--up", "flag": "--flag", "count": "--count", "offset": "--offset"}
    args = parser.parse_args(line.argv)
    assert (args.level, args.up, args.count, args.offset) == ("-3", "-z", 1, "-2,-3")
    # a word that is an option of the (sub-)command is not taken as a value
    assert CommandLine(parser, ["--up", "--flag"]).argv == ["--up", "--flag"]
    assert CommandLine(parser, ["run", "--offset", "-h"]).argv == ["run", "--offset", "-h"]


def test_a_plain_argparse_sub_parser_is_read_without_records():
    """A sub-command made with another parser class has no records: its words pass through unchanged."""
    parser = OneLineParser(prog="t")
    sub = parser.add_subparsers(dest="command", parser_class=argparse.ArgumentParser)
    sub.add_parser("x").add_argument("--up")
    assert CommandLine(parser, ["x", "--up", "-z"]).argv == ["x", "--up", "-z"]


@pytest.mark.parametrize("argv", [["--help"], ["compile", "--help"], ["device", "play", "--help"]])
def test_python_m_shapedisplay_help(argv):
    run = subprocess.run([sys.executable, "-m", "shapedisplay", *argv], capture_output=True, text=True)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert run.stdout.startswith(f"usage: shapedisplay {' '.join(argv[:-1])}".rstrip())
    if argv == ["--help"]:
        assert all(c in run.stdout for c in ("compile", "play", "export", "check", "inspect", "preview", "studio",
                                             "study"))


@pytest.mark.parametrize("argv, needle", [
    (["compile", "a.png", "--n-base"], "--n-base: expected one argument"),
    (["compile", "a.png", "-o", "t.npz", "--no-such-option", "-1N"], "unrecognized arguments: --no-such-option -1N"),
    (["play", "t.npz", "--device", "--model", "exact"], "--device: expected one argument"),
])
def test_usage_errors_exit_2_in_one_line_without_traceback(argv, needle):
    run = subprocess.run([sys.executable, "-m", "shapedisplay", *argv], capture_output=True, text=True)
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert needle in run.stderr and "Traceback" not in run.stderr


def test_a_command_line_without_a_command_lists_every_command_without_building_it(capsys, monkeypatch):
    """``shapedisplay --help``, no command and a mistyped one read a parser whose commands are listed, not built:
    the same help and the same error as with the whole tree, one parser built instead of twenty."""
    from shapedisplay.cli import main as cli

    full = build_parser()
    built = []
    init = OneLineParser.__init__

    def counting_init(self, *args, **kwargs):
        built.append(kwargs.get("prog"))
        init(self, *args, **kwargs)
    monkeypatch.setattr(OneLineParser, "__init__", counting_init)
    with pytest.raises(SystemExit) as exit_:
        cli.main(["--help"])
    assert exit_.value.code == 0 and capsys.readouterr().out == full.format_help()
    assert built == ["shapedisplay"]
    assert cli.main([]) == 2 and capsys.readouterr().out == full.format_help()
    with pytest.raises(SystemExit) as exit_:
        cli.main(["compil"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and len(err.strip().splitlines()) == 1
    assert "invalid choice: 'compil' (choose from " + ", ".join(map(repr, full.command_parsers)) + ")" in err
    # a command named after an option of the top level is built and parsed as before
    built.clear()
    with pytest.raises(SystemExit) as exit_:
        cli.main(["--version", "play"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "shapedisplay play: error: the following arguments are required" in err
    assert "shapedisplay play" in built and len(built) > 15
