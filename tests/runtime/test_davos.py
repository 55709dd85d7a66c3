"""The runtime's DAVOS tracker: its command, run without torch, against the PyTorch tracker (mask IoU >= 0.99 per
frame and object), the numpy merging and distractor regeneration against PyTorch's, late objects, bad frames."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from data.vos.composite_datamodule import lookalike_videos
from data.vos.io import read_frame, write_mask
from models.vos.distractors import regenerate_distractors as torch_regenerate
from models.vos.merge import soft_aggregate as torch_soft_aggregate
from runtime.davos import OnnxDAVOSTracker, regenerate_distractors, soft_aggregate
from runtime.vos_io import read_mask


def _ious(a: np.ndarray, b: np.ndarray, ids) -> list[float]:
    return [((a == k) & (b == k)).sum() / ((a == k) | (b == k)).sum() for k in ids if ((a == k) | (b == k)).any()]


@pytest.mark.parametrize("wta", [True, False])
def test_merging_and_regeneration_are_pytorchs(wta: bool) -> None:
    logits = torch.randn(3, 20, 30, generator=torch.Generator().manual_seed(0)) * 4
    np.testing.assert_allclose(soft_aggregate(logits.numpy()), torch_soft_aggregate(logits).numpy(), atol=1e-6)
    probs = torch.sigmoid(logits)
    labels = torch.tensor([0, 2, 5, 7])[torch_soft_aggregate(logits).argmax(0)]
    ref = torch_regenerate(probs, labels, torch.tensor([2, 5, 7]), wta)
    np.testing.assert_allclose(regenerate_distractors(probs.numpy(), labels.numpy(), [2, 5, 7], wta), ref.numpy(),
                               atol=1e-7)


@pytest.mark.slow  # uses an exported bundle
def test_command_without_torch_matches_pytorch(torch_free, davos_setup, tmp_path) -> None:
    (_, frames, labels), = lookalike_videos(1, n_frames=6, height=64, width=96, n_objects=2)
    video = tmp_path / "video"
    video.mkdir()
    for t, frame in enumerate(frames):  # PNG: both readers decode it alike
        cv2.imwrite(str(video / f"{t:05d}.png"), frame.permute(1, 2, 0).numpy()[..., ::-1])
    write_mask(tmp_path / "first.png", labels[0])
    torch_free("runtime.davos", "--bundle", davos_setup["bundle"], "--video", video, "--mask",
               tmp_path / "first.png", "--out", tmp_path / "masks", "--threads", "1")
    images = torch.stack([read_frame(video / f"{t:05d}.png") for t in range(6)])
    ref = [a.numpy() for a in davos_setup["tracker"].segment(images, {0: labels[0]})]
    got = [read_mask(tmp_path / "masks" / f"{t:05d}.png") for t in range(6)]
    ious = [iou for a, b in zip(ref, got, strict=True) for iou in _ious(a, b, (1, 2))]
    assert len(ious) >= 6 and min(ious) >= 0.99


@pytest.mark.slow  # uses an exported bundle
def test_objects_appearing_later_distractor_maps_and_bad_frames(davos_setup) -> None:
    (_, frames, labels), = lookalike_videos(1, seed=3, n_frames=5, height=64, width=96, n_objects=2)
    first = torch.where(labels[0] == 2, 0, labels[0])  # object 2 starts in frame 2
    masks = {0: first, 2: labels[2]}
    tracker = davos_setup["tracker"]
    ref = [a.numpy() for a in tracker.segment(frames, masks)]
    runtime = OnnxDAVOSTracker(davos_setup["bundle"], threads=1)
    got = list(runtime.segment(frames.numpy(), {t: m.numpy() for t, m in masks.items()}))
    assert runtime.ids == [1, 2] and not (got[1] == 2).any() and (got[2] == 2).any()
    assert min(iou for a, b in zip(ref, got, strict=True) for iou in _ious(a, b, (1, 2))) >= 0.99
    np.testing.assert_allclose(runtime.distractors, tracker.distractors.numpy(), atol=2e-3)
    with pytest.raises(InputError, match=r"frame 0 is \(3, 8, 96\)"):
        list(runtime.segment([np.zeros((3, 8, 96), np.uint8)], {0: np.ones((8, 96), np.int64)}))
    with pytest.raises(InputError, match="is not a folder"):
        OnnxDAVOSTracker(davos_setup["bundle"].parent / "missing")
