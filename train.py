"""dcfvision training and checkpoint evaluation: LightningCLI over the YAML configs in ``configs/``.

    python train.py fit  --config configs/demo/horizon_finder.yaml
    python train.py test --config configs/demo/horizon_finder.yaml --ckpt_path path/to/last.ckpt

Each config names its LightningModule and LightningDataModule by ``class_path``; ``--print_config`` shows
the full resolved configuration.
"""

from __future__ import annotations

from lightning.pytorch import LightningDataModule, LightningModule
from lightning.pytorch.cli import LightningCLI


def main(args: list[str] | None = None) -> LightningCLI:
    return LightningCLI(
        LightningModule,
        LightningDataModule,
        subclass_mode_model=True,
        subclass_mode_data=True,
        save_config_kwargs={"overwrite": True},
        args=args,
    )


if __name__ == "__main__":
    main()
