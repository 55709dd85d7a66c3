"""Optimal N-view triangulation by Powell's dogleg (thesis 2.5, paper A).

Minimises the sum of squared reprojection errors (thesis eq. 2.2) of every point independently, all points
at once: one lane per point, a fixed maximum number of iterations, and every branch of the trust-region method
(Gauss-Newton step, Cauchy point, dogleg interpolation, gain-ratio test, radius update; Madsen, Nielsen and
Tingleff, Alg. 3.21) written as ``torch.where`` masks. The 3x3 Gauss-Newton systems are solved in closed form,
so the solver runs on any device and dtype, compiles with ``torch.compile`` and exports to ONNX.

The problem is re-parametrised around the start ``X0``: with ``A_i = P_i[:2] - x_i P_i[2]`` the residual of view
``i`` is ``r_i = (A_i[:, :3] d + A_i X0~) / (P_i[2, :3] d + P_i[2] X0~)`` for ``X = X0 + d``. The constant terms
are computed once and are small near the optimum, which keeps fp32 accurate.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor, nn

from models.geometry.midpoint import midpoint_from_views, parallax_threshold
from models.geometry.projection import check_cameras_and_points, finite_inputs
from models.geometry.small_linalg import SYM3_INDEX, solve_sym3, sym3_quadratic_form
from models.geometry.views import Views, dot3, split_views

Vec3 = tuple[Tensor, Tensor, Tensor]


class DoglegTriangulation(NamedTuple):
    """Result of :func:`triangulate_dogleg`.

    Attributes:
        points: (B, 3) optimised points.
        cost: (B,) sum of squared reprojection errors in px^2.
        valid: (B,) finite input, in front of every camera, rays not near-parallel.
        converged: (B,) the step or trust radius fell below the tolerance within the iteration budget.
    """

    points: Tensor
    cost: Tensor
    valid: Tensor
    converged: Tensor


class CentredRows(NamedTuple):
    """The residual rows of all views stacked: row ``k`` of view ``i`` is entry ``2 i + k`` (2N, B)."""

    M: Vec3  # A_i[k, :3], each (2N, B)
    offset: Tensor  # A_i[k] X0~ (2N, B)
    q: Vec3  # P_i[2, :3], each (2N, B|1)
    w0: Tensor  # P_i[2] X0~ (2N, B)


def _centre(views: Views, X0: Vec3) -> CentredRows:
    P0, P1, P2 = views.P
    rows = [torch.cat((P0[c] - views.x * P2[c], P1[c] - views.y * P2[c])) for c in range(4)]
    depth = dot3(P2, X0) + P2[3]
    return CentredRows(
        (rows[0], rows[1], rows[2]),
        dot3(rows, X0) + rows[3],
        tuple(torch.cat((P2[c], P2[c])) for c in range(3)),  # type: ignore[arg-type]
        torch.cat((depth, depth)),
    )


def _linearise(rows: CentredRows, d: Vec3) -> tuple[Tensor, Tensor, list[Tensor], list[Tensor]]:
    """Half cost, smallest depth, gradient ``J^T r`` (3) and Hessian ``J^T J`` (6 entries) at ``X0 + d``."""
    w = dot3(rows.q, d) + rows.w0
    inv_w = 1.0 / w
    r = (dot3(rows.M, d) + rows.offset) * inv_w
    J = [(rows.M[c] - r * rows.q[c]) * inv_w for c in range(3)]
    F = 0.5 * (r * r).sum(0)
    g = [(J[c] * r).sum(0) for c in range(3)]
    H = [(J[a] * J[b]).sum(0) for a, b in SYM3_INDEX]
    return F, w.amin(0), g, H


def _where3(mask: Tensor, a: Vec3, b: Vec3) -> Vec3:
    return tuple(torch.where(mask, u, v) for u, v in zip(a, b, strict=True))  # type: ignore[return-value]


def _dogleg_step(g: list[Tensor], H: list[Tensor], radius: Tensor) -> tuple[Vec3, Tensor]:
    """Dogleg step inside the trust region, and its length."""
    h_gn, _ = solve_sym3(H, tuple(-v for v in g))
    gn_ok = torch.isfinite(h_gn[0]) & torch.isfinite(h_gn[1]) & torch.isfinite(h_gn[2])
    h_gn = tuple(torch.where(gn_ok, v, torch.zeros_like(v)) for v in h_gn)
    g2 = dot3(g, g)
    alpha = g2 / sym3_quadratic_form(H, g)
    a = tuple(-alpha * v for v in g)  # Cauchy point: minimiser along the steepest descent
    norm_gn = torch.sqrt(dot3(h_gn, h_gn))
    norm_a = torch.sqrt(dot3(a, a))
    clip = torch.clamp(radius / norm_a, max=1.0)  # steepest descent clipped to the region (or H singular)
    h_sd = tuple(v * clip for v in a)
    diff = tuple(u - v for u, v in zip(h_gn, a, strict=True))  # dogleg: a + beta (h_gn - a), |h| = radius
    c = dot3(a, diff)
    dd = dot3(diff, diff)
    slack = radius * radius - norm_a * norm_a
    root = torch.sqrt(c * c + dd * torch.clamp(slack, min=0.0))
    beta = torch.where(c <= 0, (root - c) / dd, slack / (c + root))
    h_dl = tuple(u + beta * v for u, v in zip(a, diff, strict=True))
    take_gn = gn_ok & (norm_gn <= radius)
    take_sd = ~take_gn & (~gn_ok | (norm_a >= radius))
    h = _where3(take_gn, h_gn, _where3(take_sd, h_sd, h_dl))  # type: ignore[arg-type]
    length = torch.where(take_gn, norm_gn, torch.where(take_sd, norm_a * clip, radius))
    return h, length


class DoglegState(NamedTuple):
    """Every point's trust-region iteration at one moment (one lane per point, all (B,) tensors).

    Attributes:
        d: three components of the step from the start ``X0``; F: half cost at ``X0 + d`` (px^2); depth: smallest
        depth over the views; g: gradient ``J^T r`` (3); H: ``J^T J`` (6 unique entries); radius: trust radius;
        scale: ``|X0| + 1``, the size convergence is relative to; active: not yet converged (bool).
    """

    d: Vec3
    F: Tensor
    depth: Tensor
    g: list[Tensor]
    H: list[Tensor]
    radius: Tensor
    scale: Tensor
    active: Tensor


def _tolerances(dtype: torch.dtype, tolerance: float | None) -> tuple[float, float]:
    """Relative step size that counts as converged and the relative gain lost in rounding, for ``dtype``."""
    eps = tolerance if tolerance is not None else 1e-2 * torch.finfo(dtype).eps ** 0.5
    return eps, 100 * torch.finfo(dtype).eps


def dogleg_start(views: Views, X0: Vec3, tolerance: float | None = None) -> tuple[CentredRows, DoglegState]:
    """The residual rows centred on ``X0`` and the state before the first dogleg iteration (the Gauss-Newton step
    length as the first trust radius)."""
    eps, _ = _tolerances(X0[0].dtype, tolerance)
    rows = _centre(views, X0)
    d = tuple(torch.zeros_like(v) for v in X0)
    F, depth, g, H = _linearise(rows, d)
    h_gn, _ = solve_sym3(H, tuple(-v for v in g))
    radius = torch.nan_to_num(torch.sqrt(dot3(h_gn, h_gn)), nan=1.0, posinf=1.0)
    scale = torch.sqrt(dot3(X0, X0)) + 1.0
    radius = torch.clamp(radius, min=eps) * torch.ones_like(scale)
    active = torch.isfinite(F) & torch.isfinite(g[0] + g[1] + g[2])
    return rows, DoglegState(d, F, depth, g, H, radius, scale, active)  # type: ignore[arg-type]


def dogleg_iteration(rows: CentredRows, state: DoglegState, tolerance: float | None = None) -> DoglegState:
    """One dogleg iteration of every active point: step, gain-ratio test, radius update, convergence test."""
    eps, rounding = _tolerances(state.F.dtype, tolerance)
    d, F, depth, g, H, radius, scale, active = state
    h, h_norm = _dogleg_step(g, H, radius)
    d_new = tuple(u + v for u, v in zip(d, h, strict=True))
    F_new, depth_new, g_new, H_new = _linearise(rows, d_new)
    predicted = -dot3(h, g) - 0.5 * sym3_quadratic_form(H, h)
    rho = (F - F_new) / predicted
    accept = active & (rho > 0) & torch.isfinite(F_new) & (predicted > 0)
    radius = torch.where(active & (rho > 0.75), torch.maximum(radius, 3 * h_norm), radius)
    radius = torch.where(active & ~(rho >= 0.25), 0.5 * radius, radius)
    tiny = eps * scale
    gain_lost_in_rounding = predicted <= rounding * F
    return DoglegState(
        _where3(accept, d_new, d),  # type: ignore[arg-type]
        torch.where(accept, F_new, F),
        torch.where(accept, depth_new, depth),
        [torch.where(accept, u, v) for u, v in zip(g_new, g, strict=True)],
        [torch.where(accept, u, v) for u, v in zip(H_new, H, strict=True)],
        radius,
        scale,
        active & (h_norm > tiny) & (radius > tiny) & ~gain_lost_in_rounding,
    )


def dogleg_refine(
    views: Views, X0: Vec3, iterations: int = 5, tolerance: float | None = None, early_exit: bool = True
) -> tuple[Vec3, Tensor, Tensor, Tensor]:
    """Refine points ``X0`` by Powell's dogleg on the reprojection error.

    Args:
        views: per-view components from :func:`split_views`.
        X0: three (B,) components of the starting points.
        iterations: maximum number of iterations (fixed when exported or compiled).
        tolerance: relative step/radius size that counts as converged (default: ``0.01 sqrt(eps)`` of the dtype);
            a point also counts as converged once the predicted gain is within rounding of its cost.
        early_exit: stop as soon as every point converged (ignored while compiling or exporting). Converged
            points are frozen, so stopping early changes no result.

    Returns:
        X (three (B,) components), cost (B,) in px^2, smallest depth over the views (B,), converged (B,).
    """
    rows, state = dogleg_start(views, X0, tolerance)
    for _ in range(iterations):
        if early_exit and not torch.compiler.is_compiling() and not bool(state.active.any()):
            break
        state = dogleg_iteration(rows, state, tolerance)
    X = tuple(u + v for u, v in zip(X0, state.d, strict=True))
    return X, 2 * state.F, state.depth, ~state.active  # type: ignore[return-value]


def midpoint_start(P: Tensor, x: Tensor, min_parallax: float) -> tuple[Views, Vec3, Tensor]:
    """Per-entry views of (B|1, N, 3, 4) cameras and (B, N, 2) observations, the midpoint start ``X0`` (three (B,)
    components, the origin where undefined) and (B,) ``usable``: finite inputs and rays not near-parallel."""
    P, x, finite = finite_inputs(P, x)
    views = split_views(P, x)
    X0, lam = midpoint_from_views(views)
    X0 = tuple(torch.where(torch.isfinite(v), v, torch.zeros_like(v)) for v in X0)
    return views, X0, finite & (lam >= parallax_threshold(min_parallax))  # type: ignore[return-value]


def triangulate_dogleg(
    P: Tensor,
    x: Tensor,
    iterations: int = 5,
    tolerance: float | None = None,
    min_parallax: float = 1e-3,
    early_exit: bool = True,
    chunk_size: int | None = None,
) -> DoglegTriangulation:
    """L2-optimal N-view triangulation: midpoint start, then Powell's dogleg on thesis eq. 2.2.

    Args:
        P: (B|1, N, 3, 4) cameras (``w > 0`` in front), N >= 2.
        x: (B, N, 2) observations in pixels.
        iterations: maximum dogleg iterations; 5 is plenty (most points converge in 2-3).
        tolerance: relative convergence tolerance (default ``0.01 sqrt(eps)`` of the dtype).
        min_parallax: near-parallel rays threshold (rad), see :func:`triangulate_midpoint`.
        early_exit: stop when all points converged (eager mode only).
        chunk_size: solve this many points at a time (keeps the working set in cache for millions of points;
            each chunk also stops as soon as its own points converged). None: all at once.

    Returns:
        ``DoglegTriangulation`` with points (B, 3), cost (B,) px^2, valid (B,), converged (B,).
    """
    check_cameras_and_points(P, x)
    if chunk_size is not None and x.shape[0] > chunk_size:
        parts = [
            triangulate_dogleg(P if P.shape[0] == 1 else P[i : i + chunk_size], x[i : i + chunk_size],
                               iterations, tolerance, min_parallax, early_exit)
            for i in range(0, x.shape[0], chunk_size)
        ]
        return DoglegTriangulation(*(torch.cat(field) for field in zip(*parts, strict=True)))
    views, X0, usable = midpoint_start(P, x, min_parallax)
    X, cost, depth, converged = dogleg_refine(views, X0, iterations, tolerance, early_exit)
    valid = usable & (depth > 0) & torch.isfinite(cost)
    return DoglegTriangulation(torch.stack(X, dim=-1), cost, valid, converged & valid)


class TriangulateDogleg(nn.Module):
    """Module form of :func:`triangulate_dogleg` with a fixed iteration budget (exports to ONNX).

    Forward: cameras (B|1, N, 3, 4) and observations (B, N, 2) in px -> ``DoglegTriangulation``.
    """

    def __init__(self, iterations: int = 5, tolerance: float | None = None, min_parallax: float = 1e-3) -> None:
        super().__init__()
        self.iterations = iterations
        self.tolerance = tolerance
        self.min_parallax = min_parallax

    def forward(self, P: Tensor, x: Tensor) -> DoglegTriangulation:
        return triangulate_dogleg(P, x, self.iterations, self.tolerance, self.min_parallax)
