"""The steepest-descent trainer of the LWL/DAVOS target model as an ``nn.Module`` (thesis ch. 6.1; paper E).

Each step takes g = J^T r and h = J g (explicit products of ``LWLResidual``, no autograd) and moves
tau <- tau - alpha g with alpha = ||g||^2 / (||h||^2 + s ||g||^2): with s = 0 the exact minimiser along -g of
the linearised (here: exactly quadratic) objective ||r||^2. The residual is affine in tau, so it is updated as
r <- r - alpha h instead of being recomputed: one filter application and one adjoint per step. The
regularisation lambda is a parameter, and every operation is differentiable, so training unrolls the steps and
back-propagates through them into the label encoder, lambda, the feature projection and everything before
("learning what to learn"). A fixed number of steps and a clamped denominator keep it exportable to ONNX.
"""

from __future__ import annotations

import torch
from torch import nn

from core.errors import InputError
from models.vos.lwl_target_model import LWLResidual, check_problem


def _sum(t: torch.Tensor) -> torch.Tensor:
    return t.flatten(1).sum(1)


class LWLSteepestDescent(nn.Module):
    """Steepest descent with the exact step on the LWL target-model objective.

    Args:
        num_iters: default number of steps (LWL: 5 in training, 20 at a first frame, 3 per frame).
        reg: initial lambda (LWL 0.01); learnt.
        step_reg: s, damping of the step (LWL 0).
        min_den: floor of the step's denominator (LWL 1e-8).
    """

    def __init__(self, num_iters: int = 5, reg: float = 0.01, step_reg: float = 0.0, min_den: float = 1e-8) -> None:
        super().__init__()
        if num_iters < 0:
            raise InputError(f"steepest descent needs num_iters >= 0, got {num_iters}")
        self.num_iters = int(num_iters)
        self.reg = nn.Parameter(torch.tensor(float(reg)))
        self.step_reg = float(step_reg)
        self.min_den = float(min_den)

    def forward(
        self,
        tau: torch.Tensor,
        x: torch.Tensor,
        encodings: torch.Tensor,
        weights: torch.Tensor,
        sample_weights: torch.Tensor,
        num_iters: int | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Run ``num_iters`` (default ``self.num_iters``) steps from ``tau``.

        Args:
            tau: (B, K, P, k, k) starting filter; x: (B, S, P, h, w) features; encodings, weights:
                (B, S, K, h, w) E(y) and W(y); sample_weights: (B, S) gamma.

        Returns:
            (filter after the steps, losses ||r||^2 (B, steps + 1): before each step and after the last).
        """
        check_problem(x, tau, encodings, weights, sample_weights)
        problem = LWLResidual(x, encodings, weights, sample_weights, self.reg.to(x.dtype))
        reg2 = problem.reg**2
        data = problem.data(tau)
        losses = [_sum(data.pow(2)) + reg2 * _sum(tau.pow(2))]
        for _ in range(self.num_iters if num_iters is None else num_iters):
            g = problem.gradient(tau, data)
            jg = problem.jvp_data(g)
            gg = _sum(g.pow(2))
            alpha = gg / (_sum(jg.pow(2)) + (reg2 + self.step_reg) * gg).clamp_min(self.min_den)
            tau = tau - alpha.view(-1, 1, 1, 1, 1) * g
            data = data - alpha.view(-1, 1, 1, 1, 1) * jg  # the data residual is affine in tau
            losses.append(_sum(data.pow(2)) + reg2 * _sum(tau.pow(2)))
        return tau, torch.stack(losses, 1)
