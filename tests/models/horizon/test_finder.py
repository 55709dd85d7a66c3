"""HorizonFinder: Fourier pooling against a loop, any input width, unit (sin, cos) outputs."""

import math

import pytest
import torch

from models.horizon.finder import HorizonFinder, fourier_pool, sincos_to_angles


def test_fourier_pool_matches_a_loop():
    x = torch.randn(2, 3, 10, dtype=torch.float64)
    out = fourier_pool(x).reshape(2, 3, 3)
    for j, weight in enumerate((lambda p: 1.0, lambda p: 2 * math.cos(p), lambda p: 2 * math.sin(p))):
        expected = sum(x[..., c] * weight(2 * math.pi * (c + 0.5) / 10) for c in range(10)) / 10
        assert torch.allclose(out[:, j], expected)


@pytest.mark.parametrize("width", [256, 320])
def test_finder_takes_any_width(width):
    finder = HorizonFinder("resnet18", stage="layer2").eval()
    image = torch.rand(2, 3, 32, width)
    out = finder(image)
    assert out.shape == (2, 4)
    assert torch.allclose(out.reshape(2, 2, 2).norm(dim=-1), torch.ones(2, 2), atol=1e-5)
    pitch, roll = sincos_to_angles(out)
    assert pitch.shape == roll.shape == (2,)


@pytest.mark.parametrize("seed", range(4))
def test_untrained_finder_starts_near_level(seed):
    """An L1 loss on (sin, cos) holds a pair that starts near cos = -1 at 180 degrees, so training starts level."""
    torch.manual_seed(seed)
    pitch, roll = sincos_to_angles(HorizonFinder("resnet18", stage="layer2").eval()(torch.rand(4, 3, 32, 256)))
    assert torch.cat([pitch, roll]).abs().max() < math.radians(30)
