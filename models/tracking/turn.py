"""How far a frame's tracked points turn: the rotation and scale change of the least-squares similarity that takes
their positions in one frame to the next, weighed by the share of their motion it explains.

A camera that rolls or zooms turns every point's patch alike, so the patches' appearance drifts away from what a
filter's sample memory holds; points on a non-rigid scene, or seen with parallax, move differently from one
another, and a similarity fitted to them explains little of their motion about the mean step. The product of the
two tells the first case from the second (:class:`~models.tracking.PointTracker` learns faster in the first).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from core.errors import InputError

_TINY = 1e-12
#: The tracked points a frame's turn needs (:class:`~models.tracking.PointTracker` and its exported ``turn`` graph): a
#: few points say little about the camera.
TURN_POINTS = 10


def _check(start: Tensor, moved: Tensor, weight: Tensor) -> None:
    if start.shape != moved.shape or start.dim() < 2 or start.shape[-1] != 2:
        raise InputError(f"start and moved must be (..., P, 2) of one shape, got {tuple(start.shape)} and "
                         f"{tuple(moved.shape)}")
    if weight.shape != start.shape[:-1]:
        raise InputError(f"weight must be (..., P) = {tuple(start.shape[:-1])}, got {tuple(weight.shape)}")


def _similarity(start: Tensor, moved: Tensor, weight: Tensor) -> tuple[Tensor, ...]:
    """The weighted least-squares similarity about the weighted centroids: ``a``, ``b`` ``(...)`` (``s R = [[a,
    -b], [b, a]]``), the centroids ``(..., 1, 2)``, the centred points ``p``, ``q`` and the spread ``sum w |p|^2``."""
    w = weight[..., None]
    mass = w.sum(-2, keepdim=True).clamp_min(_TINY)
    centre, target = (w * start).sum(-2, keepdim=True) / mass, (w * moved).sum(-2, keepdim=True) / mass
    p, q = start - centre, moved - target
    spread = (w * p.square()).sum((-2, -1))
    safe = spread.clamp_min(_TINY)
    a = (w * p * q).sum((-2, -1)) / safe
    b = (weight * (p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0])).sum(-1) / safe
    return a, b, centre, target, p, q, spread


def fit_similarity(start: Tensor, moved: Tensor, weight: Tensor) -> Tensor:
    """The weighted least-squares similarity ``(..., 2, 3)`` (``x' = A[:, :2] x + A[:, 2]``, the layout of
    ``cv2.warpAffine``) taking ``start`` to ``moved`` ``(..., P, 2)`` (x, y px), points weighted by ``weight``
    ``(..., P)``."""
    _check(start, moved, weight)
    a, b, centre, target, *_ = _similarity(start, moved, weight)
    linear = torch.stack([torch.stack([a, -b], -1), torch.stack([b, a], -1)], -2)  # (..., 2, 2)
    shift = target[..., 0, :] - (linear @ centre[..., 0, :, None])[..., 0]
    return torch.cat([linear, shift[..., None]], -1)


def camera_turn(start: Tensor, moved: Tensor, weight: Tensor, min_points: int = 2) -> Tensor:
    """The turn of points moving from ``start`` to ``moved`` ``(..., P, 2)`` (x, y px), each weighted by
    ``weight`` ``(..., P)`` (0 leaves a point out): ``share * sqrt(angle^2 + log_scale^2)`` ``(...)``; 0 where
    fewer than ``min_points`` points weigh in.

    ``angle`` (rad) and ``log_scale`` are those of the weighted least-squares similarity ``x' = s R(angle) x + t``
    (:func:`fit_similarity`; closed form about the weighted centroids: ``a = sum w p.q / sum w |p|^2``,
    ``b = sum w (p x q) / sum w |p|^2`` with ``s R = [[a, -b], [b, a]]``), and ``share`` (0-1) is the part of the
    steps' spread about their mean step (``sum w |q - p|^2``) that the fit removes. 0 where the points do not
    spread or do not move about their mean step (a pure translation, or fewer than two weighted points)."""
    _check(start, moved, weight)
    a, b, _, _, p, q, spread = _similarity(start, moved, weight)
    w = weight[..., None]
    steps = (w * (q - p).square()).sum((-2, -1))
    # what the fit leaves: sum w |q|^2 - (a^2 + b^2) sum w |p|^2 (the least-squares identity)
    left = ((w * q.square()).sum((-2, -1)) - (a.square() + b.square()) * spread).clamp_min(0)
    share = ((steps - left) / steps.clamp_min(_TINY)).clamp(0, 1)
    log_scale = 0.5 * torch.log((a.square() + b.square()).clamp_min(_TINY))  # hypot does not export
    turn = share * torch.sqrt(torch.atan2(b, a).square() + log_scale.square())
    moving = (spread > _TINY) & (steps > _TINY) & ((weight > 0).sum(-1) >= min_points)
    return torch.where(moving, turn, torch.zeros_like(turn))


class CameraTurn(nn.Module):
    """:func:`camera_turn` as a module (``min_points`` as there)."""

    def __init__(self, min_points: int = 2) -> None:
        super().__init__()
        self.min_points = min_points

    def forward(self, start: Tensor, moved: Tensor, weight: Tensor) -> Tensor:
        return camera_turn(start, moved, weight, self.min_points)
