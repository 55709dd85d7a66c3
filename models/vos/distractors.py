"""Distractor maps of DAVOS (thesis ch. 6.2, eqs. 6.1-6.5; paper E).

The distractor of target i is the union of all other targets. After each frame it is regenerated from the new
predictions: with p_j the target probability of object j (its decoder's target logit through a sigmoid, or the
0/1 ground truth for a new object) and L the merged label map (soft aggregation, 0 = background),

    p_max = max_j p_j,   p_min = min_j p_j                                      (6.1, 6.2)
    1_f = [L > 0],       1_d,i = 1_f [L != i]                                   (6.3, 6.4)
    p_d,i = 1_d,i p_max + (1 - 1_f) p_min                                        (6.5)

so the most certain target or background prediction wins in every pixel, and nothing is renormalised: an
uncertain pixel stays uncertain. With ``winner_takes_all=False`` (the ablation) the distractor of i is the soft
union max_(j != i) p_j of the other objects' probabilities instead (0 for a single object).
"""

from __future__ import annotations

import torch

from core.errors import InputError


def regenerate_distractors(
    probs: torch.Tensor, labels: torch.Tensor, ids: torch.Tensor, winner_takes_all: bool = True
) -> torch.Tensor:
    """Distractor probability maps of every object.

    Args:
        probs: (N, H, W) target probabilities p_j in [0, 1] (N >= 1).
        labels: (H, W) merged labels L (0 = background, else an id of ``ids``).
        ids: (N,) object ids in the order of ``probs``.
        winner_takes_all: eqs. 6.1-6.5 (True) or the soft union of the others (False).

    Returns:
        (N, H, W) distractor probabilities p_d,i.
    """
    if probs.ndim != 3 or probs.shape[0] < 1 or labels.shape != probs.shape[1:] or ids.shape != probs.shape[:1]:
        raise InputError(f"distractor regeneration needs probabilities (N, H, W), labels (H, W) and ids (N,); got "
                         f"{tuple(probs.shape)}, {tuple(labels.shape)}, {tuple(ids.shape)}")
    if not winner_takes_all:
        n = probs.shape[0]
        if n == 1:
            return torch.zeros_like(probs)
        others = ~torch.eye(n, dtype=torch.bool, device=probs.device)
        stacked = torch.where(others[:, :, None, None], probs[None], torch.zeros_like(probs)[None])
        return stacked.amax(1)
    p_max = probs.amax(0, keepdim=True)
    p_min = probs.amin(0, keepdim=True)
    fg = (labels > 0)[None].to(probs.dtype)
    distractor = fg * (labels[None] != ids.to(labels.device)[:, None, None]).to(probs.dtype)
    return distractor * p_max + (1 - fg) * p_min


def first_frame_distractors(labels: torch.Tensor, ids: torch.Tensor) -> torch.Tensor:
    """Distractors of new objects from a given label map: every other labelled object (void 255 excluded).

    Args:
        labels: (H, W) label map; ids: (N,) the new objects' ids.

    Returns:
        (N, H, W) 0/1 float maps.
    """
    labelled = (labels > 0) & (labels != 255)
    return (labelled[None] & (labels[None] != ids.to(labels.device)[:, None, None])).float()
