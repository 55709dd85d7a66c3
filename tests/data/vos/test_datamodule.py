"""SequenceTrainingSamples: reference/test frames of one object, and the left-right mirroring option."""

import pytest
import torch

from core.errors import InputError
from data.vos.datamodule import SequenceTrainingSamples


class FakeSequence:
    """A VOSSequence stand-in: 6 random frames with a labelled block that moves right."""

    name = "fake"

    def load(self, max_frames=None):
        frames = torch.randint(0, 256, (6, 3, 12, 16), generator=torch.Generator().manual_seed(0), dtype=torch.uint8)
        labels = torch.zeros(6, 12, 16, dtype=torch.long)
        for t in range(6):
            labels[t, 3:9, t : t + 6] = 1
        return frames, labels


def test_sample_is_object_masks_of_later_frames() -> None:
    sample = SequenceTrainingSamples([FakeSequence()], 4, n_test_frames=2, max_gap=3, min_pixels=10, seed=1)[0]
    assert sample["ref_image"].shape == (3, 12, 16) and sample["test_images"].shape == (2, 3, 12, 16)
    assert sample["ref_mask"].sum() == 36 and set(sample["test_masks"].unique().tolist()) == {0.0, 1.0}


def test_hflip_mirrors_every_tensor_of_the_same_sample() -> None:
    kept = SequenceTrainingSamples([FakeSequence()], 8, min_pixels=10, hflip=0.0, seed=3)
    mirrored = SequenceTrainingSamples([FakeSequence()], 8, min_pixels=10, hflip=1.0, seed=3)
    for i in range(8):
        a, b = kept[i], mirrored[i]
        for key in a.keys() - {"sample_key", "test_index"}:
            assert torch.equal(b[key], a[key].flip(-1)), key
        assert torch.equal(b["test_index"], a["test_index"])
        assert a["sample_key"][-1] == 0 and b["sample_key"][-1] == 1 and torch.equal(b["sample_key"][:3],
                                                                                     a["sample_key"][:3])


def test_sample_key_names_the_frames_and_references_keep_their_stride() -> None:
    frames, labels = FakeSequence().load()
    ds = SequenceTrainingSamples([FakeSequence(), FakeSequence()], 20, n_test_frames=2, max_gap=3, min_pixels=10,
                                 hflip=0.5, reference_every=2, seed=5)
    for i in range(20):
        s = ds[i]
        seq, obj, ref, flipped = s["sample_key"].tolist()
        assert seq in (0, 1) and obj == 1 and ref % 2 == 0 and ref < 5
        flip = (lambda x: x.flip(-1)) if flipped else (lambda x: x)
        assert torch.equal(s["ref_image"], flip(frames[ref].float() / 255))
        assert torch.equal(s["test_images"], flip(frames[s["test_index"]].float() / 255))
        assert torch.equal(s["test_masks"], flip((labels[s["test_index"]] == obj).float()))
        assert (s["test_index"] > ref).all()
    with pytest.raises(InputError, match="reference_every"):
        SequenceTrainingSamples([FakeSequence()], 1, reference_every=0)


class TwoObjectSequence(FakeSequence):
    """FakeSequence plus a second, static object; every other frame unannotated (-1), as YouTube-VOS."""

    def load(self, max_frames=None):
        frames, labels = super().load()
        labels[:, 0:2, 12:16] = 2
        labels[1::2] = -1
        return frames, labels


def test_distractors_are_the_other_annotated_objects_and_sparse_annotations_are_skipped() -> None:
    ds = SequenceTrainingSamples([TwoObjectSequence()], 6, n_test_frames=2, max_gap=3, min_pixels=5, seed=2)
    for i in range(6):
        s = ds[i]
        assert s["has_distractors"].item() and s["ref_distractor"].sum() > 0
        assert (s["ref_mask"] * s["ref_distractor"]).sum() == 0  # target and distractor never overlap
        assert (s["test_masks"] >= 0).all()  # unannotated frames (-1) are never picked
    single = SequenceTrainingSamples([FakeSequence()], 1, min_pixels=10)[0]
    assert not single["has_distractors"].item() and single["test_distractors"].sum() == 0


def test_crop_is_one_window_around_the_target() -> None:
    ds = SequenceTrainingSamples([FakeSequence()], 4, n_test_frames=2, max_gap=3, min_pixels=10, seed=1,
                                 crop=(16, 12))
    for i in range(4):
        s = ds[i]  # the window is clipped to the 12-px-high frame
        assert s["ref_image"].shape == (3, 12, 12) and s["test_masks"].shape == (2, 12, 12)
        assert s["ref_mask"].sum() >= 18  # the target (6 px wide) stays mostly inside
        assert "sample_key" not in s and "test_index" not in s  # cut frames are not the named ones
