"""Target-model optimizers as ``nn.Module``s (thesis ch. 5.3, eq. 5.2; paper D): Gauss-Newton with
preconditioned conjugate gradient, and steepest descent with the exact line-search step.

Both use only the explicit Jacobian products of ``TargetModelLoss`` (convolutions, transposed convolutions,
einsums), a fixed number of iterations and ``torch.where`` guards, so they run under
``torch.inference_mode``, stay differentiable for training through the optimizer, and export to ONNX.

Gauss-Newton step: at W solve J^T J dW = -J^T r(W) by PCG from dW = 0 and set W += dW. PCG uses the diagonal
preconditioner ``M = diag(c_j)`` (one constant per tensor, FRTM: the regularisation constants),
Polak-Ribiere beta clamped at 0, and no convergence test. The CG direction and rho persist between runs; at
the start of each run beta is scaled by the direction-forgetting factor (0.9^750 at inference: a reset).
"""

from __future__ import annotations

import torch
from torch import nn

from core.errors import InputError
from models.vos.target_model import TargetModelLoss

CGState = tuple[list[torch.Tensor], torch.Tensor, list[torch.Tensor]]  # (direction p, rho (B,), previous r)


def _dot(a: list[torch.Tensor], b: list[torch.Tensor]) -> torch.Tensor:
    """Per-problem inner product of two tensor lists: (B,)."""
    return sum((u * v).flatten(1).sum(1) for u, v in zip(a, b, strict=True))


def _scale(t: torch.Tensor, s: torch.Tensor) -> torch.Tensor:
    return t * s.view(-1, *([1] * (t.ndim - 1)))


def _safe_div(num: torch.Tensor, den: torch.Tensor) -> torch.Tensor:
    ok = den.abs() > 0
    return torch.where(ok, num / torch.where(ok, den, torch.ones_like(den)), torch.zeros_like(num))


def _check(x: torch.Tensor, wf: torch.Tensor, wp: torch.Tensor | None) -> None:
    b, _, d = x.shape[:3]
    if wf.ndim != 4 or wf.shape[0] != b or wf.shape[-1] != wf.shape[-2]:
        raise InputError(f"W_f must be (B={b}, C, k, k), got {tuple(wf.shape)}")
    c = wf.shape[1]
    if wp is None and d != c:
        raise InputError(f"without W_p the features must be projected to C={c} channels, got D={d}")
    if wp is not None and wp.shape != (b, c, d):
        raise InputError(f"W_p must be (B, C, D) = {(b, c, d)}, got {tuple(wp.shape)}")


class GaussNewtonCG(nn.Module):
    """Gauss-Newton with preconditioned conjugate gradient on the target-model loss (eq. 5.2).

    Args:
        schedule: CG iterations per Gauss-Newton step; FRTM init (5, 10, 10, 10, 10), update (10,).
        reg: (lambda_p, lambda_f) regularisation; FRTM (1e-4, 1e-2) at inference, (1e-5, 1e-4) in training.
        precond: per-tensor preconditioner constants (c_p, c_f); None uses ``reg``.
        direction_forget: beta factor at the start of each CG run (0.9^750 inference, 0.9^75 training).
    """

    def __init__(
        self,
        schedule: tuple[int, ...] | list[int] = (10,),
        reg: tuple[float, float] | list[float] = (1e-4, 1e-2),
        precond: tuple[float, float] | list[float] | None = None,
        direction_forget: float = 0.9**750,
    ) -> None:
        super().__init__()
        if not schedule or any(n < 1 for n in schedule):
            raise InputError(f"Gauss-Newton schedule must list CG iteration counts >= 1, got {schedule}")
        self.schedule = tuple(int(n) for n in schedule)
        self.reg = (float(reg[0]), float(reg[1]))
        self.precond = self.reg if precond is None else (float(precond[0]), float(precond[1]))
        self.direction_forget = float(direction_forget)

    def forward(
        self,
        x: torch.Tensor,
        labels: torch.Tensor,
        pixel_weights: torch.Tensor | None,
        sample_weights: torch.Tensor,
        wf: torch.Tensor,
        wp: torch.Tensor | None = None,
        state: CGState | None = None,
    ) -> tuple[torch.Tensor | None, torch.Tensor, CGState, torch.Tensor]:
        """Run the schedule.

        Args:
            x: (B, K, D, h, w) features; (B, K, C, h, w) projected ones when ``wp`` is None (W_f-only problem).
            labels, pixel_weights: (B, K, H, W); pixel_weights may be None.
            sample_weights: (B, K).
            wf: (B, C, k, k) starting filter; wp: (B, C, D) starting projection, optimised jointly, or None.
            state: CG state from the previous call (same parameter set) or None.

        Returns:
            (wp, wf, CG state, losses (B, steps + 1): the loss before each step and after the last).
        """
        _check(x, wf, wp)
        problem = TargetModelLoss(x, labels, pixel_weights, sample_weights, self.reg)
        pre = [self.precond[1]] if wp is None else list(self.precond)
        losses = []
        p, rho, r_prev = state if state is not None else (None, None, None)
        for n_cg in self.schedule:
            params = [wf] if wp is None else [wp, wf]
            z, _ = problem.scores(wp, wf)
            f0 = problem.residual(wp, wf)
            losses.append(_dot(f0, f0))
            r = [-g for g in problem.vjp(z, wp, wf, f0)]
            delta = [torch.zeros_like(t) for t in params]
            for i in range(n_cg):
                zc = [t / c for t, c in zip(r, pre, strict=True)]
                rho_new = _dot(r, zc)
                if p is None:
                    p = zc
                else:
                    beta = _safe_div(rho_new - _dot(r_prev, zc), rho)
                    if i == 0:
                        beta = beta * self.direction_forget
                    beta = beta.clamp_min(0)
                    p = [u + _scale(v, beta) for u, v in zip(zc, p, strict=True)]
                q = problem.vjp(z, wp, wf, problem.jvp(z, wp, wf, p))
                alpha = _safe_div(rho_new, _dot(p, q))
                delta = [d + _scale(u, alpha) for d, u in zip(delta, p, strict=True)]
                r_prev = r
                r = [u - _scale(v, alpha) for u, v in zip(r, q, strict=True)]
                rho = rho_new
            if wp is None:
                wf = wf + delta[0]
            else:
                wp, wf = wp + delta[0], wf + delta[1]
        f0 = problem.residual(wp, wf)
        losses.append(_dot(f0, f0))
        return wp, wf, (p, rho, r_prev), torch.stack(losses, 1)


