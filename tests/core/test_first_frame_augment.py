"""First-frame augmentation (numpy): geometry, determinism, inpainting of the target, the warps and blurs against
their PyTorch equivalents (``grid_sample``, convolutions), bad input."""

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from core.errors import InputError
from core.first_frame_augment import (
    SCALES,
    first_frame_augment,
    gaussian_blur,
    inpaint_target,
    motion_blur,
    sample_bilinear,
)


def test_augmentation_keeps_original_and_scales_area() -> None:
    image = np.random.default_rng(0).random((3, 96, 128), dtype=np.float32)
    mask = np.zeros((96, 128), np.float32)
    mask[40:56, 50:70] = 1  # 320 px
    images, masks = first_frame_augment(image, mask, num_aug=9, seed=3)
    assert images.shape == (9, 3, 96, 128) and masks.shape == (9, 96, 128)
    assert np.array_equal(images[0], image) and np.array_equal(masks[0], mask)
    areas = masks[1:].sum((1, 2)) / mask.sum()
    # rotation and skew preserve area; each area must be one of the scale factors squared (blur keeps the sum)
    allowed = np.array([s * s for s in SCALES])
    assert (np.abs(areas[:, None] - allowed[None]) / allowed[None]).min(1).max() < 0.08
    # the pasted target carries the target's pixels: mean colour inside the new mask stays close
    inside = (images[1:] * masks[1:, None]).sum((2, 3)) / masks[1:, None].sum((2, 3))
    assert np.abs(inside - image[:, mask > 0].mean(1)).max() < 0.15
    again = first_frame_augment(image, mask, num_aug=9, seed=3)
    assert np.array_equal(again[0], images) and not np.array_equal(first_frame_augment(image, mask, 9, 4)[0], images)


def test_inpainting_removes_target() -> None:
    image = np.zeros((3, 40, 40), np.float32)
    image[1] = 0.5
    image[:, 15:25, 15:25] = 1.0
    mask = np.zeros((40, 40), np.float32)
    mask[15:25, 15:25] = 1
    bg = inpaint_target(image, mask)
    assert np.abs(bg[:, 15:25, 15:25] - np.array([0, 0.5, 0])[:, None, None]).max() < 0.05


def test_warps_and_blurs_match_their_pytorch_equivalents() -> None:
    rng = np.random.default_rng(1)
    image = rng.random((3, 20, 30), dtype=np.float32)
    x, y = rng.uniform(-5, 35, (20, 30)).astype(np.float32), rng.uniform(-5, 25, (20, 30)).astype(np.float32)
    grid = torch.from_numpy(np.stack([(2 * x + 1) / 30 - 1, (2 * y + 1) / 20 - 1], -1))[None]
    for padding, reflect in (("zeros", False), ("reflection", True)):
        ref = F.grid_sample(torch.from_numpy(image)[None], grid, "bilinear", padding, align_corners=False)[0]
        np.testing.assert_allclose(sample_bilinear(image, x, y, reflect), ref.numpy(), atol=1e-5)
    tensor = torch.from_numpy(image)[:, None]  # channels as a batch of one-channel images
    for sigma in (1.0, 5.0):
        r = int(np.ceil(3 * sigma))
        k = torch.exp(-0.5 * (torch.arange(-r, r + 1.0) / sigma) ** 2)
        k = k / k.sum()
        rows = F.conv2d(F.pad(tensor, (r, r, 0, 0), mode="reflect"), k.view(1, 1, 1, -1))
        ref = F.conv2d(F.pad(rows, (0, 0, r, r), mode="reflect"), k.view(1, 1, -1, 1))[:, 0]
        np.testing.assert_allclose(gaussian_blur(image, sigma), ref.numpy(), atol=1e-6)
    blurred = motion_blur(image, 2, 90.0)  # a vertical line of 5 taps: the mean of 5 rows, zeros outside
    ref = F.conv2d(tensor, torch.full((1, 1, 5, 1), 0.2), padding=(2, 0))[:, 0]
    np.testing.assert_allclose(blurred, ref.numpy(), atol=1e-6)


def test_augmentation_errors() -> None:
    with pytest.raises(InputError, match="empty"):
        first_frame_augment(np.ones((3, 8, 8)), np.zeros((8, 8)))
    with pytest.raises(InputError, match=r"\(3, H, W\)"):
        first_frame_augment(np.ones((3, 8, 8)), np.ones((8, 9)))
