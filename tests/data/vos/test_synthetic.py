"""Synthetic VOS videos: determinism, motion, occlusion-consistent labels, distractors and late objects."""

import pytest
import torch

from core.errors import InputError
from data.vos.synthetic import synthetic_video, synthetic_video_seeds


def test_seeded_and_shapes() -> None:
    a = synthetic_video(5, n_frames=6, height=48, width=64, n_objects=2)
    b = synthetic_video(5, n_frames=6, height=48, width=64, n_objects=2)
    c = synthetic_video(6, n_frames=6, height=48, width=64, n_objects=2)
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1]) and not torch.equal(a[0], c[0])
    frames, labels = a
    assert frames.shape == (6, 3, 48, 64) and labels.shape == (6, 48, 64)
    assert frames.min() >= 0 and frames.max() <= 1 and set(labels.unique().tolist()) <= {0, 1, 2}


def test_objects_move_and_static_when_motion_zero() -> None:
    _, labels = synthetic_video(1, n_frames=12, height=64, width=96, n_distractors=0)
    centroid = [torch.nonzero(labels[t] == 1).float().mean(0) for t in (0, 11)]
    assert (centroid[0] - centroid[1]).norm() > 2
    _, still = synthetic_video(1, n_frames=12, height=64, width=96, n_distractors=0, motion=0)
    assert torch.equal(still[0], still[11])


def test_distractors_are_unlabelled_and_similar() -> None:
    frames0, labels0 = synthetic_video(2, n_frames=2, height=64, width=96, n_distractors=0, motion=0)
    frames1, labels1 = synthetic_video(2, n_frames=2, height=64, width=96, n_distractors=2, motion=0)
    assert set(labels1.unique().tolist()) <= {0, 1}
    changed = (frames1 - frames0).abs().sum(1) > 0.2  # where the distractors were drawn
    assert changed.sum() > 50 and (labels0[changed] == 1).float().mean() < 1


def test_late_objects_appear_later_and_bad_args() -> None:
    found = False
    for seed in range(10):
        _, labels = synthetic_video(seed, n_frames=10, height=48, width=64, n_objects=3, late_objects=True)
        present = [(labels == k).flatten(1).any(1) for k in (2, 3)]
        first = [int(torch.nonzero(p)[0]) for p in present if p.any()]
        found |= any(f > 0 for f in first)
    assert found
    with pytest.raises(InputError, match="n_objects"):
        synthetic_video(0, n_objects=0)
    assert set(synthetic_video_seeds("train", 3)).isdisjoint(synthetic_video_seeds("val", 3))


def test_rendering_selected_times_matches_full_video() -> None:
    full = synthetic_video(9, n_frames=10, height=40, width=56, n_objects=2, late_objects=True)
    part = synthetic_video(9, n_frames=10, height=40, width=56, n_objects=2, late_objects=True, times=[0, 4, 9])
    assert torch.equal(part[0], full[0][[0, 4, 9]]) and torch.equal(part[1], full[1][[0, 4, 9]])


def test_object_scale_sets_object_size() -> None:
    """A static single object drawn with radius fraction s lies within 0.9 s * min(H, W) of its centre; its
    largest half-extent is at least half of that (aspect >= 0.5), and the default range is unchanged."""
    h, w = 64, 96
    for seed in range(4):
        for s in (0.15, 0.35):
            _, labels = synthetic_video(seed, n_frames=1, height=h, width=w, n_distractors=0, motion=0,
                                        object_scale=(s, s))
            yx = torch.nonzero(labels[0] == 1).float() + 0.5
            extent = (yx.max(0).values - yx.min(0).values + 1).max()
            assert 0.45 * s * h <= extent <= 2 * 0.9 * s * h + 2
    default = synthetic_video(3, n_frames=2, height=h, width=w)
    explicit = synthetic_video(3, n_frames=2, height=h, width=w, object_scale=(0.15, 0.3))
    assert torch.equal(default[0], explicit[0]) and torch.equal(default[1], explicit[1])
    with pytest.raises(InputError, match="object_scale"):
        synthetic_video(0, object_scale=(0.5, 0.2))
