"""Composite training samples (twins, pastes, synthetic look-alikes) and held-out composites."""

import pytest
import torch

from core.errors import InputError
from data.vos.composite_datamodule import CompositeTrainingSamples, held_out_composites, lookalike_videos


class BlockSequence:
    """A VOSSequence stand-in: 8 random 48x64 frames with a 10x12 block object moving right."""

    def __init__(self, seed: int) -> None:
        self.name, self.seed = f"block{seed}", seed

    def load(self, max_frames=None):
        n = 8 if max_frames is None else min(8, max_frames)
        frames = torch.randint(0, 256, (n, 3, 48, 64), generator=torch.Generator().manual_seed(self.seed),
                               dtype=torch.uint8)
        labels = torch.zeros(n, 48, 64, dtype=torch.int64)
        for t in range(n):
            labels[t, 10 + self.seed : 20 + self.seed, 4 + 2 * t : 16 + 2 * t] = 1
        return frames, labels


@pytest.mark.parametrize("source", ["twin", "paste", "synthetic", "plain"])
def test_each_source_gives_samples_of_one_target_with_its_distractors(source: str) -> None:
    seqs = [BlockSequence(s) for s in range(3)]
    ds = CompositeTrainingSamples(seqs, 4, {source: 1.0}, max_extra=2, synthetic_size=(48, 64), n_test_frames=2,
                                  max_gap=3, min_pixels=20, seed=1)
    for i in range(4):
        s = ds[i]
        assert s["ref_image"].shape == (3, 48, 64) and s["test_masks"].shape == (2, 48, 64)
        assert s["ref_mask"].sum() >= 20 and (s["ref_mask"] * s["ref_distractor"]).sum() == 0
        if source in ("twin", "paste"):
            assert s["has_distractors"].item() and s["ref_distractor"].sum() > 0
        if source == "plain":
            assert not s["has_distractors"].item()
    again = CompositeTrainingSamples(seqs, 4, {source: 1.0}, max_extra=2, synthetic_size=(48, 64), n_test_frames=2,
                                     max_gap=3, min_pixels=20, seed=1)[3]
    assert all(torch.equal(v, again[k]) for k, v in ds[3].items())


@pytest.mark.parametrize("source", ["twin", "paste", "synthetic", "plain"])
def test_a_mirrored_sample_is_the_sample_flipped(source: str) -> None:
    """hflip=1 mirrors every sample of every source (composites and synthetic samples name no frames, so only a
    plain sample's sample_key records the mirroring)."""
    seqs = [BlockSequence(s) for s in range(3)]
    args = dict(max_extra=2, synthetic_size=(48, 64), n_test_frames=2, max_gap=3, min_pixels=20, seed=1)
    plain = CompositeTrainingSamples(seqs, 2, {source: 1.0}, **args)[1]
    mirrored = CompositeTrainingSamples(seqs, 2, {source: 1.0}, hflip=1.0, **args)[1]
    assert plain.keys() == mirrored.keys()
    for key, value in plain.items():
        if key == "sample_key":
            assert mirrored[key][-1] == 1 and torch.equal(mirrored[key][:-1], value[:-1])
        else:
            assert torch.equal(mirrored[key], value.flip(-1) if value.ndim >= 2 else value), key


def test_held_out_composites_have_every_object_in_the_first_frame() -> None:
    seqs = [BlockSequence(s) for s in range(3)]
    for eval_set, n_ids in (("twins", 2), ("pastes", 3)):
        videos = held_out_composites(seqs, eval_set, seed=0, max_frames=5)
        assert [name for name, _, _ in videos] == [f"block{s}-{eval_set}" for s in range(3)]
        for _, frames, labels in videos:
            assert frames.shape == (5, 3, 48, 64) and frames.dtype == torch.uint8
            assert labels[0].unique().tolist() == list(range(n_ids + 1))
    with pytest.raises(InputError, match="evaluation set"):
        held_out_composites(seqs, "triplets")


def test_lookalike_videos_and_bad_mix() -> None:
    (name, frames, labels), = lookalike_videos(1, n_frames=4, height=48, width=64, n_objects=2)
    assert name.startswith("synthetic-") and frames.shape == (4, 3, 48, 64)
    with pytest.raises(InputError, match="mix"):
        CompositeTrainingSamples([BlockSequence(0)], 2, {"plain": 1.0, "clones": 1.0})
