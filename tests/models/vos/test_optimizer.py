"""The GN-CG / steepest-descent target-model optimizers against autograd (double-backward, as FRTM computes
them) and a dense least-squares solve (problems and the plain residual: conftest.py)."""

import pytest
import torch
import torch.nn.functional as F

from models.vos.optimizer import GaussNewtonCG, SteepestDescent
from models.vos.target_model import TargetModel


def autograd_gn_cg(reference_residual, x, labels, v, gamma, wp, wf, reg, schedule, precond):
    """FRTM's GaussNewtonCG: Jp and J^T J p by double backward through autograd."""
    params = [wp.clone(), wf.clone()] if wp is not None else [wf.clone()]
    p = rho = r_prev = None
    for n_cg in schedule:
        params = [t.detach().requires_grad_(True) for t in params]
        wp_, wf_ = (params[0], params[1]) if wp is not None else (None, params[0])
        if wp_ is None:
            f0 = reference_residual_projected(x, labels, v, gamma, wf_, reg)
        else:
            f0 = reference_residual(x, labels, v, gamma, wp_, wf_, reg)
        dummy = [torch.zeros_like(t, requires_grad=True) for t in f0]
        u = torch.autograd.grad(f0, params, dummy, create_graph=True)
        b = [-t.detach() for t in torch.autograd.grad(f0, params, [t.detach() for t in f0], retain_graph=True)]
        delta = [torch.zeros_like(t) for t in params]
        r = b
        for i in range(n_cg):
            zc = [t / c for t, c in zip(r, precond, strict=True)]
            rho_new = sum((a * bb).flatten(1).sum(1) for a, bb in zip(r, zc, strict=True))
            if p is None:
                p = zc
            else:
                beta = (rho_new - sum((a * bb).flatten(1).sum(1) for a, bb in zip(r_prev, zc, strict=True))) / rho
                beta = (beta * (0.9**750 if i == 0 else 1.0)).clamp_min(0)
                p = [a + beta.view(-1, *[1] * (a.ndim - 1)) * bb for a, bb in zip(zc, p, strict=True)]
            jp = torch.autograd.grad(u, dummy, p, retain_graph=True)
            q = torch.autograd.grad(f0, params, jp, retain_graph=True)
            alpha = rho_new / sum((a * bb).flatten(1).sum(1) for a, bb in zip(p, q, strict=True))
            delta = [dd + alpha.view(-1, *[1] * (a.ndim - 1)) * a for dd, a in zip(delta, p, strict=True)]
            r_prev, rho = r, rho_new
            r = [a - alpha.view(-1, *[1] * (a.ndim - 1)) * bb for a, bb in zip(r, q, strict=True)]
        params = [(t + dd).detach() for t, dd in zip(params, delta, strict=True)]
    return params


