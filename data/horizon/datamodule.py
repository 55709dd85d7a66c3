"""LightningDataModules over rendered horizon datasets (``data.horizon.dataset``) for the two networks.

Training and validation use the classical labels of the frames the label maker accepted (``labels.npz``, as
in the thesis); testing uses every frame of a held-out dataset against the renderer's ground truth
(``truth.npz``) and also carries the classical labels, so the test can compare the network with the
label maker on the same frames. Datasets are created in ``prepare_data`` when ``create`` is set and the
directory has none.

Samples (dicts of tensors):
- ``task="finder"``: ``image`` (3, H, W) tilted panorama resized to ``input_width``; ``pitch``, ``roll``.
- ``task="segmenter"``: ``image`` (3, H, W) panorama levelled with the label (train/val) or true (test) pitch
  and roll, resized; ``horizon``, ``water`` (W,) tan elevation per column of the levelled image; ``focal``
  () px/rad of the whole resized panorama. Training crops a random ``crop_width`` columns (the network is
  width-free).
Test samples add ``true_*`` and ``classical_*`` entries, ``classical_ok``, ``degraded`` and the frame ``index``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from lightning.pytorch import LightningDataModule
from torch.utils.data import DataLoader, Dataset

from core.cylinder import warp_panorama
from core.errors import InputError
from data.horizon.dataset import DatasetSettings, read_split, write_dataset
from data.world.dem import generate_archipelago


def read_panorama(path: Path) -> torch.Tensor:
    """(3, H, W) float RGB in [0, 1] of a stored panorama."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise InputError(f"panorama image missing or unreadable: {path}")
    return torch.from_numpy(np.ascontiguousarray(image[..., ::-1])).permute(2, 0, 1).float() / 255


def read_full_panorama(path: Path, min_width: int = 64) -> torch.Tensor:
    """(1, 3, H, W) panorama of ``path``, checked to look like a 360-degree cylinder (at least ``min_width`` x 16
    px and at least twice as wide as high)."""
    image = read_panorama(path)
    height, width = image.shape[-2:]
    if width < min_width or height < 16 or width < 2 * height:
        raise InputError(f"{path}: a 360-degree panorama must be at least {min_width} x 16 px and at least twice "
                         f"as wide as high, got {width} x {height}")
    return image[None]


def resize_panorama(image: torch.Tensor, width: int) -> torch.Tensor:
    """Resize a (..., 3, H, W) panorama to ``width`` keeping the cylinder aspect (H scaled alike)."""
    height = max(int(round(image.shape[-2] * width / image.shape[-1])), 8)
    if image.shape[-1] == width:
        return image
    batched = image if image.ndim == 4 else image[None]
    out = F.interpolate(batched, size=(height, width), mode="area")
    return out if image.ndim == 4 else out[0]


class HorizonFrames(Dataset):
    """Frames of one dataset directory for one task (see the module docstring)."""

    def __init__(
        self,
        root: str | Path,
        indices: np.ndarray,
        task: str,
        input_width: int,
        crop_width: int | None = None,
        test: bool = False,
    ) -> None:
        if task not in ("finder", "segmenter"):
            raise InputError(f"task must be 'finder' or 'segmenter', got {task!r}")
        self.root, self.indices, self.task = Path(root), np.asarray(indices), task
        self.input_width, self.crop_width, self.test = input_width, crop_width, test
        self.labels = read_split(root, "labels")
        self.truth = read_split(root, "truth") if test else None

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, item: int) -> dict[str, torch.Tensor]:
        k = int(self.indices[item])
        image = read_panorama(self.root / "images" / f"{k:06d}.png")
        source = self.truth if self.test else self.labels

        def value(table: dict[str, np.ndarray], key: str) -> torch.Tensor:
            return torch.as_tensor(table[key][k], dtype=torch.float32)

        def profile(table: dict[str, np.ndarray], key: str) -> torch.Tensor:
            """Per-column profile resampled (linearly, like the image columns) to the input width."""
            values = value(table, key)
            if values.shape[0] == self.input_width:
                return values
            return F.interpolate(values[None, None], size=self.input_width, mode="linear", align_corners=False)[0, 0]

        sample: dict[str, torch.Tensor] = {}
        if self.task == "finder":
            sample["image"] = resize_panorama(image, self.input_width)
            sample["pitch"], sample["roll"] = value(source, "pitch"), value(source, "roll")
        else:
            level = warp_panorama(image[None], value(source, "pitch")[None], value(source, "roll")[None])[0]
            level = resize_panorama(level, self.input_width)
            horizon, water = profile(source, "horizon"), profile(source, "water")
            if self.crop_width and not self.test and self.crop_width < self.input_width:
                start = int(torch.randint(0, self.input_width, ()))
                columns = (torch.arange(self.crop_width) + start) % self.input_width
                level, horizon, water = level[..., columns], horizon[columns], water[columns]
            focal = torch.tensor(self.input_width / (2 * math.pi))
            sample.update(image=level, horizon=horizon, water=water, focal=focal)
        if self.test:
            for key in ("pitch", "roll"):
                sample[f"true_{key}"] = value(self.truth, key)
                sample[f"classical_{key}"] = value(self.labels, key)
            for key in ("horizon", "water"):
                sample[f"true_{key}"] = profile(self.truth, key)
                sample[f"classical_{key}"] = profile(self.labels, key)
            sample["classical_heading"] = value(self.labels, "heading")
            sample["true_heading"] = value(self.truth, "heading")
            sample["classical_ok"] = torch.as_tensor(bool(self.labels["ok"][k]))
            sample["degraded"] = torch.as_tensor(bool(self.truth["degraded"][k]))
            sample["index"] = torch.as_tensor(k)  # the frame, to merge results of distributed test runs
        return sample


