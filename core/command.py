"""What every command of the project shares: an argument parser whose errors are one line and exit code 2,
``run_command``, which turns an input error raised anywhere below into that same one line, and ``print_report``.
Torch-free, so the deployment runtime's commands share it."""

from __future__ import annotations

import argparse
import json
import logging
import re
import sys
import warnings
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


def print_report(report: dict, as_json: bool) -> None:
    """Print a command's flat ``report`` as one JSON object (``as_json``), else as right-aligned ``key: value``
    lines."""
    if as_json:
        print(json.dumps(report))
        return
    width = max(map(len, report))
    for key, value in report.items():
        print(f"{key:>{width}}: {value:.6g}" if isinstance(value, float) else f"{key:>{width}}: {value}")


#: Known third-party warnings that say nothing about the user's run (messages as regular expressions).
KNOWN_THIRD_PARTY_WARNINGS = (
    r"`isinstance\(treespec, LeafSpec\)` is deprecated",  # lightning's pytree helper on torch >= 2.14
    r"Found \d+ module\(s\) in eval mode at the start of training",  # frozen backbones are in eval mode on purpose
    r"Use `@` matmul instead of `\*` mul operator",  # rasterio's affine transforms
    r"The '\w+_dataloader' does not have many workers",  # data is synthetic or small; workers cost more
    r"Using `DistributedSampler` with the dataloaders",  # metrics are gathered and de-duplicated (models/distributed)
    r"`tensorboardX` has been removed as a dependency",  # the CSV logger is the intended default
)


#: Lightning's start-up banners, advertising tips and set-up chatter (log messages as regular expressions).
LIGHTNING_BANNERS = re.compile(
    r"^(💡 Tip:|(GPU|TPU|HPU|IPU) available|Seed set to|You are using a CUDA device"
    r"|Loading `train_dataloader` to estimate number of stepping batches)"
)


class _DropBanners(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return not LIGHTNING_BANNERS.match(record.getMessage())


def quiet_console() -> None:
    """One line per stage: Lightning's banners and tips and the known third-party warnings above are silenced;
    Lightning's other messages (restoring a checkpoint, a stopped fit) and real warnings stay. For commands and
    the demo, not for library use or tests."""
    loggers = ("lightning.pytorch.utilities.rank_zero", "lightning.fabric.utilities.rank_zero",
               "lightning.fabric.utilities.seed")
    for name in loggers:
        logger = logging.getLogger(name)  # the loggers Lightning's rank_zero_info writes to, whenever it is imported
        if not any(isinstance(f, _DropBanners) for f in logger.filters):
            logger.addFilter(_DropBanners())
    for message in KNOWN_THIRD_PARTY_WARNINGS:
        warnings.filterwarnings("ignore", message=f".*{message}")
