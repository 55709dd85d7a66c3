"""The ``infer.py`` command line: one module per command, each with ``NAME``, ``HELP``, ``add_arguments(parser)``
and ``run(args) -> exit code``. Command modules import only the standard library at the top, so building the
parser (``infer.py --help``) stays fast; each ``run`` imports its pipeline from the library.

Bad arguments and bad input files end with a one-line message on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence

from core.command import CommandParser, quiet_console, run_command

#: Command modules in the order ``--help`` lists them.
COMMANDS = ("triangulate", "render_dataset", "horizon_label", "horizon", "track", "segment", "build_bank",
            "localize", "demo")

DESCRIPTION = """dcfvision inference command line: one subcommand per capability.

Run ``python infer.py --help`` for the list and ``python infer.py COMMAND --help`` for each one.
Bad arguments and bad input files end with a one-line message and exit code 2."""


def build_parser() -> argparse.ArgumentParser:
    """The parser with every command of ``COMMANDS`` as a subcommand."""
    parser = CommandParser(prog="infer.py", description=DESCRIPTION,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=CommandParser, metavar="COMMAND")
    for module_name in COMMANDS:
        module = importlib.import_module(f"cli.{module_name}")
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` and run its command; input errors end as one line on stderr and exit code 2."""
    args = build_parser().parse_args(argv)
    quiet_console()
    return run_command(f"infer.py {args.command}", lambda: args.run(args))
