"""Area resizing of images in numpy: ``torch.nn.functional.interpolate(mode="area")`` (adaptive average pooling),
as the networks saw their inputs in training."""

from __future__ import annotations

import numpy as np


def pooling_matrix(size_in: int, size_out: int) -> np.ndarray:
    """(size_out, size_in) float32 averaging matrix: output i is the mean of inputs floor(i n / m) ..
    ceil((i + 1) n / m) - 1 (adaptive average pooling of n = size_in to m = size_out)."""
    out = np.zeros((size_out, size_in), np.float32)
    for i in range(size_out):
        start, end = (i * size_in) // size_out, -((-(i + 1) * size_in) // size_out)
        out[i, start:end] = 1.0 / (end - start)
    return out


def area_resize(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Resize (..., H, W) float arrays to (..., h, w) by adaptive average pooling along each axis."""
    h, w = size
    if image.shape[-2:] == (h, w):
        return image
    rows, columns = pooling_matrix(image.shape[-2], h), pooling_matrix(image.shape[-1], w)
    return np.matmul(np.matmul(rows, image.astype(np.float32, copy=False)), columns.T)