class HorizonDataModule(LightningDataModule):
    """Rendered horizon data for ``HorizonFinder`` or ``HorizonSegmenter``.

    Args:
        root: training dataset directory (frames split into train / val by order, i.e. by trajectory).
        test_root: held-out dataset directory for ``test`` (default: ``root``'s validation frames).
        task: ``"finder"`` (tilted panoramas, pitch/roll) or ``"segmenter"`` (levelled panoramas, profiles).
        input_width: network input width in px (panoramas are resized; height follows).
        crop_width: segmenter training crop width in px (None = whole panorama).
        val_fraction: share of the training frames kept for validation.
        batch_size, num_workers: loader settings.
        create: render missing datasets in ``prepare_data`` with the settings below.
        count, test_count, width, height, degraded_fraction, test_degraded_fraction, dem_size_m, dem_cell_m,
            dem_seed, seed: settings of created datasets (the test set uses ``seed + 1``).
    """

    def __init__(
        self,
        root: str = "outputs/horizon/train",
        test_root: str | None = "outputs/horizon/test",
        task: str = "finder",
        input_width: int = 512,
        crop_width: int | None = None,
        val_fraction: float = 0.15,
        batch_size: int = 8,
        num_workers: int = 0,
        create: bool = True,
        count: int = 400,
        test_count: int = 100,
        width: int = 1024,
        height: int = 128,
        degraded_fraction: float = 0.2,
        test_degraded_fraction: float = 0.5,
        dem_size_m: float = 8000.0,
        dem_cell_m: float = 5.0,
        dem_seed: int = 0,
        seed: int = 0,
    ) -> None:
        super().__init__()
        if task not in ("finder", "segmenter"):
            raise InputError(f"task must be 'finder' or 'segmenter', got {task!r}")
        self.save_hyperparameters()
        self.root = Path(root)
        self.test_root = Path(test_root) if test_root else None

    def _create(self, root: Path, count: int, degraded: float, seed: int) -> None:
        if (root / "meta.json").is_file():
            return
        hp = self.hparams
        dem = generate_archipelago(size_m=hp.dem_size_m, cell=hp.dem_cell_m, seed=hp.dem_seed)
        settings = DatasetSettings(count=count, width=hp.width, height=hp.height, degraded_fraction=degraded,
                                   render_bins=max(2 * hp.width, 1024), label_bins=hp.width,
                                   max_range_m=min(8000.0, hp.dem_size_m / 2), seed=seed)
        write_dataset(root, dem, settings)

    def prepare_data(self) -> None:
        hp = self.hparams
        if hp.create:
            self._create(self.root, hp.count, hp.degraded_fraction, hp.seed)
            if self.test_root is not None:
                self._create(self.test_root, hp.test_count, hp.test_degraded_fraction, hp.seed + 1)
        for root in (self.root, self.test_root):
            if root is not None and not (root / "meta.json").is_file():
                raise InputError(f"horizon dataset not found: {root} (set data.create=true or run "
                                 "`python infer.py render-dataset --out {root}`)")

    def setup(self, stage: str | None = None) -> None:
        hp = self.hparams
        count = json.loads((self.root / "meta.json").read_text())["count"]
        accepted = np.flatnonzero(read_split(self.root, "labels")["ok"])
        split = int(round(count * (1 - hp.val_fraction)))
        train, val = accepted[accepted < split], accepted[accepted >= split]
        if len(train) == 0 or len(val) == 0:
            raise InputError(f"{self.root}: too few accepted frames for a train/val split ({len(accepted)})")
        self.train_set = HorizonFrames(self.root, train, hp.task, hp.input_width, hp.crop_width)
        self.val_set = HorizonFrames(self.root, val, hp.task, hp.input_width)
        if self.test_root is not None:
            test_count = json.loads((self.test_root / "meta.json").read_text())["count"]
            self.test_set = HorizonFrames(self.test_root, np.arange(test_count), hp.task, hp.input_width,
                                          test=True)
        else:
            self.test_set = HorizonFrames(self.root, np.arange(split, count), hp.task, hp.input_width, test=True)

    def _loader(self, dataset: Dataset, shuffle: bool) -> DataLoader:
        return DataLoader(dataset, batch_size=self.hparams.batch_size, shuffle=shuffle,
                          num_workers=self.hparams.num_workers, persistent_workers=self.hparams.num_workers > 0)

    def train_dataloader(self) -> DataLoader:
        return self._loader(self.train_set, True)

    def val_dataloader(self) -> DataLoader:
        return self._loader(self.val_set, False)

    def test_dataloader(self) -> DataLoader:
        return self._loader(self.test_set, False)
