"""Decoder losses against direct per-pixel re-implementations (plain Python float arithmetic)."""

import math

import pytest
import torch

from core.errors import InputError
from models.vos.losses import lovasz_hinge, segmentation_loss, soft_iou_loss


def _near_contour(t_img: list[list[float]], i: int, j: int, radius: int) -> bool:
    """Does the (clipped) window of ``radius`` around (i, j) hold both foreground and background?"""
    values = {t_img[a][b] > 0.5 for a in range(max(0, i - radius), min(len(t_img), i + radius + 1))
              for b in range(max(0, j - radius), min(len(t_img[0]), j + radius + 1))}
    return len(values) == 2


def _reference(logits: torch.Tensor, target: torch.Tensor, pos_weight: float, iou: bool,
               boundary_weight: float = 0.0, radius: int = 2) -> float:
    bce, iou_terms = [], []
    for x_img, t_img in zip(logits.tolist(), target.tolist(), strict=True):
        inter = union = 0.0
        for i, (x_row, t_row) in enumerate(zip(x_img, t_img, strict=True)):
            for j, (x, t) in enumerate(zip(x_row, t_row, strict=True)):
                p = 1 / (1 + math.exp(-x))
                w = 1 + boundary_weight * _near_contour(t_img, i, j, radius)
                bce.append(-w * (pos_weight * t * math.log(p) + (1 - t) * math.log(1 - p)))
                inter += p * t
                union += p + t - p * t
        iou_terms.append(1 - (inter + 1) / (union + 1))
    out = sum(bce) / len(bce)
    return out + sum(iou_terms) / len(iou_terms) if iou else out


@pytest.mark.parametrize(("kind", "pos_weight", "boundary_weight"),
                         [("bce", 1.0, 0.0), ("bce", 4.0, 0.0), ("bce_iou", 1.0, 0.0), ("bce_iou", 2.5, 0.0),
                          ("bce", 1.0, 3.0), ("bce_iou", 2.0, 4.0)])
def test_segmentation_loss_matches_reference(kind: str, pos_weight: float, boundary_weight: float) -> None:
    gen = torch.Generator().manual_seed(0)
    logits = 3 * torch.randn(3, 5, 7, generator=gen, dtype=torch.float64)
    target = (torch.rand(3, 5, 7, generator=gen, dtype=torch.float64) > 0.8).double()
    target[1] = 0  # an empty mask
    target[2, 0, 0] = 0.5  # a soft label
    got = float(segmentation_loss(logits, target, kind, pos_weight, boundary_weight=boundary_weight))
    want = _reference(logits, target, pos_weight, kind == "bce_iou", boundary_weight)
    assert got == pytest.approx(want, rel=1e-12)


def test_soft_iou_limits_and_small_objects() -> None:
    target = torch.zeros(1, 32, 32)
    target[0, 10:13, 10:13] = 1  # 9 of 1024 pixels
    assert float(soft_iou_loss(torch.full((1, 32, 32), -30.0), torch.zeros(1, 32, 32))) == pytest.approx(0, abs=1e-9)
    perfect = torch.where(target > 0, 30.0, -30.0)
    assert float(soft_iou_loss(perfect, target)) == pytest.approx(0, abs=1e-9)
    # "all background": the BCE is already small, the soft-IoU term stays near its maximum
    background = torch.full((1, 32, 32), -4.0)
    assert float(soft_iou_loss(background, target)) > 0.8
    with pytest.raises(InputError, match="segmentation loss"):
        segmentation_loss(background, target, "dice")


