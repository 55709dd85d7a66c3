"""Lightning systems training HorizonFinder and HorizonSegmenter on classical labels (ch. 4.3).

Training targets are the classical pipeline's labels (``data.horizon.datamodule``); ``test`` compares the
network and the classical pipeline with the renderer's ground truth on the same held-out frames and logs
mean and median errors and failure rates, overall and for the clean and degraded frames.

A frame fails when its pitch or roll error exceeds ``fail_deg`` (finder), or its median horizon error exceeds
``fail_mrad`` (segmenter); the classical labels of the same frames are judged by the same thresholds, and a
frame the classical pipeline rejected counts as a classical failure.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import torch
import torch.nn.functional as F
from lightning.pytorch import Callback, LightningModule, Trainer

from models.distributed import gather_rows
from models.horizon.finder import HorizonFinder, sincos_to_angles
from models.horizon.segmenter import HorizonSegmenter


def _summaries(errors: dict[str, torch.Tensor], failures: dict[str, torch.Tensor], degraded: torch.Tensor,
               prefix: str) -> dict[str, float]:
    """Mean/median errors and failure rates overall and per clean/degraded subset."""
    out: dict[str, float] = {}
    for subset, mask in (("all", torch.ones_like(degraded)), ("clean", ~degraded), ("degraded", degraded)):
        if not mask.any():
            continue
        for name, values in errors.items():
            out[f"{prefix}/{subset}/{name}_mae"] = values[mask].mean().item()
            out[f"{prefix}/{subset}/{name}_median"] = values[mask].median().item()
        for name, values in failures.items():
            out[f"{prefix}/{subset}/{name}"] = values[mask].float().mean().item()
    return out


class _HorizonSystem(LightningModule):
    """Shared optimiser and test bookkeeping."""

    def __init__(self, lr: float, weight_decay: float) -> None:
        super().__init__()
        self.lr, self.weight_decay = lr, weight_decay
        self._test_outputs: list[dict[str, torch.Tensor]] = []

    def configure_optimizers(self):
        optimizer = torch.optim.AdamW(self.parameters(), lr=self.lr, weight_decay=self.weight_decay)
        scheduler = torch.optim.lr_scheduler.OneCycleLR(
            optimizer, max_lr=self.lr, total_steps=max(int(self.trainer.estimated_stepping_batches), 1),
            pct_start=0.15,
        )
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}

    def on_test_epoch_start(self) -> None:
        self._test_outputs = []

    def _collect(self) -> dict[str, torch.Tensor]:
        """Per-frame test results of the whole test set, gathered over the ranks of a distributed run."""
        local = {k: torch.cat([o[k] for o in self._test_outputs]) for k in self._test_outputs[0]}
        return gather_rows(local, "index")


class HorizonFinderSystem(_HorizonSystem):
    """Trains ``HorizonFinder`` (arguments as there) with an L1 loss on the (sin, cos) pairs.

    Args:
        lr: peak learning rate (one-cycle schedule), weight_decay: AdamW weight decay.
        fail_deg: a frame whose pitch or roll error exceeds this (degrees) fails.
    """

    def __init__(
        self,
        backbone: str = "resnet50",
        weights: str | None = None,
        stage: str = "layer4",
        frozen: bool = False,
        heads: int = 4,
        head_channels: int = 32,
        channels: int = 64,
        lr: float = 1e-3,
        weight_decay: float = 1e-4,
        fail_deg: float = 1.0,
    ) -> None:
        super().__init__(lr, weight_decay)
        self.save_hyperparameters()
        self.fail_deg = fail_deg
        self.net = HorizonFinder(backbone, weights, stage, frozen, heads, head_channels, channels)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        """(B, 3, H, W) tilted panorama -> (B, 4) (sin, cos) of pitch and roll."""
        return self.net(image)

    @staticmethod
    def _target(pitch: torch.Tensor, roll: torch.Tensor) -> torch.Tensor:
        return torch.stack([torch.sin(pitch), torch.cos(pitch), torch.sin(roll), torch.cos(roll)], -1)

    def _step(self, batch: dict[str, torch.Tensor], stage: str) -> torch.Tensor:
        out = self(batch["image"])
        loss = F.l1_loss(out, self._target(batch["pitch"], batch["roll"])) * (180 / math.pi)
        pitch, roll = sincos_to_angles(out)
        size = len(out)
        self.log(f"{stage}/loss", loss, prog_bar=True, batch_size=size)
        self.log(f"{stage}/pitch_mae_deg", torch.rad2deg((pitch - batch["pitch"]).abs()).mean(), batch_size=size)
        self.log(f"{stage}/roll_mae_deg", torch.rad2deg((roll - batch["roll"]).abs()).mean(), batch_size=size)
        return loss

    def training_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> torch.Tensor:
        return self._step(batch, "train")

    def validation_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> None:
        self._step(batch, "val")

    def test_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> None:
        pitch, roll = sincos_to_angles(self(batch["image"]))
        self._test_outputs.append({
            "pitch": torch.rad2deg((pitch - batch["true_pitch"]).abs()),
            "roll": torch.rad2deg((roll - batch["true_roll"]).abs()),
            "classical_pitch": torch.rad2deg((batch["classical_pitch"] - batch["true_pitch"]).abs()),
            "classical_roll": torch.rad2deg((batch["classical_roll"] - batch["true_roll"]).abs()),
            "classical_ok": batch["classical_ok"], "degraded": batch["degraded"], "index": batch["index"],
        })

    def on_test_epoch_end(self) -> None:
        r = self._collect()
        errors = {"pitch_deg": r["pitch"], "roll_deg": r["roll"], "classical_pitch_deg": r["classical_pitch"],
                  "classical_roll_deg": r["classical_roll"]}
        failures = {
            "failure_rate": torch.maximum(r["pitch"], r["roll"]) > self.fail_deg,
            "classical_failure_rate": ~r["classical_ok"]
            | (torch.maximum(r["classical_pitch"], r["classical_roll"]) > self.fail_deg),
        }
        self.log_dict(_summaries(errors, failures, r["degraded"], "test"))


class HorizonSegmenterSystem(_HorizonSystem):
    """Trains ``HorizonSegmenter`` (arguments as there) with a smooth L1 loss on the profiles in pixels.

    Batches carry the profiles as tan elevation and ``focal`` (B,), the focal length in px/rad of the whole
    levelled panorama the (possibly cropped) image comes from; profiles are compared as image rows.

    Args:
        lr: peak learning rate (one-cycle schedule), weight_decay: AdamW weight decay.
        fail_mrad: a frame whose median horizon error exceeds this (mrad) fails; 2 px are 6.1 mrad at 2048 px
            and 24.5 mrad at 512 px.
    """

    def __init__(
        self,
        backbone: str = "resnet50",
        weights: str | None = None,
        stage: str = "layer4",
        frozen: bool = False,
        heads: int = 4,
        head_channels: int = 32,
        channels: int = 64,
        lr: float = 1e-3,
        weight_decay: float = 1e-4,
        fail_mrad: float = 2 * 2 * math.pi / 2048 * 1e3,
    ) -> None:
        super().__init__(lr, weight_decay)
        self.save_hyperparameters()
        self.fail_mrad = fail_mrad
        self.net = HorizonSegmenter(backbone, weights, stage, frozen, heads, head_channels, channels)

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        """(B, 3, H, W) levelled panorama -> (B, 2, W) horizon and water heights in half-image-heights."""
        return self.net(image)

    @staticmethod
    def _rows(tangent: torch.Tensor, focal: torch.Tensor) -> torch.Tensor:
        """tan elevation (B, ...) -> pixels above the image centre (B, ...)."""
        return tangent * focal.reshape(-1, *([1] * (tangent.ndim - 1)))

    def _step(self, batch: dict[str, torch.Tensor], stage: str) -> torch.Tensor:
        image = batch["image"]
        out = self(image) * (image.shape[-2] / 2)  # px above the centre
        target = self._rows(torch.stack([batch["horizon"], batch["water"]], 1), batch["focal"])
        loss = F.smooth_l1_loss(out, target, beta=0.5)
        size = len(out)
        self.log(f"{stage}/loss", loss, prog_bar=True, batch_size=size)
        self.log(f"{stage}/horizon_mae_px", (out[:, 0] - target[:, 0]).abs().mean(), batch_size=size)
        return loss

    def training_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> torch.Tensor:
        return self._step(batch, "train")

    def validation_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> None:
        self._step(batch, "val")

    def test_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> None:
        image, focal = batch["image"], batch["focal"]
        out = self(image) * (image.shape[-2] / 2)

        def frame_error(rows: torch.Tensor, key: str) -> torch.Tensor:
            return (rows - self._rows(batch[key], focal)).abs().median(-1).values  # (B,) px

        horizon = frame_error(out[:, 0], "true_horizon")
        water = frame_error(out[:, 1], "true_water")
        classical = frame_error(self._rows(batch["classical_horizon"], focal), "true_horizon")
        mrad = 1e3 / focal
        self._test_outputs.append({
            "horizon_px": horizon, "water_px": water, "classical_horizon_px": classical,
            "horizon_mrad": horizon * mrad, "water_mrad": water * mrad, "classical_horizon_mrad": classical * mrad,
            "classical_ok": batch["classical_ok"], "degraded": batch["degraded"], "index": batch["index"],
        })

    def on_test_epoch_end(self) -> None:
        r = self._collect()
        errors = {k: r[k] for k in ("horizon_mrad", "water_mrad", "classical_horizon_mrad", "horizon_px",
                                    "water_px", "classical_horizon_px")}
        failures = {
            "failure_rate": r["horizon_mrad"] > self.fail_mrad,
            "classical_failure_rate": ~r["classical_ok"] | (r["classical_horizon_mrad"] > self.fail_mrad),
        }
        self.log_dict(_summaries(errors, failures, r["degraded"], "test"))


def plot_loss_curves(metrics: str | Path, path: str | Path, title: str = "") -> bool:
    """Plot the ``train/loss`` and ``val/loss`` columns of a CSVLogger ``metrics.csv`` to a PNG; False if none."""
    curves: dict[str, tuple[list[float], list[float]]] = {}
    with Path(metrics).open() as f:
        for row in csv.DictReader(f):
            for key in ("train/loss", "val/loss"):
                if row.get(key):
                    steps, values = curves.setdefault(key, ([], []))
                    steps.append(float(row["step"]))
                    values.append(float(row[key]))
    if not curves:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    for key, (steps, values) in curves.items():
        ax.plot(steps, values, label=key, alpha=0.6 if key.startswith("train") else 1.0)
    ax.set_xlabel("step")
    ax.set_ylabel("loss")
    ax.set_yscale("log")
    ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


class LossCurves(Callback):
    """Draw the logged training and validation losses (CSVLogger ``metrics.csv``) to a PNG when fitting ends.

    Args:
        path: PNG file; relative paths are taken inside the logger's directory.
    """

    def __init__(self, path: str = "loss_curves.png") -> None:
        super().__init__()
        self.path = path

    def on_fit_end(self, trainer: Trainer, pl_module: LightningModule) -> None:
        if trainer.logger is None or trainer.logger.log_dir is None:
            return
        metrics = Path(trainer.logger.log_dir) / "metrics.csv"
        path = Path(self.path)
        path = path if path.is_absolute() else Path(trainer.logger.log_dir) / path
        if metrics.is_file():
            plot_loss_curves(metrics, path, type(pl_module).__name__)
