"""dcfvision training and checkpoint evaluation: LightningCLI over the YAML configs in ``configs/``.

    python train.py fit  --config configs/demo/horizon_finder.yaml
    python train.py test --config configs/demo/horizon_finder.yaml --ckpt_path path/to/last.ckpt

Each config names its LightningModule and LightningDataModule by ``class_path``; ``--print_config`` shows
the full resolved configuration. Bad arguments, a missing or unreadable config and a ``--ckpt_path`` that is
missing, corrupt or of another model end with one line on stderr and exit code 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

from jsonargparse import ArgumentError
from lightning.pytorch import LightningDataModule, LightningModule
from lightning.pytorch.cli import LightningCLI

from core.command import quiet_console, run_command
from core.errors import InputError
from models.checkpoint import check_checkpoint_fits, read_checkpoint
from models.distributed import end_process_group

#: ``--ckpt_path`` values Lightning resolves itself (``last``: the newest ``last.ckpt`` of the run, to resume).
LIGHTNING_CKPT_ALIASES = ("last", "best", "hpc")


class DcfCLI(LightningCLI):
    """LightningCLI that checks ``--ckpt_path`` against the configured model before the trainer starts: the file
    must be a readable Lightning checkpoint of the configured model class (LightningCLI otherwise rebuilds the
    model from the checkpoint's class and fails later on the configured data) with matching weights."""

    def _parse_ckpt_path(self) -> None:
        subcommand = self.config.get("subcommand")
        path = self.config[subcommand].get("ckpt_path") if subcommand else None
        if path and path not in LIGHTNING_CKPT_ALIASES:
            stored = read_checkpoint(path, "--ckpt_path").get("hyper_parameters", {}).get("_class_path")
            configured = getattr(self.config[subcommand].get("model"), "class_path", None)
            if stored and configured and stored != configured:
                raise InputError(f"--ckpt_path {path} is a {stored.rsplit('.', 1)[-1]} checkpoint, but the config "
                                 f"trains/tests a {configured.rsplit('.', 1)[-1]}")
        super()._parse_ckpt_path()

    def _check_ckpt_path(self) -> None:
        path = self.config[self.subcommand].get("ckpt_path")
        if path is not None and path not in LIGHTNING_CKPT_ALIASES:
            check_checkpoint_fits(self.model, path)

    before_fit = before_validate = before_test = before_predict = _check_ckpt_path


def check_configs(args: list[str]) -> None:
    """``InputError`` naming a ``--config`` file that is missing or not valid YAML (LightningCLI's own message
    does not name the file)."""
    import yaml

    for flag, value in zip(args, args[1:], strict=False):
        if flag in ("-c", "--config"):
            path = Path(value)
            if not path.is_file():
                raise InputError(f"config {path} does not exist")
            try:
                yaml.safe_load(path.read_text())
            except yaml.YAMLError as err:
                raise InputError(f"config {path} is not valid YAML: {' '.join(str(err).split())}") from err


def main(args: list[str] | None = None) -> LightningCLI:
    """Parse ``args`` (default: the command line) and run the subcommand; errors propagate (``InputError``)."""
    check_configs(list(sys.argv[1:] if args is None else args))
    try:
        return DcfCLI(
            LightningModule,
            LightningDataModule,
            subclass_mode_model=True,
            subclass_mode_data=True,
            save_config_kwargs={"overwrite": True},
            parser_kwargs={"exit_on_error": False},
            args=args,
        )
    except ArgumentError as err:
        raise InputError(str(err)) from err


def run(args: list[str] | None = None) -> int:
    """The command line: ``main`` with input errors as one line on stderr and exit code 2."""

    def fit_or_evaluate() -> None:
        try:
            main(args)
        finally:
            end_process_group()  # each DDP process, while the interpreter is whole

    quiet_console()
    return run_command("train.py", fit_or_evaluate)


if __name__ == "__main__":
    sys.exit(run())