class SteepestDescent(nn.Module):
    """Steepest descent with the exact Gauss-Newton line-search step alpha = ||g||^2 / ||J g||^2, g = J^T r.

    Args:
        num_iters: number of steps.
        reg: (lambda_p, lambda_f) as for ``GaussNewtonCG``.
    """

    def __init__(self, num_iters: int = 10, reg: tuple[float, float] | list[float] = (1e-4, 1e-2)) -> None:
        super().__init__()
        if num_iters < 1:
            raise InputError(f"steepest descent needs num_iters >= 1, got {num_iters}")
        self.num_iters = int(num_iters)
        self.reg = (float(reg[0]), float(reg[1]))

    def forward(
        self,
        x: torch.Tensor,
        labels: torch.Tensor,
        pixel_weights: torch.Tensor | None,
        sample_weights: torch.Tensor,
        wf: torch.Tensor,
        wp: torch.Tensor | None = None,
        state: CGState | None = None,
    ) -> tuple[torch.Tensor | None, torch.Tensor, CGState | None, torch.Tensor]:
        """Same arguments and returns as ``GaussNewtonCG.forward`` (the state passes through unchanged)."""
        _check(x, wf, wp)
        problem = TargetModelLoss(x, labels, pixel_weights, sample_weights, self.reg)
        losses = []
        for _ in range(self.num_iters):
            z, _ = problem.scores(wp, wf)
            f0 = problem.residual(wp, wf)
            losses.append(_dot(f0, f0))
            g = problem.vjp(z, wp, wf, f0)
            jg = problem.jvp(z, wp, wf, g)
            alpha = _safe_div(_dot(g, g), _dot(jg, jg))
            if wp is None:
                wf = wf - _scale(g[0], alpha)
            else:
                wp, wf = wp - _scale(g[0], alpha), wf - _scale(g[1], alpha)
        f0 = problem.residual(wp, wf)
        losses.append(_dot(f0, f0))
        return wp, wf, state, torch.stack(losses, 1)


def build_optimizer(
    kind: str, schedule: tuple[int, ...] | list[int], reg: tuple[float, float] | list[float]
) -> GaussNewtonCG | SteepestDescent:
    """``"gauss_newton"``: GN-CG with ``schedule``; ``"steepest_descent"``: sum(schedule) exact-step iterations."""
    if kind == "gauss_newton":
        return GaussNewtonCG(schedule, reg)
    if kind == "steepest_descent":
        return SteepestDescent(sum(schedule), reg)
    raise InputError(f"optimizer {kind!r} is not 'gauss_newton' or 'steepest_descent'")
