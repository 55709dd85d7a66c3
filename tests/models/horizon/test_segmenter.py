"""HorizonSegmenter: any input width, a crop gives the same rows as the whole panorama, the deployed form."""

import math

import pytest
import torch

from models.horizon.segmenter import HorizonSegmenter, PanoramaSegmenter


@pytest.mark.parametrize("width", [256, 320])
def test_segmenter_takes_any_width(width):
    """Any width; the segmenter gives the same rows for a crop as for the whole panorama (away from the cut)."""
    segmenter = HorizonSegmenter("resnet18", stage="layer2").eval()
    image = torch.rand(2, 3, 32, width)
    whole = segmenter(image)
    assert whole.shape == (2, 2, width)
    with torch.no_grad():
        crop = segmenter(image[..., : width // 2])
    inner = slice(48, width // 2 - 48)
    assert (crop[..., inner] - whole[..., inner]).abs().max() < 0.05 * whole.abs().max()
    # Deployed form: tan elevation = half-image-heights * (H / 2) / (W / 2 pi) for a whole panorama.
    tangent = PanoramaSegmenter(segmenter)(image)
    assert torch.allclose(tangent, whole * 16 / (width / (2 * math.pi)), atol=1e-6)
