"""LWL target-model operators against per-problem conv2d loops and autograd."""

import pytest
import torch
import torch.nn.functional as F

from core.errors import InputError
from models.vos import lwl_target_model
from models.vos.lwl_target_model import FeatureProjection, LWLResidual, apply_filter, check_problem, filter_gradient


def _problem(seed: int, dtype=torch.float64, b=2, s=3, p=5, k=4, h=6, w=7, size=3):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(b, s, p, h, w, generator=g, dtype=dtype)
    tau = torch.randn(b, k, p, size, size, generator=g, dtype=dtype)
    enc = torch.rand(b, s, k, h, w, generator=g, dtype=dtype)
    wts = torch.rand(b, s, k, h, w, generator=g, dtype=dtype) + 0.5
    gamma = torch.rand(b, s, generator=g, dtype=dtype)
    return x, tau, enc, wts, gamma


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("size", [1, 3, 5])
def test_apply_filter_equals_per_problem_convolutions(dtype: torch.dtype, size: int) -> None:
    x, tau, *_ = _problem(0, dtype, size=size)
    ref = torch.stack([F.conv2d(x[i], tau[i], padding=size // 2) for i in range(x.shape[0])])
    tol = 1e-5 if dtype == torch.float32 else 1e-12
    torch.testing.assert_close(apply_filter(x, tau), ref, rtol=tol, atol=tol)


@pytest.mark.parametrize("export_form", [False, True])
@pytest.mark.parametrize("size", [1, 3, 5])
def test_filter_gradient_is_the_adjoint_in_the_filter(size: int, export_form: bool, monkeypatch) -> None:
    """Both forms (the convolution; in an export the product with the residual's windows) against autograd."""
    x, tau, enc, *_ = _problem(1, size=size)
    tau = tau.requires_grad_(True)
    (ref,) = torch.autograd.grad((apply_filter(x, tau) * enc).sum(), tau)
    monkeypatch.setattr(lwl_target_model, "exporting", lambda: export_form)
    torch.testing.assert_close(filter_gradient(x, enc, size), ref, rtol=1e-12, atol=1e-12)


def test_residual_products_match_autograd() -> None:
    x, tau, enc, wts, gamma = _problem(2)
    problem = LWLResidual(x, enc, wts, gamma, 0.3)
    t = tau.clone().requires_grad_(True)
    data = gamma.sqrt()[..., None, None, None] * wts * (apply_filter(x, t) - enc)
    loss = (data**2).sum() / 2 + (0.3 * t).pow(2).sum() / 2
    (g_ref,) = torch.autograd.grad(loss, t)
    torch.testing.assert_close(problem.data(tau), data.detach(), rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(problem.gradient(tau, problem.data(tau)), g_ref, rtol=1e-10, atol=1e-12)
    d = torch.randn_like(tau)
    _, jd = torch.func.jvp(lambda f: gamma.sqrt()[..., None, None, None] * wts * apply_filter(x, f), (tau,), (d,))
    torch.testing.assert_close(problem.jvp_data(d), jd, rtol=1e-12, atol=1e-12)


def test_feature_projection_scales_each_sample_to_the_filter_norm() -> None:
    torch.manual_seed(0)
    proj = FeatureProjection(12, channels=8, filter_size=3)
    out = proj(torch.randn(3, 12, 9, 11) * torch.tensor([1.0, 10.0, 100.0])[:, None, None, None])
    rms = out.pow(2).mean(dim=(1, 2, 3)).sqrt()
    torch.testing.assert_close(rms, torch.full((3,), (1 / (8 * 9)) ** 0.5), rtol=1e-5, atol=1e-7)


def test_check_problem_names_the_mismatch() -> None:
    x, tau, enc, wts, gamma = _problem(3)
    check_problem(x, tau, enc, wts, gamma)
    with pytest.raises(InputError, match="B, S, K, h, w"):
        check_problem(x, tau, enc[:, :, :2], wts, gamma)
    with pytest.raises(InputError, match="does not fit"):
        check_problem(x, tau[:, :, :3], enc, wts, gamma)
    with pytest.raises(InputError, match="sample weights"):
        check_problem(x, tau, enc, wts, gamma[:, :2])
    with pytest.raises(InputError, match="must be"):
        check_problem(x[0], tau, enc, wts, gamma)
