"""YouTube-VOS as a LightningDataModule (LWL and DAVOS train on it, thesis ch. 6): training samples from the
annotated frames (every 5th) of the ``train`` videos, with the other objects as distractors; validation and
test on held-out ``train`` videos, scored on their annotated frames (the ``valid`` split's masks are on the
challenge server only)."""

from __future__ import annotations

from torch.utils.data import Dataset

from core.errors import InputError
from data.vos.datamodule import SequenceTrainingSamples, VideoDataModule, Videos
from data.vos.ytvos import ytvos_sequences


class YouTubeVOSDataModule(VideoDataModule):
    """YouTube-VOS layout data (``ROOT/train/JPEGImages``, ``Annotations``, ``meta.json``).

    Args:
        root: the YouTube-VOS root; split: the annotated split (``train``).
        val_videos: the last ``val_videos`` videos (sorted by name) are held out for validation and test.
        train_samples, max_gap (in annotated frames), n_test_frames, min_pixels, hflip, crop: see
            ``SequenceTrainingSamples``.
        val_max_frames: cut evaluation videos to this many frames.
    """

    def __init__(
        self,
        root: str,
        split: str = "train",
        val_videos: int = 32,
        train_samples: int = 4000,
        max_gap: int = 20,
        n_test_frames: int = 3,
        min_pixels: int = 100,
        hflip: float = 0.5,
        crop: tuple[int, int] | None = None,
        val_max_frames: int | None = None,
        batch_size: int = 4,
        num_workers: int = 0,
        seed: int = 0,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()

    def _split(self) -> tuple[list, list]:
        h = self.hparams
        videos = ytvos_sequences(h.root, h.split)
        if len(videos) <= h.val_videos:
            raise InputError(f"YouTube-VOS {h.root}/{h.split} has {len(videos)} videos; {h.val_videos} held out "
                             "would leave none for training")
        return videos[: len(videos) - h.val_videos], videos[len(videos) - h.val_videos :]

    def training_samples(self) -> Dataset:
        h = self.hparams
        return SequenceTrainingSamples(self._split()[0], h.train_samples, h.n_test_frames, h.max_gap, h.min_pixels,
                                       hflip=h.hflip, seed=h.seed, crop=h.crop)

    def evaluation_videos(self, stage: str) -> Videos:
        return [(seq.name, *seq.load(self.hparams.val_max_frames)) for seq in self._split()[1]]
