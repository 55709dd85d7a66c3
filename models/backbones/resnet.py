"""ResNet feature extractor (torchvision) for the horizon networks (ch. 4.3) and the VOS networks (ch. 5).

``ResNetBackbone`` wraps a torchvision ResNet without its average pool and classifier and returns the four
residual stages. Stage names follow torchvision (``layer1`` .. ``layer4``, strides 4, 8, 16, 32); FRTM's code
calls them ``layer2`` .. ``layer5``. Inputs are RGB images in [0, 1]; the ImageNet normalisation is applied
inside, so callers never repeat it.
"""

from __future__ import annotations

import torch
import torchvision
from torch import nn

from core.errors import InputError
from models.backbones.base import STAGES, STRIDES, Backbone, check_stages

_IMAGENET_MEAN = (0.485, 0.456, 0.406)
_IMAGENET_STD = (0.229, 0.224, 0.225)
RESNETS = ("resnet18", "resnet34", "resnet50", "resnet101", "resnet152")


class ResNetBackbone(Backbone):
    """Torchvision ResNet returning the four stages as a dict.

    Args:
        name: one of ``resnet18``, ``resnet34``, ``resnet50``, ``resnet101``, ``resnet152``.
        weights: torchvision weights name (e.g. ``"IMAGENET1K_V1"``, ``"DEFAULT"``; ``"imagenet"`` means
            ``"IMAGENET1K_V1"``, the weights FRTM used) or ``None`` for random initialisation. Weights are
            downloaded by torchvision into its cache on first use.
        frozen: if True, no parameter takes gradients and batch norm stays in eval mode even in ``train()``.
        stages: the stages ``forward`` computes; deeper stages than the deepest requested are skipped.

    Attributes:
        channels: ``{stage: channels}``, e.g. ``layer3: 256`` for resnet18 and ``1024`` for resnet50/101.
        strides: ``{stage: stride}`` in input pixels.
    """

    def __init__(
        self,
        name: str = "resnet18",
        weights: str | None = None,
        frozen: bool = True,
        stages: tuple[str, ...] | list[str] = STAGES,
    ) -> None:
        super().__init__()
        if name not in RESNETS:
            raise InputError(f"backbone name {name!r} is not one of {', '.join(RESNETS)}")
        self.name = name
        self.stages = check_stages(stages)
        net = getattr(torchvision.models, name)(weights="IMAGENET1K_V1" if weights == "imagenet" else weights)
        self.stem = nn.Sequential(net.conv1, net.bn1, net.relu, net.maxpool)
        deepest = STAGES.index(self.stages[-1])
        self.layers = nn.ModuleDict({s: getattr(net, s) for s in STAGES[: deepest + 1]})
        expansion = 1 if name in ("resnet18", "resnet34") else 4
        self.channels = {s: 64 * 2**i * expansion for i, s in enumerate(STAGES) if s in self.stages}
        self.strides = {s: STRIDES[s] for s in self.stages}
        self.register_buffer("mean", torch.tensor(_IMAGENET_MEAN).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(_IMAGENET_STD).view(1, 3, 1, 1), persistent=False)
        self.freeze(frozen)

    def forward(self, image: torch.Tensor) -> dict[str, torch.Tensor]:
        """Features of ``image``.

        Args:
            image: (B, 3, H, W) RGB in [0, 1].

        Returns:
            ``{stage: (B, channels[stage], ~H / stride, ~W / stride)}`` for the requested stages.
        """
        self.check_image(image)
        x = self.stem((image - self.mean.to(image.dtype)) / self.std.to(image.dtype))
        out: dict[str, torch.Tensor] = {}
        for stage, layer in self.layers.items():
            x = layer(x)
            if stage in self.stages:
                out[stage] = x
        return out
