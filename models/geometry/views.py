"""Per-view scalar components of cameras and observations.

The triangulation solvers work on lists of (B,) tensors, one per matrix entry and view, rather than on small
(B, N, 3, 4) blocks: every operation is then element-wise over points, which keeps eager PyTorch free of tiny
batched matmuls, lets ``torch.compile`` fuse a whole solve into one loop, and exports to a flat ONNX graph.
Cameras shared by all points stay (1,) tensors and broadcast for free.
"""

from __future__ import annotations

from typing import NamedTuple

from torch import Tensor


class View(NamedTuple):
    """One view: camera entries ``P[r][c]`` as (B|1,) tensors and the observation (x, y) as (B,) tensors in px."""

    P: tuple[tuple[Tensor, ...], ...]
    x: Tensor
    y: Tensor


def split_views(P: Tensor, x: Tensor) -> list[View]:
    """(B|1, N, 3, 4) cameras and (B, N, 2) observations -> N ``View``s of scalar components."""
    views = []
    for Pi, xi in zip(P.unbind(1), x.unbind(1), strict=True):
        rows = tuple(tuple(Pi[:, r, c] for c in range(4)) for r in range(3))
        views.append(View(rows, xi[:, 0], xi[:, 1]))
    return views


def dot3(a: tuple[Tensor, ...], b: tuple[Tensor, ...]) -> Tensor:
    """Dot product of two 3-vectors given as component tuples."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
