"""YouTubeVOSDataModule: samples from annotated frames only, held-out videos with sparse labels."""

from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from core.errors import InputError
from data.vos.io import write_mask
from data.vos.ytvos_datamodule import YouTubeVOSDataModule


def _layout(root: Path, n_videos: int = 3) -> None:
    for v in range(n_videos):
        (root / f"train/JPEGImages/v{v}").mkdir(parents=True)
        (root / f"train/Annotations/v{v}").mkdir(parents=True)
        for t in range(16):
            Image.fromarray(np.full((32, 48, 3), 10 * t, np.uint8)).save(root / f"train/JPEGImages/v{v}/{t:05d}.jpg")
            if t % 5 == 0:
                labels = torch.zeros(32, 48, dtype=torch.long)
                labels[4:16, 2 + t : 14 + t] = 1
                labels[20:30, 30:44] = 2
                write_mask(root / f"train/Annotations/v{v}/{t:05d}.png", labels)


def test_samples_come_from_annotated_frames_with_distractors(tmp_path: Path) -> None:
    _layout(tmp_path)
    dm = YouTubeVOSDataModule(str(tmp_path), val_videos=1, train_samples=4, max_gap=2, n_test_frames=2,
                              min_pixels=20, batch_size=2)
    batch = next(iter(dm.train_dataloader()))
    assert batch["test_images"].shape == (2, 2, 3, 32, 48) and batch["has_distractors"].all()
    # annotated frames only: the frames' brightness is 10 t, t a multiple of 5
    assert set((batch["ref_image"][:, 0, 0, 0] * 255).round().long().tolist()) <= {0, 50, 100, 150}
    video = next(iter(dm.val_dataloader()))
    assert video["name"] == "v2" and (video["labels"][1] == -1).all() and video["labels"][5].max() == 2
    with pytest.raises(InputError, match="would leave none"):
        YouTubeVOSDataModule(str(tmp_path), val_videos=3).train_dataloader()
