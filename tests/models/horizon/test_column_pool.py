"""Column pooling: the feature-row position grids and the soft arg-max over the rows of each column."""

import math

import pytest
import torch

from core.cylinder import row_tangents
from models.horizon.column_pool import ColumnPool, row_height_grid, row_tangent_grid


def test_row_tangent_grid_is_the_mean_of_the_input_rows():
    height, width, stride = 64, 512, 8
    rows = row_tangents(height, width, torch.float64).reshape(height // stride, stride).mean(1)
    assert torch.allclose(row_tangent_grid(height // stride, width // stride, torch.float64, None), rows)
    centre_heights = ((height - 1) / 2 - (torch.arange(height // stride) + 0.5) * stride + 0.5) / (height / 2)
    assert torch.allclose(row_height_grid(height // stride, torch.float64, None), centre_heights.double())


def test_column_pool_finds_the_row_of_a_single_bright_row():
    pool = ColumnPool(1, heads=1, head_channels=2).double()
    with torch.no_grad():
        pool.score.weight.fill_(50.0)
        pool.score.bias.zero_()
    features = torch.zeros(1, 1, 8, 16, dtype=torch.float64)
    features[0, 0, 5] = 1.0
    _, position = pool(features)
    assert torch.allclose(position, torch.full_like(position, math.pi * (8 - 2 * 5 - 1) / 16), atol=1e-6)
    pool.full_panorama = False  # heights in half-image-heights: row 5 of 8 is centred 3/8 below the centre
    _, position = pool(features)
    assert torch.allclose(position, torch.full_like(position, -3 / 8), atol=1e-6)


@pytest.mark.parametrize("full_panorama", [True, False])
def test_column_pool_gradcheck(full_panorama):
    """Features and positions are differentiable in the features and in the row scores (the soft arg-max)."""
    torch.manual_seed(0)
    pool = ColumnPool(3, heads=2, head_channels=2, full_panorama=full_panorama).double()
    features = torch.randn(2, 3, 4, 6, dtype=torch.float64, requires_grad=True)
    score = pool.score.weight.detach().clone().requires_grad_()

    def pooled(features, score):
        return torch.func.functional_call(pool, {"score.weight": score}, (features,))

    assert torch.autograd.gradcheck(pooled, (features, score))
