"""Sample memory weights against the scalar FRTM/pytracking rule."""

import numpy as np
import torch

from models.vos.memory import memory_init, memory_insert


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
