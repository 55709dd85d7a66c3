"""Merging per-object predictions: soft aggregation against eq. 5.3, a single object at threshold one half."""

import numpy as np
import pytest
import torch

from models.vos.merge import merge_objects, soft_aggregate


def test_soft_aggregation_is_eq_5_3_with_background() -> None:
    g = torch.Generator().manual_seed(0)
    logits = torch.randn(3, 5, 6, generator=g, dtype=torch.float64) * 3
    p = torch.sigmoid(logits).numpy()
    p0 = np.prod(1 - p, axis=0, keepdims=True)
    allp = np.concatenate([p0, p])
    odds = allp / (1 - allp)
    np.testing.assert_allclose(soft_aggregate(logits).numpy(), odds / odds.sum(0, keepdims=True), rtol=1e-9)
    labels, soft = merge_objects(logits, torch.tensor([4, 7, 9]))
    ref = np.array([0, 4, 7, 9])[np.argmax(odds, 0)]
    assert np.array_equal(labels.numpy(), ref)
    assert torch.equal(soft > 0, torch.stack([labels == i for i in (4, 7, 9)]))


def test_single_object_is_threshold_half() -> None:
    logits = torch.linspace(-3, 3, 61).view(1, 1, 61)
    labels, _ = merge_objects(logits)
    assert torch.equal(labels[0], (logits[0, 0] > 0).long())
    with pytest.raises(ValueError, match="N >= 1"):
        soft_aggregate(torch.zeros(0, 2, 2))
