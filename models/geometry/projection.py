"""Pinhole projection with 3x4 camera matrices, reprojection residuals and input checks.

Convention: a camera ``P = [M | p4]`` maps a homogeneous point ``X~`` to ``(u, v, w) = P X~``; the image point is
``(u / w, v / w)`` in pixels and the point is in front of the camera when ``w > 0``. Camera matrices with the
opposite sign (for example ``-K[R|t]``) describe the same projection but flip the cheirality test, so readers
normalise cameras to ``w > 0`` in front (see ``data/sfm``).
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

from core.checks import check_same_dtype, check_tensor
from core.errors import InputError


class Triangulation(NamedTuple):
    """Result of a batched triangulation.

    Attributes:
        points: (B, 3) triangulated points in world units.
        cost: (B,) sum of squared reprojection errors over the views used, in px^2.
        valid: (B,) True where inputs were finite, the point lies in front of every camera and the rays were
            not near-parallel.
    """

    points: Tensor
    cost: Tensor
    valid: Tensor


def check_cameras_and_points(P: Tensor, x: Tensor, min_views: int = 2) -> None:
    """Raise ``InputError`` naming the problem unless ``P`` (B|1, N, 3, 4) and ``x`` (B, N, 2) fit together."""
    check_tensor(P, "cameras P (B, N, 3, 4)", shape=(None, None, 3, 4), floating=True)
    check_tensor(x, "observations x (B, N, 2)", shape=(None, None, 2), floating=True)
    if P.shape[1] != x.shape[1]:
        raise InputError(f"cameras P have {P.shape[1]} views but observations x have {x.shape[1]}")
    if P.shape[0] not in (1, x.shape[0]):
        raise InputError(f"cameras P have batch size {P.shape[0]}, expected 1 or {x.shape[0]} (the points)")
    if x.shape[1] < min_views:
        raise InputError(f"triangulation needs at least {min_views} views per point, got {x.shape[1]}")
    check_same_dtype(("P", P), ("x", x))


def finite_inputs(P: Tensor, x: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Replace non-finite per-point inputs by harmless values so that the solvers never see NaN.

    Args:
        P: (B|1, N, 3, 4) cameras.
        x: (B, N, 2) observations in pixels.

    Returns:
        P and x with non-finite entries replaced, and a (B,) mask of points whose inputs were all finite.
    """
    finite = torch.isfinite(x).flatten(1).all(1) & torch.isfinite(P).flatten(1).all(1)
    x = torch.where(torch.isfinite(x), x, torch.zeros_like(x))
    canonical = torch.tensor([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1]], dtype=P.dtype, device=P.device)
    P = torch.where(torch.isfinite(P).flatten(2).all(2)[..., None, None], P, canonical)
    return P, x, finite


def project(P: Tensor, X: Tensor) -> tuple[Tensor, Tensor]:
    """Project points into every view.

    Args:
        P: (B|1, N, 3, 4) cameras.
        X: (B, 3) points.

    Returns:
        uv: (B, N, 2) image points in pixels; w: (B, N) projective depths (positive in front).
    """
    Xh = torch.cat((X, torch.ones_like(X[:, :1])), dim=-1)
    p = torch.einsum("bnij,bj->bni", P.expand(X.shape[0], -1, -1, -1), Xh)
    return p[..., :2] / p[..., 2:], p[..., 2]


def reprojection_residuals(P: Tensor, X: Tensor, x: Tensor) -> Tensor:
    """Residuals ``proj(P_i, X) - x_i``: (B|1, N, 3, 4), (B, 3), (B, N, 2) -> (B, N, 2) in pixels."""
    uv, _ = project(P, X)
    return uv - x


def reprojection_cost(P: Tensor, X: Tensor, x: Tensor) -> Tensor:
    """Sum of squared reprojection errors (thesis eq. 2.2): (B|1, N, 3, 4), (B, 3), (B, N, 2) -> (B,) in px^2."""
    return reprojection_residuals(P, X, x).square().sum(dim=(-1, -2))


def in_front_of_cameras(P: Tensor, X: Tensor) -> Tensor:
    """Cheirality: (B|1, N, 3, 4), (B, 3) -> (B,) True where the point has positive depth in every view."""
    _, w = project(P, X)
    return (w > 0).all(dim=-1)
