"""FRTM first-frame augmentation (thesis ch. 5.3; paper D): the target is cut out, the hole inpainted (OpenCV
Telea, radius 1), and the target pasted back at grid locations with rotation, scale, flip, skew and motion
blur over a zoomed and blurred background. Sample 0 is the original frame. Warps use ``grid_sample``.
"""

from __future__ import annotations

import itertools
import math

import cv2
import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError

ROTATIONS = (5.0, -5.0, 10.0, -10.0, 20.0, -20.0, 30.0, -30.0, 45.0, -45.0)
SCALES = (0.5, 0.7, 1.0, 1.5, 2.0, 2.5)
FLIP_P = 0.2
SKEW, SKEW_P = 0.1, 1 / 3
MOTION_BLUR_SIZES = (0, 0, 0, 2)
MOTION_BLUR_ANGLES = (0.0, 45.0, 90.0, 135.0)
BG_SCALES = (1.0, 1.0, 1.2)
BG_BLURS = (0.0, 0.0, 1.0, 2.0, 5.0)


def inpaint_target(image: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Background with the target removed: OpenCV Telea inpainting (radius 1) of the dilated mask.

    Args:
        image: (3, H, W) RGB in [0, 1]; mask: (H, W), target where > 0.5.
    """
    rgb = (image.permute(1, 2, 0).clamp(0, 1) * 255).round().to(torch.uint8).cpu().numpy()
    hole = cv2.dilate((mask > 0.5).to(torch.uint8).cpu().numpy(), np.ones((5, 5), np.uint8))
    out = cv2.inpaint(np.ascontiguousarray(rgb), hole, 1, cv2.INPAINT_TELEA)
    return torch.from_numpy(out).to(image.device, image.dtype).permute(2, 0, 1) / 255


def _gaussian_blur(x: torch.Tensor, sigma: float) -> torch.Tensor:
    """Separable Gaussian blur of (N, C, H, W) with reflect padding; sigma 0 returns x."""
    if sigma <= 0:
        return x
    r = max(1, int(math.ceil(3 * sigma)))
    k = torch.exp(-0.5 * (torch.arange(-r, r + 1, dtype=x.dtype, device=x.device) / sigma) ** 2)
    k = k / k.sum()
    c = x.shape[1]
    x = F.pad(x, (r, r, 0, 0), mode="reflect") if x.shape[-1] > r else F.pad(x, (r, r, 0, 0), mode="replicate")
    x = F.conv2d(x, k.view(1, 1, 1, -1).expand(c, 1, 1, -1), groups=c)
    x = F.pad(x, (0, 0, r, r), mode="reflect") if x.shape[-2] > r else F.pad(x, (0, 0, r, r), mode="replicate")
    return F.conv2d(x, k.view(1, 1, -1, 1).expand(c, 1, -1, 1), groups=c)


def _motion_blur(x: torch.Tensor, size: int, angle_deg: float) -> torch.Tensor:
    """Blur (N, C, H, W) along a line of ``size`` px each side in direction ``angle_deg``; size 0 returns x."""
    if size <= 0:
        return x
    k = torch.zeros(2 * size + 1, 2 * size + 1, dtype=x.dtype, device=x.device)
    a = math.radians(angle_deg)
    for t in torch.linspace(-size, size, 4 * size + 1).tolist():
        k[round(size + t * math.sin(a)), round(size + t * math.cos(a))] = 1
    k = k / k.sum()
    c = x.shape[1]
    return F.conv2d(x, k.expand(c, 1, -1, -1), padding=size, groups=c)


def _grid(h: int, w: int, src_of_dst: torch.Tensor, offset_src: torch.Tensor, offset_dst: torch.Tensor) -> torch.Tensor:
    """Sampling grid (1, H, W, 2) for src = offset_src + M (dst - offset_dst) in pixel coordinates."""
    ys, xs = torch.meshgrid(torch.arange(h, dtype=torch.float32), torch.arange(w, dtype=torch.float32), indexing="ij")
    d = torch.stack([xs, ys], -1) - offset_dst
    src = d @ src_of_dst.T + offset_src
    return torch.stack([(2 * src[..., 0] + 1) / w - 1, (2 * src[..., 1] + 1) / h - 1], -1)[None]


def first_frame_augment(
    image: torch.Tensor, mask: torch.Tensor, num_aug: int = 5, seed: int = 0
) -> tuple[torch.Tensor, torch.Tensor]:
    """Augmented copies of the first frame and its target mask.

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
    fg = mask > 0.5
    if not fg.any():
        raise InputError("the first-frame target mask is empty")
    if num_aug < 1:
        raise InputError(f"num_aug must be >= 1, got {num_aug}")
    h, w = mask.shape
    dev, dt = image.device, image.dtype
    mask = mask.to(dt)
    gen = torch.Generator().manual_seed(seed)
    images, masks = [image], [mask]
    if num_aug == 1:
        return image[None], mask[None]
    background = inpaint_target(image, mask)
    ys, xs = torch.nonzero(fg, as_tuple=True)
    centre = torch.stack([xs.float().mean(), ys.float().mean()]).to(dev)
    extent = torch.stack([(xs.max() - xs.min() + 1).float(), (ys.max() - ys.min() + 1).float()]).to(dev)
    combos = list(itertools.product(ROTATIONS, SCALES))
    order = torch.randperm(len(combos), generator=gen).tolist()
    cells = [((i + 0.5) / 3, (j + 0.5) / 3) for i in range(3) for j in range(3)]
    cell_order = torch.randperm(len(cells), generator=gen).tolist()
    rgba = torch.cat([image * mask, mask[None]], 0)[None]

    def pick(options: tuple) -> float:
        return options[int(torch.randint(len(options), (), generator=gen))]

    for i in range(num_aug - 1):
        rot, scale = combos[order[i % len(combos)]]
        scale = min(scale, 0.9 * w / float(extent[0]), 0.9 * h / float(extent[1]))
        flip = -1.0 if float(torch.rand((), generator=gen)) < FLIP_P else 1.0
        skew = SKEW * (1 if float(torch.rand((), generator=gen)) < 0.5 else -1)
        skew = skew if float(torch.rand((), generator=gen)) < SKEW_P else 0.0
        a = math.radians(rot)
        fwd = torch.tensor([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]) @ torch.tensor(
            [[1.0, skew], [0.0, 1.0]]) @ torch.diag(torch.tensor([scale * flip, scale]))
        cx, cy = cells[cell_order[i % len(cells)]]
        half = fwd.abs().to(dev) @ (extent / 2)  # half size of the transformed bounding box
        dst = torch.stack([
            torch.tensor(cx * w).clamp(float(half[0]), max(float(half[0]), w - float(half[0]))),
            torch.tensor(cy * h).clamp(float(half[1]), max(float(half[1]), h - float(half[1]))),
        ]).to(dev)
        grid = _grid(h, w, torch.linalg.inv(fwd).to(dev), centre, dst).to(dt)
        target = F.grid_sample(rgba, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
        target = _motion_blur(target, int(pick(MOTION_BLUR_SIZES)), pick(MOTION_BLUR_ANGLES))
        bg_scale = pick(BG_SCALES)
        centre_img = torch.tensor([(w - 1) / 2, (h - 1) / 2], device=dev)
        bg_grid = _grid(h, w, torch.eye(2, device=dev) / bg_scale, centre_img, centre_img).to(dt)
        bg = F.grid_sample(background[None], bg_grid, mode="bilinear", padding_mode="reflection", align_corners=False)
        bg = _gaussian_blur(bg, pick(BG_BLURS))
        alpha = target[:, 3:4].clamp(0, 1)
        images.append((bg * (1 - alpha) + target[:, :3]).clamp(0, 1)[0])
        masks.append(alpha[0, 0])
    return torch.stack(images), torch.stack(masks)


class FirstFrameAugment(nn.Module):
    """Module form of ``first_frame_augment`` with a fixed number of samples and seed."""

    def __init__(self, num_aug: int = 5, seed: int = 0) -> None:
        super().__init__()
        self.num_aug = num_aug
        self.seed = seed

    def forward(self, image: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(3, H, W), (H, W) -> images (K, 3, H, W), masks (K, H, W)."""
        return first_frame_augment(image, mask, self.num_aug, self.seed)
