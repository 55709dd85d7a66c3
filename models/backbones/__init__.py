"""Feature extractors with four stages ``layer1`` .. ``layer4`` (strides 4, 8, 16, 32) and ``build_backbone``."""

from models.backbones.base import STAGES, STRIDES, Backbone
from models.backbones.efficientnet_lite import EfficientNetLite, EfficientNetLiteBackbone, efficientnet_lite
from models.backbones.factory import BACKBONES, build_backbone
from models.backbones.resnet import ResNetBackbone

__all__ = ["BACKBONES", "STAGES", "STRIDES", "Backbone", "EfficientNetLite", "EfficientNetLiteBackbone",
           "ResNetBackbone", "build_backbone", "efficientnet_lite"]
