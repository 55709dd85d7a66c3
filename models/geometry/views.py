"""Cameras and observations as per-entry tensors with the views stacked in front.

The triangulation solvers work on one tensor per matrix entry, shaped (N, B) with N views and B points, rather
than on small (B, N, 3, 4) blocks: every operation is then element-wise over all views and points at once,
which keeps eager PyTorch free of tiny batched matmuls (and its op count independent of N), lets
``torch.compile`` fuse a whole solve, and exports to a flat ONNX graph. Cameras shared by all points stay
(N, 1) tensors and broadcast for free.
"""

from __future__ import annotations

from typing import NamedTuple

from torch import Tensor


class Views(NamedTuple):
    """All views: camera entries ``P[r][c]`` as (N, B|1) tensors and observations x, y as (N, B) tensors in px."""

    P: tuple[tuple[Tensor, ...], ...]
    x: Tensor
    y: Tensor


def split_views(P: Tensor, x: Tensor) -> Views:
    """(B|1, N, 3, 4) cameras and (B, N, 2) observations -> ``Views`` of per-entry (N, B|1) tensors."""
    Pt = P.permute(1, 2, 3, 0)
    # The reshape makes the (2N, B) layout explicit: onnxruntime's transpose optimiser otherwise moves the
    # transpose behind the element-wise ops, which then broadcast the cameras over a (B, N) layout, 30 % slower.
    num_views = x.shape[1]
    xt = x.permute(2, 1, 0).reshape(2 * num_views, -1)
    return Views(tuple(tuple(Pt[:, r, c] for c in range(4)) for r in range(3)), xt[:num_views], xt[num_views:])


def dot3(a: tuple[Tensor, ...] | list[Tensor], b: tuple[Tensor, ...] | list[Tensor]) -> Tensor:
    """Dot product of two 3-vectors given as component tuples (extra components are ignored)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
