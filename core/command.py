"""What every command of the project shares: an argument parser whose errors are one line and exit code 2, and
``run_command``, which turns an input error raised anywhere below into that same one line."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

from core.errors import InputError

#: Exit code of a command given bad arguments or bad input (argparse's convention).
EXIT_BAD_INPUT = 2


class CommandParser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line on stderr (``prog: error: message``) and exit code 2."""

    def error(self, message: str) -> None:  # noqa: D102
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(EXIT_BAD_INPUT)


def run_command(prog: str, run: Callable[[], int | None]) -> int:
    """Run ``run()`` and return its exit code (0 for None); an ``InputError`` or a missing file anywhere below
    ends as one line ``prog: error: message`` on stderr and exit code 2."""
    try:
        return run() or 0
    except (InputError, FileNotFoundError) as err:
        message = " ".join(str(err).split())  # one line, whatever the message held
        sys.stderr.write(f"{prog}: error: {message}\n")
        return EXIT_BAD_INPUT
