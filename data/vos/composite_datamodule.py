"""Multi-object training and evaluation data for distractor-aware VOS (thesis ch. 6) from single-object videos:
composites (``data.vos.composites``: twins and pasted objects) of DAVIS-layout sequences, the sequences
themselves and synthetic look-alike videos, mixed per sample; held-out composites for evaluation."""

from __future__ import annotations

import torch
from torch.utils.data import Dataset

from core.errors import InputError
from data.vos.composites import compose, composite_video, random_pastes
from data.vos.datamodule import SequenceTrainingSamples, VideoDataModule, Videos, synthetic_videos, training_sample
from data.vos.davis import davis_sequences
from data.vos.io import VOSSequence
from data.vos.synthetic import synthetic_video, synthetic_video_seeds

#: Sample sources of ``CompositeTrainingSamples``.
SOURCES = ("plain", "twin", "paste", "synthetic")
#: Held-out evaluation sets: per host sequence one twin (2 objects) / two objects of other sequences (3 objects).
EVAL_SETS = {"twins": ["twin"], "pastes": ["paste", "paste"]}


class CompositeTrainingSamples(SequenceTrainingSamples):
    """Training samples drawn, per sample, from one of ``SOURCES`` with probabilities ``mix``:

    - ``plain``: a sequence as it is (``SequenceTrainingSamples``);
    - ``twin`` / ``paste``: a composite of a host sequence with 1..``max_extra`` twins / objects of other
      sequences, placed at the reference frame;
    - ``synthetic``: a synthetic video of 1..3 labelled look-alike objects and one unlabelled look-alike
      (``synthetic_video(lookalike=True)``) at ``synthetic_size``.

    The target is a random object of the reference frame; the others are its distractors.
    """

    def __init__(
        self,
        sequences: list[VOSSequence],
        n_samples: int,
        mix: dict[str, float] | None = None,
        max_extra: int = 2,
        synthetic_size: tuple[int, int] | list[int] = (240, 427),
        **sequence_args,
    ) -> None:
        super().__init__(sequences, n_samples, **sequence_args)
        mix = mix or {"plain": 0.3, "twin": 0.3, "paste": 0.3, "synthetic": 0.1}
        unknown = sorted(set(mix) - set(SOURCES))
        if unknown or min(mix.values(), default=-1) < 0 or sum(mix.values()) <= 0:
            raise InputError(f"mix must give non-negative weights of {SOURCES} (some positive), got {mix}")
        if max_extra < 1:
            raise InputError(f"max_extra must be at least 1, got {max_extra}")
        self.sources = [k for k in SOURCES if mix.get(k, 0) > 0]
        self.weights = torch.tensor([float(mix[k]) for k in self.sources])
        self.max_extra = max_extra
        self.synthetic_size = tuple(synthetic_size)

    def _synthetic(self, gen: torch.Generator, i: int) -> dict[str, torch.Tensor]:
        seed = synthetic_video_seeds("train", 1, self.seed * 1_000_003 + i)[0]
        n_frames = self.max_gap + 1
        tests = (torch.randperm(self.max_gap, generator=gen)[: self.n_test_frames] + 1).sort().values.tolist()
        n_objects = int(torch.randint(1, 4, (), generator=gen))
        h, w = self.synthetic_size
        frames, labels = synthetic_video(seed, n_frames=n_frames, height=h, width=w, n_objects=n_objects,
                                         n_distractors=1, times=[0, *tests], lookalike=True, object_scale=(0.1, 0.25))
        obj = self.pick_object(gen, labels[0])
        return None if obj is None else training_sample(frames, labels, obj, 0, range(1, len(tests) + 1))

    def _composite(self, gen: torch.Generator, kind: str) -> dict[str, torch.Tensor] | None:
        s = int(torch.randint(len(self.sequences), (), generator=gen))
        host = self._load(s)
        picked = self.pick_reference(gen, host[1])
        if picked is None or self.pick_object(gen, host[1][picked[0]]) is None:
            return None
        ref, later = picked
        tests = self.pick_tests(gen, later)
        videos = [self._load(k) for k in range(len(self.sequences))] if kind == "paste" else [host]
        n_extra = int(torch.randint(1, self.max_extra + 1, (), generator=gen))
        pastes = random_pastes(gen, s if kind == "paste" else 0, videos, [kind] * n_extra, anchor=ref,
                               min_pixels=self.min_pixels)
        frames, labels = compose(videos[s if kind == "paste" else 0], videos, pastes, [ref, *tests])
        obj = self.pick_object(gen, labels[0])
        return None if obj is None else training_sample(frames, labels, obj, 0, range(1, len(tests) + 1))

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        gen = torch.Generator().manual_seed(self.seed * 1_000_003 + i)
        kind = self.sources[int(torch.multinomial(self.weights, 1, generator=gen))]
        if kind == "plain":
            return super().__getitem__(i)
        for _ in range(100):
            sample = self._synthetic(gen, i) if kind == "synthetic" else self._composite(gen, kind)
            if sample is not None:
                return self.mirror(gen, sample)
        raise InputError(f"no {kind} training sample could be made (objects too small or videos too short)")


