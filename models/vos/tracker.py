"""FRTM online inference over a video (thesis ch. 5.3; paper D).

frame -> backbone features -> per object: target model W_f * (W_p * x) on stride-16 features -> coarse score
-> decoder (with all backbone stages) -> logit -> soft aggregation over objects -> labels; the merged soft
masks and projected features go into each object's memory, and W_f is re-optimised every ``update_every``
frames. A new object (in the first frame or later) gets the first-frame augmentation, a joint W_p/W_f fit,
then W_p is frozen. With ``flip_test`` the decoder's logits are averaged with those of the mirrored frame. With
``use_decoder=False`` the upsampled target-model score thresholded at 0.5 replaces the decoder (the
``target_model_only`` baseline). With ``search_radius`` an object's mask keeps only the components near its
previous mask (a search region, as the DCF trackers have; ``core.search_region``); with
``memory_main_component`` the memory learns from each object's largest component only; with ``ignore_band`` the
pixels just outside each mask get no weight in the memory; with ``keep_first`` the first frame keeps a share of
the memory's weight (LWL's rule).
"""

from __future__ import annotations

from abc import abstractmethod

import torch
import torch.nn.functional as F
from torch import nn

from core.errors import InputError
from core.search_region import (
    DROPPED_LOGIT,
    ignore_band,
    main_component,
    outside_search_region,
    unsupported_components,
)
from models.backbones import Backbone
from models.vos.augment import first_frame_augment
from models.vos.decoder import SegmentationDecoder, flip_averaged_logits
from models.vos.memory import Memory, memory_init, memory_insert
from models.vos.merge import merge_objects
from models.vos.optimizer import build_optimizer
from models.vos.target_features import TargetFeatures
from models.vos.target_model import apply_filter, hinge_pixel_weights, project, target_model_init
from models.vos.tracker_settings import FRTMSettings
from models.vos.video_loop import VideoLoop

COMPONENTS = ("backbone", "target_model", "decoder", "update", "init")


def frame_memory_insert(
    memory: Memory,
    z: torch.Tensor,
    labels: torch.Tensor,
    lr: float = 0.1,
    pixel_weighting: bool = True,
    fg_target: float = 0.1,
    min_pixels: int = 10,
    keep_first: float = 0.0,
    ignore: torch.Tensor | None = None,
) -> Memory:
    """Insert one frame per object: projected features z (B, C, h, w) and soft labels (B, H', W'); an object
    whose label has fewer than ``min_pixels`` pixels above 0.5 is skipped. Pixel weights follow the hinge rule;
    ``keep_first`` as in ``memory_insert``."""
    valid = (labels > 0.5).flatten(1).sum(1) >= min_pixels
    v = hinge_pixel_weights(labels[:, None], fg_target, min_pixels)[:, 0] if pixel_weighting else labels * 0 + 1
    if ignore is not None:
        v = v.masked_fill(ignore, 0)
    return memory_insert(memory, z, labels, v, valid, lr, keep_first)


