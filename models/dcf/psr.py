"""Peak-to-sidelobe ratio (Bolme et al. 2010): ``(g_max - mean_sl) / std_sl`` over the response minus a
window.

The sidelobe is the whole response except a ``exclude``-wide window (per axis, circular) centred on the peak;
the excluded values are left out of the statistics, unlike OpenCV's variants (see REFERENCE.md 3.1).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from models.dcf._signal import check_signal


def peak_to_sidelobe_ratio(response: Tensor, ndim: int = 2, exclude: int = 11, eps: float = 1e-12) -> Tensor:
    """PSR of each response map.

    Args:
        response: ``(..., *S)`` real responses, ``ndim`` signal axes (periodic).
        exclude: odd side length of the window around the peak that is not sidelobe; must leave at least two
            sidelobe values.
    Returns:
        ``(...)`` PSR (dimensionless).
    """
    check_signal(response, ndim, "response")
    size = tuple(response.shape[-ndim:])
    if exclude < 1 or exclude % 2 == 0:
        raise ValueError(f"exclude must be a positive odd number, got {exclude}")
    n_side = 1
    for n in size:
        n_side *= n
    excluded = 1
    for n in size:
        excluded *= min(exclude, n)
    if n_side - excluded < 2:
        raise ValueError(f"response of size {size} leaves no sidelobe outside a {exclude}-wide window")
    flat = response.flatten(-ndim)
    peak, arg = flat.max(dim=-1)
    inside = torch.ones_like(flat, dtype=torch.bool)
    half = exclude // 2
    view = [1] * (flat.dim() - 1)
    for axis, n in enumerate(size):
        stride = 1
        for m in size[axis + 1 :]:
            stride *= m
        i_peak = (arg // stride) % n
        i_all = (torch.arange(n_side, device=flat.device) // stride) % n
        d = torch.remainder(i_all.view(*view, -1) - i_peak.unsqueeze(-1), n)
        inside = inside & (torch.minimum(d, n - d) <= half)
    side = (~inside).to(flat.dtype)
    count = side.sum(-1)
    mean = (flat * side).sum(-1) / count
    var = ((flat - mean.unsqueeze(-1)).square() * side).sum(-1) / count
    return (peak - mean) / (var.sqrt() + eps)


class PeakToSidelobeRatio(nn.Module):
    """Module form of :func:`peak_to_sidelobe_ratio`."""

    def __init__(self, ndim: int = 2, exclude: int = 11) -> None:
        super().__init__()
        self.ndim, self.exclude = ndim, exclude

    def forward(self, response: Tensor) -> Tensor:
        return peak_to_sidelobe_ratio(response, self.ndim, self.exclude)
