"""ASCII PLY point-cloud writer."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from torch import Tensor

from core.errors import InputError


def write_ply(path: str | Path, points: Tensor, colors: Tensor | None = None) -> None:
    """Write points (M, 3) and optional uint8 colours (M, 3) as an ASCII PLY file.

    The file is written to a temporary name beside ``path`` and renamed, so a failure leaves nothing half-written.
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise InputError(f"{path}: the folder {path.parent} does not exist")
    xyz = points.detach().cpu().double().numpy()
    header = ["ply", "format ascii 1.0", f"element vertex {len(xyz)}", "property double x", "property double y",
              "property double z"]
    if colors is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
        rows = np.concatenate((xyz, colors.detach().cpu().numpy().astype(np.float64)), axis=1)
        fmt = "%.9g %.9g %.9g %d %d %d"
    else:
        rows, fmt = xyz, "%.9g %.9g %.9g"
    tmp = path.with_name(path.name + ".partial")
    with tmp.open("w") as handle:
        handle.write("\n".join([*header, "end_header"]) + "\n")
        np.savetxt(handle, rows, fmt=fmt)
    os.replace(tmp, path)