class FRTMLoop(VideoLoop):
    """The host side of FRTM shared by every engine: objects, memory, the update schedule and the merging of
    objects, around five computational hooks (``target_features``, ``fit_target_models``, ``segment_frame``,
    ``insert_samples``, ``optimize_filters``) that ``FRTMTracker`` runs in PyTorch and
    ``runtime.vos.OnnxFRTMTracker`` reproduces in numpy on the exported graphs.

    Args:
        settings: the tracker settings (``FRTMSettings``).
    """

    def __init__(self, settings: FRTMSettings) -> None:
        self.settings = settings
        super().__init__(settings.process_height)

    def reset(self) -> None:
        """Forget the current video."""
        super().reset()
        self.wp: torch.Tensor | None = None
        self.wf: torch.Tensor | None = None
        self.memory: Memory | None = None
        self.cg_state = None

    def _label_size(self, size: tuple[int, int]) -> tuple[int, int]:
        return (max(1, size[0] // self.settings.label_stride), max(1, size[1] // self.settings.label_stride))

    def _to_label_res(self, masks: torch.Tensor) -> torch.Tensor:
        """(N, H, W) -> (N, H', W') soft masks at the memory label resolution."""
        if self.settings.label_stride == 1:
            return masks
        return F.interpolate(masks[:, None], size=self._label_size(masks.shape[-2:]), mode="area")[:, 0]

    def _pixel_weights(self, labels: torch.Tensor) -> torch.Tensor:
        if not self.settings.pixel_weighting:
            return torch.ones_like(labels)
        return hinge_pixel_weights(labels, self.settings.fg_target, self.settings.min_update_pixels)

    @abstractmethod
    def target_features(self, images: torch.Tensor) -> torch.Tensor:
        """Target-model features (M, D, h, w) of images (M, 3, H, W)."""

    @abstractmethod
    def fit_target_models(
        self, x: torch.Tensor, y: torch.Tensor, v: torch.Tensor, gamma: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Joint W_p/W_f fit on the augmented samples: x (B, K, D, h, w), y, v (B, K, H', W'), gamma (B, K)."""

    @abstractmethod
    def segment_frame(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Per-object logits (N, H, W) and projected features (N, C, h, w) of one frame (3, H, W)."""

    @abstractmethod
    def insert_samples(self, z: torch.Tensor, y: torch.Tensor, ignore: torch.Tensor | None = None) -> None:
        """Insert projected features (N, C, h, w) and soft labels (N, H', W') into the memory; ``ignore``
        (N, H', W') bool pixels get zero weight."""

    @abstractmethod
    def optimize_filters(self) -> None:
        """Re-optimise W_f on the filled memory slots."""

    def add_objects(self, image: torch.Tensor, labels: torch.Tensor, ids: list[int]) -> None:
        """Train target models for new objects ``ids`` whose masks are ``labels == id`` in ``image``: first-frame
        augmentation, joint W_p/W_f fit, W_p frozen, memory of the projected samples, one W_f update.

        Args:
            image: (3, H, W) RGB in [0, 1]; labels: (H, W) int label map.
        """
        device = image.device
        start = self._tic(device)
        if any(i in self.ids for i in ids):
            raise InputError(f"objects {sorted(set(ids) & set(self.ids))} are already tracked")
        images, masks = [], []
        for i, obj in enumerate(ids):
            mask = (labels == obj).to(image.dtype)
            if mask.sum() == 0:
                raise InputError(f"the first mask of object {obj} is empty")
            im, m = first_frame_augment(image, mask, self.settings.num_aug, self.settings.seed + 7919 * i + obj)
            images.append(im)
            masks.append(m)
        b, k = len(ids), self.settings.num_aug
        feats = self.target_features(torch.cat(images))
        x = feats.view(b, k, *feats.shape[1:])
        y = self._to_label_res(torch.cat(masks)).view(b, k, *self._label_size(image.shape[-2:]))
        v = self._pixel_weights(y)
        gamma = x.new_ones(b, k)
        gamma[:, 0] = 2
        gamma = gamma / gamma.sum(1, keepdim=True)
        wp, wf = self.fit_target_models(x, y, v, gamma)
        memory = memory_init(project(x, wp), y, v, self.settings.memory_size)
        if self.ids:
            mem = self.memory
            memory = Memory(*(torch.cat([a, c], 0) for a, c in zip(mem, memory, strict=True)))
            wp, wf = torch.cat([self.wp, wp]), torch.cat([self.wf, wf])
        self.ids += list(ids)
        self.wp, self.wf, self.memory, self.cg_state = wp, wf, memory, None
        self.optimize_filters()
        self._toc("init", start, device)

    def step(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Segment one frame; with ``search_radius`` the mask components far from each object's previous mask,
        and with ``score_support`` those its target model does not support, are given to the background
        (``core.search_region``) before the masks go to the memory.

        Args:
            image: (3, H, W) RGB in [0, 1].

        Returns:
            labels (H, W) int64, per-object merged soft masks (N, H, W) for the memory, projected features
            (N, C, h, w).
        """
        if not self.ids:
            raise InputError("no object is tracked: give a first-frame mask")
        logits, z = self.segment_frame(image)
        ids = torch.tensor(self.ids)
        labels, soft = merge_objects(logits, ids)
        if self.settings.search_radius > 0 and self.previous_labels is not None:
            drop = outside_search_region(labels.cpu().numpy(), self.previous_labels.cpu().numpy(), self.ids,
                                         self.settings.search_radius)
            if drop.any():
                logits = logits.masked_fill(torch.from_numpy(drop).to(logits.device), DROPPED_LOGIT)
                labels, soft = merge_objects(logits, ids)
        if self.settings.score_support:
            score = apply_filter(z[:, None], self.wf)[:, 0]  # (N, h, w), as in segment_frame
            drop = unsupported_components(labels.cpu().numpy(), score.float().cpu().numpy(), self.ids)
            if drop.any():
                logits = logits.masked_fill(torch.from_numpy(drop).to(logits.device), DROPPED_LOGIT)
                labels, soft = merge_objects(logits, ids)
        return labels, soft, z

    def update(self, soft: torch.Tensor, z: torch.Tensor) -> None:
        """Insert merged soft masks (N, H, W) and projected features into memory (with ``memory_main_component``
        each object's largest component only; with ``ignore_band`` zero pixel weight on a band around each mask);
        optimise every k frames."""
        device = soft.device
        start = self._tic(device)
        if self.settings.memory_main_component:
            soft = soft * torch.from_numpy(main_component((soft > 0.5).cpu().numpy())).to(device, soft.dtype)
        y = self._to_label_res(soft)
        ignore = None
        if self.settings.ignore_band > 0:
            ignore = torch.from_numpy(ignore_band((y > 0.5).cpu().numpy(), self.settings.ignore_band)).to(device)
        self.insert_samples(z, y, ignore)
        if self.frame % self.settings.update_every == 0:
            self.optimize_filters()
        self._toc("update", start, device)


class FRTMTracker(nn.Module, FRTMLoop):
    """Video object segmentation with fast and robust target models, computed in PyTorch.

    Args:
        backbone: feature extractor returning ``settings.feature_layer`` and the decoder's stages.
        decoder: segmentation decoder, or None (target-model-only segmentation).
        settings: ``FRTMSettings`` (default: the paper's inference settings).
    """

    def __init__(
        self, backbone: Backbone, decoder: SegmentationDecoder | None = None, settings: FRTMSettings | None = None
    ) -> None:
        nn.Module.__init__(self)
        settings = settings or FRTMSettings()
        self.backbone = backbone
        self.decoder = decoder
        self.target_input = TargetFeatures(settings.feature_layer, backbone.channels, backbone.strides,
                                           settings.feature_norm, settings.feature_scale)
        self.init_optimizer = build_optimizer(settings.optimizer, settings.init_schedule, settings.reg)
        self.update_optimizer = build_optimizer(settings.optimizer, settings.update_schedule, settings.reg)
        FRTMLoop.__init__(self, settings)

    @property
    def use_decoder(self) -> bool:
        """Whether the decoder segments (else the thresholded target-model score)."""
        return self.settings.use_decoder and self.decoder is not None

    @property
    def flip_test(self) -> bool:
        """Whether the decoder also reads the mirrored frame (``FRTMSettings.flip_test``)."""
        return self.settings.flip_test and self.use_decoder

    def target_features(self, images: torch.Tensor) -> torch.Tensor:
        """Target-model features (M, D, h, w) of images (M, 3, H, W)."""
        return torch.cat([self.target_input(self.backbone(x[None])) for x in images])

    def fit_target_models(
        self, x: torch.Tensor, y: torch.Tensor, v: torch.Tensor, gamma: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Joint W_p/W_f fit on the augmented samples: x (B, K, D, h, w), y, v (B, K, H', W'), gamma (B, K)."""
        b, d, s = x.shape[0], x.shape[2], self.settings
        wp, wf = target_model_init(b, d, s.channels, s.kernel_size, s.seed, x.dtype, x.device)
        dt = getattr(torch, s.optimizer_dtype)
        wp, wf, _, _ = self.init_optimizer(x.to(dt), y.to(dt), v.to(dt) if s.pixel_weighting else None,
                                           gamma.to(dt), wf.to(dt), wp.to(dt))
        return wp.to(x.dtype), wf.to(x.dtype)

    def segment_frame(self, image: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Per-object logits (N, H, W) and projected features (N, C, h, w) of one frame (3, H, W)."""
        device = image.device
        start = self._tic(device)
        feats = self.backbone(image[None])
        mirrored = self.backbone(image.flip(-1)[None]) if self.flip_test else None
        self._toc("backbone", start, device)
        start = self._tic(device)
        z = project(self.target_input(feats)[:, None], self.wp)[:, 0]  # (N, C, h, w)
        score = apply_filter(z[:, None], self.wf)[:, 0]  # (N, h, w)
        self._toc("target_model", start, device)
        start = self._tic(device)
        size = (image.shape[-2], image.shape[-1])
        if mirrored is not None:
            logits = flip_averaged_logits(self.decoder, score[:, None], feats, mirrored, size)[:, 0]
        elif self.use_decoder:
            logits = self.decoder(score[:, None], feats, size)[:, 0]
        else:
            up = F.interpolate(score[:, None], size=size, mode="bilinear", align_corners=False)[:, 0]
            logits = (up - 0.5) * 10  # score 0.5 <-> probability 0.5
        self._toc("decoder", start, device)
        return logits, z

    def insert_samples(self, z: torch.Tensor, y: torch.Tensor, ignore: torch.Tensor | None = None) -> None:
        """Insert projected features (N, C, h, w) and soft labels (N, H', W') into the memory; ``ignore``
        (N, H', W') bool pixels get zero weight."""
        s = self.settings
        self.memory = frame_memory_insert(self.memory, z, y, s.learning_rate, s.pixel_weighting, s.fg_target,
                                          s.min_update_pixels, s.keep_first, ignore)

    def optimize_filters(self) -> None:
        """Re-optimise W_f on the filled memory slots."""
        n = int((self.memory.weights > 0).sum(1).max())
        mem = self.memory
        dt, keep = getattr(torch, self.settings.optimizer_dtype), self.wf.dtype
        state = self.cg_state
        if state is not None:
            state = ([t.to(dt) for t in state[0]], state[1].to(dt), [t.to(dt) for t in state[2]])
        _, wf, state, _ = self.update_optimizer(
            mem.features[:, :n].to(dt), mem.labels[:, :n].to(dt), mem.pixel_weights[:, :n].to(dt),
            mem.weights[:, :n].to(dt), self.wf.to(dt), state=state,
        )
        self.wf = wf.to(keep)
        if state is not None:  # steepest descent keeps no state
            p, rho, r_prev = state
            state = ([t.to(keep) for t in p], rho.to(keep), [t.to(keep) for t in r_prev])
        self.cg_state = state
