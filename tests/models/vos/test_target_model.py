"""Target model and its loss: separable upsampling, residual and explicit Jacobian products against autograd,
the hinge pixel weights, and the float64 shifted-einsum filters against per-problem convolutions."""

import pytest
import torch
import torch.nn.functional as F

from models.vos.target_model import (
    TargetModel,
    TargetModelLoss,
    apply_filter,
    apply_filter_transpose,
    filter_grad,
    hinge_pixel_weights,
    upsample,
)


def test_upsample_matches_interpolate() -> None:
    s = torch.randn(2, 3, 5, 7, dtype=torch.float64)
    for size in ((5, 7), (17, 23), (80, 112), (4, 9)):
        loss = TargetModelLoss(torch.zeros(2, 3, 1, 5, 7, dtype=torch.float64), torch.zeros(2, 3, *size,
                               dtype=torch.float64), None, torch.ones(2, 3, dtype=torch.float64), (0, 0))
        ref = F.interpolate(s, size=size, mode="bilinear", align_corners=False)
        torch.testing.assert_close(upsample(s, loss.ay, loss.ax), ref, rtol=1e-12, atol=1e-12)


def test_residual_and_jacobian_products_match_autograd(problem, reference_residual) -> None:
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


@pytest.mark.parametrize("size", [1, 3])
def test_filter_ops_gradcheck(size: int) -> None:
    """The float64 filter path (shifted einsums) and its adjoints are differentiable in both arguments."""
    g = torch.Generator().manual_seed(size)
    z = torch.randn(2, 2, 3, 4, 5, generator=g, dtype=torch.float64, requires_grad=True)
    q = torch.randn(2, 2, 4, 5, generator=g, dtype=torch.float64, requires_grad=True)
    wf = torch.randn(2, 3, size, size, generator=g, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(apply_filter, (z, wf))
    assert torch.autograd.gradcheck(apply_filter_transpose, (q, wf))
    assert torch.autograd.gradcheck(lambda z, q: filter_grad(z, q, size), (z, q))


def test_target_model_and_residual_gradcheck(problem) -> None:
    x, labels, v, gamma, wp, wf = problem(7, b=1, k=2, d=3, c=2, h=3, w=4, big=(5, 7))
    x, labels, gamma, wp, wf = (t.requires_grad_() for t in (x, labels, gamma, wp, wf))
    assert torch.autograd.gradcheck(TargetModel(), (x, wp, wf))

    def residual(x, labels, gamma, wp, wf):
        return tuple(TargetModelLoss(x, labels, v, gamma, (0.3, 0.2)).residual(wp, wf))

    assert torch.autograd.gradcheck(residual, (x, labels, gamma, wp, wf))
