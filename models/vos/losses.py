"""Segmentation losses for training the FRTM decoder.

FRTM trains with plain binary cross-entropy (REFERENCE.md 5.7). With small objects (a few percent of the
pixels) and a decoder trained from scratch, plain BCE first settles on "all background"; the options below
counter that: a positive-class weight on the BCE and a soft-IoU (Jaccard) term, whose gradient does not
shrink with the foreground fraction.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from data.errors import InputError

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


def segmentation_loss(
    logits: torch.Tensor, target: torch.Tensor, kind: str = "bce", pos_weight: float = 1.0, iou_weight: float = 1.0
) -> torch.Tensor:
    """Decoder loss over (N, H, W) logits and targets in [0, 1].

    Args:
        kind: ``bce`` (mean binary cross-entropy, foreground pixels weighted by ``pos_weight``) or ``bce_iou``
            (that plus ``iou_weight`` times ``soft_iou_loss``).
    """
    if kind not in LOSSES:
        raise InputError(f"segmentation loss {kind!r} is not one of {', '.join(LOSSES)}")
    weight = None if pos_weight == 1.0 else logits.new_tensor(float(pos_weight))
    loss = F.binary_cross_entropy_with_logits(logits, target, pos_weight=weight)
    if kind == "bce_iou":
        loss = loss + iou_weight * soft_iou_loss(logits, target)
    return loss
