"""Segmentation losses for training the FRTM decoder.

FRTM trains with plain binary cross-entropy (paper D, thesis ch. 5.3). With small objects (a few percent of the
pixels) and a decoder trained from scratch, plain BCE first settles on "all background"; the options below
counter that: a positive-class weight on the BCE and a soft-IoU (Jaccard) term, whose gradient does not
shrink with the foreground fraction. A boundary weight raises the BCE on the pixels near the mask's contour,
the few pixels the boundary measure F of the DAVIS protocol is about and that a coarse target-model score
alone gets wrong.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from core.errors import InputError

LOSSES = ("bce", "bce_iou")


def soft_iou_loss(logits: torch.Tensor, target: torch.Tensor, eps: float = 1.0) -> torch.Tensor:
    """Mean over images of ``1 - (sum p t + eps) / (sum (p + t - p t) + eps)`` with p = sigmoid(logits).

    Args:
        logits: (N, H, W); target: (N, H, W) in [0, 1]. ``eps`` smooths empty masks (loss 0 when both are empty).
    """
    p = torch.sigmoid(logits).flatten(1)
    t = target.flatten(1)
    inter = (p * t).sum(1)
    union = (p + t - p * t).sum(1)
    return (1 - (inter + eps) / (union + eps)).mean()


def boundary_band(target: torch.Tensor, radius: int) -> torch.Tensor:
    """Pixels within ``radius`` (chessboard distance) of a label change of ``target > 0.5``: (N, H, W) -> bool."""
    k = 2 * radius + 1
    fg = (target > 0.5).to(torch.float32)[:, None]
    grown = F.max_pool2d(fg, k, 1, radius)
    shrunk = -F.max_pool2d(-fg, k, 1, radius)
    return (grown > shrunk)[:, 0]


def segmentation_loss(
    logits: torch.Tensor,
    target: torch.Tensor,
    kind: str = "bce",
    pos_weight: float = 1.0,
    iou_weight: float = 1.0,
    boundary_weight: float = 0.0,
    boundary_radius: int = 2,
) -> torch.Tensor:
    """Decoder loss over (N, H, W) logits and targets in [0, 1].

    Args:
        kind: ``bce`` (mean binary cross-entropy, foreground pixels weighted by ``pos_weight``) or ``bce_iou``
            (that plus ``iou_weight`` times ``soft_iou_loss``).
        boundary_weight: extra BCE weight of the pixels in :func:`boundary_band` (``boundary_radius`` px); the
            per-pixel weight is ``1 + boundary_weight`` there and 1 elsewhere.
    """
    if kind not in LOSSES:
        raise InputError(f"segmentation loss {kind!r} is not one of {', '.join(LOSSES)}")
    weight = None if pos_weight == 1.0 else logits.new_tensor(float(pos_weight))
    pixel_weight = None
    if boundary_weight:
        pixel_weight = 1 + boundary_weight * boundary_band(target, boundary_radius).to(logits.dtype)
    loss = F.binary_cross_entropy_with_logits(logits, target, weight=pixel_weight, pos_weight=weight)
    if kind == "bce_iou":
        loss = loss + iou_weight * soft_iou_loss(logits, target)
    return loss
