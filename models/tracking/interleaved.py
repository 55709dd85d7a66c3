"""Peak and peak-to-sidelobe ratio of many small response maps stored point-interleaved, ``(N, P, N)`` (rows,
points, columns), the layout in which :class:`~models.dcf.dft.RealDft2` returns them.

The same quantities as :func:`models.dcf.response_peak` and :func:`models.dcf.peak_to_sidelobe_ratio` on the
``(P, N, N)`` maps, computed without reordering the maps: maxima and sums reduce over the first and last axes,
and the few values each point needs (peak neighbours, the window around the peak) are gathered by flat index.
Maps are in FFT order (zero shift at index 0) and periodic.
"""

from __future__ import annotations

import torch
from torch import Tensor

from models.dcf._signal import wrap_index
from models.export_mode import exporting


def interleaved_argmax(score: Tensor, weight: Tensor | None = None) -> tuple[Tensor, Tensor, Tensor]:
    """Maximum of each map of ``score`` ``(N, P, N)``: value, row and column index, each ``(P,)``; with a
    ``weight`` (broadcasting to the maps, e.g. ``(N, 1, N)``) the maximum of ``score * weight``, its value read
    from ``score``.

    Reduces over the outer axis first (an element-wise maximum of contiguous slabs, much faster on a CPU than
    a reduction over the short inner axis), then finds the row within the winning column."""
    weighted = score if weight is None else score * weight
    value, column = (_halving_max(weighted) if exporting() else weighted.amax(0)).max(1)
    rows = torch.arange(score.shape[0], device=score.device)[:, None]
    row = _at(weighted, rows, column).argmax(0)  # the winning column of every map
    if weight is not None:
        value = _at(score, row, column)
    return value, row, column


def _halving_max(score: Tensor) -> Tensor:
    """``score.amax(0)`` as element-wise maxima of two halves, ``ceil(log2 N)`` rounds (an odd count's halves share
    the middle slab): what an exported graph takes, since onnxruntime's ``ReduceMax`` over the outer axis is about
    2.5x slower (and a chain of ``N - 1`` maxima makes the export much longer)."""
    while score.shape[0] > 1:
        half = (score.shape[0] + 1) // 2
        score = torch.maximum(score[:half], score[score.shape[0] - half :])
    return score[0]


def _flat_index(score: Tensor, row: Tensor, column: Tensor) -> Tensor:
    """Flat index into ``score`` ``(N, P, N)`` of (row, point, column), rows and columns taken circularly.

    ``row`` and ``column`` broadcast together with the point axis either as ``(P,)``, ``(P, a, b)`` (points
    first) or ``(R, P)`` (points last, ``row`` of shape ``(R, 1)``)."""
    n, p, m = score.shape
    points = torch.arange(p, device=score.device)
    if row.dim() == 3 or column.dim() == 3:
        points = points[:, None, None]
    return (torch.remainder(row, n) * p + points) * m + torch.remainder(column, m)


def _at(score: Tensor, row: Tensor, column: Tensor) -> Tensor:
    """The values of ``score`` ``(N, P, N)`` at (row, point, column) as :func:`_flat_index` takes them, shaped as
    the index. Exported as GatherElements (``torch.gather``), which onnxruntime runs several times faster than the
    GatherND of advanced indexing; eager, ``index_select`` on the flat maps (4-5x faster than advanced indexing on
    a CPU)."""
    index = _flat_index(score, row, column)
    if exporting():
        return torch.gather(score.reshape(1, -1), 1, index.reshape(1, -1)).view(index.shape)
    return score.flatten().index_select(0, index.flatten()).view(index.shape)


def interleaved_peak(
    score: Tensor, subpixel: bool = True, argmax: tuple[Tensor, Tensor, Tensor] | None = None
) -> tuple[Tensor, Tensor]:
    """Circular shift of each map's maximum, refined per axis by a parabola through its two neighbours.

    Args:
        score: ``(N, P, N)`` maps. subpixel: add the parabola's offset (at most half a bin, and zero where the
        three samples are not concave). argmax: :func:`interleaved_argmax` of ``score`` if already at hand.
    Returns:
        shift ``(P, 2)`` (x, y) in bins and the value at the integer maximum ``(P,)``.
    """
    value, row, column = interleaved_argmax(score) if argmax is None else argmax
    shifts = []
    for index, size, step in ((column, score.shape[2], (0, 1)), (row, score.shape[0], (1, 0))):  # x, then y
        shift = wrap_index(index, size).to(score.dtype)
        if subpixel and size >= 3:
            left = _at(score, row - step[0], column - step[1])
            right = _at(score, row + step[0], column + step[1])
            curvature = left - 2 * value + right
            concave = curvature < 0
            delta = 0.5 * (left - right) / torch.where(concave, curvature, torch.ones_like(curvature))
            shift = shift + torch.where(concave, delta, torch.zeros_like(delta)).clamp(-0.5, 0.5)
        shifts.append(shift)
    return torch.stack(shifts, dim=-1), value


def interleaved_psr(
    score: Tensor, exclude: int = 11, argmax: tuple[Tensor, Tensor, Tensor] | None = None, eps: float = 1e-12
) -> Tensor:
    """Peak-to-sidelobe ratio ``(g_max - mean_sl) / std_sl`` of each map ``(N, P, N)`` -> ``(P,)``; the sidelobe
    is the map without the ``exclude``-wide (odd) window around the peak (as
    :func:`models.dcf.peak_to_sidelobe_ratio`). ``argmax``: :func:`interleaved_argmax` if already at hand."""
    n, p, m = score.shape
    if exclude < 1 or exclude % 2 == 0 or exclude > min(n, m):
        raise ValueError(f"exclude must be an odd number up to the map size {min(n, m)}, got {exclude}")
    if n * m - exclude * exclude < 2:
        raise ValueError(f"maps of size {(n, m)} leave no sidelobe outside a {exclude}-wide window")
    peak, row, column = interleaved_argmax(score) if argmax is None else argmax
    # statistics of values centred by the map mean (accuracy; the centred map sums to zero), sidelobe = map
    # minus window; reductions over the outer axis first, as in interleaved_argmax
    centre = score.sum(0).sum(1) / (n * m)
    squares = score.square().sum(0).sum(1) - n * m * centre.square()
    offsets = torch.arange(exclude, device=score.device) - exclude // 2
    rows = (row[:, None] + offsets)[:, :, None]
    cols = (column[:, None] + offsets)[:, None, :]
    window = _at(score, rows, cols).flatten(1) - centre[:, None]  # (P, exclude^2)
    count = n * m - exclude * exclude
    mean = -window.sum(-1) / count
    var = ((squares - window.square().sum(-1)) / count - mean.square()).clamp_min(0)
    return (peak - centre - mean) / (var.sqrt() + eps)
