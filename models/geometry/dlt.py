"""Linear N-view triangulation (DLT, Hartley and Zisserman 12.2): the algebraic least-squares point."""

from __future__ import annotations

import torch
from torch import Tensor, nn

from models.geometry.midpoint import assemble_triangulation, midpoint_from_views
from models.geometry.projection import Triangulation, check_cameras_and_points, finite_inputs
from models.geometry.views import split_views


def triangulate_dlt(P: Tensor, x: Tensor, min_parallax: float = 1e-3) -> Triangulation:
    """Homogeneous DLT: the unit 4-vector minimising ``|A X~|``, rows ``x_i P_i[2] - P_i[0]``, ``y_i P_i[2] - P_i[1]``.

    Each row is scaled to unit norm (balancing views) and the smallest eigenvector of the 4x4 ``A^T A`` is found
    in fp64 whatever the input dtype. Not meant for export (uses ``torch.linalg.eigh``).

    Args:
        P: (B|1, N, 3, 4) cameras, N >= 2; x: (B, N, 2) observations in px.
        min_parallax: near-parallel rays threshold (rad), as for :func:`triangulate_midpoint`.

    Returns:
        ``Triangulation`` with points (B, 3), cost (B,) in px^2 and valid (B,).
    """
    check_cameras_and_points(P, x)
    P, x, finite = finite_inputs(P, x)
    P64 = P.double().expand(x.shape[0], -1, -1, -1)
    x64 = x.double()
    rows = torch.cat(
        (x64[..., 0:1] * P64[..., 2, :] - P64[..., 0, :], x64[..., 1:2] * P64[..., 2, :] - P64[..., 1, :]), dim=1
    )
    rows = rows / rows.norm(dim=-1, keepdim=True).clamp_min(1e-300)
    _, vectors = torch.linalg.eigh(rows.transpose(1, 2) @ rows)
    Xh = vectors[..., 0]
    X = (Xh[:, :3] / Xh[:, 3:]).to(x.dtype)
    _, lam = midpoint_from_views(split_views(P, x))
    return assemble_triangulation(P, x, X, finite, lam, min_parallax)


class TriangulateDLT(nn.Module):
    """Module form of :func:`triangulate_dlt`: (B|1, N, 3, 4), (B, N, 2) -> ``Triangulation``."""

    def __init__(self, min_parallax: float = 1e-3) -> None:
        super().__init__()
        self.min_parallax = min_parallax

    def forward(self, P: Tensor, x: Tensor) -> Triangulation:
        return triangulate_dlt(P, x, self.min_parallax)
