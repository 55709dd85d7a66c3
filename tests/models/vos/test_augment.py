"""The tensor form of the first-frame augmentation: the samples of ``core.first_frame_augment`` on the input's
dtype, the input itself as sample 0, bad input."""

import numpy as np
import pytest
import torch

from core import first_frame_augment as core_augment
from core.errors import InputError
from models.vos.augment import FirstFrameAugment, first_frame_augment


def test_tensor_augmentation_is_the_numpy_one() -> None:
    image = torch.rand(3, 48, 64, generator=torch.Generator().manual_seed(0))
    mask = torch.zeros(48, 64)
    mask[10:30, 20:40] = 1
    images, masks = FirstFrameAugment(num_aug=4, seed=5)(image, mask)
    ref_images, ref_masks = core_augment.first_frame_augment(image.numpy(), mask.numpy(), 4, 5)
    assert images.dtype == torch.float32 and torch.equal(images[0], image) and torch.equal(masks[0], mask)
    np.testing.assert_array_equal(images.numpy(), ref_images)
    np.testing.assert_array_equal(masks.numpy(), ref_masks)
    double = first_frame_augment(image.double(), mask.double(), 4, 5)[0]
    assert double.dtype == torch.float64 and torch.allclose(double.float(), images)


def test_bad_input() -> None:
    with pytest.raises(InputError, match=r"\(3, H, W\)"):
        first_frame_augment(torch.rand(3, 8, 8), torch.ones(8, 9))
