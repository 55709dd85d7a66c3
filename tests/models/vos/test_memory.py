"""Sample memory weights against the scalar FRTM/pytracking rule; soft aggregation against eq. 5.3."""

import numpy as np
import pytest
import torch

from models.vos.memory import memory_init, memory_insert
from models.vos.merge import merge_objects, soft_aggregate


def reference_weights(k: int, capacity: int, inserts: list[bool], lr: float) -> list[float]:
    w = [2.0] + [1.0] * (k - 1)
    w = [v / sum(w) for v in w] + [0.0] * (capacity - k)
    prev = None
    for ok in inserts:
        if not ok:
            continue
        slot = min(range(capacity), key=lambda i: (w[i], i))
        if prev is None:
            w = [v / (1 - lr) for v in w]
            w[slot] = lr
        else:
            w[slot] = w[prev] / (1 - lr)
        prev = slot
        w = [v / sum(w) for v in w]
    return w


def test_memory_weights_follow_the_scalar_rule() -> None:
    b, k, cap = 2, 5, 12
    feats = torch.randn(b, k, 3, 2, 2, dtype=torch.float64)
    labels = torch.rand(b, k, 4, 4, dtype=torch.float64)
    mem = memory_init(feats, labels, torch.ones_like(labels), cap)
    valid_seq = [[True, True], [True, False], [True, True]] * 6
    for t, valid in enumerate(valid_seq):
        f = torch.full((b, 3, 2, 2), float(t), dtype=torch.float64)
        mem = memory_insert(mem, f, torch.zeros(b, 4, 4, dtype=torch.float64), torch.ones(b, 4, 4, dtype=torch.float64),
                            torch.tensor(valid), lr=0.1)
    for i in range(b):
        ref = reference_weights(k, cap, [v[i] for v in valid_seq], 0.1)
        np.testing.assert_allclose(mem.weights[i].numpy(), ref, rtol=1e-12)
        # the newest slot holds the last valid insertion
        last = max(t for t, v in enumerate(valid_seq) if v[i])
        assert mem.features[i, mem.newest[i]].eq(float(last)).all()
    assert mem.weights.sum(1).allclose(torch.ones(b, dtype=torch.float64))


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
