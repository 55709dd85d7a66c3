"""Hartley-Sturm optimal two-view triangulation (thesis 2.3, eq. 2.1): roots of a degree-6 polynomial.

Batched over points: every point may have its own pair of cameras. The correction runs in fp64 whatever the
input dtype (the polynomial is ill-conditioned in fp32); roots come from companion-matrix eigenvalues, so this
method is for evaluation and comparison, not for ONNX export (use the dogleg solver for deployment).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from core.errors import InputError
from models.geometry.midpoint import assemble_triangulation, midpoint_from_views
from models.geometry.projection import Triangulation, check_cameras_and_points, finite_inputs
from models.geometry.views import split_views


def fundamental_from_cameras(P1: Tensor, P2: Tensor) -> Tensor:
    """Fundamental matrix with ``x2^T F x1 = 0`` from two cameras (B, 3, 4) -> (B, 3, 3).

    Uses the determinant form ``F[j, i] = (-1)^(i+j) det([P1 without row i; P2 without row j])`` (Hartley and
    Zisserman eq. 17.3), valid for any pair of finite cameras.
    """
    keep = ((1, 2), (0, 2), (0, 1))
    F = torch.empty(P1.shape[:-2] + (3, 3), dtype=P1.dtype, device=P1.device)
    for i in range(3):
        for j in range(3):
            block = torch.cat((P1[..., keep[i], :], P2[..., keep[j], :]), dim=-2)
            F[..., j, i] = (-1) ** (i + j) * torch.linalg.det(block)
    return F


def _null_vector(F: Tensor) -> Tensor:
    """Right null vector (B, 3) of rank-2 matrices (B, 3, 3): the largest cross product of two rows."""
    r0, r1, r2 = F.unbind(-2)
    cands = torch.stack((torch.linalg.cross(r0, r1), torch.linalg.cross(r0, r2), torch.linalg.cross(r1, r2)), 1)
    best = cands.norm(dim=-1).argmax(dim=1)
    return cands[torch.arange(F.shape[0], device=F.device), best]


def _polymul(p: Tensor, q: Tensor) -> Tensor:
    """Product of polynomials with coefficients in increasing order: (B, m), (B, n) -> (B, m + n - 1)."""
    out = p.new_zeros(p.shape[0], p.shape[1] + q.shape[1] - 1)
    for i in range(p.shape[1]):
        out[:, i : i + q.shape[1]] += p[:, i : i + 1] * q
    return out


def _real_roots_candidates(coeffs: Tensor) -> Tensor:
    """Real parts of the roots of degree-6 polynomials (B, 7) (increasing order) -> (B, 6)."""
    scale = coeffs.abs().amax(dim=1, keepdim=True).clamp_min(1e-300)
    c = coeffs / scale
    lead = c[:, 6]
    lead = torch.where(lead.abs() < 1e-13, torch.full_like(lead, 1e-13) * torch.where(lead < 0, -1.0, 1.0), lead)
    companion = torch.zeros(c.shape[0], 6, 6, dtype=c.dtype, device=c.device)
    companion[:, 1:, :-1] = torch.eye(5, dtype=c.dtype, device=c.device)
    companion[:, :, -1] = -c[:, :6] / lead.unsqueeze(-1)
    return torch.linalg.eigvals(companion).real


def correct_matches(F: Tensor, x1: Tensor, x2: Tensor) -> tuple[Tensor, Tensor]:
    """Optimal correction of a pair of matches to satisfy the epipolar constraint (Hartley and Zisserman Alg. 12.1).

    Finds the points ``x1^, x2^`` with ``x2^T F x1^ = 0`` closest (sum of squared distances) to ``x1, x2``: the
    minimum of eq. 2.1 over the real roots of its degree-6 derivative and the asymptotic value.

    Args:
        F: (B, 3, 3) fundamental matrices with ``x2^T F x1 = 0``.
        x1, x2: (B, 2) observations in px.

    Returns:
        corrected x1, x2: (B, 2) each, in the input dtype.
    """
    dtype = x1.dtype
    F, x1, x2 = F.double(), x1.double(), x2.double()
    B = F.shape[0]
    eye = torch.eye(3, dtype=F.dtype, device=F.device).expand(B, 3, 3)
    T1inv, T2inv = eye.clone(), eye.clone()
    T1inv[:, :2, 2] = x1
    T2inv[:, :2, 2] = x2
    F = T2inv.transpose(1, 2) @ F @ T1inv
    e1 = _null_vector(F)
    e2 = _null_vector(F.transpose(1, 2))
    e1 = e1 / e1[:, :2].norm(dim=-1, keepdim=True)
    e2 = e2 / e2[:, :2].norm(dim=-1, keepdim=True)

    def rotation(e: Tensor) -> Tensor:
        R = eye.clone()
        R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1] = e[:, 0], e[:, 1], -e[:, 1], e[:, 0]
        return R

    R1, R2 = rotation(e1), rotation(e2)
    F = R2 @ F @ R1.transpose(1, 2)
    f1, f2 = e1[:, 2:3], e2[:, 2:3]
    a, b, c, d = F[:, 1, 1:2], F[:, 1, 2:3], F[:, 2, 1:2], F[:, 2, 2:3]
    zero = torch.zeros_like(a)
    one = torch.ones_like(a)
    at_b = torch.cat((b, a), 1)
    ct_d = torch.cat((d, c), 1)
    quad = _polymul(at_b, at_b) + f2.square() * _polymul(ct_d, ct_d)
    lhs = _polymul(torch.cat((zero, one), 1), _polymul(quad, quad))
    one_f1 = torch.cat((one, zero, f1.square()), 1)
    rhs = (a * d - b * c) * _polymul(_polymul(one_f1, one_f1), _polymul(at_b, ct_d))
    coeffs = torch.cat((lhs, zero), 1) - rhs
    t = _real_roots_candidates(coeffs)

    def cost(t: Tensor) -> Tensor:
        return t.square() / (1 + f1.square() * t.square()) + (c * t + d).square() / (
            (a * t + b).square() + f2.square() * (c * t + d).square()
        )

    cost_inf = 1 / f1.square() + c.square() / (a.square() + f2.square() * c.square())
    costs = torch.cat((cost(t), cost_inf), 1)
    best = torch.nan_to_num(costs, nan=float("inf")).argmin(dim=1, keepdim=True)
    at_inf = best.squeeze(1) == 6
    t_best = torch.gather(torch.cat((t, zero), 1), 1, best)
    # Epipolar lines in the rotated frames; at t = inf they are the limits of l1 / t and l2 / t.
    l1 = torch.cat((t_best * f1, one, -t_best), 1)
    l2 = torch.cat((-f2 * (c * t_best + d), a * t_best + b, c * t_best + d), 1)
    l1_inf = torch.cat((f1, zero, -one), 1)
    l2_inf = torch.cat((-f2 * c, a, c), 1)
    l1 = torch.where(at_inf.unsqueeze(1), l1_inf, l1)
    l2 = torch.where(at_inf.unsqueeze(1), l2_inf, l2)

    def foot(line: Tensor) -> Tensor:
        lam, mu, nu = line.unbind(1)
        return torch.stack((-lam * nu, -mu * nu, lam.square() + mu.square()), 1)

    y1 = (T1inv @ R1.transpose(1, 2) @ foot(l1).unsqueeze(-1)).squeeze(-1)
    y2 = (T2inv @ R2.transpose(1, 2) @ foot(l2).unsqueeze(-1)).squeeze(-1)
    return (y1[:, :2] / y1[:, 2:]).to(dtype), (y2[:, :2] / y2[:, 2:]).to(dtype)


def triangulate_polynomial(P: Tensor, x: Tensor, min_parallax: float = 1e-3) -> Triangulation:
    """Optimal two-view triangulation: correct the matches (Hartley-Sturm), then intersect the now-meeting rays.

    Args:
        P: (B|1, 2, 3, 4) cameras; x: (B, 2, 2) observations in px.
        min_parallax: near-parallel rays threshold (rad), as for :func:`triangulate_midpoint`.

    Returns:
        ``Triangulation`` with points (B, 3), cost (B,) in px^2 (against the original observations), valid (B,).
    """
    check_cameras_and_points(P, x)
    if x.shape[1] != 2:
        raise InputError(f"the polynomial method takes exactly 2 views, got {x.shape[1]}")
    P, x, finite = finite_inputs(P, x)
    Pb = P.expand(x.shape[0], -1, -1, -1).double()
    F = fundamental_from_cameras(Pb[:, 0], Pb[:, 1])
    y1, y2 = correct_matches(F, x[:, 0], x[:, 1])
    corrected = torch.stack((y1, y2), dim=1)
    X_parts, _ = midpoint_from_views(split_views(P, corrected))
    X = torch.stack(X_parts, dim=-1)
    _, lam = midpoint_from_views(split_views(P, x))
    return assemble_triangulation(P, x, X, finite, lam, min_parallax)


class TriangulatePolynomial(nn.Module):
    """Module form of :func:`triangulate_polynomial`: (B|1, 2, 3, 4), (B, 2, 2) -> ``Triangulation``."""

    def __init__(self, min_parallax: float = 1e-3) -> None:
        super().__init__()
        self.min_parallax = min_parallax

    def forward(self, P: Tensor, x: Tensor) -> Triangulation:
        return triangulate_polynomial(P, x, self.min_parallax)
