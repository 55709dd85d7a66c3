"""Reconstruction helpers: radial undistortion inverts the Bundler/BAL distortion model."""

import torch

from data.sfm.reconstruction import undistort_radial


def test_undistortion_inverts_the_distortion_model():
    g = torch.Generator().manual_seed(0)
    p = (torch.rand(500, 2, generator=g, dtype=torch.float64) - 0.5) * 0.8
    f = torch.full((500,), 500.0, dtype=torch.float64)
    k = torch.tensor([[-0.12, 0.03]], dtype=torch.float64).expand(500, 2)
    r2 = p.square().sum(-1, keepdim=True)
    distorted = f[:, None] * (1 + k[:, :1] * r2 + k[:, 1:] * r2.square()) * p
    torch.testing.assert_close(undistort_radial(distorted, f, k), f[:, None] * p, rtol=0, atol=1e-8)
