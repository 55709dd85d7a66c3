"""Segmentation losses for training the FRTM, LWL and DAVOS decoders.

FRTM trains with plain binary cross-entropy (paper D, thesis ch. 5.3). With small objects (a few percent of the
pixels) and a decoder trained from scratch, plain BCE first settles on "all background"; the options below
counter that: a positive-class weight on the BCE and a soft-IoU (Jaccard) term, whose gradient does not
shrink with the foreground fraction. A boundary weight raises the BCE on the pixels near the mask's contour,
the few pixels the boundary measure F of the DAVIS protocol is about and that a coarse target-model score
alone gets wrong. LWL and DAVOS (thesis ch. 6) train with the Lovasz hinge, a convex surrogate of the IoU; a
mask restricts any of them to some pixels (DAVOS's soft loss masking of the distractor channel).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from core.errors import InputError

LOSSES = ("bce", "bce_iou", "bce_lovasz", "lovasz")


def soft_iou_loss(
    logits: torch.Tensor, target: torch.Tensor, eps: float = 1.0, mask: torch.Tensor | None = None
) -> torch.Tensor:
    """Mean over images of ``1 - (sum p t + eps) / (sum (p + t - p t) + eps)`` with p = sigmoid(logits).

    Args:
        logits: (N, H, W); target: (N, H, W) in [0, 1]. ``eps`` smooths empty masks (loss 0 when both are empty).
        mask: (N, H, W) bool, the pixels that count (None: all).
    """
    p = torch.sigmoid(logits).flatten(1)
    t = target.flatten(1)
    if mask is not None:
        keep = mask.flatten(1).to(p.dtype)
        p, t = p * keep, t * keep
    inter = (p * t).sum(1)
    union = (p + t - p * t).sum(1)
    return (1 - (inter + eps) / (union + eps)).mean()


def lovasz_hinge(logits: torch.Tensor, target: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
    """Lovasz hinge (Berman et al., CVPR 2018; the LWL/DAVOS decoder loss): the Lovasz extension of the Jaccard
    loss |M| / |G u M| (M the mispredicted pixels, G the foreground) evaluated at the hinge errors
    max(0, 1 - logit * sign), per image, averaged over images.

    Args:
        logits: (N, H, W); target: (N, H, W), foreground where > 0.5.
        mask: (N, H, W) bool, the pixels that count (None: all); an image without any counts 0.
    """
    x = logits.flatten(1)
    fg = (target > 0.5).flatten(1)
    signs = fg.to(x.dtype) * 2 - 1
    errors = 1 - x * signs
    if mask is not None:  # left-out pixels: correct background beyond the margin, ranked after every hinge error
        keep = mask.flatten(1).bool()
        errors = torch.where(keep, errors, torch.full_like(errors, -1.0))
        fg = fg & keep
    errors, order = torch.sort(errors, dim=1, descending=True)
    fg_sorted = torch.gather(fg.to(x.dtype), 1, order)
    n_fg = fg_sorted.sum(1, keepdim=True)
    inter = n_fg - fg_sorted.cumsum(1)
    union = n_fg + (1 - fg_sorted).cumsum(1)
    jaccard = 1 - inter / union
    grad = torch.cat([jaccard[:, :1], jaccard[:, 1:] - jaccard[:, :-1]], 1)
    return (F.relu(errors) * grad).sum(1).mean()


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
    mask: torch.Tensor | None = None,
) -> torch.Tensor:
    """Decoder loss over (N, H, W) logits and targets in [0, 1].

    Args:
        kind: ``bce`` (mean binary cross-entropy, foreground pixels weighted by ``pos_weight``), ``bce_iou``
            (that plus ``iou_weight`` times ``soft_iou_loss``), ``bce_lovasz`` (the BCE plus ``iou_weight`` times
            ``lovasz_hinge``) or ``lovasz`` (``lovasz_hinge`` alone; the weights do not apply).
        boundary_weight: extra BCE weight of the pixels in :func:`boundary_band` (``boundary_radius`` px); the
            per-pixel weight is ``1 + boundary_weight`` there and 1 elsewhere.
        mask: (N, H, W) bool, the pixels that count (None: all); the BCE is then the mean over them.
    """
    if kind not in LOSSES:
        raise InputError(f"segmentation loss {kind!r} is not one of {', '.join(LOSSES)}")
    if mask is not None and mask.shape != logits.shape:
        raise InputError(f"loss mask {tuple(mask.shape)} does not match the logits {tuple(logits.shape)}")
    if kind == "lovasz":
        return lovasz_hinge(logits, target, mask)
    weight = None if pos_weight == 1.0 else logits.new_tensor(float(pos_weight))
    pixel_weight = None
    if boundary_weight:
        pixel_weight = 1 + boundary_weight * boundary_band(target, boundary_radius).to(logits.dtype)
    if mask is None:
        loss = F.binary_cross_entropy_with_logits(logits, target, weight=pixel_weight, pos_weight=weight)
    else:
        keep = mask.to(logits.dtype)
        bce = F.binary_cross_entropy_with_logits(logits, target, weight=pixel_weight, pos_weight=weight,
                                                 reduction="none")
        loss = (bce * keep).sum() / keep.sum().clamp_min(1)
    if kind == "bce_iou":
        loss = loss + iou_weight * soft_iou_loss(logits, target, mask=mask)
    elif kind == "bce_lovasz":
        loss = loss + iou_weight * lovasz_hinge(logits, target, mask)
    return loss
