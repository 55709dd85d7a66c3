"""The DAVOS training loss (thesis ch. 6.2; paper E): a target and a distractor term with soft loss masking.

The distractor ground truth of a target is every annotated pixel of the other objects. A sample with such
annotations supervises the distractor output everywhere. A sample without any (a single annotated object)
says nothing about distractors off the target, so there the distractor output is only required to be 0 under
the target and is free elsewhere, which lets the decoder mark look-alikes nobody annotated (ch. 6.2, fig. 6.3):

    enable = target (1 - d) + d,            d = 1 if the sample has annotated distractors, else 0
    L = L_t + clamp(n_t / n_d, 0, 1) L_d    n_t, n_d: target and distractor pixel counts (n_d = 0 gives 1)

The "hard loss" ablation (``soft=False``) supervises the distractor output everywhere in every sample.
"""

from __future__ import annotations

import torch

from core.errors import InputError
from models.vos.losses import segmentation_loss


def distractor_loss_mask(target: torch.Tensor, has_distractors: torch.Tensor) -> torch.Tensor:
    """Pixels where the distractor output is supervised: (N, H, W) target in [0, 1], (N,) bool -> (N, H, W) bool."""
    if target.ndim != 3 or has_distractors.shape != target.shape[:1]:
        raise InputError(f"distractor loss mask needs targets (N, H, W) and flags (N,), got {tuple(target.shape)} "
                         f"and {tuple(has_distractors.shape)}")
    return (target > 0.5) | has_distractors.bool()[:, None, None]


def distractor_term_weight(target: torch.Tensor, distractor: torch.Tensor) -> torch.Tensor:
    """clamp(n_t / n_d, 0, 1) per sample, 1 where there are no distractor pixels: (N, H, W) x2 -> (N,)."""
    n_t = (target > 0.5).flatten(1).sum(1).to(target.dtype)
    n_d = (distractor > 0.5).flatten(1).sum(1).to(target.dtype)
    return torch.where(n_d > 0, n_t / n_d.clamp_min(1), torch.ones_like(n_t)).clamp(0, 1)


def davos_loss(
    logits: torch.Tensor,
    target: torch.Tensor,
    distractor: torch.Tensor | None = None,
    has_distractors: torch.Tensor | None = None,
    kind: str = "lovasz",
    soft: bool = True,
    **loss_args,
) -> torch.Tensor:
    """Loss of decoder logits (N, O, H, W): O = 1 (LWL, target only) or 2 (DAVOS, target and distractor).

    Args:
        target, distractor: (N, H, W) ground truth in [0, 1]; distractor and has_distractors (N,) are needed when
            O = 2.
        kind, loss_args: ``models.vos.losses.segmentation_loss`` options of both terms (the paper: Lovasz).
        soft: soft loss masking of the distractor term (True) or the hard loss (False).
    """
    if logits.ndim != 4 or logits.shape[1] not in (1, 2) or logits.shape[-2:] != target.shape[-2:]:
        raise InputError(f"DAVOS loss needs logits (N, 1 or 2, H, W) matching targets (N, H, W), got "
                         f"{tuple(logits.shape)} and {tuple(target.shape)}")
    loss_t = segmentation_loss(logits[:, 0], target, kind, **loss_args)
    if logits.shape[1] == 1:
        return loss_t
    if distractor is None or has_distractors is None:
        raise InputError("a distractor channel needs distractor ground truth and has_distractors flags")
    mask = distractor_loss_mask(target, has_distractors) if soft else None
    weight = distractor_term_weight(target, distractor)
    per_sample = torch.stack([segmentation_loss(logits[i : i + 1, 1], distractor[i : i + 1], kind, **loss_args,
                                                mask=None if mask is None else mask[i : i + 1])
                              for i in range(logits.shape[0])])
    return loss_t + (weight * per_sample).mean()
