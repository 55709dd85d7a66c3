"""Peak-to-sidelobe ratio (Bolme et al. 2010): ``(g_max - mean_sl) / std_sl`` outside a peak window.

The sidelobe is the whole response except a ``exclude``-wide window (per axis, circular) centred on the peak;
the excluded values are left out of the statistics, unlike OpenCV's variants (thesis ch. 3.1).
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

from core.errors import InputError
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
        raise InputError(f"exclude must be a positive odd number, got {exclude}")
    n_side = 1
    for n in size:
        n_side *= n
    excluded = 1
    for n in size:
        excluded *= min(exclude, n)
    if n_side - excluded < 2:
        raise InputError(f"response of size {size} leaves no sidelobe outside a {exclude}-wide window")
    flat = response.flatten(-ndim)
    peak, arg = flat.max(dim=-1)
    # Gather the window around the peak (circularly) instead of masking the whole map; statistics of the sidelobe
    # are those of the whole map minus the window, computed on values centred by the map mean for accuracy.
    centre = flat.mean(-1, keepdim=True)
    shifted = flat - centre
    index = torch.zeros_like(arg).unsqueeze(-1)
    stride = n_side
    for n in size:
        stride //= n
        count = min(exclude, n)
        offsets = torch.arange(count, device=flat.device) - (exclude // 2 if count == exclude else 0)
        i_peak = (arg // stride) % n if count == exclude else torch.zeros_like(arg)
        i_axis = torch.remainder(i_peak.unsqueeze(-1) + offsets, n) * stride
        index = (index.unsqueeze(-1) + i_axis.unsqueeze(-2)).flatten(-2)
    window = shifted.gather(-1, index)
    count = n_side - excluded
    mean = (shifted.sum(-1) - window.sum(-1)) / count
    var = ((shifted.square().sum(-1) - window.square().sum(-1)) / count - mean.square()).clamp_min(0)
    return (peak - centre.squeeze(-1) - mean) / (var.sqrt() + eps)


class PeakToSidelobeRatio(nn.Module):
    """Module form of :func:`peak_to_sidelobe_ratio`."""

    def __init__(self, ndim: int = 2, exclude: int = 11) -> None:
        super().__init__()
        self.ndim, self.exclude = ndim, exclude

    def forward(self, response: Tensor) -> Tensor:
        return peak_to_sidelobe_ratio(response, self.ndim, self.exclude)
