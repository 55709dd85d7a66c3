"""KeyedMemo: rows computed once per key, handed back as computed; FRTMSegmentation's cached training step equals
the uncached one with the same augmentation seeds and runs the backbone and the fits only for new keys."""

import pytest
import torch

from core.errors import InputError
from data.vos.datamodule import SequenceTrainingSamples
from models.vos.lit import FRTMSegmentation
from models.vos.training_cache import KeyedMemo
from tests.data.vos.test_datamodule import FakeSequence


def _square(x: torch.Tensor, calls: list[list[int]]):
    def compute(positions: list[int]) -> dict[str, torch.Tensor]:
        calls.append(positions)
        return {"sq": x[positions].square(), "id": torch.tensor(positions)}
    return compute


def test_memo_computes_each_key_once_and_returns_rows_in_key_order() -> None:
    x = torch.randn(5, 3, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    memo, calls = KeyedMemo(), []
    keys = ["a", "b", "a", "c"]
    out = memo(keys, _square(x[[0, 1, 0, 2]], calls))
    assert calls == [[0, 1, 3]]  # "a" twice in the batch, computed once
    torch.testing.assert_close(out["sq"], x[[0, 1, 0, 2]].square(), rtol=0, atol=0)
    out = memo(["c", "d", "b"], _square(x[[2, 3, 1]], calls))
    assert calls[-1] == [1] and len(memo) == 4 and (memo.hits, memo.misses) == (3, 4)
    torch.testing.assert_close(out["sq"], x[[2, 3, 1]].square(), rtol=0, atol=0)
    assert out["id"].dtype == torch.int64


def test_memo_stores_in_half_precision_and_hands_back_the_computed_dtype() -> None:
    x = torch.randn(4, 8, generator=torch.Generator().manual_seed(1))
    memo = KeyedMemo(torch.float16)
    memo(range(4), lambda pos: {"x": x[pos]})
    out = memo([3, 0], lambda pos: pytest.fail("nothing new to compute"))
    assert out["x"].dtype == torch.float32
    torch.testing.assert_close(out["x"], x[[3, 0]], rtol=1e-3, atol=1e-3)


def test_memo_refuses_a_compute_with_the_wrong_row_count() -> None:
    with pytest.raises(InputError, match="2 rows for 3 keys"):
        KeyedMemo()(["a", "b", "c"], lambda pos: {"x": torch.zeros(2)})


def _model(**kw) -> FRTMSegmentation:
    torch.manual_seed(0)
    model = FRTMSegmentation(mdim=8, train_channels=8, train_num_aug=2, train_schedule=(2, 2), feature_layer="layer2",
                             **kw)
    model.log = lambda *a, **k: None
    return model


def test_cached_training_step_equals_the_uncached_one_and_reuses_fits_and_features() -> None:
    ds = SequenceTrainingSamples([FakeSequence()] * 2, 4, n_test_frames=2, max_gap=3, min_pixels=10, hflip=0.5,
                                 seed=4)
    batch = torch.utils.data.default_collate([ds[i] for i in range(4)])
    cached, plain = _model(cache_training=True), _model()
    plain.load_state_dict(cached.state_dict())
    calls = []
    cached.backbone.register_forward_hook(lambda m, i, o: calls.append(i[0].shape[0]))
    loss = cached.training_step(batch, 0)
    keys = [tuple(k) for k in batch["sample_key"].tolist()]
    seeds = [1_000_003 * s + 10_007 * r + 101 * o + m for s, o, r, m in keys]  # the cache's seeds (model seed 0)
    fits = plain._fit_target_models(batch["ref_image"], batch["ref_mask"], seeds)
    plain._fit_target_models = lambda images, masks: fits
    torch.testing.assert_close(loss, plain.training_step(batch, 0), rtol=2e-3, atol=1e-4)  # features in float16
    n_fits, n_frames = len(set(keys)), len({(s, f, m) for (s, _, _, m), t in
                                            zip(keys, batch["test_index"].tolist(), strict=True) for f in t})
    assert (len(cached._fitted), len(cached._test_features)) == (n_fits, n_frames)
    calls.clear()
    torch.testing.assert_close(cached.training_step(batch, 1), loss, rtol=0, atol=0)  # all served from memory
    assert calls == []


def test_cache_training_needs_a_frozen_backbone_and_named_samples() -> None:
    with pytest.raises(InputError, match="frozen backbone"):
        FRTMSegmentation(cache_training=True, train_backbone=True)
    ds = SequenceTrainingSamples([FakeSequence()], 2, n_test_frames=2, max_gap=3, min_pixels=10, crop=(8, 8))
    batch = torch.utils.data.default_collate([ds[0], ds[1]])
    with pytest.raises(InputError, match="sample_key"):
        _model(cache_training=True).training_step(batch, 0)


def test_zoomed_test_frames_are_cached_apart_from_the_unzoomed_ones() -> None:
    args = dict(n_test_frames=2, max_gap=3, min_pixels=10, seed=4)
    collate = torch.utils.data.default_collate
    plain = collate([SequenceTrainingSamples([FakeSequence()], 2, **args)[i] for i in range(2)])
    zoom = SequenceTrainingSamples([FakeSequence()], 2, zooms=[2.0], zoom_prob=1.0, **args)
    zoomed = collate([zoom[i] for i in range(2)])
    model = _model(cache_training=True)
    model.training_step(plain, 0)
    n_plain = len(model._test_features)
    frames = zoomed["test_images"].flatten(0, 1)
    _, _, feats = model._cached_inputs(zoomed)
    assert len(model._test_features) == 2 * n_plain  # every test frame again, zoomed
    expected = model.backbone(frames)
    for name, value in feats.items():
        torch.testing.assert_close(value, expected[name], rtol=2e-3, atol=2e-3)  # float16 storage
