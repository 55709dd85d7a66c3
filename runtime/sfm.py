"""Bundler v0.3 and BAL reconstructions in numpy, and the triangulation inputs they give (the runtime's
counterpart of ``data.sfm``: same camera model, same track selection).

Camera model: ``X_c = R X + t``, ``p = -X_c / X_c.z``, distorted ``p' = f (1 + k1 |p|^2 + k2 |p|^4) p`` in px,
origin at the image centre, +y up; undistorted observations fit the linear cameras ``diag(f, f, -1) [R | t]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from core.errors import InputError
from core.tokens import TokenReader


@dataclass
class Reconstruction:
    """Cameras (C,), reference points (M, 3) and observations (K,) of one reconstruction, float64.

    Attributes:
        focal (C,) px (0 = unregistered), radial (C, 2), rotation (C, 3, 3), translation (C, 3), points (M, 3),
        colors (M, 3) uint8, obs_camera / obs_point (K,) int64, obs_xy (K, 2) px (centred, +y up, distorted).
    """

    focal: np.ndarray
    radial: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    points: np.ndarray
    colors: np.ndarray
    obs_camera: np.ndarray
    obs_point: np.ndarray
    obs_xy: np.ndarray

    def linear_cameras(self) -> np.ndarray:
        """(C, 3, 4) pinhole cameras ``diag(f, f, -1) [R | t]`` (``w > 0`` in front)."""
        rt = np.concatenate([self.rotation, self.translation[:, :, None]], -1)
        scale = np.stack([self.focal, self.focal, -np.ones_like(self.focal)], -1)
        return rt * scale[:, :, None]

    def undistorted_observations(self, iterations: int = 20) -> np.ndarray:
        """(K, 2) observations with the radial distortion removed (fixed-point iteration of the model)."""
        focal = self.focal[self.obs_camera][:, None]
        k1, k2 = (self.radial[self.obs_camera, i : i + 1] for i in (0, 1))
        pd = self.obs_xy / focal
        p = pd
        for _ in range(iterations):
            r2 = np.square(p).sum(-1, keepdims=True)
            p = pd / (1 + k1 * r2 + k2 * r2 * r2)
        return p * focal

    def tracks(self, views: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cameras (B, views, 3, 4), undistorted observations (B, views, 2), reference points (B, 3) and file
        indices (B,) of every point seen by at least ``views`` registered cameras (its first ``views`` views in
        file order)."""
        if views < 2:
            raise InputError(f"--views must be at least 2, got {views}")
        keep = self.focal[self.obs_camera] != 0
        cam, pt, xy = self.obs_camera[keep], self.obs_point[keep], self.undistorted_observations()[keep]
        order = np.argsort(pt, kind="stable")
        cam, pt, xy = cam[order], pt[order], xy[order]
        counts = np.bincount(pt, minlength=len(self.points))
        first = np.cumsum(counts) - counts
        rank = np.arange(len(pt)) - first[pt]
        chosen = (counts[pt] >= views) & (rank < views)
        index = np.flatnonzero(counts >= views)
        cameras = self.linear_cameras()[cam[chosen]].reshape(-1, views, 3, 4)
        return cameras, xy[chosen].reshape(-1, views, 2), self.points[index], index


def read_bundler(path: str | Path) -> Reconstruction:
    """A Bundler v0.3 ``.out`` file; errors name the file and line."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    with path.open("rb") as handle:
        header = handle.readline().decode("latin-1").strip()
    if not header.startswith("# Bundle file"):
        raise InputError(f"{path}:1: not a Bundler file (expected '# Bundle file v0.3', got {header[:40]!r})")
    tokens = TokenReader(path, skip_comment_lines=True)
    n_cams, n_pts = tokens.int("the number of cameras"), tokens.int("the number of points")
    cams = np.array([tokens.floats(15, f"camera {i}") for i in range(n_cams)], np.float64).reshape(n_cams, 15)
    points, colors, obs_cam, obs_pt, obs_xy = [], [], [], [], []
    for j in range(n_pts):
        points.append(tokens.floats(3, f"the position of point {j}"))
        colors.append(tokens.floats(3, f"the colour of point {j}"))
        for _ in range(tokens.int(f"the number of views of point {j}")):
            cam = tokens.int(f"a camera index of point {j}")
            if cam >= n_cams:
                raise tokens.error(f"point {j} refers to camera {cam} but the file has {n_cams} cameras")
            tokens.int(f"a feature key of point {j}")
            obs_cam.append(cam)
            obs_pt.append(j)
            obs_xy.append(tokens.floats(2, f"an observation of point {j}"))
    tokens.expect_end()
    return Reconstruction(
        cams[:, 0], cams[:, 1:3], cams[:, 3:12].reshape(n_cams, 3, 3), cams[:, 12:15],
        np.array(points, np.float64).reshape(n_pts, 3),
        np.clip(np.array(colors, np.float64).reshape(n_pts, 3), 0, 255).astype(np.uint8),
        np.array(obs_cam, np.int64), np.array(obs_pt, np.int64), np.array(obs_xy, np.float64).reshape(-1, 2))


def read_bal(path: str | Path) -> Reconstruction:
    """A BAL problem file (Rodrigues rotations); errors name the file and line."""
    tokens = TokenReader(path)
    n_cams, n_pts = tokens.int("the number of cameras"), tokens.int("the number of points")
    n_obs = tokens.int("the number of observations")
    obs = []
    for k in range(n_obs):
        cam, pt = tokens.int(f"the camera of observation {k}"), tokens.int(f"the point of observation {k}")
        if cam >= n_cams or pt >= n_pts:
            raise tokens.error(f"observation {k} refers to camera {cam} / point {pt} outside {n_cams} / {n_pts}")
        obs.append((cam, pt, *tokens.floats(2, f"observation {k}")))
    cams = np.array([tokens.floats(9, f"camera {i}") for i in range(n_cams)], np.float64).reshape(n_cams, 9)
    points = np.array([tokens.floats(3, f"point {j}") for j in range(n_pts)], np.float64).reshape(n_pts, 3)
    tokens.expect_end()
    obs_array = np.array(obs, np.float64).reshape(-1, 4)
    rotation = np.stack([cv2.Rodrigues(r)[0] for r in cams[:, :3]]) if n_cams else np.zeros((0, 3, 3))
    return Reconstruction(cams[:, 6], cams[:, 7:9], rotation, cams[:, 3:6], points, np.zeros((n_pts, 3), np.uint8),
                          obs_array[:, 0].astype(np.int64), obs_array[:, 1].astype(np.int64), obs_array[:, 2:])


def read_reconstruction(path: str | Path, bal: bool = False) -> Reconstruction:
    """A Bundler file, or a BAL file with ``bal``."""
    return read_bal(path) if bal else read_bundler(path)