@pytest.mark.parametrize(("kind", "pos_weight", "boundary_weight"), [("bce", 1.0, 0.0), ("bce_iou", 2.5, 3.0)])
def test_segmentation_loss_gradcheck(kind: str, pos_weight: float, boundary_weight: float) -> None:
    gen = torch.Generator().manual_seed(1)
    logits = (3 * torch.randn(2, 6, 7, generator=gen, dtype=torch.float64)).requires_grad_()
    target = (torch.rand(2, 6, 7, generator=gen, dtype=torch.float64) > 0.7).double()
    target[1, 0, 0] = 0.5  # a soft label

    def loss(logits, target):
        return segmentation_loss(logits, target, kind, pos_weight, boundary_weight=boundary_weight)

    assert torch.autograd.gradcheck(loss, (logits, target))  # the target is held (its band is piecewise constant)
    soft = torch.rand(2, 6, 7, generator=gen, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(soft_iou_loss, (logits, soft))


def _lovasz_integral(logits: list, target: list, keep: list) -> float:
    """The Lovasz extension as the integral of the set function f(A) = |A| / |G u A| (Jaccard loss of the
    mispredicted set A) over the level sets {i: e_i >= theta} of the hinge errors e, per image, averaged."""
    total = 0.0
    for x_img, t_img, k_img in zip(logits, target, keep, strict=True):
        idx = [i for i, k in enumerate(k_img) if k]
        fg = {i for i in idx if t_img[i] > 0.5}
        err = {i: max(0.0, 1 - x_img[i] * (1 if i in fg else -1)) for i in idx}
        levels = sorted(set(err.values()) | {0.0})
        for low, high in zip(levels[:-1], levels[1:], strict=True):
            a = {i for i in idx if err[i] >= high}
            total += (high - low) * len(a) / len(fg | a)
    return total / len(logits)


@pytest.mark.parametrize("masked", [False, True])
def test_lovasz_hinge_equals_the_integral_of_the_jaccard_set_function(masked: bool) -> None:
    gen = torch.Generator().manual_seed(2)
    logits = 2 * torch.randn(4, 3, 5, generator=gen, dtype=torch.float64)
    target = (torch.rand(4, 3, 5, generator=gen) > 0.6).double()
    keep = torch.rand(4, 3, 5, generator=gen) > 0.3 if masked else torch.ones(4, 3, 5, dtype=torch.bool)
    keep[3] = not masked  # a fully masked image counts 0
    got = float(lovasz_hinge(logits, target, keep if masked else None))
    want = _lovasz_integral(logits.flatten(1).tolist(), target.flatten(1).tolist(), keep.flatten(1).tolist())
    assert got == pytest.approx(want, rel=1e-12)
    assert float(segmentation_loss(logits, target, "lovasz", mask=keep if masked else None)) == pytest.approx(want)


def test_bce_lovasz_is_the_weighted_bce_plus_the_lovasz_integral() -> None:
    gen = torch.Generator().manual_seed(4)
    logits = 2 * torch.randn(3, 4, 6, generator=gen, dtype=torch.float64)
    target = (torch.rand(3, 4, 6, generator=gen) > 0.6).double()
    target[1] = 0  # an empty mask
    got = float(segmentation_loss(logits, target, "bce_lovasz", 2.0, iou_weight=0.5, boundary_weight=3.0))
    ones = torch.ones(3, 24, dtype=torch.bool).tolist()
    lovasz = _lovasz_integral(logits.flatten(1).tolist(), target.flatten(1).tolist(), ones)
    want = _reference(logits, target, 2.0, False, 3.0) + 0.5 * lovasz
    assert got == pytest.approx(want, rel=1e-12)


def test_lovasz_hinge_is_zero_for_confident_correct_logits_and_masked_bce_is_a_masked_mean() -> None:
    target = torch.zeros(1, 4, 4)
    target[0, 1:3, 1:3] = 1
    assert float(lovasz_hinge(torch.where(target > 0, 2.0, -2.0), target)) == 0
    logits = torch.randn(1, 4, 4, generator=torch.Generator().manual_seed(3))
    mask = torch.zeros(1, 4, 4, dtype=torch.bool)
    mask[0, :2] = True
    full = torch.nn.functional.binary_cross_entropy_with_logits(logits, target, reduction="none")
    got = segmentation_loss(logits, target, "bce", mask=mask)
    torch.testing.assert_close(got, full[mask].mean())
    with pytest.raises(InputError, match="loss mask"):
        segmentation_loss(logits, target, "bce", mask=mask[:, :2])
