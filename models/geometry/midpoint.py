"""Midpoint triangulation for N >= 2 views (thesis 2.2), the closed-form start of the dogleg solver."""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

from models.geometry.projection import (
    Triangulation,
    check_cameras_and_points,
    finite_inputs,
    in_front_of_cameras,
    reprojection_cost,
)
from models.geometry.small_linalg import (
    SYM3_INDEX,
    adjugate3,
    matvec3,
    solve_sym3,
    sym3_smallest_eigenvalue_estimate,
)
from models.geometry.views import Views, dot3, split_views


def _rays(views: Views) -> tuple[tuple[Tensor, ...], tuple[Tensor, ...]]:
    """Centres ``C = -M^-1 p4`` (N, B|1) and unit directions ``M^-1 x~`` (N, B) (positive depth side) of all rays."""
    M = tuple(row[:3] for row in views.P)
    p4 = tuple(row[3] for row in views.P)
    adj, det = adjugate3(M)  # type: ignore[arg-type]
    centre = tuple(-c / det for c in matvec3(adj, p4))
    direction = tuple(c * torch.sign(det) for c in matvec3(adj, (views.x, views.y, torch.ones_like(views.x))))
    norm = torch.sqrt(dot3(direction, direction))
    return centre, tuple(v / norm for v in direction)


def midpoint_from_views(views: Views) -> tuple[tuple[Tensor, Tensor, Tensor], Tensor]:
    """Point nearest to all rays, ``(sum_i (I - d_i d_i^T))^-1 sum_i (I - d_i d_i^T) C_i``.

    Returns:
        X: three (B,) components of the points (non-finite for parallel rays); lam: (B,) estimate of the
        smallest eigenvalue of the normal matrix (``1 - cos(angle)`` for two rays), small for near-parallel rays.
    """
    C, d = _rays(views)
    dC = dot3(d, C)
    A = [((1.0 if r == s else 0.0) - d[r] * d[s]).sum(0) for r, s in SYM3_INDEX]
    b = [(C[r] - d[r] * dC).sum(0) for r in range(3)]
    X, det = solve_sym3(A, b)
    return X, sym3_smallest_eigenvalue_estimate(A, det)


def parallax_threshold(min_parallax: float) -> float:
    """Smallest-eigenvalue threshold equivalent to two rays ``min_parallax`` rad apart."""
    return 1.0 - math.cos(min_parallax)


def assemble_triangulation(
    P: Tensor, x: Tensor, X: Tensor, finite: Tensor, lam: Tensor, min_parallax: float
) -> Triangulation:
    """Cost and validity flags of triangulated points ``X`` (B, 3), non-finite ones replaced by the origin.

    ``finite`` (B,) flags finite inputs and ``lam`` (B,) is the ray-spread estimate of
    :func:`midpoint_from_views`; a point is valid when finite, not near-parallel and in front of every camera.
    """
    X = torch.where(torch.isfinite(X), X, torch.zeros_like(X))
    cost = reprojection_cost(P, X, x)
    valid = finite & (lam >= parallax_threshold(min_parallax)) & in_front_of_cameras(P, X) & torch.isfinite(cost)
    return Triangulation(X, cost, valid)


def triangulate_midpoint(P: Tensor, x: Tensor, min_parallax: float = 1e-3) -> Triangulation:
    """Point closest to all back-projected rays, in closed form (no iterations).

    Args:
        P: (B|1, N, 3, 4) cameras, N >= 2.
        x: (B, N, 2) observations in pixels.
        min_parallax: rays whose spread is below this angle (rad, the two-view angle equivalent) are flagged
            near-parallel and the point invalid.

    Returns:
        ``Triangulation`` with points (B, 3), cost (B,) in px^2 and valid (B,).
    """
    check_cameras_and_points(P, x)
    P, x, finite = finite_inputs(P, x)
    components, lam = midpoint_from_views(split_views(P, x))
    return assemble_triangulation(P, x, torch.stack(components, dim=-1), finite, lam, min_parallax)


class TriangulateMidpoint(nn.Module):
    """Module form of :func:`triangulate_midpoint`: (B|1, N, 3, 4), (B, N, 2) -> ``Triangulation``."""

    def __init__(self, min_parallax: float = 1e-3) -> None:
        super().__init__()
        self.min_parallax = min_parallax

    def forward(self, P: Tensor, x: Tensor) -> Triangulation:
        return triangulate_midpoint(P, x, self.min_parallax)
