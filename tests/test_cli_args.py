"""Command-line parsing: negative quantities after an option, one-line usage errors."""
import json
from pathlib import Path

import pytest

from shapedisplay.cli.main import build_parser, join_negative_values, main

ROOT = Path(__file__).resolve().parent.parent
TENT = ROOT / "assets" / "maps" / "tent_profile.png"
KEYCAP = ROOT / "assets" / "meshes" / "keycap.stl"


@pytest.fixture(scope="module")
def parser():
    return build_parser()


@pytest.mark.parametrize("argv, expected", [
    (["compile", "a.png", "-o", "t.npz", "--n-base", "-1N"], ["compile", "a.png", "-o", "t.npz", "--n-base=-1N"]),
    (["compile", "a.png", "--size", "-60x4mm"], ["compile", "a.png", "--size=-60x4mm"]),
    (["compile", "a.stl", "--up", "-y"], ["compile", "a.stl", "--up=-y"]),
    (["compile", "a.stl", "--up=-y"], ["compile", "a.stl", "--up=-y"]),
    (["compile", "a.stl", "--up", "-1,-0,0"], ["compile", "a.stl", "--up=-1,-0,0"]),
    (["play", "t.npz", "--max-stick-period", "-5ms"], ["play", "t.npz", "--max-stick-period=-5ms"]),
    (["play", "t.npz", "-o", "-x.wav"], ["play", "t.npz", "-o-x.wav"]),
    # an abbreviated long option is joined as argparse would expand it
    (["compile", "a.png", "--n-bas", "-1N"], ["compile", "a.png", "--n-bas=-1N"]),
    # the next word is an option of the command: a forgotten value stays an error
    (["play", "t.npz", "--device", "--model", "exact"], ["play", "t.npz", "--device", "--model", "exact"]),
    # flags take no value; '-' and words after '--' are left alone
    (["play", "t.npz", "--json", "-o", "-"], ["play", "t.npz", "--json", "-o", "-"]),
    (["play", "--", "--rate", "-1"], ["play", "--", "--rate", "-1"]),
    # nested sub-commands know their own options
    (["device", "play", "t.npz", "p", "--stroke", "-1:5mm @ 5mm/s"], ["device", "play", "t.npz", "p", "--stroke=-1:5mm @ 5mm/s"]),
])
def test_join_negative_values(parser, argv, expected):
    assert join_negative_values(parser, argv) == expected


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("opts, needle", [
    (["--n-base", "-1N"], "--n-base"),
    (["--n-base=-1N"], "--n-base"),
    (["--size", "-60x4mm"], "--size"),
    (["--size=-60x4mm"], "--size"),
])
def test_negative_quantity_reaches_the_one_line_error(tmp_path, capsys, opts, needle):
    argv = ["compile", TENT, "-o", tmp_path / "t.npz", "--size", "60x4mm", "--height", "0:2mm", *opts]
    code, out, err = run(argv, capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert needle in err and "usage" not in err
    assert not (tmp_path / "t.npz").exists()


def test_negative_axis_after_up_is_the_value(tmp_path, capsys):
    code, out, err = run(["compile", KEYCAP, "-o", tmp_path / "k.npz", "--up", "-y", "--resolution", "1mm"], capsys)
    assert code == 0, err
    code, out, err = run(["compile", KEYCAP, "-o", tmp_path / "q.npz", "--up", "-w", "--resolution", "1mm"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "-w" in err


def test_negative_stick_period_is_refused_in_one_line(tmp_path, capsys):
    t = tmp_path / "t.npz"
    assert run(["compile", TENT, "-o", t, "--size", "60x4mm", "--height", "0:2mm"], capsys)[0] == 0
    code, out, err = run(["play", t, "--stroke", "0:60mm @ 50mm/s", "-o", tmp_path / "o.wav",
                          "--max-stick-period", "-5ms"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "--max-stick-period" in err, err
    assert not (tmp_path / "o.wav").exists()


@pytest.mark.parametrize("argv", [
    ["play"],
    ["play", "t.npz", "--max-stick-period"],
    ["compile", "a.png", "--no-such-option", "1"],
    ["no-such-command"],
    ["device", "emulate", "--tick"],
])
def test_usage_errors_are_one_line(capsys, argv):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    _, err = capsys.readouterr()
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1 and "error:" in err, err


@pytest.mark.parametrize("opts, expected", [
    (["--height", "0:NaNmm"], "`--height` must be finite (got 'NaNmm')"),
    (["--height", "0:-infmm"], "`--height` must be finite"),
    (["--weber", "-1"], "`--weber` must be within (0, 1)"),
    (["--max-slope", "-1"], "`--max-slope` must be > 0"),
    (["--n-bas", "-1N"], "`--n-bas` must be finite and >= 0 (got --n-bas=-1.0)"),
])
def test_errors_name_the_option_as_typed(tmp_path, capsys, opts, expected):
    argv = ["compile", TENT, "-o", tmp_path / "t.npz", "--size", "60x4mm", "--height", "0:2mm", *opts]
    code, out, err = run(argv, capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and expected in err, err
    for internal in ("weber_fraction", "max_slope", "n_base", "bare number '0'"):
        assert internal not in err


def test_tick_rate_error_names_the_rate_option(tmp_path, capsys):
    t = tmp_path / "t.npz"
    assert run(["compile", TENT, "-o", t, "--size", "60x4mm", "--height", "0:2mm"], capsys)[0] == 0
    code, out, err = run(["play", t, "--stroke", "0:60mm @ 50mm/s", "-o", tmp_path / "o.wav", "--rate", "5Hz"],
                         capsys)
    assert code == 2 and "`--rate` must be within" in err and "tick_rate" not in err, err


def test_tick_rate_is_one_option_spelled_tick_rate_or_rate(tmp_path, capsys):
    """play and device emulate take --tick-rate; --rate is the same option; errors name the spelling typed."""
    t = tmp_path / "t.npz"
    assert run(["compile", TENT, "-o", t, "--size", "60x4mm", "--height", "0:2mm"], capsys)[0] == 0
    rates = []
    for flag in ("--tick-rate", "--rate"):
        code, out, err = run(["play", t, "--stroke", "0:60mm @ 50mm/s", "-o", tmp_path / f"o{flag}.wav", flag,
                              "2kHz", "--json"], capsys)
        assert code == 0, err
        rates.append(json.loads(out)["tick_rate_hz"])
        code, out, err = run(["play", t, "--stroke", "0:60mm @ 50mm/s", "-o", tmp_path / "x.wav", flag, "5Hz"],
                             capsys)
        assert code == 2 and f"`{flag}` must be within" in err and "tick_rate" not in err, err
    assert rates == [2000.0, 2000.0]
    code, out, err = run(["device", "emulate", "--rate", "1500Hz", "--stream-rate", "1kHz"], capsys)
    assert code == 2 and "`--rate` must be a multiple of `--stream-rate`" in err, err


def test_each_command_module_registers_the_commands_main_names_for_it():
    """main builds only the named command's parser; the table it looks the command up in must be true."""
    import importlib

    from shapedisplay.cli.main import COMMAND_MODULES, OneLineParser
    for module, commands in COMMAND_MODULES.items():
        top = OneLineParser(prog="shapedisplay")
        sub = top.add_subparsers(dest="command")
        importlib.import_module(module).register(sub)
        assert tuple(sub.choices) == tuple(top.command_parsers) == commands, module
    full = build_parser()
    assert list(full.command_parsers) == [c for commands in COMMAND_MODULES.values() for c in commands]
    # a command line naming one command parses and reports errors as with the whole parser
    for argv in (["play", "t.npz", "--stroke", "0:5mm @ 5mm/s", "-o", "o.wav"], ["device", "info", "p"]):
        assert vars(build_parser(argv[0]).parse_args(argv)).keys() == vars(full.parse_args(argv)).keys()


# One meaning per option name: old spellings still work, with one note line on stderr.
OLD_SPELLINGS = [
    (["play", "TABLE", "--stroke", "0,2 -> 20,2 @ 20mm/s", "-o", "OUT/a.wav", "--format", "int16"],
     "--format is now --sample-format"),
    (["preview", "MAP", "--extent", "60x24mm", "--height", "0:1mm", "-o", "OUT/p.png", "--pixels", "320x200"],
     "--extent is now --size"),
    (["new", "scene", "s", "-o", "OUT/s.toml", "--force"], "--force is now --overwrite"),
]


@pytest.mark.parametrize("argv,note", OLD_SPELLINGS, ids=lambda v: v[0] if isinstance(v, list) else None)
def test_old_option_spellings_still_work_with_a_note(argv, note, tmp_path, capsys):
    from pathlib import Path

    from shapedisplay.cli.main import build_parser, main
    root = Path(__file__).resolve().parent.parent
    table = tmp_path / "t.npz"
    assert main(["compile", str(root / "assets/maps/tent_profile.png"), "-o", str(table), "--size", "60x4mm",
                 "--height", "0:2mm", "-q"]) == 0
    subs = {"TABLE": str(table), "MAP": str(root / "assets/maps/buttons.png")}
    argv = [subs.get(a, a.replace("OUT", str(tmp_path))) for a in argv]
    if argv[0] == "preview":
        pytest.importorskip("pyvista")
        args = build_parser().parse_args(argv)          # the parse is what changed; drawing is tested elsewhere
        assert args.size == "60x24mm" and args.pixels == "320x200"
        from shapedisplay.cli.main import CommandLine
        assert any(note in n for n in CommandLine(build_parser(), argv).notes)
        return
    capsys.readouterr()
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert note in err and len(err.strip().splitlines()) == 1, err


def test_preview_size_without_a_unit_is_the_old_pixel_size(capsys):
    from shapedisplay.cli.cmd_preview import picture_size
    from shapedisplay.cli.main import build_parser
    args = build_parser().parse_args(["preview", "t.npz", "--size", "1200x800"])
    assert picture_size(args) == (None, "1200x800")
    assert "write --pixels 1200x800" in capsys.readouterr().err
    args = build_parser().parse_args(["preview", "m.png", "--size", "120x80mm", "--pixels", "640x400"])
    assert picture_size(args) == ("120x80mm", "640x400")
    assert capsys.readouterr().err == ""


def test_no_option_name_has_two_meanings():
    """An option spelled the same in two commands stores the same thing; the names that once meant two things
    (--size pixels/physical, --trace cursor CSV/played trace, --force overwrite/force recording, --format
    file/sample format, --timeout reply wait/run time) now mean one."""
    import argparse

    from shapedisplay.cli.main import build_parser
    seen: dict = {}

    def walk(parser, name):
        for o, a in parser.option_actions.items():
            if a.help != argparse.SUPPRESS and o.startswith("--") and o != "--help":
                seen.setdefault(o, {})[name] = a.dest
        for k, sp in parser.command_parsers.items():
            walk(sp, f"{name} {k}".strip())
    walk(build_parser(), "")
    for option, where in seen.items():
        assert len(set(where.values())) == 1, (option, where)
    assert {"compile", "preview", "heightmap", "studio"} <= set(seen["--size"]) and "--extent" not in seen
    assert "play" not in seen["--trace"] and "--force" not in seen and "play" not in seen["--format"]
    assert "device emulate" not in seen["--timeout"] and "device emulate" in seen["--stop-after"]


@pytest.mark.parametrize("env, expected", [
    ({}, "1"),                                   # unset: one BLAS thread
    ({"OPENBLAS_NUM_THREADS": "4"}, "4"),        # the user's choice is kept
    ({"OMP_NUM_THREADS": "2"}, "None"),          # a general thread setting is left to BLAS
])
def test_the_command_line_asks_blas_for_one_thread_unless_the_user_chose(env, expected):
    import os
    import subprocess
    import sys
    base = {k: v for k, v in os.environ.items()
            if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    code = ("import os, sys; from shapedisplay.cli.main import main; main(['--version']); "
            "import numpy; print(os.environ.get('OPENBLAS_NUM_THREADS'), 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[-2:] == [expected, "True"]


@pytest.mark.parametrize("env, expected", [
    ({}, "False"),                               # unset: no huge pages asked for (page faults stall less)
    ({"NUMPY_MADVISE_HUGEPAGE": "1"}, "True"),   # the user's choice is kept
])
def test_the_command_line_asks_numpy_for_no_huge_pages_unless_the_user_chose(env, expected):
    import os
    import subprocess
    import sys
    base = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    code = ("from shapedisplay.cli.main import main; main(['--version']); "
            "from numpy._core import multiarray; print(multiarray._get_madvise_hugepage())")
    out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[-1] == expected


def test_argparse_words_are_its_own_and_argparse_is_left_as_it_is(capsys):
    """Usage errors use argparse's English words, through its own gettext calls: main replaces nothing in
    argparse or gettext (it once replaced argparse's ``_`` to save the catalog search, about 5 ms of --help)."""
    import argparse
    import gettext

    from shapedisplay.cli.main import main
    before = {m: dict(vars(m)) for m in (argparse, gettext)}
    with pytest.raises(SystemExit) as exit_:
        main(["play"])
    assert exit_.value.code == 2
    assert "the following arguments are required: table, -o/--output" in capsys.readouterr().err
    for module, names in before.items():
        assert {k for k, v in vars(module).items() if names.get(k, object()) is not v} == set(), module


@pytest.mark.parametrize("module", ["shapedisplay.cli.main", "shapedisplay"])
def test_the_program_exits_with_the_commands_status(module):
    """``entry`` (the installed ``shapedisplay`` program, ``python -m``) exits with main's status: 0, or 2
    and one line for a usage error."""
    import subprocess
    import sys
    ok = subprocess.run([sys.executable, "-m", module, "--version"], capture_output=True, text=True)
    bad = subprocess.run([sys.executable, "-m", module, "play"], capture_output=True, text=True)
    assert ok.returncode == 0 and ok.stdout.startswith("shapedisplay ")
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "required" in bad.stderr
