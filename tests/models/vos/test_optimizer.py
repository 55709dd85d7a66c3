"""Target model, explicit Jacobian products and the GN-CG / steepest-descent optimizers against autograd
(double-backward, as FRTM computes them) and a dense least-squares solve."""

import pytest
import torch
import torch.nn.functional as F

from models.vos.optimizer import GaussNewtonCG, SteepestDescent
from models.vos.target_model import (
    TargetModel,
    TargetModelLoss,
    hinge_pixel_weights,
    target_model_init,
    upsample,
)


def problem(seed: int, dtype=torch.float64, b=2, k=3, d=6, c=4, h=5, w=7, big=(17, 23)):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(b, k, d, h, w, generator=g, dtype=dtype).relu()
    labels = (torch.rand(b, k, *big, generator=g, dtype=dtype) > 0.7).to(dtype)
    v = hinge_pixel_weights(labels)
    gamma = torch.rand(b, k, generator=g, dtype=dtype) + 0.1
    wp, wf = target_model_init(b, d, c, 3, seed=seed, dtype=dtype)
    return x, labels, v, gamma, wp, wf


def reference_residual(x, labels, v, gamma, wp, wf, reg):
    """Eq. 5.2 residual written with plain conv2d per problem and F.interpolate."""
    out = []
    for i in range(x.shape[0]):
        z = F.conv2d(x[i], wp[i][..., None, None])
        s = F.conv2d(z, wf[i][None], padding=wf.shape[-1] // 2)
        up = F.interpolate(s, size=labels.shape[-2:], mode="bilinear", align_corners=False)[:, 0]
        out.append(gamma[i].sqrt()[:, None, None] * v[i] * (up - labels[i]))
    return [torch.stack(out), reg[0] * wp, reg[1] * wf]


def test_upsample_matches_interpolate() -> None:
    s = torch.randn(2, 3, 5, 7, dtype=torch.float64)
    for size in ((5, 7), (17, 23), (80, 112), (4, 9)):
        loss = TargetModelLoss(torch.zeros(2, 3, 1, 5, 7, dtype=torch.float64), torch.zeros(2, 3, *size,
                               dtype=torch.float64), None, torch.ones(2, 3, dtype=torch.float64), (0, 0))
        ref = F.interpolate(s, size=size, mode="bilinear", align_corners=False)
        torch.testing.assert_close(upsample(s, loss.ay, loss.ax), ref, rtol=1e-12, atol=1e-12)


def test_residual_and_jacobian_products_match_autograd() -> None:
    x, labels, v, gamma, wp, wf = problem(0)
    reg = (0.3, 0.2)
    loss = TargetModelLoss(x, labels, v, gamma, reg)
    for got, ref in zip(loss.residual(wp, wf), reference_residual(x, labels, v, gamma, wp, wf, reg), strict=True):
        torch.testing.assert_close(got, ref, rtol=1e-12, atol=1e-12)
    dp, df = torch.randn_like(wp), torch.randn_like(wf)
    _, jd = torch.func.jvp(lambda a, b: tuple(reference_residual(x, labels, v, gamma, a, b, reg)), (wp, wf), (dp, df))
    z, _ = loss.scores(wp, wf)
    for got, ref in zip(loss.jvp(z, wp, wf, [dp, df]), jd, strict=True):
        torch.testing.assert_close(got, ref, rtol=1e-10, atol=1e-10)
    r = [torch.randn_like(t) for t in jd]
    _, vjp_fn = torch.func.vjp(lambda a, b: tuple(reference_residual(x, labels, v, gamma, a, b, reg)), wp, wf)
    for got, ref in zip(loss.vjp(z, wp, wf, r), vjp_fn(tuple(r)), strict=True):
        torch.testing.assert_close(got, ref, rtol=1e-10, atol=1e-10)


def autograd_gn_cg(x, labels, v, gamma, wp, wf, reg, schedule, precond):
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
def test_gauss_newton_steps_match_double_backward_reference(seed: int, dtype: torch.dtype) -> None:
    x, labels, v, gamma, wp, wf = problem(seed, dtype)
    reg = (1e-2, 1e-1)
    schedule = (3, 4)
    opt = GaussNewtonCG(schedule, reg)
    wp1, wf1, _, losses = opt(x, labels, v, gamma, wf, wp)
    ref_p, ref_f = autograd_gn_cg(x, labels, v, gamma, wp, wf, reg, schedule, reg)
    tol = 1e-4 if dtype == torch.float32 else 1e-9
    for got, ref in ((wp1, ref_p), (wf1, ref_f)):
        assert ((got - ref).norm() / ref.norm()).item() < tol
    assert (losses[:, -1] < losses[:, 0]).all()


def test_steepest_descent_matches_autograd_line_search() -> None:
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


def test_filter_only_problem_reaches_least_squares_optimum() -> None:
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


def test_init_schedule_decreases_loss_under_inference_mode() -> None:
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


def test_hinge_weights_follow_the_rule() -> None:
    labels = torch.zeros(1, 3, 20, 20)
    labels[0, 0, :2, :10] = 1  # 20 px: a_f = 0.05 < 0.1 -> reweighted
    labels[0, 1, :, :10] = 1  # a_f = 0.5 -> unweighted
    labels[0, 2, 0, :5] = 1  # 5 px < 10 -> a_f := t_f -> unweighted
    v = hinge_pixel_weights(labels) ** 2
    a = 0.05
    assert v[0, 0, 0, 0].item() == pytest.approx(0.1 / a) and v[0, 0, 5, 5].item() == pytest.approx(0.9 / (1 - a))
    assert torch.allclose(v[0, 1], torch.ones(20, 20)) and torch.allclose(v[0, 2], torch.ones(20, 20))
    assert (v[0, 0] * (labels[0, 0] > 0.5)).sum().item() == pytest.approx(0.1 * 400)


@pytest.mark.parametrize("size", [1, 3, 5])
def test_float64_shifted_einsums_equal_per_problem_convolutions(size: int) -> None:
    """The float64 path (shifted einsums, exportable to ONNX Runtime) against F.conv2d / conv_transpose2d run
    per problem and sample in float64, and the adjoint identities <W_f * z, q> = <z, T(q)> = <W_f, G(z, q)>."""
    from models.vos.target_model import apply_filter, apply_filter_transpose, filter_grad

    g = torch.Generator().manual_seed(size)
    b, k, c, h, w = 2, 3, 4, 5, 6
    z = torch.randn(b, k, c, h, w, generator=g, dtype=torch.float64)
    q = torch.randn(b, k, h, w, generator=g, dtype=torch.float64)
    wf = torch.randn(b, c, size, size, generator=g, dtype=torch.float64)
    pad = size // 2
    s = apply_filter(z, wf)
    t = apply_filter_transpose(q, wf)
    for i in range(b):
        for j in range(k):
            ref = F.conv2d(z[i, j][None], wf[i][None], padding=pad)[0, 0]
            torch.testing.assert_close(s[i, j], ref, rtol=1e-12, atol=1e-12)
            ref_t = F.conv_transpose2d(q[i, j][None, None], wf[i][None], padding=pad)[0]
            torch.testing.assert_close(t[i, j], ref_t, rtol=1e-12, atol=1e-12)
    gf = filter_grad(z, q, size)
    lhs = (s * q).flatten(1).sum(1)
    torch.testing.assert_close((z * t).flatten(1).sum(1), lhs, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close((wf * gf).flatten(1).sum(1), lhs, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(apply_filter(z.float(), wf.float()).double(), s, rtol=1e-4, atol=1e-4)

