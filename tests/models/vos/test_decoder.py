"""Segmentation decoder: shapes, gradient flow, independent objects, bicubic 2x upsampling, initialisation, the
test-time flip average."""

import pytest
import torch
import torch.nn.functional as F

from core.errors import InputError
from models.backbones import ResNetBackbone
from models.vos.decoder import SegmentationDecoder, bicubic_upsample2x, flip_averaged_logits


def test_decoder_shapes_shared_features_and_gradients() -> None:
    backbone = ResNetBackbone("resnet18")
    decoder = SegmentationDecoder(backbone.channels, mdim=16)
    feats = backbone(torch.rand(1, 3, 64, 96))
    score = torch.randn(3, 1, 4, 6, requires_grad=True)
    out = decoder(score, feats, (64, 96))
    assert out.shape == (3, 1, 64, 96)
    out.sum().backward()
    assert score.grad.abs().sum() > 0 and all(p.grad is not None for p in decoder.parameters())
    # objects are decoded independently: one object's output does not depend on another's score
    decoder.eval()
    a = decoder(score.detach(), feats, (64, 96))
    s2 = score.detach().clone()
    s2[1] += 5
    b = decoder(s2, feats, (64, 96))
    assert torch.allclose(a[0], b[0]) and not torch.allclose(a[1], b[1])


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("size", [(1, 1), (2, 5), (7, 3), (24, 40)])
def test_bicubic_upsample2x_equals_interpolate(dtype: torch.dtype, size: tuple[int, int]) -> None:
    gen = torch.Generator().manual_seed(0)
    x = torch.randn(2, 3, *size, generator=gen, dtype=dtype, requires_grad=True)
    g = torch.randn(2, 3, 2 * size[0], 2 * size[1], generator=gen, dtype=dtype)
    ours = bicubic_upsample2x(x)
    (grad_ours,) = torch.autograd.grad(ours, x, g)
    ref = F.interpolate(x, scale_factor=2.0, mode="bicubic", align_corners=False)
    (grad_ref,) = torch.autograd.grad(ref, x, g)
    tol = 1e-5 if dtype == torch.float32 else 1e-12
    torch.testing.assert_close(ours, ref, atol=tol, rtol=tol)
    torch.testing.assert_close(grad_ours, grad_ref, atol=tol, rtol=tol)


@pytest.mark.parametrize("size", [(1, 1), (3, 4)])
def test_bicubic_upsample2x_gradcheck(size: tuple[int, int]) -> None:
    x = torch.randn(1, 2, *size, generator=torch.Generator().manual_seed(2), dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(bicubic_upsample2x, (x,))


def test_bicubic_upsample2x_rejects_non_4d() -> None:
    with pytest.raises(InputError, match="N, C, H, W"):
        bicubic_upsample2x(torch.zeros(3, 4, 5))


def test_decoder_he_initialisation() -> None:
    torch.manual_seed(0)
    decoder = SegmentationDecoder({"layer1": 64, "layer2": 128, "layer3": 256, "layer4": 512}, 64)
    for module in decoder.modules():
        if isinstance(module, torch.nn.Conv2d) and module is not decoder.upsampler.conv2:
            fan_in = module.weight[0].numel()
            assert abs(module.weight.std().item() / (2 / fan_in) ** 0.5 - 1) < 0.15
            assert not module.bias.any()


def test_flip_averaged_logits_mirror_symmetry_and_mean() -> None:
    """Mirrored inputs give the mirrored logits (exactly, in float64), and the result is the mean of the plain
    decoder's logits and those of the mirrored inputs mirrored back."""
    torch.manual_seed(0)
    backbone = ResNetBackbone("resnet18").double().eval()
    decoder = SegmentationDecoder(backbone.channels, mdim=8).double().eval()
    image = torch.rand(1, 3, 64, 96, dtype=torch.float64)
    with torch.no_grad():
        feats, mirrored = backbone(image), backbone(image.flip(-1))
        score = torch.randn(2, 1, 4, 6, dtype=torch.float64)
        out = flip_averaged_logits(decoder, score, feats, mirrored, (64, 96))
        swapped = flip_averaged_logits(decoder, score.flip(-1), mirrored, feats, (64, 96))
        plain, other = decoder(score, feats, (64, 96)), decoder(score.flip(-1), mirrored, (64, 96)).flip(-1)
    assert out.shape == (2, 1, 64, 96)
    torch.testing.assert_close(swapped, out.flip(-1), rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(out, (plain + other) / 2, rtol=1e-12, atol=1e-12)
    assert (plain - other).abs().max() > 1e-3  # the mirrored frame changes the logits

