"""First-frame augmentation geometry, inpainting of the target, bad input."""

import pytest
import torch

from core.errors import InputError
from models.vos.augment import SCALES, first_frame_augment, inpaint_target


def test_augmentation_keeps_original_and_scales_area() -> None:
    image = torch.rand(3, 96, 128)
    mask = torch.zeros(96, 128)
    mask[40:56, 50:70] = 1  # 320 px
    images, masks = first_frame_augment(image, mask, num_aug=9, seed=3)
    assert images.shape == (9, 3, 96, 128) and masks.shape == (9, 96, 128)
    assert torch.equal(images[0], image) and torch.equal(masks[0], mask)
    areas = masks[1:].sum((1, 2)) / mask.sum()
    # rotation and skew preserve area; each area must be one of the scale factors squared (blur keeps the sum)
    allowed = torch.tensor([s * s for s in SCALES])
    assert ((areas[:, None] - allowed[None]).abs() / allowed[None]).min(1).values.max() < 0.08
    # the pasted target carries the target's pixels: mean colour inside the new mask stays close
    inside = (images[1:] * masks[1:, None]).sum((2, 3)) / masks[1:, None].sum((2, 3))
    ref = image[:, mask > 0].mean(1)
    assert (inside - ref).abs().max() < 0.15
    again = first_frame_augment(image, mask, num_aug=9, seed=3)
    assert torch.equal(again[0], images)


def test_inpainting_removes_target() -> None:
    image = torch.zeros(3, 40, 40)
    image[1] = 0.5
    image[:, 15:25, 15:25] = 1.0
    mask = torch.zeros(40, 40)
    mask[15:25, 15:25] = 1
    bg = inpaint_target(image, mask)
    assert (bg[:, 15:25, 15:25] - torch.tensor([0, 0.5, 0])[:, None, None]).abs().max() < 0.05


def test_augmentation_errors() -> None:
    with pytest.raises(InputError, match="empty"):
        first_frame_augment(torch.rand(3, 8, 8), torch.zeros(8, 8))
    with pytest.raises(InputError, match=r"\(3, H, W\)"):
        first_frame_augment(torch.rand(3, 8, 8), torch.ones(8, 9))
