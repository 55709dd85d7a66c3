"""VOS datasets and LightningDataModules: training samples (a reference frame and later test frames of one
object) and whole evaluation videos, from the synthetic generator or a DAVIS-layout folder."""

from __future__ import annotations

from collections.abc import Sequence

import lightning as L
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader, Dataset

from core.errors import InputError
from data.vos.davis import davis_sequences
from data.vos.io import VOSSequence
from data.vos.synthetic import synthetic_video, synthetic_video_seeds
from data.vos.zoom import zoom_on_object


def training_sample(
    frames: torch.Tensor, labels: torch.Tensor, obj: int, ref: int, tests: Sequence[int]
) -> dict[str, torch.Tensor]:
    """One training sample of object ``obj``: reference frame/mask and test frames/masks (float in [0, 1]), their
    distractor masks (the other annotated objects, thesis ch. 6.2; void 255 and unannotated frames -1 are
    neither) and ``has_distractors``, whether ``labels`` annotate any other object at all."""
    frames = frames.float() / 255 if frames.dtype == torch.uint8 else frames
    masks = (labels == obj).float()
    others = (labels > 0) & (labels != obj) & (labels != 255)
    idx = torch.tensor(list(tests))
    return {"ref_image": frames[ref], "ref_mask": masks[ref], "test_images": frames[idx], "test_masks": masks[idx],
            "ref_distractor": others[ref].float(), "test_distractors": others[idx].float(),
            "has_distractors": others.any()}


def _resize_video(frames: torch.Tensor, labels: torch.Tensor, scale: float) -> tuple[torch.Tensor, torch.Tensor]:
    if scale == 1.0:
        return frames, labels
    size = (round(frames.shape[-2] * scale), round(frames.shape[-1] * scale))
    f = F.interpolate(frames.float(), size=size, mode="bilinear", align_corners=False, antialias=True)
    lab = F.interpolate(labels[:, None].float(), size=size, mode="nearest")[:, 0].long()
    return f.round().clamp(0, 255).to(torch.uint8), lab


class SyntheticTrainingSamples(Dataset):
    """Samples from fresh synthetic videos: ``len`` videos, video ``i`` seeded by the split's seed range."""

    def __init__(self, n_samples: int, n_test_frames: int = 2, max_gap: int = 8, seed: int = 0, **video) -> None:
        self.seeds = synthetic_video_seeds("train", n_samples, seed)
        self.n_test_frames = n_test_frames
        self.max_gap = max_gap
        self.video = video

    def __len__(self) -> int:
        return len(self.seeds)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        seed = self.seeds[i]
        gen = torch.Generator().manual_seed(seed)
        tests = (torch.randperm(self.max_gap, generator=gen)[: self.n_test_frames] + 1).sort().values.tolist()
        frames, labels = synthetic_video(seed, n_frames=self.max_gap + 1, times=[0, *tests], **self.video)
        ids = labels[0].unique()
        ids = ids[ids > 0]
        obj = int(ids[torch.randint(len(ids), (), generator=gen)])
        return training_sample(frames, labels, obj, 0, range(1, len(tests) + 1))


