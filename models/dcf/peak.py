"""Peak of a sampled correlation response with sub-bin refinement (parabola through its neighbours)."""

from __future__ import annotations

import torch
from torch import Tensor

from models.dcf._signal import check_signal, wrap_index


def _unravel(flat: Tensor, size: tuple[int, ...]) -> list[Tensor]:
    """Per-axis integer indices (outermost first) of flat indices into ``size``."""
    idx = []
    for n in reversed(size):
        idx.append(flat % n)
        flat = flat // n
    return idx[::-1]


def response_peak(response: Tensor, ndim: int = 2, subpixel: bool = True) -> tuple[Tensor, Tensor]:
    """Circular shift of the maximum of a response map.

    Args:
        response: ``(..., *S)`` real responses in FFT order (zero shift at index 0).
        ndim: number of signal axes (1 or 2).
        subpixel: refine each axis by a parabola through the peak and its two circular neighbours
            (the refinement is at most half a bin, and zero where the three samples are not concave).
    Returns:
        shift: ``(..., ndim)`` float shift in bins, ordered last axis first (``(x, y)`` for images), each in
            ``[-N/2, N/2)`` before refinement.
        value: ``(...)`` response value at the integer peak.
    """
    check_signal(response, ndim, "response")
    size = tuple(response.shape[-ndim:])
    flat = response.flatten(-ndim)
    value, arg = flat.max(dim=-1)
    idx = _unravel(arg, size)
    shifts = []
    for axis in range(ndim):
        n = size[axis]
        shift = wrap_index(idx[axis], n).to(response.dtype)
        if subpixel and n >= 3:
            neighbours = []
            for step in (-1, 1):
                moved = list(idx)
                moved[axis] = torch.remainder(idx[axis] + step, n)
                flat_index = torch.zeros_like(arg)
                for a in range(ndim):
                    flat_index = flat_index * size[a] + moved[a]
                neighbours.append(flat.gather(-1, flat_index.unsqueeze(-1)).squeeze(-1))
            left, right = neighbours
            curvature = left - 2 * value + right
            concave = curvature < 0
            delta = 0.5 * (left - right) / torch.where(concave, curvature, torch.ones_like(curvature))
            shift = shift + torch.where(concave, delta, torch.zeros_like(delta)).clamp(-0.5, 0.5)
        shifts.append(shift)
    return torch.stack(shifts[::-1], dim=-1), value
