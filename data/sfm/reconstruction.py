"""A bundle-adjusted reconstruction (Bundler/BAL camera model) and its conversion to triangulation inputs.

Camera model of Bundler and BAL files: ``X_c = R X + t``, ``p = -X_c / X_c.z`` (the camera looks down -Z),
distorted ``p' = f (1 + k1 |p|^2 + k2 |p|^4) p``; image coordinates have their origin at the image centre and
+y up. Observations stay in that frame (pixels); undistortion and the linear cameras ``P = diag(f, f, -1)[R | t]``
(``w > 0`` in front) make them fit the pinhole solvers of ``models.geometry``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from core.errors import InputError


@dataclass
class Reconstruction:
    """Cameras, reference points and observations of one reconstruction.

    Attributes:
        focal: (C,) focal lengths in px (0 for unregistered cameras).
        radial: (C, 2) radial distortion (k1, k2).
        rotation: (C, 3, 3) world-to-camera rotations.
        translation: (C, 3) translations.
        points: (M, 3) the file's (bundle-adjusted) 3D points.
        colors: (M, 3) uint8 colours (zeros when the format has none).
        obs_camera, obs_point: (K,) camera and point index of each observation, in file order.
        obs_xy: (K, 2) observed image points in px (centred, +y up, distorted).
    """

    focal: Tensor
    radial: Tensor
    rotation: Tensor
    translation: Tensor
    points: Tensor
    colors: Tensor
    obs_camera: Tensor
    obs_point: Tensor
    obs_xy: Tensor

    @property
    def registered(self) -> Tensor:
        """(C,) cameras with a pose (Bundler writes all zeros for the others)."""
        return self.focal != 0

    def linear_cameras(self) -> Tensor:
        """(C, 3, 4) pinhole cameras ``diag(f, f, -1) [R | t]`` with ``w > 0`` in front."""
        Rt = torch.cat((self.rotation, self.translation.unsqueeze(-1)), dim=-1)
        scale = torch.stack((self.focal, self.focal, -torch.ones_like(self.focal)), dim=-1)
        return Rt * scale.unsqueeze(-1)

    def undistorted_observations(self, iterations: int = 20) -> Tensor:
        """(K, 2) observations with radial distortion removed, by fixed-point iteration of the model."""
        return undistort_radial(self.obs_xy, self.focal[self.obs_camera], self.radial[self.obs_camera], iterations)

    def tracks(self, views: int) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        """Triangulation inputs for every point seen by at least ``views`` registered cameras.

        Uses each such point's first ``views`` observations in file order.

        Returns:
            P: (B, views, 3, 4) cameras; x: (B, views, 2) undistorted observations in px;
            reference: (B, 3) the file's points; index: (B,) their indices in the file.
        """
        if views < 2:
            raise InputError(f"--views must be at least 2, got {views}")
        keep = self.registered[self.obs_camera]
        cam, pt = self.obs_camera[keep], self.obs_point[keep]
        xy = self.undistorted_observations()[keep]
        order = torch.argsort(pt, stable=True)
        cam, pt, xy = cam[order], pt[order], xy[order]
        counts = torch.bincount(pt, minlength=self.points.shape[0])
        first = torch.cumsum(counts, 0) - counts
        rank = torch.arange(pt.shape[0]) - first[pt]
        chosen = (counts[pt] >= views) & (rank < views)
        index = torch.nonzero(counts >= views).squeeze(1)
        P = self.linear_cameras()[cam[chosen]].reshape(-1, views, 3, 4)
        x = xy[chosen].reshape(-1, views, 2)
        return P, x, self.points[index], index


def undistort_radial(xy: Tensor, focal: Tensor, radial: Tensor, iterations: int = 20) -> Tensor:
    """Invert ``p' = f (1 + k1 |p|^2 + k2 |p|^4) p`` for p (fixed point), returning ``f p``.

    Args:
        xy: (K, 2) distorted points in px; focal: (K,) in px; radial: (K, 2) coefficients (k1, k2).
    """
    pd = xy / focal.unsqueeze(-1)
    p = pd
    k1, k2 = radial[:, 0:1], radial[:, 1:2]
    for _ in range(iterations):
        r2 = p.square().sum(-1, keepdim=True)
        p = pd / (1 + k1 * r2 + k2 * r2.square())
    return p * focal.unsqueeze(-1)


def scene_radius(points: Tensor) -> Tensor:
    """Scale of a point cloud: median distance of the points (M, 3) to their median, a scalar."""
    centre = points.median(dim=0).values
    return (points - centre).norm(dim=-1).median()
