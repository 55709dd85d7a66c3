"""Reader for Bundler v0.3 ``.out`` reconstructions (Snavely's bundler_sfm)."""

from __future__ import annotations

from pathlib import Path

import torch

from core.errors import InputError
from core.tokens import TokenReader
from data.sfm.reconstruction import Reconstruction


def read_bundler(path: str | Path) -> Reconstruction:
    """Read a Bundler v0.3 file: header, ``n_cams n_pts``, per camera ``f k1 k2``, R (3x3) and t, per point xyz,
    rgb and the view list ``n (cam key x y)*``. Errors name the file and line.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    with path.open("rb") as handle:
        header = handle.readline().decode("latin-1").strip()
    if not header.startswith("# Bundle file"):
        raise InputError(f"{path}:1: not a Bundler file (expected '# Bundle file v0.3', got {header[:40]!r})")
    tokens = TokenReader(path, skip_comment_lines=True)
    n_cams = tokens.int("the number of cameras")
    n_pts = tokens.int("the number of points")
    cams = torch.tensor([tokens.floats(15, f"camera {i}") for i in range(n_cams)], dtype=torch.float64)
    cams = cams.reshape(n_cams, 15)
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
        focal=cams[:, 0],
        radial=cams[:, 1:3],
        rotation=cams[:, 3:12].reshape(n_cams, 3, 3),
        translation=cams[:, 12:15],
        points=torch.tensor(points, dtype=torch.float64).reshape(n_pts, 3),
        colors=torch.tensor(colors, dtype=torch.float64).reshape(n_pts, 3).clamp(0, 255).to(torch.uint8),
        obs_camera=torch.tensor(obs_cam, dtype=torch.long),
        obs_point=torch.tensor(obs_pt, dtype=torch.long),
        obs_xy=torch.tensor(obs_xy, dtype=torch.float64).reshape(-1, 2),
    )
