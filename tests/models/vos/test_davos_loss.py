"""The DAVOS loss against the text of thesis ch. 6.2: soft loss masking of the distractor channel and the
clamped weight of the distractor term."""

import pytest
import torch

from core.errors import InputError
from models.vos.davos_loss import davos_loss, distractor_loss_mask, distractor_term_weight
from models.vos.losses import segmentation_loss


def _maps():
    target = torch.zeros(2, 6, 8)
    target[:, 1:4, 1:4] = 1  # 9 target pixels
    distractor = torch.zeros(2, 6, 8)
    distractor[0, 2:5, 5:8] = 1  # 9 distractor pixels in sample 0 only
    return target, distractor


def test_loss_mask_cases_follow_the_text() -> None:
    target, _ = _maps()
    mask = distractor_loss_mask(target, torch.tensor([True, False]))
    # a sample with annotated distractors supervises the distractor output everywhere
    assert mask[0].all()
    # without distractor annotations: required to be zero under the target, free elsewhere
    assert torch.equal(mask[1], target[1] > 0.5)


def test_distractor_term_weight_is_clamped_ratio() -> None:
    target, distractor = _maps()
    distractor[1, :, :] = 1  # 48 distractor pixels against 9 target pixels
    torch.testing.assert_close(distractor_term_weight(target, distractor), torch.tensor([1.0, 9 / 48]))
    # no distractor pixels: weight 1; more target than distractor pixels: clamped to 1
    torch.testing.assert_close(distractor_term_weight(target, torch.zeros_like(target)), torch.ones(2))


@pytest.mark.parametrize("soft", [True, False])
def test_loss_is_target_term_plus_weighted_masked_distractor_term(soft: bool) -> None:
    target, distractor = _maps()
    logits = torch.randn(2, 2, 6, 8, generator=torch.Generator().manual_seed(0))
    has = torch.tensor([True, False])
    got = davos_loss(logits, target, distractor, has, "lovasz", soft)
    mask = distractor_loss_mask(target, has) if soft else torch.ones_like(target, dtype=torch.bool)
    terms = [segmentation_loss(logits[i : i + 1, 1], distractor[i : i + 1], "lovasz", mask=mask[i : i + 1])
             for i in range(2)]
    want = segmentation_loss(logits[:, 0], target, "lovasz") + (terms[0] + terms[1]) / 2
    torch.testing.assert_close(got, want)


def test_invented_distractors_cost_nothing_off_the_target_with_the_soft_loss() -> None:
    target, _ = _maps()
    none = torch.zeros_like(target)
    logits = torch.full((2, 2, 6, 8), -3.0)
    logits[:, 0] = torch.where(target > 0.5, 3.0, -3.0)
    calm = davos_loss(logits, target, none, torch.tensor([False, False]))
    logits[:, 1, 4:, 5:] = 3.0  # the decoder marks a look-alike nobody annotated
    assert float(davos_loss(logits, target, none, torch.tensor([False, False]))) == pytest.approx(float(calm))
    assert float(davos_loss(logits, target, none, torch.tensor([False, False]), soft=False)) > float(calm) + 0.5
    logits[:, 1, 2, 2] = 3.0  # ... but never under the target
    assert float(davos_loss(logits, target, none, torch.tensor([False, False]))) > float(calm)


def test_one_channel_is_lwl_and_bad_shapes_fail() -> None:
    target, distractor = _maps()
    logits = torch.randn(2, 1, 6, 8)
    torch.testing.assert_close(davos_loss(logits, target), segmentation_loss(logits[:, 0], target, "lovasz"))
    with pytest.raises(InputError, match="distractor ground truth"):
        davos_loss(torch.randn(2, 2, 6, 8), target)
    with pytest.raises(InputError, match="DAVOS loss"):
        davos_loss(torch.randn(2, 3, 6, 8), target, distractor, torch.tensor([True, True]))
