"""Shared by the reader tests: the formats' forward camera model."""

import pytest
import torch

from data.sfm.reconstruction import Reconstruction


def _reproject_distorted(recon: Reconstruction) -> torch.Tensor:
    """Forward camera model of the format, written out directly: (K, 2) predicted observations."""
    R = recon.rotation[recon.obs_camera]
    t = recon.translation[recon.obs_camera]
    Xc = torch.einsum("kij,kj->ki", R, recon.points[recon.obs_point]) + t
    p = -Xc[:, :2] / Xc[:, 2:]
    r2 = p.square().sum(-1, keepdim=True)
    k = recon.radial[recon.obs_camera]
    return recon.focal[recon.obs_camera, None] * (1 + k[:, :1] * r2 + k[:, 1:] * r2.square()) * p


@pytest.fixture
def reproject_distorted():
    """``reproject_distorted(recon) -> (K, 2)``: the observations the file's cameras and points predict."""
    return _reproject_distorted
