"""`proxplan` command-line dispatcher.

Each package contributes its sub-commands through a ``commands`` module exposing
``register(subparsers)``; a sub-command sets ``func(args) -> int`` as its handler. Command modules
import only argparse at module level so that ``proxplan --help`` stays fast; heavy libraries are
imported inside the handlers.

Exit codes: 0 success, 1 a result that fails a check (e.g. ``verify`` found violations, infeasible
plan), 2 a user mistake (bad input), reported on one line on stderr without a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from proxplan.cli_args import OneLineParser
from proxplan.fileio import UserError

COMMAND_MODULES = (
    "proxplan.commands.model",  # vehicles, wrench
    "proxplan.commands.costmap",  # costmap
    "proxplan.commands.plan",  # plan, verify
    "proxplan.commands.simulate",  # simulate
    "proxplan.commands.track",  # track-limits
    "proxplan.commands.view",  # view
    "proxplan.commands.identify",  # identify
    "proxplan.commands.evaluate",  # evaluate
    "proxplan.commands.logs",  # logs
    "proxplan.commands.certify",  # certify
    "proxplan.commands.export",  # export
    "proxplan.commands.schema",  # schema
)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog="proxplan",
        description="Plan multirotor flights in close proximity within each vehicle's controller authority.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        module = importlib.import_module(name)
        module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as err:
        print(f"proxplan {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"proxplan {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
