"""Sample memory weights against the scalar FRTM/pytracking rule."""

import numpy as np
import pytest
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


def test_keep_first_never_replaces_the_first_frame_and_keeps_its_share() -> None:
    feats = torch.zeros(1, 1, 2, 2, 2, dtype=torch.float64)
    labels = torch.zeros(1, 1, 3, 2, 2, dtype=torch.float64)  # K-channel encodings as labels
    mem = memory_init(feats, labels, torch.ones_like(labels), 4, first_weight=1.0)
    for t in range(1, 12):
        f = torch.full((1, 2, 2, 2), float(t), dtype=torch.float64)
        mem = memory_insert(mem, f, torch.zeros(1, 3, 2, 2, dtype=torch.float64),
                            torch.ones(1, 3, 2, 2, dtype=torch.float64), torch.tensor([True]), 0.1, keep_first=0.25)
        w = mem.weights[0]
        assert mem.features[0, 0].eq(0).all() and float(w[0]) >= 0.25 - 1e-12
        assert float(w.sum()) == pytest.approx(1.0)
        # the later samples keep the decay rule among themselves: newest / previous = 1 / (1 - lr)
        if t >= 2:
            order = sorted(range(1, 4), key=lambda i: float(mem.features[0, i, 0, 0, 0]))
            filled = [i for i in order if float(w[i]) > 0]
            ratios = [float(w[b] / w[a]) for a, b in zip(filled, filled[1:], strict=False)]
            assert all(r == pytest.approx(1 / 0.9) for r in ratios)
    # the last three insertions fill slots 1..3
    assert sorted(float(mem.features[0, i, 0, 0, 0]) for i in range(1, 4)) == [9.0, 10.0, 11.0]
