"""Target-model input: feature norms against per-sample loops, stage concatenation against a direct build."""

import pytest
import torch
import torch.nn.functional as F

from core.errors import InputError
from models.vos.target_features import TargetFeatures, normalize_features


def test_feature_norms_against_per_sample_loops() -> None:
    x = torch.randn(3, 2, 5, 4, 6, generator=torch.Generator().manual_seed(0), dtype=torch.float64) * 7
    assert torch.equal(normalize_features(x), x)
    torch.testing.assert_close(normalize_features(x, "fixed", 7.0), x / 7.0)
    unit = normalize_features(x, "instance_l2")
    for i in range(3):
        for j in range(2):
            sample = x[i, j]
            torch.testing.assert_close(unit[i, j], sample / (sample**2).sum().div(sample.numel()).sqrt())
            assert abs(float((unit[i, j] ** 2).mean()) - 1) < 1e-12
    assert torch.equal(normalize_features(torch.zeros(1, 2, 3, 3), "instance_l2"), torch.zeros(1, 2, 3, 3))
    with pytest.raises(InputError, match="feature_norm"):
        normalize_features(x, "batch")
    with pytest.raises(InputError, match="feature_scale"):
        normalize_features(x, "fixed", 0.0)


def test_concatenated_stages_at_the_first_stage_resolution() -> None:
    g = torch.Generator().manual_seed(1)
    feats = {"layer2": torch.randn(2, 4, 6, 10, generator=g) * 3, "layer3": torch.randn(2, 5, 3, 5, generator=g)}
    channels, strides = {"layer2": 4, "layer3": 5}, {"layer2": 8, "layer3": 16}
    single = TargetFeatures("layer3", channels, strides, "fixed", 2.0)
    assert single.channels == 5 and single.stride == 16
    torch.testing.assert_close(single(feats), feats["layer3"] / 2)
    joined = TargetFeatures("layer2+layer3", channels, strides, "instance_l2")
    assert joined.channels == 9 and joined.stride == 8
    up = F.interpolate(feats["layer3"], size=(6, 10), mode="bilinear", align_corners=False)
    unit = [t / t.pow(2).mean((1, 2, 3), keepdim=True).sqrt() for t in (feats["layer2"], up)]
    torch.testing.assert_close(joined(feats), torch.cat(unit, 1))
    with pytest.raises(InputError, match="layer4"):
        TargetFeatures("layer2+layer4", channels, strides)
