"""Image noise estimate: against a NumPy/OpenCV reference of the same median, and on images of known noise."""

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from models.dcf import ImageNoiseStd, image_noise_std


def _textured(h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth random texture (std about 30 gray levels) with sharp-edged rectangles, float64 around 128."""
    image = cv2.GaussianBlur(rng.normal(0, 1, (h, w)), (0, 0), 3.0)
    image = 128 + 30 * image / image.std()
    for _ in range(12):
        x, y = rng.integers(0, w - 20), rng.integers(0, h - 20)
        image[y : y + rng.integers(5, 20), x : x + rng.integers(5, 20)] += rng.uniform(-60, 60)
    return image


def _reference(image: np.ndarray, stride: int) -> float:
    kernel = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float64)
    response = cv2.filter2D(image, cv2.CV_64F, kernel)[1:-1, 1:-1][::stride, ::stride]  # valid, symmetric kernel
    values = np.sort(np.abs(response).ravel())
    return values[values.size // 2] / (6 * 0.6744897501960817)


@pytest.mark.parametrize("stride", [1, 2, 4])
def test_equals_numpy_median_of_the_noise_kernel(stride):
    rng = np.random.default_rng(0)
    images = [_textured(61, 90, rng) for _ in range(2)]
    got = image_noise_std(torch.from_numpy(np.stack(images))[:, None], stride)
    np.testing.assert_allclose(got.numpy(), [_reference(i, stride) for i in images], rtol=1e-12)


@pytest.mark.parametrize("sigma", [1.0, 3.0])
def test_recovers_known_noise_despite_texture_and_edges(sigma):
    rng = np.random.default_rng(1)
    clean = _textured(240, 320, rng)
    noisy = torch.from_numpy(clean + rng.normal(0, sigma, clean.shape))[None, None]
    assert image_noise_std(noisy, 2).item() == pytest.approx(sigma, rel=0.1)


def test_median_is_less_biased_by_texture_than_the_mean():
    """At low noise the mean of |L| (Immerkaer's own average) is pulled up by the edges and the texture."""
    rng = np.random.default_rng(1)
    clean = _textured(240, 320, rng)
    sigma = 0.5
    noisy = torch.from_numpy(clean + rng.normal(0, sigma, clean.shape))[None, None]
    kernel = torch.tensor([[1.0, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=torch.float64)[None, None]
    mean_based = torch.nn.functional.conv2d(noisy, kernel).abs().mean().item() * np.sqrt(np.pi / 2) / 6
    assert abs(mean_based - sigma) > abs(image_noise_std(noisy, 2).item() - sigma)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_exported_median_form_equals_the_eager_one(monkeypatch, dtype):
    # topk in an exported graph, kthvalue in eager mode: the same lower median, to the bit
    from models.dcf import noise

    image = (torch.rand(2, 1, 61, 90, generator=torch.Generator().manual_seed(3)) * 255).to(dtype)
    eager = image_noise_std(image, 2)
    monkeypatch.setattr(noise, "exporting", lambda: True)
    assert torch.equal(image_noise_std(image, 2), eager)


def test_module_and_float32():
    image = torch.rand(3, 1, 40, 50, generator=torch.Generator().manual_seed(2)) * 255
    torch.testing.assert_close(ImageNoiseStd(2)(image), image_noise_std(image, 2))
    assert image_noise_std(image).shape == (3,) and image_noise_std(image).dtype == torch.float32


def test_bad_input():
    with pytest.raises(InputError, match="gray images"):
        image_noise_std(torch.rand(40, 50))
    with pytest.raises(InputError, match="gray images"):
        image_noise_std(torch.rand(1, 3, 40, 50))
    with pytest.raises(InputError, match="stride"):
        image_noise_std(torch.rand(1, 1, 40, 50), 0)
