"""LightningModule for DAVOS and LWL (thesis ch. 6; paper E): meta-learning the label encoder, the target
model's feature projection and regularisation, and the decoder through the unrolled steepest-descent trainer.

Training step, per sample (a reference frame and T later test frames of one target; the other annotated
objects are its distractors): the label [target, distractor] of the reference frame is encoded and a zero
filter gets ``train_init_iters`` steps on it. For each test frame in turn the filter predicts the mask
encoding, the decoder turns it into target and distractor logits, the loss (``davos_loss``: Lovasz terms,
soft loss masking of the distractor channel) is taken, and, before the next test frame, the sigmoid of the
prediction (detached, as in LWL) joins the samples and the filter gets ``train_refine_iters`` more steps. The
loss is the mean over the test frames. Gradients flow through every unrolled step into the label encoder,
lambda, the projection and the decoder; the backbone stays frozen (stage 1 of the papers).
"""

from __future__ import annotations

import torch

from models.vos.davos_loss import davos_loss
from models.vos.davos_net import DAVOSNet
from models.vos.davos_settings import DAVOSSettings
from models.vos.davos_tracker import DAVOSTracker
from models.vos.lit_evaluation import VOSEvaluation


class DAVOSSegmentation(VOSEvaluation):
    """DAVOS (``distractors=True``) or LWL (``distractors=False``) video object segmentation system.

    Args:
        backbone, weights, train_backbone, feature_layer, projection_channels, encoding_channels, distractors,
            mdim, encoder_dims, pass_labels, reg: the networks (``DAVOSNet``).
        train_init_iters: steepest-descent steps on the reference frame (LWL/DAVOS 5).
        train_refine_iters: steps after each test frame but the last (LWL 2, DAVOS 4).
        loss: ``lovasz`` (the papers), ``bce`` or ``bce_iou`` for both terms; boundary_weight: extra BCE weight
            near the contours (``models.vos.losses.segmentation_loss``); soft_loss: soft loss masking of the
            distractor term (False: the "hard loss" ablation).
        lr, weight_decay, lr_milestones, lr_gamma: Adam and MultiStepLR over epochs (papers: milestones 40, 0.2).
        tracker: ``DAVOSSettings`` fields for validation, test and inference.
        init_checkpoint: weights to start ``fit`` from (no optimizer state).
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
        mdim: int = 32,
        encoder_dims: tuple[int, int, int] = (16, 32, 64),
        pass_labels: bool = False,
        reg: float = 0.01,
        train_init_iters: int = 5,
        train_refine_iters: int = 4,
        loss: str = "lovasz",
        boundary_weight: float = 0.0,
        soft_loss: bool = True,
        lr: float = 1e-3,
        weight_decay: float = 0.0,
        lr_milestones: tuple[int, ...] = (40,),
        lr_gamma: float = 0.2,
        tracker: dict | None = None,
        init_checkpoint: str | None = None,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()
        self.net = DAVOSNet(backbone, weights, train_backbone, feature_layer, projection_channels, encoding_channels,
                            distractors, mdim=mdim, encoder_dims=encoder_dims, pass_labels=pass_labels,
                            train_iters=train_init_iters, reg=reg)
        DAVOSSettings.from_dict(tracker or {})  # a bad setting fails here, not after training

    def tracker_settings(self, **overrides) -> DAVOSSettings:
        """The tracker settings: this system's ``tracker`` hyper-parameters, then ``overrides``."""
        return DAVOSSettings.from_dict({**(self.hparams.tracker or {}), **overrides})

    def make_tracker(self, **overrides) -> DAVOSTracker:
        """A tracker sharing this module's networks (``tracker_settings(**overrides)``)."""
        return DAVOSTracker(self.net, self.tracker_settings(**overrides)).eval()

    def forward(self, frames: torch.Tensor, first_labels: torch.Tensor) -> torch.Tensor:
        """Segment a video: frames (T, 3, H, W) in [0, 1] or uint8, first-frame labels (H, W) -> (T, H, W)."""
        return torch.stack(list(self.make_tracker().segment(frames, {0: first_labels})))

    def _labels(self, target: torch.Tensor, distractor: torch.Tensor) -> torch.Tensor:
        return torch.stack([target, distractor], 1) if self.net.label_channels == 2 else target[:, None]

    def training_step(self, batch: dict[str, torch.Tensor], batch_idx: int) -> torch.Tensor:
        h, net = self.hparams, self.net
        test = batch["test_images"]
        b, t = test.shape[:2]
        size = tuple(test.shape[-2:])
        feats, x = net.features(torch.cat([batch["ref_image"][:, None], test], 1).flatten(0, 1))
        feats = {k: v.view(b, t + 1, *v.shape[1:]) for k, v in feats.items()}
        x = x.view(b, t + 1, *x.shape[1:])
        encodings, weights = net.encode(self._labels(batch["ref_mask"], batch["ref_distractor"]), x.shape[-2:])
        tau, _ = net.optimizer(net.initial_filter(b, x), x[:, :1], encodings[:, None], weights[:, None],
                               x.new_ones(b, 1), h.train_init_iters)
        samples = [(encodings, weights)]
        losses, ious = [], []
        for i in range(t):
            logits = net.decode(net.scores(tau, x[:, i + 1]), {k: v[:, i + 1] for k, v in feats.items()}, size)
            target = batch["test_masks"][:, i]
            losses.append(davos_loss(logits, target, batch["test_distractors"][:, i], batch["has_distractors"],
                                     h.loss, h.soft_loss, boundary_weight=h.boundary_weight))
            with torch.no_grad():
                pred, gt = logits[:, 0] > 0, target > 0.5
                ious.append(((pred & gt).flatten(1).sum(1) / (pred | gt).flatten(1).sum(1).clamp_min(1)).mean())
            if i < t - 1 and h.train_refine_iters > 0:
                samples.append(net.encode(torch.sigmoid(logits.detach()), x.shape[-2:]))
                n = len(samples)
                tau, _ = net.optimizer(tau, x[:, :n], torch.stack([e for e, _ in samples], 1),
                                       torch.stack([w for _, w in samples], 1), x.new_full((b, n), 1 / n),
                                       h.train_refine_iters)
        loss = torch.stack(losses).mean()
        self.log("train/loss", loss, prog_bar=True)
        self.log("train/iou", torch.stack(ious).mean(), prog_bar=True)
        self.log("train/lambda", net.optimizer.reg.detach().abs())
        return loss

    def configure_optimizers(self):
        h = self.hparams
        params = [p for p in self.parameters() if p.requires_grad]
        opt = torch.optim.Adam(params, lr=h.lr, weight_decay=h.weight_decay)
        sched = torch.optim.lr_scheduler.MultiStepLR(opt, milestones=list(h.lr_milestones), gamma=h.lr_gamma)
        return {"optimizer": opt, "lr_scheduler": {"scheduler": sched, "interval": "epoch"}}
