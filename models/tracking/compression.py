"""Block-transform compression seen in a decoded frame: the strength of the 8 px block grid that JPEG (and the
intra frames of block-based video codecs) leave behind.

A codec that quantises each 8 x 8 block on its own makes the blocks' borders step: the mean absolute difference
between neighbouring pixels across a block border exceeds the one inside the blocks. The ratio of the two, per
axis, is about 1 for a frame that never went through such a codec or whose grid was lost in a resize (0.96-1.28 on
the DAVIS frames, stored as JPEG at a high quality), 1.2-2.4 at JPEG qualities of 37-60, 1.8-4 at 14-26 and 6-26
at quality 3, where the blocks have become nearly flat (measured on the point-tracking benchmark's frames). The
frame's grid is assumed to start at pixel 0, as it does in a decoded image.

The same steps give the size of the compression error (:func:`compression_error_variance`): each block carries an
error of its own, so a step across a border adds the difference of two blocks' errors to the scene's step.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor

from core.errors import InputError

BLOCK = 8  # px: the block of JPEG and of the intra frames of block-based video codecs
# block-grid ratios over which compression_error_variance fades in: frames stored at a high quality read up to
# about 1.28 (the DAVIS frames), and their small error is no reason to regularise; JPEG at quality 37-60 reads 1.2-2.4
GRID_RAMP = (1.25, 1.5)


def _steps(image: Tensor) -> tuple[Tensor, Tensor]:
    """Mean absolute difference of neighbouring pixels of ``(B, 1, H, W)`` images, per pixel gap: between columns
    ``(B, W - 1)`` and between rows ``(B, H - 1)``."""
    columns = (image[..., 1:] - image[..., :-1]).abs().mean(-2)[:, 0]
    rows = (image[..., 1:, :] - image[..., :-1, :]).abs().mean(-1)[:, 0]
    return columns, rows


def _check(image: Tensor, block: int, name: str) -> None:
    if image.dim() != 4 or image.shape[1] != 1:
        raise InputError(f"{name} expects (B, 1, H, W) gray images, got shape {tuple(image.shape)}")
    if block < 2 or min(image.shape[-2:]) < 2 * block:
        raise InputError(f"{name} needs a block of at least 2 px and images of at least 2 blocks a side, "
                         f"got block {block} and shape {tuple(image.shape)}")


def _border_and_inside(steps: Tensor, block: int) -> tuple[Tensor, Tensor]:
    """Mean of ``steps`` ``(B, N - 1)`` at the block borders (between pixels ``block k - 1`` and ``block k``) and
    elsewhere, each ``(B,)``."""
    border = steps[:, block - 1 :: block]
    inside = (steps.sum(-1) - border.sum(-1)) / (steps.shape[-1] - border.shape[-1])
    return border.mean(-1), inside


def block_grid(image: Tensor, block: int = BLOCK, name: str = "block_grid") -> tuple[Tensor, Tensor]:
    """:func:`block_grid_ratio` and :func:`compression_error_variance` of ``(B, 1, H, W)`` images from one pass
    over their pixel steps, each ``(B,)`` (``name``: the function named in an input error)."""
    _check(image, block, name)
    ratios, variance = [], 0
    for steps in _steps(image):
        border, inside = _border_and_inside(steps, block)
        ratios.append((border + 1e-6) / (inside + 1e-6))  # 1 where no step is larger than a rounding error
        variance = variance + math.pi / 8 * (border.square() - inside.square()).clamp_min(0)  # mean of 2 axes
    ratio = (ratios[0] + ratios[1]) / 2
    low, high = GRID_RAMP
    return ratio, variance * ((ratio - low) / (high - low)).clamp(0, 1)


def block_grid_ratio(image: Tensor, block: int = BLOCK) -> Tensor:
    """Strength of a ``block`` px compression grid in gray images.

    Args:
        image: ``(B, 1, H, W)`` gray values (any scale), at least ``2 block`` px on each side.
        block: the codec's block size in px.
    Returns:
        ``(B,)`` the mean over both axes of (mean absolute step across the block borders) / (mean absolute step
        between the other neighbouring pixels): about 1 without compression, larger with.
    """
    return block_grid(image, block, "block_grid_ratio")[0]


def compression_error_variance(image: Tensor, block: int = BLOCK) -> Tensor:
    """Variance of the compression error of block-coded images (gray levels^2), from the steps at the block
    borders.

    A border step is the scene's step plus the difference of two neighbouring blocks' errors, so with errors of
    variance ``v`` (independent from block to block and of the scene) and Gaussian steps, the mean absolute border
    step ``b`` and the mean absolute step elsewhere ``a`` give ``2 v = pi / 2 (b^2 - a^2)``, averaged over both
    axes. Without the fade below it reads a std of 4.4, 7.3 and 9.9 gray levels against a true 3.8, 7.1 and 11.7 on
    an alley_1 frame at JPEG qualities 60, 15 and 5. It fades in with the block-grid ratio
    (:func:`block_grid_ratio`) over ``GRID_RAMP``: a frame stored at a high quality reads a grid of chance
    strength, and its error is small.

    Args:
        image: ``(B, 1, H, W)`` gray values, at least ``2 block`` px on each side.
    Returns:
        ``(B,)`` variance; 0 for a frame without a grid.
    """
    return block_grid(image, block, "compression_error_variance")[1]


class BlockGridRatio(torch.nn.Module):
    """Module form of :func:`block_grid_ratio`: ``(B, 1, H, W)`` -> ``(B,)``."""

    def __init__(self, block: int = BLOCK) -> None:
        super().__init__()
        self.block = block

    def forward(self, image: Tensor) -> Tensor:
        return block_grid_ratio(image, self.block)