class SequenceTrainingSamples(Dataset):
    """Samples from annotated videos (e.g. DAVIS): random sequence, object, reference frame and test frames
    within ``max_gap`` after it, with the object at least ``min_pixels`` large in the reference frame; with
    probability ``hflip`` the whole sample is mirrored left-right; with ``crop`` (h, w) every frame of a sample
    is cut to the same window, centred on the target in the reference frame give or take a quarter window.
    With probability ``zoom_prob`` the test frames are scaled around the object by one of ``zooms`` (chosen
    uniformly; ``data.vos.zoom``), so the object is larger (zoom > 1) or smaller (< 1) than in the reference;
    ``test_zoom`` (T,) says by how much each test frame was (1: not zoomed).

    References are every ``reference_every``-th annotated frame (1: any). Without ``crop`` a sample also names
    what it was cut from, so a trainer on a frozen backbone can reuse features and fitted target models (FRTM
    cached them): ``sample_key`` (sequence, object, reference frame, mirrored) and ``test_index`` (T,)."""

    def __init__(
        self,
        sequences: list[VOSSequence],
        n_samples: int,
        n_test_frames: int = 2,
        max_gap: int = 8,
        min_pixels: int = 100,
        scale: float = 1.0,
        hflip: float = 0.0,
        seed: int = 0,
        crop: tuple[int, int] | list[int] | None = None,
        reference_every: int = 1,
        zooms: Sequence[float] = (),
        zoom_prob: float = 0.0,
    ) -> None:
        if not sequences:
            raise InputError("no training sequences")
        if reference_every < 1:
            raise InputError(f"reference_every must be at least 1, got {reference_every}")
        if crop is not None and (len(crop) != 2 or min(crop) < 1):
            raise InputError(f"crop must be (height, width) in pixels, got {crop}")
        if not 0 <= zoom_prob <= 1 or (zoom_prob > 0 and not zooms) or any(not z > 0 for z in zooms):
            raise InputError(f"zoom_prob must be in [0, 1] and zooms positive (needed when zoom_prob > 0), got "
                             f"zoom_prob {zoom_prob} and zooms {list(zooms)}")
        self.crop = None if crop is None else (int(crop[0]), int(crop[1]))
        self.zooms = tuple(float(z) for z in zooms)
        self.zoom_prob = float(zoom_prob)
        self.sequences = sequences
        self.n_samples = n_samples
        self.n_test_frames = n_test_frames
        self.max_gap = max_gap
        self.min_pixels = min_pixels
        self.scale = scale
        self.hflip = hflip
        self.seed = seed
        self.reference_every = reference_every
        self._cache: dict[int, tuple[torch.Tensor, torch.Tensor]] = {}

    def __len__(self) -> int:
        return self.n_samples

    def _load(self, s: int) -> tuple[torch.Tensor, torch.Tensor]:
        if s not in self._cache:
            self._cache[s] = _resize_video(*self.sequences[s].load(), self.scale)
        return self._cache[s]

    def pick_reference(self, gen: torch.Generator, labels: torch.Tensor) -> tuple[int, torch.Tensor] | None:
        """A random reference frame among every ``reference_every``-th of the annotated ones (labels >= 0;
        YouTube-VOS annotates every 5th) but the last, and the annotated frames after it; None for a video with
        fewer than two."""
        annotated = torch.nonzero((labels >= 0).flatten(1).any(1))[:, 0]
        if annotated.numel() < 2:
            return None
        choices = range(0, annotated.numel() - 1, self.reference_every)
        r = choices[int(torch.randint(len(choices), (), generator=gen))]
        return int(annotated[r]), annotated[r + 1 :]

    def pick_tests(self, gen: torch.Generator, later: torch.Tensor) -> list[int]:
        """``n_test_frames`` test frames (sorted, repeats allowed) among the first ``max_gap`` of ``later``."""
        later = later[: self.max_gap]
        return later[torch.randint(len(later), (self.n_test_frames,), generator=gen)].sort().values.tolist()

    def pick_object(self, gen: torch.Generator, labels: torch.Tensor) -> int | None:
        """A random object of at least ``min_pixels`` pixels in a label map, or None."""
        ids = [k for k in labels.unique().tolist() if 0 < k < 255 and int((labels == k).sum()) >= self.min_pixels]
        return ids[int(torch.randint(len(ids), (), generator=gen))] if ids else None

    def zoom(self, gen: torch.Generator, sample: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """With probability ``zoom_prob``, the test frames, masks and distractor masks scaled around the object by
        one of ``zooms``; ``test_zoom`` (T,) set. No random draw is made when ``zoom_prob`` is 0."""
        n = sample["test_masks"].shape[0]
        sample["test_zoom"] = torch.ones(n)
        if self.zoom_prob == 0 or float(torch.rand((), generator=gen)) >= self.zoom_prob:
            return sample
        z = self.zooms[int(torch.randint(len(self.zooms), (), generator=gen))]
        stacked = torch.cat([sample["test_images"], sample["test_distractors"][:, None]], 1)
        stacked, masks, zoomed = zoom_on_object(stacked, sample["test_masks"], z)
        sample["test_images"], sample["test_masks"] = stacked[:, :-1], masks
        sample["test_distractors"] = (stacked[:, -1] > 0.5).float()
        sample["test_zoom"] = torch.tensor([z if done else 1.0 for done in zoomed])
        return sample

    def mirror(self, gen: torch.Generator, sample: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The sample mirrored left-right with probability ``hflip`` (``sample_key``'s last entry says so), then
        cut to ``crop`` (and ``sample_key`` and ``test_index`` dropped: the frames are no longer whole)."""
        if float(torch.rand((), generator=gen)) < self.hflip:
            sample = {k: v.flip(-1) if v.ndim >= 2 else v for k, v in sample.items()}
            if "sample_key" in sample:  # composite and synthetic samples name no frames
                sample["sample_key"][-1] = 1
        if self.crop is None:
            return sample
        sample = {k: v for k, v in sample.items() if k not in ("sample_key", "test_index", "test_zoom")}
        h, w = sample["ref_mask"].shape
        ch, cw = min(self.crop[0], h), min(self.crop[1], w)
        ys, xs = torch.nonzero(sample["ref_mask"] > 0.5, as_tuple=True)
        cy, cx = (float(ys.float().mean()), float(xs.float().mean())) if ys.numel() else (h / 2, w / 2)
        jitter = (torch.rand(2, generator=gen) - 0.5) / 2
        top = int(min(max(cy - ch / 2 + float(jitter[0]) * ch, 0), h - ch))
        left = int(min(max(cx - cw / 2 + float(jitter[1]) * cw, 0), w - cw))
        return {k: v[..., top : top + ch, left : left + cw] if v.ndim >= 2 else v for k, v in sample.items()}

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        gen = torch.Generator().manual_seed(self.seed * 1_000_003 + i)
        for _ in range(100):
            s = int(torch.randint(len(self.sequences), (), generator=gen))
            frames, labels = self._load(s)
            picked = self.pick_reference(gen, labels)
            obj = None if picked is None else self.pick_object(gen, labels[picked[0]])
            if obj is None:
                continue
            ref, later = picked
            tests = self.pick_tests(gen, later)
            sample = training_sample(frames, labels, obj, ref, tests)
            sample["sample_key"] = torch.tensor([s, obj, ref, 0])
            sample["test_index"] = torch.tensor(tests)
            return self.mirror(gen, self.zoom(gen, sample))
        raise InputError("no sequence yields a training sample (objects too small or videos too short)")


class VideoDataset(Dataset):
    """Whole videos for evaluation: ``{"name", "frames" (T, 3, H, W) uint8, "labels" (T, H, W)}``."""

    def __init__(self, videos: list[tuple[str, torch.Tensor, torch.Tensor]]) -> None:
        self.videos = videos

    def __len__(self) -> int:
        return len(self.videos)

    def __getitem__(self, i: int) -> dict:
        name, frames, labels = self.videos[i]
        return {"name": name, "frames": frames, "labels": labels}


def first_item(batch: list[dict]) -> dict:
    """Collate of batch size 1: the one item (whole videos are not stacked)."""
    return batch[0]


def synthetic_videos(
    split: str, n_videos: int, seed: int = 0, **video
) -> list[tuple[str, torch.Tensor, torch.Tensor]]:
    """``n_videos`` held-out synthetic videos as (name, frames uint8, labels)."""
    out = []
    for s in synthetic_video_seeds(split, n_videos, seed):
        frames, labels = synthetic_video(s, **video)
        out.append((f"synthetic-{s}", (frames * 255).round().to(torch.uint8), labels))
    return out


Videos = list[tuple[str, torch.Tensor, torch.Tensor]]


class VideoDataModule(L.LightningDataModule):
    """Base of the VOS DataModules: shuffled batches of ``training_samples()`` (``batch_size``, ``num_workers``
    hyper-parameters) for training, whole ``evaluation_videos(stage)`` (name, frames uint8, labels) one at a time
    for validation and test."""

    def training_samples(self) -> Dataset:
        raise NotImplementedError

    def evaluation_videos(self, stage: str) -> Videos:
        raise NotImplementedError

    def train_dataloader(self) -> DataLoader:
        h = self.hparams
        return DataLoader(self.training_samples(), batch_size=h.batch_size, shuffle=True, num_workers=h.num_workers,
                          drop_last=True)

    def val_dataloader(self) -> DataLoader:
        return DataLoader(VideoDataset(self.evaluation_videos("val")), batch_size=1, collate_fn=first_item)

    def test_dataloader(self) -> DataLoader:
        return DataLoader(VideoDataset(self.evaluation_videos("test")), batch_size=1, collate_fn=first_item)


class SyntheticVOSDataModule(VideoDataModule):
    """Synthetic videos: training samples from fresh videos, validation/test on disjoint seeds.

    Args:
        train_samples: samples (= videos) per epoch; val_videos / test_videos: held-out videos.
        n_frames: frames of evaluation videos; height, width: frame size.
        n_objects / n_distractors: per video (training samples pick one object).
        object_scale: (low, high) object radius as a fraction of the short side (``synthetic_video``).
        lookalike: the labelled objects are look-alikes of the first (``synthetic_video``; distractor-aware VOS).
        eval_objects: objects per evaluation video.
        max_gap: test frames are drawn from the ``max_gap`` frames after the reference.
    """

    def __init__(
        self,
        train_samples: int = 512,
        val_videos: int = 4,
        test_videos: int = 8,
        n_frames: int = 24,
        height: int = 128,
        width: int = 224,
        n_objects: int = 1,
        n_distractors: int = 1,
        object_scale: tuple[float, float] = (0.15, 0.3),
        lookalike: bool = False,
        eval_objects: int = 1,
        max_gap: int = 8,
        n_test_frames: int = 2,
        batch_size: int = 4,
        num_workers: int = 0,
        seed: int = 0,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()

    def _video_args(self, n_objects: int) -> dict:
        h = self.hparams
        return {"height": h.height, "width": h.width, "n_objects": n_objects, "n_distractors": h.n_distractors,
                "object_scale": tuple(h.object_scale), "lookalike": h.lookalike}

    def training_samples(self) -> Dataset:
        h = self.hparams
        return SyntheticTrainingSamples(h.train_samples, h.n_test_frames, h.max_gap, h.seed,
                                        **self._video_args(h.n_objects))

    def evaluation_videos(self, stage: str) -> Videos:
        h = self.hparams
        n = h.val_videos if stage == "val" else h.test_videos
        return synthetic_videos(stage, n, h.seed, n_frames=h.n_frames, **self._video_args(h.eval_objects))


class DavisVOSDataModule(VideoDataModule):
    """DAVIS-layout data: training samples from ``train_sequences`` of ``train_split``; validation/test on
    ``val_sequences`` (of ``val_split``). Sequence lists default to the whole split.

    Args:
        root: DAVIS root (``../shared/data/davis2016`` here); resolution: folder such as ``240p`` or ``480p``.
        scale: resize factor applied to frames and masks after loading (1 = as stored).
        hflip: probability of mirroring a training sample left-right; crop: (h, w) training windows around the
            target; reference_every: references only at every n-th frame, so that a trainer caching fitted target
            models meets each one several times (``SequenceTrainingSamples``); test_zooms, test_zoom_prob: with
            that probability a sample's test frames are scaled around the object by one of the zooms (> 1
            magnifies, < 1 shrinks the frame onto a black canvas).
        val_max_frames: cut evaluation videos to this many frames (None = all).
    """

    def __init__(
        self,
        root: str = "../shared/data/davis2016",
        resolution: str = "240p",
        train_split: str = "train",
        val_split: str = "train",
        train_sequences: list[str] | None = None,
        val_sequences: list[str] | None = None,
        train_samples: int = 512,
        max_gap: int = 8,
        n_test_frames: int = 2,
        scale: float = 1.0,
        hflip: float = 0.0,
        crop: tuple[int, int] | None = None,
        reference_every: int = 1,
        test_zooms: tuple[float, ...] = (),
        test_zoom_prob: float = 0.0,
        val_max_frames: int | None = None,
        batch_size: int = 4,
        num_workers: int = 0,
        seed: int = 0,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()

    def _sequences(self, split: str, names: list[str] | None) -> list[VOSSequence]:
        h = self.hparams
        return davis_sequences(h.root, split, h.resolution, names)

    def training_samples(self) -> Dataset:
        h = self.hparams
        seqs = self._sequences(h.train_split, h.train_sequences)
        return SequenceTrainingSamples(seqs, h.train_samples, h.n_test_frames, h.max_gap, scale=h.scale,
                                       hflip=h.hflip, seed=h.seed, crop=h.crop, reference_every=h.reference_every,
                                       zooms=h.test_zooms, zoom_prob=h.test_zoom_prob)

    def evaluation_videos(self, stage: str) -> Videos:
        h = self.hparams
        videos = []
        for seq in self._sequences(h.val_split, h.val_sequences):
            frames, labels = seq.load(h.val_max_frames)
            videos.append((seq.name, *_resize_video(frames, labels, h.scale)))
        return videos
