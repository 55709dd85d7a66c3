"""Shared by the target-model and optimizer tests: seeded target-model problems and the eq. 5.2 residual
written with plain per-problem convolutions."""

import pytest
import torch
import torch.nn.functional as F

from models.vos.target_model import hinge_pixel_weights, target_model_init


def _problem(seed: int, dtype=torch.float64, b=2, k=3, d=6, c=4, h=5, w=7, big=(17, 23)):
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(b, k, d, h, w, generator=g, dtype=dtype).relu()
    labels = (torch.rand(b, k, *big, generator=g, dtype=dtype) > 0.7).to(dtype)
    v = hinge_pixel_weights(labels)
    gamma = torch.rand(b, k, generator=g, dtype=dtype) + 0.1
    wp, wf = target_model_init(b, d, c, 3, seed=seed, dtype=dtype)
    return x, labels, v, gamma, wp, wf


def _reference_residual(x, labels, v, gamma, wp, wf, reg):
    """Eq. 5.2 residual written with plain conv2d per problem and F.interpolate."""
    out = []
    for i in range(x.shape[0]):
        z = F.conv2d(x[i], wp[i][..., None, None])
        s = F.conv2d(z, wf[i][None], padding=wf.shape[-1] // 2)
        up = F.interpolate(s, size=labels.shape[-2:], mode="bilinear", align_corners=False)[:, 0]
        out.append(gamma[i].sqrt()[:, None, None] * v[i] * (up - labels[i]))
    return [torch.stack(out), reg[0] * wp, reg[1] * wf]


@pytest.fixture
def problem():
    """``problem(seed, dtype, b, k, d, c, h, w, big) -> x, labels, v, gamma, wp, wf``: a seeded random problem."""
    return _problem


@pytest.fixture
def reference_residual():
    """``reference_residual(x, labels, v, gamma, wp, wf, reg)``: the eq. 5.2 residual by per-problem conv2d."""
    return _reference_residual
