"""LightningModule for FRTM (thesis ch. 5.3; paper D): trains the decoder (optionally the backbone too)
with the target model in the loop, and evaluates the full tracker on whole videos with the DAVIS J&F protocol.

Training step, per sample: augment the reference frame (first-frame augmentation), fit a fresh target model
on it with the optimizer module (C = 32, lambda = (1e-5, 1e-4), no pixel weights), apply it to the test
frames (no updates), decode, and take a binary cross-entropy loss per test frame. With ``train_backbone`` the
backbone is trained as well; ``backprop_through_optimizer`` then also differentiates through the unrolled
optimizer (its explicit Jacobian products are ordinary differentiable ops), so the features learn to suit the
target model; otherwise the fitted filters are treated as constants. With ``cache_training`` (frozen backbone)
each reference's fitted target model and each test frame's features are computed once and reused whenever a
sample meets them again, as FRTM cached its target models.
"""

from __future__ import annotations

import contextlib

import torch
import torch.nn.functional as F

from core.errors import InputError
from models.backbones import build_backbone
from models.vos.augment import first_frame_augment
from models.vos.decoder import SegmentationDecoder
from models.vos.lit_evaluation import VOSEvaluation
from models.vos.losses import segmentation_loss
from models.vos.optimizer import GaussNewtonCG, build_optimizer
from models.vos.target_features import TargetFeatures
from models.vos.target_model import apply_filter, project, target_model_init
from models.vos.tracker import FRTMTracker
from models.vos.tracker_settings import FRTMSettings
from models.vos.training_cache import KeyedMemo


