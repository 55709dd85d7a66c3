"""First-frame augmentation geometry and decoder shapes / gradient flow."""

import pytest
import torch
import torch.nn.functional as F

from core.errors import InputError
from models.backbones import ResNetBackbone
from models.vos.augment import SCALES, first_frame_augment, inpaint_target
from models.vos.decoder import SegmentationDecoder, bicubic_upsample2x


def test_augmentation_keeps_original_and_scales_area() -> None:
    image = torch.rand(3, 96, 128)
    mask = torch.zeros(96, 128)
    mask[40:56, 50:70] = 1  # 320 px
    images, masks = first_frame_augment(image, mask, num_aug=9, seed=3)
    assert images.shape == (9, 3, 96, 128) and masks.shape == (9, 96, 128)
    assert torch.equal(images[0], image) and torch.equal(masks[0], mask)
    areas = masks[1:].sum((1, 2)) / mask.sum()
    # rotation and skew preserve area; each area must be one of the scale factors squared (blur keeps the sum)
    allowed = torch.tensor([s * s for s in SCALES])
    assert ((areas[:, None] - allowed[None]).abs() / allowed[None]).min(1).values.max() < 0.08
    # the pasted target carries the target's pixels: mean colour inside the new mask stays close
    inside = (images[1:] * masks[1:, None]).sum((2, 3)) / masks[1:, None].sum((2, 3))
    ref = image[:, mask > 0].mean(1)
    assert (inside - ref).abs().max() < 0.15
    again = first_frame_augment(image, mask, num_aug=9, seed=3)
    assert torch.equal(again[0], images)


def test_inpainting_removes_target() -> None:
    image = torch.zeros(3, 40, 40)
    image[1] = 0.5
    image[:, 15:25, 15:25] = 1.0
    mask = torch.zeros(40, 40)
    mask[15:25, 15:25] = 1
    bg = inpaint_target(image, mask)
    assert (bg[:, 15:25, 15:25] - torch.tensor([0, 0.5, 0])[:, None, None]).abs().max() < 0.05


def test_augmentation_errors() -> None:
    with pytest.raises(InputError, match="empty"):
        first_frame_augment(torch.rand(3, 8, 8), torch.zeros(8, 8))
    with pytest.raises(InputError, match=r"\(3, H, W\)"):
        first_frame_augment(torch.rand(3, 8, 8), torch.ones(8, 9))


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
