"""Decoder losses against direct per-pixel re-implementations (plain Python float arithmetic)."""

import math

import pytest
import torch

from data.errors import InputError
from models.vos.losses import segmentation_loss, soft_iou_loss


def _reference(logits: torch.Tensor, target: torch.Tensor, pos_weight: float, iou: bool) -> float:
    bce, iou_terms = [], []
    for x_img, t_img in zip(logits.tolist(), target.tolist(), strict=True):
        inter = union = 0.0
        for x_row, t_row in zip(x_img, t_img, strict=True):
            for x, t in zip(x_row, t_row, strict=True):
                p = 1 / (1 + math.exp(-x))
                bce.append(-(pos_weight * t * math.log(p) + (1 - t) * math.log(1 - p)))
                inter += p * t
                union += p + t - p * t
        iou_terms.append(1 - (inter + 1) / (union + 1))
    out = sum(bce) / len(bce)
    return out + sum(iou_terms) / len(iou_terms) if iou else out


@pytest.mark.parametrize(("kind", "pos_weight"), [("bce", 1.0), ("bce", 4.0), ("bce_iou", 1.0), ("bce_iou", 2.5)])
def test_segmentation_loss_matches_reference(kind: str, pos_weight: float) -> None:
    gen = torch.Generator().manual_seed(0)
    logits = 3 * torch.randn(3, 5, 7, generator=gen, dtype=torch.float64)
    target = (torch.rand(3, 5, 7, generator=gen, dtype=torch.float64) > 0.8).double()
    target[1] = 0  # an empty mask
    target[2, 0, 0] = 0.5  # a soft label
    got = float(segmentation_loss(logits, target, kind, pos_weight))
    assert got == pytest.approx(_reference(logits, target, pos_weight, kind == "bce_iou"), rel=1e-12)


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
