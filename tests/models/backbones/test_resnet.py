"""ResNetBackbone: stage shapes, channels, frozen behaviour and input checks; the backbone factory."""

import pytest
import torch

from core.errors import InputError
from models.backbones import EfficientNetLiteBackbone, ResNetBackbone, build_backbone


@pytest.mark.parametrize("name, c3", [("resnet18", 256), ("resnet50", 1024)])
def test_stage_shapes_and_channels(name: str, c3: int) -> None:
    net = ResNetBackbone(name)
    feats = net(torch.rand(2, 3, 64, 96))
    assert list(feats) == ["layer1", "layer2", "layer3", "layer4"]
    assert net.channels["layer3"] == c3
    for stage, f in feats.items():
        s = net.strides[stage]
        assert f.shape == (2, net.channels[stage], 64 // s, 96 // s)


def test_frozen_stays_eval_and_takes_no_grad() -> None:
    net = ResNetBackbone("resnet18", frozen=True)
    net.train()
    assert not net.training and not any(p.requires_grad for p in net.parameters())
    trainable = ResNetBackbone("resnet18", frozen=False).train()
    assert trainable.training and all(p.requires_grad for p in trainable.parameters())


def test_stage_subset_skips_deeper_layers() -> None:
    net = ResNetBackbone("resnet18", stages=("layer1", "layer3"))
    assert "layer4" not in net.layers
    assert set(net(torch.rand(1, 3, 32, 32))) == {"layer1", "layer3"}


def test_bad_input() -> None:
    with pytest.raises(InputError, match="resnet7"):
        ResNetBackbone("resnet7")
    with pytest.raises(InputError, match="RGB"):
        ResNetBackbone("resnet18")(torch.rand(1, 1, 32, 32))


def test_factory_builds_both_families_by_name() -> None:
    assert isinstance(build_backbone("resnet18", stages=("layer2",)), ResNetBackbone)
    lite = build_backbone("efficientnet_lite0", None, stages=("layer2",))
    assert isinstance(lite, EfficientNetLiteBackbone) and lite.channels == {"layer2": 40}
    with pytest.raises(InputError, match="efficientnet_lite0"):
        build_backbone("mobilenet")
