"""The networks of LWL and DAVOS (thesis ch. 6; paper E) in one module, shared by training and the tracker.

frame -> backbone stages -> target-model features (the stages joined at the first one's stride, each scaled to
unit RMS, then a 3x3 projection and InstanceL2Norm) -> per object: scores = tau * x (K channels: the predicted
mask encoding) -> decoder with the backbone stages -> logits [target] (LWL) or [target, distractor] (DAVOS).
The filter tau is trained online by the steepest-descent module from the label encoder's E(y) and W(y); in
training the steps are unrolled so that the label encoder, lambda, the projection and the decoder learn what
the target model should learn.
"""

from __future__ import annotations

import contextlib

import torch
from torch import nn

from models.backbones import build_backbone
from models.vos.decoder import SegmentationDecoder
from models.vos.label_encoder import LabelEncoder
from models.vos.lwl_optimizer import LWLSteepestDescent
from models.vos.lwl_target_model import FeatureProjection, apply_filter
from models.vos.target_features import TargetFeatures


class DAVOSNet(nn.Module):
    """Backbone, target-model features, label encoder, steepest-descent trainer and decoder.

    Args:
        backbone, weights, train_backbone: ``models.backbones.build_backbone`` name, weights and whether the
            backbone is trained (frozen by default, as in the papers' first stage).
        feature_layer: the stages the target model reads (DAVOS ``layer2+layer3`` at stride 8; LWL ``layer3``).
        projection_channels: P, the projected feature width (LWL/DAVOS 512).
        encoding_channels: K, channels of the mask encoding and of the filter's output (LWL 16, DAVOS 32).
        distractors: two label channels [target, distractor] and two logits (DAVOS) or one (LWL).
        filter_size: k of the target-model filter (3).
        mdim: decoder width (64 in the papers).
        encoder_dims: label-encoder widths; pass_labels: the encoding's first channels are the labels themselves
            (``LabelEncoder``).
        train_iters: default steepest-descent steps; reg: initial lambda (0.01).
    """

    def __init__(
        self,
        backbone: str = "efficientnet_lite0",
        weights: str | None = "imagenet",
        train_backbone: bool = False,
        feature_layer: str = "layer2+layer3",
        projection_channels: int = 64,
        encoding_channels: int = 16,
        distractors: bool = True,
        filter_size: int = 3,
        mdim: int = 32,
        encoder_dims: tuple[int, int, int] | list[int] = (16, 32, 64),
        pass_labels: bool = False,
        train_iters: int = 5,
        reg: float = 0.01,
    ) -> None:
        super().__init__()
        self.backbone = build_backbone(backbone, weights, frozen=not train_backbone)
        self.target_input = TargetFeatures(feature_layer, self.backbone.channels, self.backbone.strides, "instance_l2")
        self.projection = FeatureProjection(self.target_input.channels, projection_channels, filter_size)
        self.label_channels = 2 if distractors else 1
        self.label_encoder = LabelEncoder(self.label_channels, encoding_channels, self.target_input.stride,
                                          encoder_dims, pass_labels)
        self.optimizer = LWLSteepestDescent(train_iters, reg)
        self.decoder = SegmentationDecoder(self.backbone.channels, mdim, score_channels=encoding_channels,
                                           out_channels=self.label_channels)
        self.filter_shape = (encoding_channels, projection_channels, filter_size, filter_size)

    def stages(self, images: torch.Tensor) -> dict[str, torch.Tensor]:
        """Backbone stages ``{stage: (N, C_l, h_l, w_l)}`` of images (N, 3, H, W) in [0, 1]."""
        with torch.no_grad() if self.backbone.frozen else contextlib.nullcontext():
            return self.backbone(images)

    def target_features(self, feats: dict[str, torch.Tensor]) -> torch.Tensor:
        """Target-model features (N, P, h, w) of backbone stages."""
        return self.projection(self.target_input(feats))

    def features(self, images: torch.Tensor) -> tuple[dict[str, torch.Tensor], torch.Tensor]:
        """``stages`` and ``target_features`` of images (N, 3, H, W)."""
        feats = self.stages(images)
        return feats, self.target_features(feats)

    def encode(self, labels: torch.Tensor, size: tuple[int, int]) -> tuple[torch.Tensor, torch.Tensor]:
        """E(y), W(y) (N, K, h, w) of labels (N, L, H, W) at the features' size (h, w)."""
        return self.label_encoder(labels, size)

    def initial_filter(self, n: int, like: torch.Tensor) -> torch.Tensor:
        """Zero filters (n, K, P, k, k) (LWL's initialisation) with ``like``'s dtype and device."""
        return like.new_zeros(n, *self.filter_shape)

    def scores(self, tau: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """Predicted mask encodings (N, K, h, w) of N problems with their own features x (N, P, h, w)."""
        return apply_filter(x[:, None], tau)[:, 0]

    def frame_scores(self, tau: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """Predicted mask encodings (N, K, h, w) of N objects in one frame's features x (1, P, h, w)."""
        n, k, p, size, _ = tau.shape
        out = nn.functional.conv2d(x, tau.reshape(n * k, p, size, size), padding=size // 2)
        return out.view(n, k, *x.shape[-2:])

    def decode(self, scores: torch.Tensor, feats: dict[str, torch.Tensor], size: tuple[int, int]) -> torch.Tensor:
        """Logits (N, L, H, W) from scores (N, K, h, w) and stages with batch N or 1."""
        return self.decoder(scores, feats, size)