def reference_residual_projected(z, labels, v, gamma, wf, reg):
    out = []
    for i in range(z.shape[0]):
        s = F.conv2d(z[i], wf[i][None], padding=wf.shape[-1] // 2)
        up = F.interpolate(s, size=labels.shape[-2:], mode="bilinear", align_corners=False)[:, 0]
        out.append(gamma[i].sqrt()[:, None, None] * v[i] * (up - labels[i]))
    return [torch.stack(out), reg[1] * wf]


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_gauss_newton_steps_match_double_backward_reference(problem, reference_residual, seed: int,
                                                             dtype: torch.dtype) -> None:
    x, labels, v, gamma, wp, wf = problem(seed, dtype)
    reg = (1e-2, 1e-1)
    schedule = (3, 4)
    opt = GaussNewtonCG(schedule, reg)
    wp1, wf1, _, losses = opt(x, labels, v, gamma, wf, wp)
    ref_p, ref_f = autograd_gn_cg(reference_residual, x, labels, v, gamma, wp, wf, reg, schedule, reg)
    tol = 1e-4 if dtype == torch.float32 else 1e-9
    for got, ref in ((wp1, ref_p), (wf1, ref_f)):
        assert ((got - ref).norm() / ref.norm()).item() < tol
    assert (losses[:, -1] < losses[:, 0]).all()


def test_steepest_descent_matches_autograd_line_search(problem, reference_residual) -> None:
    x, labels, v, gamma, wp, wf = problem(4)
    reg = (1e-2, 1e-1)
    wp1, wf1, _, losses = SteepestDescent(1, reg)(x, labels, v, gamma, wf, wp)
    a, b = wp.clone().requires_grad_(True), wf.clone().requires_grad_(True)
    r = reference_residual(x, labels, v, gamma, a, b, reg)
    g = torch.autograd.grad(sum((t**2).sum() for t in r) / 2, (a, b))
    # exact step along -g: minimise the Gauss-Newton model, per problem
    _, jg = torch.func.jvp(lambda p, f: tuple(reference_residual(x, labels, v, gamma, p, f, reg)), (wp, wf), g)
    gg = (g[0] ** 2).flatten(1).sum(1) + (g[1] ** 2).flatten(1).sum(1)
    alpha = gg / sum((t**2).flatten(1).sum(1) for t in jg)
    torch.testing.assert_close(wp1, wp - alpha[:, None, None] * g[0], rtol=1e-9, atol=1e-12)
    torch.testing.assert_close(wf1, wf - alpha[:, None, None, None] * g[1], rtol=1e-9, atol=1e-12)
    assert (losses[:, 1] < losses[:, 0]).all()


def test_filter_only_problem_reaches_least_squares_optimum(problem) -> None:
    """W_f-only loss is linear least squares: GN-CG must reach the dense normal-equation solution."""
    x, labels, v, gamma, wp, wf = problem(5, c=3, d=3)
    reg = (1e-4, 1e-2)
    _, wf1, state, losses = GaussNewtonCG((60,), reg, direction_forget=0.0)(x, labels, v, gamma, wf)
    for i in range(x.shape[0]):
        # dense design matrix: column j = residual of the unit filter j
        cols = []
        for j in range(wf[i].numel()):
            e = torch.zeros(wf[i].numel(), dtype=x.dtype)
            e[j] = 1
            s = F.conv2d(x[i], e.view(1, *wf.shape[1:]), padding=1)
            up = F.interpolate(s, size=labels.shape[-2:], mode="bilinear", align_corners=False)[:, 0]
            cols.append((gamma[i].sqrt()[:, None, None] * v[i] * up).flatten())
        a = torch.stack(cols, 1)
        rhs = (gamma[i].sqrt()[:, None, None] * v[i] * labels[i]).flatten()
        opt = torch.linalg.solve(a.T @ a + reg[1] ** 2 * torch.eye(a.shape[1], dtype=x.dtype), a.T @ rhs)
        torch.testing.assert_close(wf1[i].flatten(), opt, rtol=1e-6, atol=1e-8)
    assert state[1].shape == (2,)


def test_init_schedule_decreases_loss_under_inference_mode(problem) -> None:
    x, labels, v, gamma, wp, wf = problem(6, torch.float32, k=5, d=16, c=8, h=8, w=10, big=(32, 40))
    opt = GaussNewtonCG((5, 10, 10, 10, 10), (1e-4, 1e-2))
    with torch.inference_mode():
        wp1, wf1, state, losses = opt(x, labels, v, gamma, wf, wp)
        assert losses.shape == (2, 6) and (losses[:, -1] < 0.7 * losses[:, 0]).all()
        assert (losses[:, 1:] <= losses[:, :-1] * 1.0001).all()
        # W_p frozen: update the filter on projected features, continuing the CG state
        z = TargetModel()(x, wp1, wf1)
        assert z.shape == (2, 5, 8, 10)
        proj = torch.einsum("bcd,bkdhw->bkchw", wp1, x)
        _, wf2, _, l2 = GaussNewtonCG((10,), (1e-4, 1e-2))(proj, labels, v, gamma, wf1, state=None)
        assert (l2[:, -1] <= l2[:, 0] * 1.0001).all()
        _, _, _, l3 = SteepestDescent(5)(x, labels, v, gamma, wf, wp)
        assert (l3[:, -1] < l3[:, 0]).all()


@pytest.mark.parametrize("optimizer", [GaussNewtonCG((2, 2), (1e-2, 1e-1)), SteepestDescent(3, (1e-2, 1e-1))],
                         ids=["gauss_newton", "steepest_descent"])
def test_unrolled_optimizer_gradcheck(problem, optimizer) -> None:
    """Stays differentiable when unrolled (training through the optimizer): the fitted filters in the features,
    labels, sample weights and starting filters, for the joint and the W_f-only problem."""
    x, labels, v, gamma, wp, wf = problem(8, b=1, k=2, d=2, c=2, h=2, w=3, big=(4, 5))
    x, labels, gamma, wp, wf = (t.requires_grad_() for t in (x, labels, gamma, wp, wf))

    def joint(x, labels, gamma, wf, wp):
        wp1, wf1, _, _ = optimizer(x, labels, v, gamma, wf, wp)
        return wp1, wf1

    # fast mode: the directional derivatives of random projections (the full Jacobian takes seconds)
    assert torch.autograd.gradcheck(joint, (x, labels, gamma, wf, wp), fast_mode=True)
    z = torch.einsum("bcd,bkdhw->bkchw", wp.detach(), x.detach()).requires_grad_()

    def filter_only(z, labels, gamma, wf):
        return optimizer(z, labels, v, gamma, wf)[1]

    assert torch.autograd.gradcheck(filter_only, (z, labels, gamma, wf), fast_mode=True)
