"""Merging per-object predictions (thesis eq. 5.3, soft aggregation of RGMP).

Each object's decoder logit gives p_i = sigmoid(logit_i), clamped to [1e-7, 1 - 1e-7]; the background gets
p_0 = prod_j (1 - p_j). The merged probabilities are the odds p/(1 - p) normalised over {0, 1..N} (eq. 5.3 with
the background as class 0, i.e. a softmax of the log-odds, as RGMP, LWL and DAVOS do). With one object this
is the 0.5 threshold. Each pixel takes the most probable label; an object's memory label is its merged
probability where it won ("winner takes all") and 0 elsewhere.
"""

from __future__ import annotations

import torch

from core.errors import InputError

EPS = 1e-7


def soft_aggregate(logits: torch.Tensor) -> torch.Tensor:
    """Merged probabilities.

    Args:
        logits: (N, ..., H, W) per-object logits (N >= 1).

    Returns:
        (N + 1, ..., H, W) probabilities summing to 1 over dim 0; index 0 is the background.
    """
    if logits.ndim < 3 or logits.shape[0] < 1:
        raise InputError(f"soft aggregation needs (N, ..., H, W) logits with N >= 1, got {tuple(logits.shape)}")
    p = torch.sigmoid(logits).clamp(EPS, 1 - EPS)
    p0 = torch.prod(1 - p, dim=0, keepdim=True).clamp(EPS, 1 - EPS)
    probs = torch.cat([p0, p], 0)
    return torch.softmax(torch.log(probs) - torch.log1p(-probs), dim=0)


def merge_objects(logits: torch.Tensor, ids: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Label map and per-object soft memory labels from per-object logits.

    Args:
        logits: (N, H, W) per-object decoder logits.
        ids: (N,) object ids (default 1..N).

    Returns:
        labels (H, W) int64 with values in {0} + ids; soft (N, H, W) = merged probability of object i where it won.
    """
    probs = soft_aggregate(logits)
    win = probs.argmax(0)
    n = logits.shape[0]
    ids = torch.arange(1, n + 1, device=logits.device) if ids is None else ids.to(logits.device)
    table = torch.cat([ids.new_zeros(1), ids])
    labels = table[win]
    won = win[None] == torch.arange(1, n + 1, device=logits.device)[:, None, None]
    return labels, probs[1:] * won
