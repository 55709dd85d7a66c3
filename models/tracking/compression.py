"""Block-transform compression seen in a decoded frame: the strength of the 8 px block grid that JPEG (and the
intra frames of block-based video codecs) leave behind.

A codec that quantises each 8 x 8 block on its own makes the blocks' borders step: the mean absolute difference
between neighbouring pixels across a block border exceeds the one inside the blocks. The ratio of the two, per
axis, is about 1 for a frame that never went through such a codec or whose grid was lost in a resize (0.96-1.28 on
the DAVIS frames, stored as JPEG at a high quality), 1.2-2.4 at JPEG qualities of 37-60, 1.8-4 at 14-26 and 6-26
at quality 3, where the blocks have become nearly flat (measured on the point-tracking benchmark's frames). The
frame's grid is assumed to start at pixel 0, as it does in a decoded image.
"""

from __future__ import annotations

import torch
from torch import Tensor

from core.errors import InputError

BLOCK = 8  # px: the block of JPEG and of the intra frames of block-based video codecs


def _axis_ratio(steps: Tensor, block: int) -> Tensor:
    """Mean of ``steps`` ``(B, N - 1)`` at the block borders (between pixels ``block k - 1`` and ``block k``) over
    their mean elsewhere, ``(B,)``; 1 where no step is larger than a rounding error."""
    border = steps[:, block - 1 :: block]
    inside = (steps.sum(-1) - border.sum(-1)) / (steps.shape[-1] - border.shape[-1])
    return (border.mean(-1) + 1e-6) / (inside + 1e-6)


def block_grid_ratio(image: Tensor, block: int = BLOCK) -> Tensor:
    """Strength of a ``block`` px compression grid in gray images.

    Args:
        image: ``(B, 1, H, W)`` gray values (any scale), at least ``2 block`` px on each side.
        block: the codec's block size in px.
    Returns:
        ``(B,)`` the mean over both axes of (mean absolute step across the block borders) / (mean absolute step
        between the other neighbouring pixels): about 1 without compression, larger with.
    """
    if image.dim() != 4 or image.shape[1] != 1:
        raise InputError(f"block_grid_ratio expects (B, 1, H, W) gray images, got shape {tuple(image.shape)}")
    if block < 2 or min(image.shape[-2:]) < 2 * block:
        raise InputError(f"block_grid_ratio needs a block of at least 2 px and images of at least 2 blocks a side, "
                         f"got block {block} and shape {tuple(image.shape)}")
    columns = (image[..., 1:] - image[..., :-1]).abs().mean(-2)[:, 0]  # (B, W - 1)
    rows = (image[..., 1:, :] - image[..., :-1, :]).abs().mean(-1)[:, 0]  # (B, H - 1)
    return (_axis_ratio(columns, block) + _axis_ratio(rows, block)) / 2


class BlockGridRatio(torch.nn.Module):
    """Module form of :func:`block_grid_ratio`: ``(B, 1, H, W)`` -> ``(B,)``."""

    def __init__(self, block: int = BLOCK) -> None:
        super().__init__()
        self.block = block

    def forward(self, image: Tensor) -> Tensor:
        return block_grid_ratio(image, self.block)