class FRTMSegmentation(VOSEvaluation):
    """FRTM video object segmentation system.

    Args:
        backbone: ``resnet18`` .. ``resnet152`` or ``efficientnet_lite0`` .. ``2`` (``models.backbones``);
            weights: ``"imagenet"``, a torchvision weights name (ResNets) or None (random init).
        train_backbone: train the backbone too (needed without pretrained weights).
        backprop_through_optimizer: with ``train_backbone``, differentiate through the target-model fit.
        mdim: decoder width (64).
        feature_layer: stage the target model reads (layer3, stride 16), or stages joined by ``+``
            (``layer2+layer3``: concatenated at stride 8, as DAVOS).
        feature_norm, feature_scale: ``none``, ``fixed`` (divided by ``feature_scale``) or ``instance_l2``: scaling
            of the target model's features (``models.vos.target_features.normalize_features``), in training and in
            the tracker.
        feature_dropout: in training, the probability with which each channel of the backbone features the decoder
            reads is zeroed (``F.dropout2d``, the rest scaled by ``1 / (1 - p)``; the target model's input is
            untouched): a regulariser for a decoder trained on few sequences whose cached features repeat.
        train_channels, train_num_aug, train_reg, train_schedule, train_optimizer: target model fitted in
            training (32, 15, (1e-5, 1e-4), (5, 10, 10, 10, 10), ``gauss_newton``).
        loss, pos_weight, iou_weight, boundary_weight: decoder loss (``models.vos.losses.segmentation_loss``;
            FRTM: plain ``bce``; ``bce_iou`` adds a soft-IoU term against the collapse to background on small
            objects, ``bce_lovasz`` the Lovasz hinge instead; ``boundary_weight`` raises the BCE near the contours).
        target_loss_weight: weight of an auxiliary loss on the target model itself (mean squared error of its
            bilinearly upsampled test-frame scores against the test masks, the data term of eq. 5.2; FRTM: 0).
            It gives a backbone trained from scratch a direct signal to make the target model discriminative.
        lr, weight_decay, lr_step, lr_gamma: Adam and StepLR (FRTM 1e-3, 1e-5, 127, 0.1). amsgrad: FRTM's
            Adam variant (True); its step sizes never grow again after large early gradients, which can stall a
            network trained from scratch.
        tracker: ``FRTMSettings`` fields for validation, test and inference (the rest keep their defaults).
        seed: seeds augmentation and filter initialisation.
        init_checkpoint: checkpoint of an ``FRTMSegmentation`` with the same architecture whose weights
            ``fit`` starts from (fine-tuning, e.g. synthetic -> DAVIS). Unlike ``--ckpt_path`` it restores no
            optimizer, epoch or scheduler state; a resumed ``--ckpt_path`` still wins.
        cache_training: keep every fitted target model (per sequence, object, reference frame and mirroring) and
            every test frame's backbone features (float16; per mirroring and ``test_zoom``) in memory and reuse
            them; needs a frozen backbone and samples with ``sample_key`` / ``test_index`` (``DavisVOSDataModule``
            without crop; its ``reference_every`` bounds the fits). Each reference then keeps one first-frame
            augmentation. Memory: about 0.6 MB per 240p frame and mirroring with EfficientNet-Lite0.
    """

    def __init__(
        self,
        backbone: str = "resnet18",
        weights: str | None = None,
        train_backbone: bool = False,
        backprop_through_optimizer: bool = False,
        mdim: int = 64,
        feature_layer: str = "layer3",
        feature_norm: str = "none",
        feature_scale: float = 1.0,
        feature_dropout: float = 0.0,
        train_channels: int = 32,
        train_num_aug: int = 15,
        train_reg: tuple[float, float] = (1e-5, 1e-4),
        train_schedule: tuple[int, ...] = (5, 10, 10, 10, 10),
        train_optimizer: str = "gauss_newton",
        loss: str = "bce",
        pos_weight: float = 1.0,
        iou_weight: float = 1.0,
        boundary_weight: float = 0.0,
        target_loss_weight: float = 0.0,
        lr: float = 1e-3,
        weight_decay: float = 1e-5,
        lr_step: int = 127,
        lr_gamma: float = 0.1,
        amsgrad: bool = True,
        tracker: dict | None = None,
        seed: int = 0,
        init_checkpoint: str | None = None,
        cache_training: bool = False,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()
        if cache_training and train_backbone:
            raise InputError("cache_training needs a frozen backbone (train_backbone: false)")
        if not 0 <= feature_dropout < 1:
            raise InputError(f"feature_dropout must lie in [0, 1), got {feature_dropout}")
        self._fitted = KeyedMemo()
        self._test_features = KeyedMemo(torch.float16)
        self.backbone = build_backbone(backbone, weights, frozen=not train_backbone)
        self.target_input = TargetFeatures(feature_layer, self.backbone.channels, self.backbone.strides,
                                           feature_norm, feature_scale)
        self.decoder = SegmentationDecoder(self.backbone.channels, mdim)
        optimizer = build_optimizer(train_optimizer, train_schedule, train_reg)
        if isinstance(optimizer, GaussNewtonCG):
            optimizer.direction_forget = 0.9**75
        self.fit_optimizer = optimizer

    def tracker_settings(self, **overrides) -> FRTMSettings:
        """The tracker settings: this system's feature input, its ``tracker`` hyper-parameters, then ``overrides``."""
        h = self.hparams
        return FRTMSettings.from_dict({"feature_layer": h.feature_layer, "feature_norm": h.feature_norm,
                                       "feature_scale": h.feature_scale, **(h.tracker or {}), **overrides})

    def make_tracker(self, use_decoder: bool = True, **overrides) -> FRTMTracker:
        """A tracker sharing this module's backbone and decoder (``tracker_settings(**overrides)``)."""
        settings = self.tracker_settings(use_decoder=use_decoder, **overrides)
        return FRTMTracker(self.backbone, self.decoder, settings).eval()

    def forward(self, frames: torch.Tensor, first_mask: torch.Tensor) -> torch.Tensor:
        """Segment a video: frames (T, 3, H, W) in [0, 1] or uint8, first-frame labels (H, W) -> (T, H, W)."""
        return torch.stack(list(self.make_tracker().segment(frames, {0: first_mask})))

    def _fit_target_models(
        self, images: torch.Tensor, masks: torch.Tensor, seeds: list[int] | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Fit target models on augmented reference frames: (B, 3, H, W), (B, H, W) -> W_p, W_f; ``seeds`` (B)
        of the augmentations (default: from the seed and the step)."""
        h = self.hparams
        if seeds is None:
            seeds = [h.seed + int(self.global_step) * 131 + j for j in range(images.shape[0])]
        aug = [first_frame_augment(i, m, h.train_num_aug, seed)
               for i, m, seed in zip(images.detach(), masks, seeds, strict=True)]
        aug_images = torch.stack([a[0] for a in aug])
        aug_masks = torch.stack([a[1] for a in aug])
        b, k = aug_masks.shape[:2]
        differentiable = self.training and h.train_backbone and h.backprop_through_optimizer
        with contextlib.nullcontext() if differentiable else torch.no_grad():
            x = self.target_input(self.backbone(aug_images.flatten(0, 1)))
            x = x.view(b, k, *x.shape[1:])
            gamma = x.new_ones(b, k)
            gamma[:, 0] = 2
            gamma = gamma / gamma.sum(1, keepdim=True)
            wp, wf = target_model_init(b, x.shape[2], h.train_channels, 3, h.seed, x.dtype, x.device)
            wp, wf, _, _ = self.fit_optimizer(x, aug_masks, None, gamma, wf, wp)
        return wp, wf

    def _cached_inputs(
        self, batch: dict[str, torch.Tensor]
    ) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
        """W_p, W_f of the batch's references and the backbone features of its test frames (B T, ...), each
        computed the first time its key is met (``cache_training``)."""
        if "sample_key" not in batch or "test_index" not in batch:
            raise InputError("cache_training needs samples that name their frames (sample_key, test_index): "
                             "DavisVOSDataModule or YouTubeVOSDataModule without crop")
        h = self.hparams
        keys = [tuple(k) for k in batch["sample_key"].tolist()]  # (sequence, object, reference, mirrored)
        seeds = [h.seed + 1_000_003 * s + 10_007 * r + 101 * o + m for s, o, r, m in keys]

        def fit(pos: list[int]) -> dict[str, torch.Tensor]:
            wp, wf = self._fit_target_models(batch["ref_image"][pos], batch["ref_mask"][pos], [seeds[i] for i in pos])
            return {"wp": wp, "wf": wf}

        fitted = self._fitted(keys, fit)
        zooms = batch["test_zoom"].tolist() if "test_zoom" in batch else [[1.0] * len(t) for t in batch["test_index"]]
        # a zoomed frame's window is centred on its object, so the object is part of its key
        frames = [(s, f, m) if z == 1 else (s, f, m, o, z)
                  for (s, o, _, m), tests, zs in zip(keys, batch["test_index"].tolist(), zooms, strict=True)
                  for f, z in zip(tests, zs, strict=True)]
        test = batch["test_images"].flatten(0, 1)
        with torch.no_grad():
            feats = self._test_features(frames, lambda pos: self.backbone(test[pos]))
        self.log("train/cached_fits", float(len(self._fitted)))
        return fitted["wp"], fitted["wf"], feats

    def training_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> torch.Tensor:
        h = self.hparams
        test = batch["test_images"]
        b, t = test.shape[:2]
        if h.cache_training:
            wp, wf, feats = self._cached_inputs(batch)
        else:
            wp, wf = self._fit_target_models(batch["ref_image"], batch["ref_mask"])
            feats = self.backbone(test.flatten(0, 1))
        x = self.target_input(feats)
        score = apply_filter(project(x.view(b, t, *x.shape[1:]), wp), wf)
        if h.feature_dropout > 0 and self.training:
            feats = {k: F.dropout2d(v, h.feature_dropout) for k, v in feats.items()}
        logits = self.decoder(score.flatten(0, 1)[:, None], feats, tuple(test.shape[-2:]))
        masks = batch["test_masks"].flatten(0, 1)
        loss = segmentation_loss(logits[:, 0], masks, h.loss, h.pos_weight, h.iou_weight, h.boundary_weight)
        if h.target_loss_weight > 0:
            up = F.interpolate(score.flatten(0, 1)[:, None], size=masks.shape[-2:], mode="bilinear",
                               align_corners=False)[:, 0]
            target_loss = F.mse_loss(up, masks)
            self.log("train/target_loss", target_loss)
            loss = loss + h.target_loss_weight * target_loss
        with torch.no_grad():
            pred = logits[:, 0] > 0
            gt = masks > 0.5
            iou = ((pred & gt).flatten(1).sum(1) / (pred | gt).flatten(1).sum(1).clamp_min(1)).mean()
        self.log("train/loss", loss, prog_bar=True)
        self.log("train/iou", iou, prog_bar=True)
        return loss

    def configure_optimizers(self):
        h = self.hparams
        params = [p for p in self.parameters() if p.requires_grad]
        opt = torch.optim.Adam(params, lr=h.lr, weight_decay=h.weight_decay, amsgrad=h.amsgrad)
        sched = torch.optim.lr_scheduler.StepLR(opt, step_size=h.lr_step, gamma=h.lr_gamma)
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "epoch"}}
