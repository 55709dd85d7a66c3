"""Area resizing in numpy equals ``F.interpolate(mode="area")`` (integer and fractional factors, identity)."""

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from runtime.area import area_resize, pooling_matrix


@pytest.mark.parametrize("size", [(32, 256), (13, 77), (64, 512), (50, 300)])
def test_area_resize_matches_torch(size) -> None:
    image = torch.rand(2, 3, 64, 512, generator=torch.Generator().manual_seed(0))
    expected = F.interpolate(image, size=size, mode="area").numpy()
    np.testing.assert_allclose(area_resize(image.numpy(), size), expected, atol=1e-6)


def test_pooling_rows_average_their_window() -> None:
    matrix = pooling_matrix(5, 2)  # windows [0, 3) and [2, 5): adaptive pooling overlaps them
    np.testing.assert_allclose(matrix, [[1 / 3, 1 / 3, 1 / 3, 0, 0], [0, 0, 1 / 3, 1 / 3, 1 / 3]])
