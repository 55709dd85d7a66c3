"""FRTM sample memory (thesis ch. 5.3; paper D): fixed-capacity slots of projected features, soft labels and pixel
weights with decaying sample weights.

The initial (augmented) samples get weights 1 each and the original frame ``first_weight`` (2), normalised.
Each insertion replaces the slot with the smallest weight (empty slots weigh 0, so they fill first); the first
insertion divides the old weights by (1 - lr) and gives the new sample lr, later ones give the new sample the
previous newest weight / (1 - lr); weights are then renormalised. With lr = 0.1 a sample's weight decays by 0.9
per insertion relative to the newest. All operations are fixed-shape tensor ops (``torch.where`` selects per
problem), so ``memory_insert`` exports to ONNX with the memory as graph inputs and outputs.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from core.errors import InputError


class Memory(NamedTuple):
    """Memory of B problems with N slots.

    features: (B, N, C, h, w) projected features; labels, pixel_weights: (B, N, H, W);
    weights: (B, N) sample weights (0 = empty); newest: (B,) int64 slot of the last insertion, -1 before any.
    """

    features: torch.Tensor
    labels: torch.Tensor
    pixel_weights: torch.Tensor
    weights: torch.Tensor
    newest: torch.Tensor


def check_keep_first(share: float, memory_size: int) -> float:
    """``share`` (``memory_insert``'s ``keep_first``) when it is a number in [0, 1) that a memory of ``memory_size``
    slots can hold (a positive share needs a second slot), else an ``InputError`` naming the tracker setting."""
    if isinstance(share, bool) or not isinstance(share, int | float) or not 0 <= share < 1:
        raise InputError(f"tracker setting keep_first must lie in [0, 1), got {share!r}")
    if share > 0 and memory_size < 2:
        raise InputError("tracker setting keep_first needs memory_size >= 2")
    return float(share)


def memory_init(
    features: torch.Tensor,
    labels: torch.Tensor,
    pixel_weights: torch.Tensor,
    capacity: int = 80,
    first_weight: float = 2.0,
) -> Memory:
    """Memory holding the K initial samples (sample 0 = the original frame) in its first K slots.

    Args:
        features: (B, K, C, h, w); labels, pixel_weights: (B, K, H, W).
        capacity: number of slots N >= K (FRTM 80 at inference, 20 in training).
        first_weight: relative weight of the original frame; the K - 1 augmented samples weigh 1.
    """
    b, k = features.shape[:2]
    if capacity < k:
        raise InputError(f"memory capacity {capacity} is smaller than the {k} initial samples")
    if labels.shape[:2] != (b, k) or pixel_weights.shape != labels.shape:
        raise InputError(f"memory labels/pixel weights {tuple(labels.shape)} do not match features {(b, k)}")
    pad = capacity - k

    def grow(t: torch.Tensor) -> torch.Tensor:
        return torch.cat([t, t.new_zeros(b, pad, *t.shape[2:])], 1)

    w = features.new_ones(b, k)
    w[:, 0] = first_weight
    w = grow(w / w.sum(1, keepdim=True))
    newest = torch.full((b,), -1, dtype=torch.int64, device=features.device)
    return Memory(grow(features), grow(labels), grow(pixel_weights), w, newest)


def memory_insert(
    memory: Memory,
    features: torch.Tensor,
    labels: torch.Tensor,
    pixel_weights: torch.Tensor,
    valid: torch.Tensor,
    lr: float = 0.1,
    keep_first: float = 0.0,
) -> Memory:
    """Insert one sample per problem where ``valid``.

    Args:
        memory: the current memory.
        features: (B, C, h, w); labels, pixel_weights: (B, H, W) (or any trailing shape matching the memory's).
        valid: (B,) bool; problems where it is False keep their memory unchanged.
        lr: learning rate of the weight decay (FRTM 0.1).
        keep_first: with a value > 0 (LWL: 0.25) slot 0, the first frame, is never replaced and keeps at least
            this share of the total weight (the other weights are scaled down to make room).
    """
    w = memory.weights
    n = w.shape[1]
    if keep_first > 0 and n < 2:
        raise InputError(f"keep_first needs a memory of at least 2 slots, got {n}")
    candidates = w
    if keep_first > 0:
        candidates = torch.cat([torch.full_like(w[:, :1], float("inf")), w[:, 1:]], 1)
    slot = torch.argmin(candidates, dim=1)  # first empty slot, else the lightest
    onehot = torch.arange(n, device=w.device)[None] == slot[:, None]
    prev = torch.gather(w, 1, memory.newest.clamp_min(0)[:, None])[:, 0]
    first = memory.newest < 0
    scaled = torch.where(first[:, None], w / (1 - lr), w)
    new_weight = torch.where(first, torch.full_like(prev, lr), prev / (1 - lr))
    w_new = torch.where(onehot, new_weight[:, None], scaled)
    w_new = w_new / w_new.sum(1, keepdim=True)
    if keep_first > 0:
        w_first = w_new[:, :1].clamp_min(keep_first)
        rest = w_new[:, 1:]
        rest = rest * (1 - w_first) / rest.sum(1, keepdim=True).clamp_min(1e-30)
        w_new = torch.cat([w_first, rest], 1)
    keep = ~valid
    put = onehot & valid[:, None]

    def place(old: torch.Tensor, new: torch.Tensor) -> torch.Tensor:
        mask = put.view(*put.shape, *([1] * (old.ndim - 2)))
        return torch.where(mask, new[:, None].to(old.dtype), old)

    return Memory(
        place(memory.features, features),
        place(memory.labels, labels),
        place(memory.pixel_weights, pixel_weights),
        torch.where(keep[:, None], w, w_new),
        torch.where(keep, memory.newest, slot),
    )
