"""FRTM first-frame augmentation (thesis ch. 5.3; paper D) on tensors: ``core.first_frame_augment`` (numpy and
OpenCV, shared with the deployment runtime so that both train their target models on the same samples) with
tensors in and out, on the input's device and dtype."""

from __future__ import annotations

import torch
from torch import nn

from core import first_frame_augment as augment
from core.errors import InputError


def first_frame_augment(
    image: torch.Tensor, mask: torch.Tensor, num_aug: int = 5, seed: int = 0
) -> tuple[torch.Tensor, torch.Tensor]:
    """Augmented copies of the first frame and its target mask (``core.first_frame_augment``).

    Args:
        image: (3, H, W) RGB in [0, 1].
        mask: (H, W) target mask (binary or soft); must not be empty.
        num_aug: K, the number of samples including the original (FRTM 5 at inference, 15 in training).
        seed: seeds the transform choices.

    Returns:
        images (K, 3, H, W) and masks (K, H, W) in [0, 1]; index 0 is the input.
    """
    if image.ndim != 3 or image.shape[0] != 3 or mask.shape != image.shape[-2:]:
        raise InputError(f"augmentation needs a (3, H, W) image and an (H, W) mask, got {tuple(image.shape)}, "
                         f"{tuple(mask.shape)}")
    images, masks = augment.first_frame_augment(image.detach().float().cpu().numpy(),
                                                mask.detach().float().cpu().numpy(), num_aug, seed)
    images = torch.from_numpy(images).to(image.device, image.dtype)
    masks = torch.from_numpy(masks).to(image.device, image.dtype)
    images[0], masks[0] = image, mask.to(image.dtype)  # the input itself, bit for bit
    return images, masks


class FirstFrameAugment(nn.Module):
    """Module form of ``first_frame_augment`` with a fixed number of samples and seed."""

    def __init__(self, num_aug: int = 5, seed: int = 0) -> None:
        super().__init__()
        self.num_aug = num_aug
        self.seed = seed

    def forward(self, image: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(3, H, W), (H, W) -> images (K, 3, H, W), masks (K, H, W)."""
        return first_frame_augment(image, mask, self.num_aug, self.seed)
