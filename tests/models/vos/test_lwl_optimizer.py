"""The LWL steepest-descent step against an autograd double-backward reference (as pytracking computes it) and
the closed-form minimiser along -g; differentiability for meta-learning."""

import pytest
import torch
import torch.nn.functional as F

from models.vos.lwl_optimizer import LWLSteepestDescent


def _problem(seed: int, dtype=torch.float64, b=2, s=3, p=5, k=4, h=6, w=7):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(b, s, p, h, w, generator=g, dtype=dtype)
    enc = torch.rand(b, s, k, h, w, generator=g, dtype=dtype)
    wts = torch.rand(b, s, k, h, w, generator=g, dtype=dtype) + 0.5
    gamma = torch.rand(b, s, generator=g, dtype=dtype) + 0.1
    tau = 0.1 * torch.randn(b, k, p, 3, 3, generator=g, dtype=dtype)
    return x, enc, wts, gamma, tau


def _residual(x, enc, wts, gamma, tau, reg):
    """[sqrt(gamma) W (tau * x - E), lambda tau] with a plain conv2d per problem."""
    scores = torch.stack([F.conv2d(x[i], tau[i], padding=1) for i in range(x.shape[0])])
    return gamma.sqrt()[..., None, None, None] * wts * (scores - enc), reg * tau


def _reference_step(x, enc, wts, gamma, tau, reg):
    """g by autograd, h = J g by double backward through a dummy (pytracking's GNSteepestDescent)."""
    t = tau.clone().requires_grad_(True)
    r = _residual(x, enc, wts, gamma, t, reg)
    dummy = [torch.zeros_like(u, requires_grad=True) for u in r]
    jt_dummy = torch.autograd.grad(r, t, dummy, create_graph=True)[0]
    g = torch.autograd.grad(r, t, [u.detach() for u in r], retain_graph=True)[0]
    h = torch.autograd.grad(jt_dummy, dummy, g)
    gg = g.pow(2).flatten(1).sum(1)
    hh = sum(u.pow(2).flatten(1).sum(1) for u in h)
    alpha = gg / hh.clamp_min(1e-8)
    return tau - alpha.view(-1, 1, 1, 1, 1) * g, alpha, g


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_step_matches_double_backward_reference(seed: int, dtype: torch.dtype) -> None:
    x, enc, wts, gamma, tau = _problem(seed, dtype)
    opt = LWLSteepestDescent(reg=0.2).to(dtype)
    ours, losses = opt(tau, x, enc, wts, gamma, num_iters=3)
    ref = tau
    for _ in range(3):
        ref, _, _ = _reference_step(x, enc, wts, gamma, ref, 0.2)
    assert ((ours - ref).norm() / ref.norm()).item() < (1e-4 if dtype == torch.float32 else 1e-10)
    # the losses are ||r||^2 before each step and after the last, and fall
    r = _residual(x, enc, wts, gamma, ours, 0.2)
    final = sum(u.pow(2).flatten(1).sum(1) for u in r)
    torch.testing.assert_close(losses[:, -1], final.detach(), rtol=1e-4, atol=1e-6)
    assert (losses[:, 1:] < losses[:, :-1]).all()


def test_step_is_the_exact_minimiser_along_the_negative_gradient() -> None:
    x, enc, wts, gamma, tau = _problem(3)
    opt = LWLSteepestDescent(reg=0.1).double()
    new, _ = opt(tau, x, enc, wts, gamma, num_iters=1)
    _, alpha, g = _reference_step(x, enc, wts, gamma, tau, 0.1)

    def loss_at(a: torch.Tensor) -> torch.Tensor:
        r = _residual(x, enc, wts, gamma, tau - a.view(-1, 1, 1, 1, 1) * g, 0.1)
        return sum(u.pow(2).flatten(1).sum(1) for u in r)

    # the objective is quadratic in alpha: its derivative vanishes at the step, and the step is a minimum
    a = alpha.clone().requires_grad_(True)
    (slope,) = torch.autograd.grad(loss_at(a).sum(), a)
    scale = g.pow(2).flatten(1).sum(1)
    assert (slope.abs() / scale < 1e-9).all()
    for eps in (1e-3, -1e-3):
        assert (loss_at(alpha * (1 + eps)) > loss_at(alpha)).all()
    torch.testing.assert_close(new, tau - alpha.view(-1, 1, 1, 1, 1) * g, rtol=1e-10, atol=1e-12)


def test_unrolled_steps_are_differentiable_in_every_input_and_lambda() -> None:
    x, enc, wts, gamma, tau = _problem(4)
    x, enc, wts = (t.clone().requires_grad_(True) for t in (x, enc, wts))
    opt = LWLSteepestDescent(reg=0.05).double()
    out, _ = opt(tau, x, enc, wts, gamma, num_iters=4)
    (out * torch.randn_like(out)).sum().backward()
    for t in (x, enc, wts, opt.reg):
        assert t.grad is not None and torch.isfinite(t.grad).all() and t.grad.abs().sum() > 0


def test_runs_under_inference_mode_and_zero_steps_keep_the_filter() -> None:
    x, enc, wts, gamma, tau = _problem(5, torch.float32)
    opt = LWLSteepestDescent()
    with torch.inference_mode():
        same, losses = opt(tau, x, enc, wts, gamma, num_iters=0)
        assert torch.equal(same, tau) and losses.shape == (2, 1)
        out, _ = opt(tau, x, enc, wts, torch.zeros_like(gamma), num_iters=2)  # no data: only the regulariser acts
        assert (out.norm() < tau.norm()).item()
