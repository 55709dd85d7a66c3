"""Image noise level, for noise-adaptive (Wiener) filter regularisation.

The estimator is Immerkaer's (1996): the image convolved with the 3 x 3 difference of two Laplacians
``[[1, -2, 1], [-2, 4, -2], [1, -2, 1]]``, which cancels smooth image content up to second order and leaves
white noise of std ``sigma`` with std ``6 sigma``. Where Immerkaer averages the absolute responses, this takes
their median (``sigma = median |L| / (6 * 0.6745)``), so edges and texture, which give the large responses, do
not count as noise. The median is taken over the responses on a grid of every ``stride``-th pixel (a 1/16 sample
at stride 4 gives the same estimate within a few per cent on a 1024 x 436 frame), selected by ``kthvalue`` and, in an
exported graph, by ``topk``, which ONNX has.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from core.errors import InputError
from models.export_mode import exporting

_NOISE_KERNEL = ((1.0, -2.0, 1.0), (-2.0, 4.0, -2.0), (1.0, -2.0, 1.0))
_KERNEL_GAIN = 6.0  # sqrt of the sum of the squared taps: the std of the response to unit white noise
_MAD_TO_STD = 0.6744897501960817  # median of |N(0, 1)|


def image_noise_std(image: Tensor, stride: int = 1) -> Tensor:
    """Std of the white noise in images, in their units.

    Args:
        image: ``(B, 1, H, W)`` gray images, ``H, W >= 3``. stride: evaluate the noise kernel on every
        ``stride``-th pixel of each axis (faster on large images).
    Returns:
        ``(B,)`` noise std.
    """
    if image.dim() != 4 or image.shape[1] != 1 or min(image.shape[-2:]) < 3:
        raise InputError(f"image_noise_std needs (B, 1, H, W) gray images with H, W >= 3, got {tuple(image.shape)}")
    if stride < 1:
        raise InputError(f"stride must be a positive integer, got {stride}")
    kernel = torch.tensor(_NOISE_KERNEL, dtype=image.dtype, device=image.device)[None, None]
    response = F.conv2d(image, kernel, stride=stride).flatten(1).abs()
    rank = response.shape[1] // 2 + 1  # the lower median's
    if exporting():
        median = response.topk(rank, dim=1, largest=False).values[:, -1]
    else:  # the same value, selected without sorting half of the responses (about 2.5x faster)
        median = response.kthvalue(rank, dim=1).values
    return median / (_KERNEL_GAIN * _MAD_TO_STD)


class ImageNoiseStd(nn.Module):
    """Module form of :func:`image_noise_std`: ``(B, 1, H, W)`` -> ``(B,)``."""

    def __init__(self, stride: int = 1) -> None:
        super().__init__()
        self.stride = stride

    def forward(self, image: Tensor) -> Tensor:
        return image_noise_std(image, self.stride)
