"""``shapedisplay`` command: argument parsing and error reporting only.

Each sub-command lives in its own module exposing ``register(subparsers)``
(which adds its parser and sets ``func``). Command modules import only
argparse at module level so that ``shapedisplay --help`` stays fast; the
library is imported inside each command's function.
"""
from __future__ import annotations

import argparse
import importlib
import sys

#: Sub-command modules, in help order.
COMMAND_MODULES = (
    "shapedisplay_cli.cmd_compile",
    "shapedisplay_cli.cmd_table",
    "shapedisplay_cli.cmd_heightmap",
    "shapedisplay_cli.cmd_preview",
    "shapedisplay_cli.cmd_scene",
    "shapedisplay_cli.cmd_device",
    "shapedisplay_cli.cmd_play",
    "shapedisplay_cli.cmd_study",
    "shapedisplay_cli.cmd_report",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="shapedisplay",
        description="Author tactile shapes for friction-based shape displays and play them.",
    )
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.version:
        from importlib.metadata import version
        print(f"shapedisplay {version('shapedisplay')}")
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from shapedisplay.errors import ShapeDisplayError
    try:
        return int(args.func(args) or 0)
    except ShapeDisplayError as exc:
        print(f"shapedisplay {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("shapedisplay: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader closed the pipe (e.g. `| head`): stop quietly.
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
