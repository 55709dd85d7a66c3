"""The runtime's FRTM tracker: its command, run without torch, against the PyTorch tracker on synthetic videos
(mask IoU >= 0.99 per frame and object), the numpy soft aggregation, pixel weights and target-model scores against
PyTorch's, objects appearing later, bad frames."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from data.vos.io import read_frame, write_mask
from data.vos.synthetic import synthetic_video
from models.vos.merge import merge_objects as torch_merge
from models.vos.target_model import apply_filter
from models.vos.target_model import hinge_pixel_weights as torch_hinge
from runtime.vos import OnnxFRTMTracker, hinge_pixel_weights, merge_objects, target_score
from runtime.vos_io import read_mask


def _ious(a: np.ndarray, b: np.ndarray, ids) -> list[float]:
    out = []
    for k in ids:
        union = ((a == k) | (b == k)).sum()
        if union:
            out.append(((a == k) & (b == k)).sum() / union)
    return out


def test_soft_aggregation_and_pixel_weights_are_pytorchs() -> None:
    logits = torch.randn(3, 20, 30, generator=torch.Generator().manual_seed(0)) * 4
    labels, soft = merge_objects(logits.numpy(), [2, 5, 7])
    ref_labels, ref_soft = torch_merge(logits, torch.tensor([2, 5, 7]))
    np.testing.assert_array_equal(labels, ref_labels.numpy())
    np.testing.assert_allclose(soft, ref_soft.numpy(), atol=1e-6)
    masks = (torch.rand(2, 3, 20, 30, generator=torch.Generator().manual_seed(1)) > 0.97).float()
    masks[0, 0] = 1  # all foreground
    np.testing.assert_allclose(hinge_pixel_weights(masks.numpy(), 0.1, 10), torch_hinge(masks, 0.1, 10).numpy(),
                               rtol=1e-6)


@pytest.mark.slow  # uses an exported bundle
@pytest.mark.parametrize("seed", [5, 8])
def test_command_without_torch_matches_pytorch(torch_free, vos_setup, tmp_path, seed) -> None:
    frames, labels = synthetic_video(seed, n_frames=8, height=64, width=96, n_objects=2)
    video = tmp_path / "video"
    video.mkdir()
    for t, frame in enumerate((frames * 255).round().to(torch.uint8)):  # PNG: both readers decode it alike
        cv2.imwrite(str(video / f"{t:05d}.png"), frame.permute(1, 2, 0).numpy()[..., ::-1])
    write_mask(tmp_path / "first.png", labels[0])
    torch_free("runtime.vos", "--bundle", vos_setup["bundle"], "--video", video, "--mask", tmp_path / "first.png",
               "--out", tmp_path / "masks")
    images = torch.stack([read_frame(video / f"{t:05d}.png") for t in range(8)])
    ref = [a.numpy() for a in vos_setup["tracker"].segment(images, {0: labels[0]})]
    got = [read_mask(tmp_path / "masks" / f"{t:05d}.png") for t in range(8)]
    ious = [iou for a, b in zip(ref, got, strict=True) for iou in _ious(a, b, (1, 2))]
    assert len(ious) >= 8 and min(ious) >= 0.99


@pytest.mark.slow  # uses an exported bundle
def test_objects_appearing_later_and_bad_frames(vos_setup) -> None:
    frames, labels = synthetic_video(3, n_frames=5, height=64, width=96, n_objects=2)
    first = torch.where(labels[0] == 2, 0, labels[0])  # object 2 starts in frame 2
    masks = {0: first, 2: labels[2]}
    ref = [a.numpy() for a in vos_setup["tracker"].segment(frames, masks)]
    runtime = OnnxFRTMTracker(vos_setup["bundle"], threads=1)
    got = list(runtime.segment(frames.numpy(), {t: m.numpy() for t, m in masks.items()}))
    assert runtime.ids == [1, 2] and not (got[1] == 2).any() and (got[2] == 2).any()
    assert min(iou for a, b in zip(ref, got, strict=True) for iou in _ious(a, b, (1, 2))) >= 0.99
    with pytest.raises(InputError, match=r"frame 0 is \(3, 8, 96\)"):
        list(runtime.segment([np.zeros((3, 8, 96), np.uint8)], {0: np.ones((8, 96), np.int64)}))
    with pytest.raises(InputError, match="first-frame mask is empty"):
        list(runtime.segment(frames.numpy()[:1], {0: np.zeros((64, 96), np.int64)}))


def test_target_score_is_pytorchs_filter() -> None:
    g = torch.Generator().manual_seed(3)
    z, wf = torch.randn(2, 6, 7, 9, generator=g, dtype=torch.float64), torch.randn(2, 6, 3, 3, generator=g,
                                                                                  dtype=torch.float64)
    ref = apply_filter(z[:, None], wf)[:, 0]
    np.testing.assert_allclose(target_score(z.float().numpy(), wf.float().numpy()), ref.numpy(), rtol=1e-5,
                               atol=1e-5)
