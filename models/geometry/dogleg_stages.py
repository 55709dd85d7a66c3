"""The dogleg solver as two graphs, a start and one iteration, so that the caller runs the iterations and stops
as soon as every point converged, as eager :func:`triangulate_dogleg` does (a graph exported with a fixed
iteration count always pays for all of them; most points converge in two).

Tensors between the stages are packed component-major, each row one quantity for all B points:

- ``rows`` (8, 2N, B): the centred residual rows ``M`` (3), ``offset``, ``q`` (3, expanded to B), ``w0`` of
  :class:`~models.geometry.dogleg.CentredRows`;
- ``state`` (16, B): ``d`` (3), ``F``, ``depth``, ``g`` (3), ``H`` (6), ``radius``, ``scale`` of
  :class:`~models.geometry.dogleg.DoglegState`, and ``active`` (B,) bool beside it.

The triangulation is then ``points = (X0 + state[0:3])^T``, ``cost = 2 state[3]``, ``valid = usable & (depth > 0)
& isfinite(cost)`` and ``converged = ~active & valid``.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from models.geometry.dogleg import CentredRows, DoglegState, dogleg_iteration, dogleg_start, midpoint_start

STATE_ROWS = 16


def pack_rows(rows: CentredRows) -> Tensor:
    """``CentredRows`` -> (8, 2N, B), the camera rows ``q`` expanded to all points."""
    like = rows.offset
    return torch.stack((*rows.M, rows.offset, *(q.expand_as(like) for q in rows.q), rows.w0))


def unpack_rows(rows: Tensor) -> CentredRows:
    """(8, 2N, B) -> ``CentredRows``."""
    r = rows.unbind(0)
    return CentredRows(r[0:3], r[3], r[4:7], r[7])  # type: ignore[arg-type]


def pack_state(state: DoglegState) -> tuple[Tensor, Tensor]:
    """``DoglegState`` -> (16, B) float rows and (B,) ``active``."""
    return torch.stack((*state.d, state.F, state.depth, *state.g, *state.H, state.radius, state.scale)), state.active


def unpack_state(state: Tensor, active: Tensor) -> DoglegState:
    """(16, B) float rows and (B,) ``active`` -> ``DoglegState``."""
    s = state.unbind(0)
    return DoglegState(s[0:3], s[3], s[4], list(s[5:8]), list(s[8:14]), s[14], s[15], active)  # type: ignore[arg-type]


class DoglegStart(nn.Module):
    """Midpoint start and the state before the first iteration (exports to ONNX).

    Forward: cameras (B|1, N, 3, 4) and observations (B, N, 2) px -> ``X0`` (3, B), ``usable`` (B,) bool (finite
    input, rays not near-parallel), ``rows`` (8, 2N, B), ``state`` (16, B), ``active`` (B,) bool.
    """

    def __init__(self, tolerance: float | None = None, min_parallax: float = 1e-3) -> None:
        super().__init__()
        self.tolerance = tolerance
        self.min_parallax = min_parallax

    def forward(self, P: Tensor, x: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        views, X0, usable = midpoint_start(P, x, self.min_parallax)
        rows, state = dogleg_start(views, X0, self.tolerance)
        return (torch.stack(X0), usable, pack_rows(rows), *pack_state(state))


class DoglegStep(nn.Module):
    """One dogleg iteration of every active point (exports to ONNX).

    Forward: ``rows`` (8, 2N, B), ``state`` (16, B), ``active`` (B,) -> the next ``state`` and ``active``.
    """

    def __init__(self, tolerance: float | None = None) -> None:
        super().__init__()
        self.tolerance = tolerance

    def forward(self, rows: Tensor, state: Tensor, active: Tensor) -> tuple[Tensor, Tensor]:
        return pack_state(dogleg_iteration(unpack_rows(rows), unpack_state(state, active), self.tolerance))