def held_out_composites(
    sequences: list[VOSSequence], eval_set: str = "twins", seed: int = 0, max_frames: int | None = None
) -> list[tuple[str, torch.Tensor, torch.Tensor]]:
    """One composite per sequence of ``EVAL_SETS[eval_set]`` (pasted objects come from the other sequences), as
    (name, frames uint8, labels) with every object in frame 0; seeded per host."""
    if eval_set not in EVAL_SETS:
        raise InputError(f"composite evaluation set {eval_set!r} is not one of {sorted(EVAL_SETS)}")
    videos = [s.load(max_frames) for s in sequences]
    kinds = EVAL_SETS[eval_set]
    if "paste" in kinds and len(videos) < 2:
        raise InputError("pasted-object composites need at least two sequences")
    out = []
    for host, seq in enumerate(sequences):
        gen = torch.Generator().manual_seed(seed * 1_000_003 + host)
        frames, labels = composite_video(gen, host, videos, kinds)
        out.append((f"{seq.name}-{eval_set}", frames, labels))
    return out


def lookalike_videos(n_videos: int, seed: int = 0, n_frames: int = 40, height: int = 240, width: int = 427,
                     n_objects: int = 3) -> list[tuple[str, torch.Tensor, torch.Tensor]]:
    """Held-out (``test`` seeds) synthetic videos of ``n_objects`` labelled look-alikes and one unlabelled one."""
    return synthetic_videos("test", n_videos, seed, n_frames=n_frames, height=height, width=width,
                            n_objects=n_objects, n_distractors=1, lookalike=True, object_scale=(0.1, 0.25))


class CompositeVOSDataModule(VideoDataModule):
    """Composite multi-object data from a DAVIS-layout root (DAVIS 2016 here): ``CompositeTrainingSamples`` of
    ``train_sequences``; validation and test on held-out composites (``eval_set``) of ``val_sequences`` only.

    Args:
        root, resolution, split: the DAVIS root, resolution folder and ImageSets split.
        train_sequences, val_sequences: sequence names (default: the whole split for training, none held out).
        mix, max_extra, synthetic_size: see ``CompositeTrainingSamples``; hflip, crop: see
            ``SequenceTrainingSamples``.
        eval_set: ``twins`` or ``pastes``; val_max_frames: cut evaluation videos to this many frames.
    """

    def __init__(
        self,
        root: str = "../shared/data/davis2016",
        resolution: str = "240p",
        split: str = "train",
        train_sequences: list[str] | None = None,
        val_sequences: list[str] | None = None,
        train_samples: int = 512,
        mix: dict[str, float] | None = None,
        max_extra: int = 2,
        synthetic_size: tuple[int, int] = (240, 427),
        max_gap: int = 8,
        n_test_frames: int = 3,
        min_pixels: int = 100,
        hflip: float = 0.5,
        crop: tuple[int, int] | None = None,
        eval_set: str = "twins",
        val_max_frames: int | None = None,
        batch_size: int = 4,
        num_workers: int = 0,
        seed: int = 0,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()

    def training_samples(self) -> Dataset:
        h = self.hparams
        seqs = davis_sequences(h.root, h.split, h.resolution, h.train_sequences)
        return CompositeTrainingSamples(seqs, h.train_samples, h.mix, h.max_extra, h.synthetic_size,
                                        n_test_frames=h.n_test_frames, max_gap=h.max_gap, min_pixels=h.min_pixels,
                                        hflip=h.hflip, seed=h.seed, crop=h.crop)

    def evaluation_videos(self, stage: str) -> Videos:
        h = self.hparams
        if not h.val_sequences:
            raise InputError("CompositeVOSDataModule needs val_sequences to evaluate on")
        seqs = davis_sequences(h.root, h.split, h.resolution, h.val_sequences)
        return held_out_composites(seqs, h.eval_set, h.seed, h.val_max_frames)
