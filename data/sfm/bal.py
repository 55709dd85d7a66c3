"""Reader for Bundle Adjustment in the Large (BAL) problem files."""

from __future__ import annotations

from pathlib import Path

import torch
from kornia.geometry.conversions import axis_angle_to_rotation_matrix

from core.tokens import TokenReader
from data.sfm.reconstruction import Reconstruction


def read_bal(path: str | Path) -> Reconstruction:
    """Read a BAL file: ``n_cams n_pts n_obs``, ``n_obs`` lines ``cam pt x y``, 9 values per camera (Rodrigues
    rotation, translation, f, k1, k2), 3 per point. Parsed as a token stream (blank lines occur); errors name
    the file and line.
    """
    tokens = TokenReader(path)
    n_cams = tokens.int("the number of cameras")
    n_pts = tokens.int("the number of points")
    n_obs = tokens.int("the number of observations")
    obs_cam, obs_pt, obs_xy = [], [], []
    for k in range(n_obs):
        cam = tokens.int(f"the camera of observation {k}")
        pt = tokens.int(f"the point of observation {k}")
        if cam >= n_cams or pt >= n_pts:
            raise tokens.error(f"observation {k} refers to camera {cam} / point {pt} outside {n_cams} / {n_pts}")
        obs_cam.append(cam)
        obs_pt.append(pt)
        obs_xy.append(tokens.floats(2, f"observation {k}"))
    cams = torch.tensor([tokens.floats(9, f"camera {i}") for i in range(n_cams)], dtype=torch.float64)
    cams = cams.reshape(n_cams, 9)
    points = torch.tensor([tokens.floats(3, f"point {j}") for j in range(n_pts)], dtype=torch.float64)
    tokens.expect_end()
    return Reconstruction(
        focal=cams[:, 6],
        radial=cams[:, 7:9],
        rotation=axis_angle_to_rotation_matrix(cams[:, 0:3]),
        translation=cams[:, 3:6],
        points=points.reshape(n_pts, 3),
        colors=torch.zeros(n_pts, 3, dtype=torch.uint8),
        obs_camera=torch.tensor(obs_cam, dtype=torch.long),
        obs_point=torch.tensor(obs_pt, dtype=torch.long),
        obs_xy=torch.tensor(obs_xy, dtype=torch.float64).reshape(-1, 2),
    )
